/* One ABI for Rust over Embree 3 and Embree 4.
 *
 * The two major versions differ in ways bindgen cannot paper over:
 *  - rtcIntersect1/rtcOccluded1 take (scene, context, ray) in Embree 3 and
 *    (scene, ray, args) in Embree 4;
 *  - Embree 3 needs an RTCIntersectContext whose initialiser, rtcInitIntersectContext,
 *    is a header-only inline function (no symbol in the shared library), and
 *    Embree 4 replaced it with optional RTCIntersectArguments.
 * build.rs defines CVT_EMBREE_MAJOR and adds the include directory.
 */
#if CVT_EMBREE_MAJOR == 4
#include <embree4/rtcore.h>
#elif CVT_EMBREE_MAJOR == 3
#include <embree3/rtcore.h>
#else
#error "CVT_EMBREE_MAJOR must be 3 or 4"
#endif

/* Nearest hit along rayhit->ray; fills rayhit->hit (geomID stays RTC_INVALID_GEOMETRY_ID on a miss). */
void cvt_intersect1(RTCScene scene, struct RTCRayHit* rayhit)
{
#if CVT_EMBREE_MAJOR == 4
  rtcIntersect1(scene, rayhit, NULL);
#else
  struct RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcIntersect1(scene, &context, rayhit);
#endif
}

/* Nearest hits of n rays that start close together and point alike (the camera rays of one
 * pixel), rayhits[i] at byte offset i * stride. Embree 3 traces them in its coherent stream
 * mode, about 2.5x cheaper per ray than one by one; Embree 4 has no stream API, so there each
 * ray goes alone with the coherent hint. */
void cvt_intersect_coherent(RTCScene scene, struct RTCRayHit* rayhits, unsigned int n, size_t stride)
{
#if CVT_EMBREE_MAJOR == 4
  struct RTCIntersectArguments args;
  rtcInitIntersectArguments(&args);
  args.flags = RTC_RAY_QUERY_FLAG_COHERENT;
  for (unsigned int i = 0; i < n; i++)
    rtcIntersect1(scene, (struct RTCRayHit*)((char*)rayhits + i * stride), &args);
#else
  struct RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  rtcIntersect1M(scene, &context, rayhits, n, stride);
#endif
}

/* Any hit in [tnear, tfar]: Embree sets ray->tfar to -inf when one is found. */
void cvt_occluded1(RTCScene scene, struct RTCRay* ray)
{
#if CVT_EMBREE_MAJOR == 4
  rtcOccluded1(scene, ray, NULL);
#else
  struct RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcOccluded1(scene, &context, ray);
#endif
}

/* The Embree major version the shim was compiled against (a link-time sanity check). */
int cvt_embree_major(void)
{
  return RTC_VERSION_MAJOR;
}

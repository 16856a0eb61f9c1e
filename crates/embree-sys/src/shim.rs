//! The calls whose form differs between Embree 3 and Embree 4:
//! - `rtcIntersect1`/`rtcOccluded1` take `(scene, context, ray)` in Embree 3 and
//!   `(scene, ray, arguments)` in Embree 4;
//! - Embree 3 needs an `RTCIntersectContext`, whose initialiser is an inline function of its
//!   headers (no symbol in the library), and Embree 4 replaced it by optional arguments, also
//!   initialised inline. Both initialisers are written here, so no C compiler or header is
//!   needed for a library that ships without them.
use crate::*;

/// What `rtcInitIntersectContext` makes: the given flags, no filter, no instance on the stack
/// (fields a configuration adds, such as a minimum width or an instance stack size, are zero,
/// as the initialiser sets them).
#[cfg(embree_major = "3")]
fn context(flags: RTCIntersectContextFlags) -> RTCIntersectContext {
    let mut context = RTCIntersectContext { flags, ..Default::default() };
    context.instID.fill(RTC_INVALID_GEOMETRY_ID);
    context
}

/// What `rtcInitIntersectArguments` makes, with `flags`, followed by room for fields a build
/// option adds at the end of the structure (`minWidthDistanceFactor`), which the library then
/// reads as zero, the value the initialiser gives them.
#[cfg(embree_major = "4")]
#[repr(C)]
struct Arguments {
    args: RTCIntersectArguments,
    _room: [u64; 4],
}

#[cfg(embree_major = "4")]
fn arguments(flags: RTCRayQueryFlags) -> Arguments {
    let args = RTCIntersectArguments { flags, feature_mask: RTCFeatureFlags::RTC_FEATURE_FLAG_ALL, ..Default::default() };
    Arguments { args, _room: [0; 4] }
}

/// Nearest hit along `rayhit.ray`; fills `rayhit.hit` (`geomID` stays
/// [`RTC_INVALID_GEOMETRY_ID`] on a miss).
///
/// # Safety
/// `scene` is a committed scene and `rayhit` points to an initialised, 16-byte aligned
/// `RTCRayHit` (with room for the instance fields of any configuration: the bindings' type).
#[inline]
pub unsafe fn intersect1(scene: RTCScene, rayhit: *mut RTCRayHit) {
    #[cfg(embree_major = "3")]
    {
        let mut context = context(RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: the caller's guarantees, and a context initialised as Embree's own initialiser does.
        unsafe { rtcIntersect1(scene, &mut context, rayhit) };
    }
    #[cfg(embree_major = "4")]
    // SAFETY: the caller's guarantees; null arguments select the defaults.
    unsafe {
        rtcIntersect1(scene, rayhit, std::ptr::null_mut())
    };
}

/// Nearest hits of `n` rays that start close together and point alike, `rayhits[i]` at byte
/// offset `i * stride`. Embree 3 traces them in its coherent stream mode; Embree 4 has no
/// stream API, so there each ray goes alone with the coherent hint.
///
/// # Safety
/// `scene` is a committed scene, and `rayhits` points to `n` initialised, 16-byte aligned
/// `RTCRayHit`s `stride` bytes apart.
#[inline]
pub unsafe fn intersect_coherent(scene: RTCScene, rayhits: *mut RTCRayHit, n: u32, stride: usize) {
    #[cfg(embree_major = "3")]
    {
        let mut context = context(RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
        // SAFETY: the caller's guarantees, and an initialised context.
        unsafe { rtcIntersect1M(scene, &mut context, rayhits, n, stride) };
    }
    #[cfg(embree_major = "4")]
    {
        let mut args = arguments(RTCRayQueryFlags::RTC_RAY_QUERY_FLAG_COHERENT);
        for i in 0..n as usize {
            // SAFETY: the caller's guarantees put ray `i` at this offset; the arguments are
            // initialised as Embree's initialiser does, with room for optional fields.
            unsafe { rtcIntersect1(scene, rayhits.byte_add(i * stride), &mut args.args) };
        }
    }
}

/// Any hit in `[tnear, tfar]`: Embree sets `ray.tfar` to −∞ when there is one.
///
/// # Safety
/// `scene` is a committed scene and `ray` points to an initialised, 16-byte aligned `RTCRay`.
#[inline]
pub unsafe fn occluded1(scene: RTCScene, ray: *mut RTCRay) {
    #[cfg(embree_major = "3")]
    {
        let mut context = context(RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: the caller's guarantees, and an initialised context.
        unsafe { rtcOccluded1(scene, &mut context, ray) };
    }
    #[cfg(embree_major = "4")]
    // SAFETY: the caller's guarantees; null arguments select the defaults.
    unsafe {
        rtcOccluded1(scene, ray, std::ptr::null_mut())
    };
}

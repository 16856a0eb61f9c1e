//! The calls whose form differs between Embree 3 and Embree 4:
//! - `rtcIntersect1`/`rtcOccluded1` take `(scene, context, ray)` in Embree 3 and
//!   `(scene, ray, arguments)` in Embree 4;
//! - Embree 3 needs an `RTCIntersectContext`, whose initialiser is an inline function of its
//!   headers (no symbol in the library), and Embree 4 replaced it by optional arguments, also
//!   initialised inline. Both initialisers are written here, so no C compiler or header is
//!   needed for a library that ships without them;
//! - the packet calls (`rtcIntersect8/16`, `rtcOccluded8/16`) take `(valid, scene, context,
//!   rays)` in Embree 3 and `(valid, scene, rays, arguments)` in Embree 4.
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

/// The lane masks of an 8-wide packet call: −1 for a lane that is traced, 0 for one left as
/// it is. Embree loads them as one vector, so they are aligned as the packet is.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Valid8(pub [i32; 8]);

/// The lane masks of a 16-wide packet call, aligned as the packet is (see [`Valid8`]).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Valid16(pub [i32; 16]);

/// The packet calls of one width: the nearest hits and the occlusion of `N` rays in
/// structure-of-arrays form, of which the lanes whose `valid` entry is −1 are traced (0: left
/// as they are).
macro_rules! packet_calls {
    ($intersect:ident, $occluded:ident, $valid:ty, $rayhit:ty, $ray:ty, $rtc_intersect:ident, $rtc_occluded:ident, $n:literal) => {
        #[doc = concat!("Nearest hits of the valid lanes of a packet of ", stringify!($n), " rays (Embree's `", stringify!($rtc_intersect), "`): fills their `hit` (`geomID` stays [`RTC_INVALID_GEOMETRY_ID`] on a miss) and sets their `tfar` to the hit distance.")]
        ///
        /// # Safety
        /// `scene` is a committed scene, `valid` points to the packet's lane masks (−1 traced,
        /// 0 not) and `rayhit` to an initialised packet, both aligned as their types are.
        #[inline]
        pub unsafe fn $intersect(scene: RTCScene, valid: *const $valid, rayhit: *mut $rayhit) {
            #[cfg(embree_major = "3")]
            {
                let mut context = context(RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
                // SAFETY: the caller's guarantees, and an initialised context.
                unsafe { $rtc_intersect(valid.cast(), scene, &mut context, rayhit) };
            }
            #[cfg(embree_major = "4")]
            // SAFETY: the caller's guarantees; null arguments select the defaults.
            unsafe {
                $rtc_intersect(valid.cast(), scene, rayhit, std::ptr::null_mut())
            };
        }

        #[doc = concat!("Occlusion of the valid lanes of a packet of ", stringify!($n), " rays in `[tnear, tfar]` (Embree's `", stringify!($rtc_occluded), "`): Embree sets `tfar` to −∞ where something is hit.")]
        ///
        /// # Safety
        /// As for the nearest-hit call of this width, with an initialised ray packet.
        #[inline]
        pub unsafe fn $occluded(scene: RTCScene, valid: *const $valid, ray: *mut $ray) {
            #[cfg(embree_major = "3")]
            {
                let mut context = context(RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
                // SAFETY: the caller's guarantees, and an initialised context.
                unsafe { $rtc_occluded(valid.cast(), scene, &mut context, ray) };
            }
            #[cfg(embree_major = "4")]
            // SAFETY: the caller's guarantees; null arguments select the defaults.
            unsafe {
                $rtc_occluded(valid.cast(), scene, ray, std::ptr::null_mut())
            };
        }
    };
}

packet_calls!(intersect8, occluded8, Valid8, RTCRayHit8, RTCRay8, rtcIntersect8, rtcOccluded8, 8);
packet_calls!(intersect16, occluded16, Valid16, RTCRayHit16, RTCRay16, rtcIntersect16, rtcOccluded16, 16);

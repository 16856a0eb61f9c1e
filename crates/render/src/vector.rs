//! Vector helpers shared by the camera, the BSDFs and the lights.
use glam::Vec3A;

/// `v` scaled to unit length by the reciprocal of its length, as glam's scalar
/// `Vec3::normalize` does; `Vec3A::normalize` divides by the length, which rounds differently.
/// Renders kept this rounding when the render path moved from `Vec3` to the SIMD `Vec3A`
/// (docs/performance.md), so no image changed.
#[inline]
pub fn unit(v: Vec3A) -> Vec3A {
    v * v.length_recip()
}

/// Rec. 709 luminance, used to weight lobes and lights.
#[inline]
pub fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_rounds_as_the_scalar_normalize() {
        let mut state = 1u64;
        for _ in 0..10_000 {
            let mut next = || {
                state = crate::sampler::mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
                (state >> 40) as f32 / (1u64 << 24) as f32 * 200.0 - 100.0
            };
            let v = glam::Vec3::new(next(), next(), next());
            assert_eq!(unit(v.into()).to_array(), v.normalize().to_array(), "{v}");
        }
    }
}

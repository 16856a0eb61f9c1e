//! Selects that stay free of branches.
//!
//! Why: where a condition is a coin toss (which octant a random point falls in, which half of
//! a quad a ray hits), a branch is mispredicted about half the time. The compiler turns scalar
//! selects, even `std::hint::select_unpredictable` and bit-mask forms, back into branches; a
//! select of SIMD lanes it keeps as a blend.
use glam::{BVec4A, Vec4};

/// `if c { a } else { b }` for up to four floats at once, as one lane blend.
#[inline]
pub fn select4(c: bool, a: Vec4, b: Vec4) -> Vec4 {
    Vec4::select(BVec4A::splat(c), a, b)
}

/// `if c { a } else { b }` for a pair of floats.
#[inline]
pub fn select_pair(c: bool, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    let v = select4(c, Vec4::new(a.0, a.1, 0.0, 0.0), Vec4::new(b.0, b.1, 0.0, 0.0));
    (v.x, v.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selects_the_first_when_true_and_the_second_when_false() {
        let (a, b) = (Vec4::new(1.0, -0.0, f32::INFINITY, 4.0), Vec4::new(-1.0, 0.0, 3.0, f32::MIN_POSITIVE));
        assert_eq!(select4(true, a, b).to_array().map(f32::to_bits), a.to_array().map(f32::to_bits));
        assert_eq!(select4(false, a, b).to_array().map(f32::to_bits), b.to_array().map(f32::to_bits));
        assert_eq!(select_pair(true, (1.0, 2.0), (3.0, 4.0)), (1.0, 2.0));
        assert_eq!(select_pair(false, (1.0, 2.0), (3.0, 4.0)), (3.0, 4.0));
    }
}

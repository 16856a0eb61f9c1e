//! Emissive triangles as area lights: a point uniformly on the chosen triangle (the triangle
//! itself is chosen by [`super::LightSet`] in proportion to `luminance(emission) · area`).
//!
//! Emitters are one-sided: they emit from the front face, i.e. the side the geometric normal
//! `(p1 − p0) × (p2 − p0)` points to (counter-clockwise winding, as glTF specifies).
use crate::vector::luminance;
use glam::{Vec2, Vec3A};

/// Power of a triangle as a light: luminance of its mean emission times its area.
pub fn triangle_power(mean_emission: Vec3A, area: f32) -> f64 {
    (luminance(mean_emission.max(Vec3A::ZERO)) as f64) * area as f64
}

/// A uniform point on the triangle by the square-root warp: `(point, barycentrics (u, v) of
/// vertices 1 and 2)` in Embree's convention.
#[inline]
pub fn sample_triangle(u: Vec2, [p0, p1, p2]: [Vec3A; 3]) -> (Vec3A, Vec2) {
    let su = u.x.sqrt();
    let bary = Vec2::new(su * (1.0 - u.y), su * u.y);
    (p0 * (1.0 - bary.x - bary.y) + p1 * bary.x + p2 * bary.y, bary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_uniform_on_the_triangle() {
        // Mean of a uniform point on a triangle is its centroid; check with a fixed-seed MC bound.
        use crate::sampler::{StreamKind, StreamSampler};
        let verts = [Vec3A::ZERO, Vec3A::new(2.0, 0.0, 0.0), Vec3A::new(0.0, 1.0, 0.0)];
        let st = StreamSampler::new(1, StreamKind::Pt);
        let n = 40_000;
        let mut sum = Vec3A::ZERO.as_dvec3();
        let mut inside_lower_half = 0;
        for i in 0..n {
            let (point, bary) = sample_triangle(st.sample(0, i).get2d(0), verts);
            assert!((verts[0] * (1.0 - bary.x - bary.y) + verts[1] * bary.x + verts[2] * bary.y - point).length() < 1e-6);
            sum += point.as_dvec3();
            // The region y < 0.5 holds 3/4 of the triangle's area.
            inside_lower_half += (point.y < 0.5) as u32;
        }
        let mean = sum / n as f64;
        let centroid = (verts[0] + verts[1] + verts[2]).as_dvec3() / 3.0;
        // Coordinates are bounded by 2, so sd of the mean ≤ 2/sqrt(n).
        assert!((mean - centroid).length() < 5.0 * 2.0 / (n as f64).sqrt(), "{mean} vs {centroid}");
        let p = inside_lower_half as f64 / n as f64;
        assert!((p - 0.75).abs() < 5.0 * (0.75f64 * 0.25 / n as f64).sqrt(), "{p}");
    }
}

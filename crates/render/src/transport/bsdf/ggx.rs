//! The GGX (Trowbridge–Reitz) microfacet distribution, isotropic, with height-correlated Smith
//! masking and Heitz's (2018) visible-normal sampling.
//!
//! `alpha` is glTF's `roughness²`. Tangent-space quantities are computed from the x/y components
//! directly (not `1 − cos²`) so near-mirror lobes keep their precision in f32.
use crate::vector::unit;
use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// Smallest `alpha` used for rough lobes; smoother opaque surfaces are rendered at this roughness
/// (roughness ≈ 0.03), which is visually a mirror but keeps `eval`/`pdf` finite.
pub const MIN_ALPHA: f32 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    #[inline]
    pub fn new(alpha: f32) -> Ggx {
        Ggx { alpha: alpha.max(MIN_ALPHA) }
    }

    /// Normal distribution `D(h)` for a local half vector `h` (z > 0).
    #[inline]
    pub fn d(&self, h: Vec3A) -> f32 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let cos2 = h.z * h.z;
        let tan2 = (h.x * h.x + h.y * h.y) / cos2;
        let a2 = self.alpha * self.alpha;
        let e = 1.0 + tan2 / a2;
        1.0 / (PI * a2 * cos2 * cos2 * e * e)
    }

    /// Smith's Λ for direction `w`.
    #[inline]
    pub fn lambda(&self, w: Vec3A) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 == 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (w.x * w.x + w.y * w.y) / cos2;
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    #[inline]
    pub fn g1(&self, w: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing `G2(wo, wi)`.
    #[inline]
    pub fn g2(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of the visible normal `h` seen from `wo` (either hemisphere; `h.z > 0`):
    /// `G1(wo) · max(0, wo·h) · D(h) / |wo.z|` with `wo` flipped to the upper side.
    #[inline]
    pub fn pdf_visible(&self, wo: Vec3A, h: Vec3A) -> f32 {
        let wo = if wo.z < 0.0 { -wo } else { wo };
        if wo.z == 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(h).max(0.0) * self.d(h) / wo.z
    }

    /// Samples a visible normal (z > 0) for `wo` (Heitz 2018); `wo` may be below the surface,
    /// in which case its mirror image is used, as the distribution is symmetric.
    #[inline]
    pub fn sample_visible(&self, wo: Vec3A, u: Vec2) -> Vec3A {
        let wo = if wo.z < 0.0 { -wo } else { wo };
        let vh = unit(Vec3A::new(self.alpha * wo.x, self.alpha * wo.y, wo.z));
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 { Vec3A::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { Vec3A::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let mut p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        unit(Vec3A::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(1e-6)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{StreamKind, StreamSampler};

    /// ∫ D(h) cos θh dω = 1 for any alpha (the projected microfacet area is the macro area).
    #[test]
    fn distribution_is_normalised() {
        let st = StreamSampler::new(5, StreamKind::Pt);
        for alpha in [0.1f32, 0.4, 1.0] {
            let g = Ggx::new(alpha);
            let n = 200_000u32;
            // Importance-sample cos θ with a cosine-power proposal: plain uniform on the hemisphere.
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for i in 0..n {
                let u = st.sample(0, i).get2d(0);
                let z = u.x; // uniform hemisphere: pdf 1/(2π)
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let h = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
                let v = (g.d(h) * h.z * 2.0 * PI) as f64;
                sum += v;
                sum2 += v * v;
            }
            let mean = sum / n as f64;
            let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!((mean - 1.0).abs() < 5.0 * se + 1e-3, "alpha {alpha}: {mean} ± {se}");
        }
    }
}

//! Emissive triangles as area lights: chosen in proportion to their power
//! (`luminance(emission) · area`), then a point uniformly on the chosen triangle.
//!
//! Emitters are one-sided: they emit from the front face, i.e. the side the geometric normal
//! `(p1 − p0) × (p2 − p0)` points to (counter-clockwise winding, as glTF specifies).
use crate::bsdf::luminance;
use glam::{Vec2, Vec3};

/// The light-selection distribution over the scene's triangles.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    /// Triangle index of each light.
    prims: Vec<u32>,
    /// Cumulative selection probability, `cdf[i]` = P(light ≤ i); the last entry is 1.
    cdf: Vec<f32>,
    /// Per triangle: selection probability / area (0 for non-emitters), i.e. the area density.
    pdf_area: Vec<f32>,
    total_power: f64,
}

/// A point sampled on a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub prim: u32,
    pub point: Vec3,
    /// Barycentrics `(u, v)` of vertices 1 and 2 (Embree's convention).
    pub bary: Vec2,
    /// Density with respect to area (selection probability / triangle area).
    pub pdf_area: f32,
}

impl LightSet {
    /// Builds the distribution from per-triangle power (`0` for non-emitters) and areas.
    pub fn new(power: &[f64], area: &[f32]) -> LightSet {
        let total: f64 = power.iter().filter(|p| p.is_finite() && **p > 0.0).sum();
        let mut pdf_area = vec![0.0f32; power.len()];
        if total <= 0.0 || total.is_nan() {
            return LightSet { prims: Vec::new(), cdf: Vec::new(), pdf_area, total_power: 0.0 };
        }
        let mut prims = Vec::new();
        let mut cdf = Vec::new();
        let mut acc = 0.0f64;
        for (i, &p) in power.iter().enumerate() {
            if p.is_finite() && p > 0.0 && area[i] > 0.0 {
                acc += p;
                prims.push(i as u32);
                cdf.push((acc / total) as f32);
                pdf_area[i] = ((p / total) / area[i] as f64) as f32;
            }
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        LightSet { prims, cdf, pdf_area, total_power: total }
    }

    pub fn is_empty(&self) -> bool {
        self.prims.is_empty()
    }

    pub fn len(&self) -> usize {
        self.prims.len()
    }

    /// Total emitted power (in luminance × area units), for diagnostics.
    pub fn total_power(&self) -> f64 {
        self.total_power
    }

    /// Area density of `prim` as a light (selection probability / area); 0 if it is not one.
    #[inline]
    pub fn pdf_area(&self, prim: u32) -> f32 {
        self.pdf_area[prim as usize]
    }

    /// Chooses a light with `u_select` and a point on it with `u`, given the triangle's vertices.
    #[inline]
    pub fn sample(&self, u_select: f32, u: Vec2, vertices: impl Fn(u32) -> [Vec3; 3]) -> Option<LightSample> {
        if self.prims.is_empty() {
            return None;
        }
        let i = self.cdf.partition_point(|&c| c <= u_select).min(self.prims.len() - 1);
        let prim = self.prims[i];
        let [p0, p1, p2] = vertices(prim);
        // Uniform on the triangle by the square-root warp.
        let su = u.x.sqrt();
        let bary = Vec2::new(su * (1.0 - u.y), su * u.y);
        let point = p0 * (1.0 - bary.x - bary.y) + p1 * bary.x + p2 * bary.y;
        Some(LightSample { prim, point, bary, pdf_area: self.pdf_area[prim as usize] })
    }
}

/// Power of a triangle as a light: luminance of its mean emission times its area.
pub fn triangle_power(mean_emission: Vec3, area: f32) -> f64 {
    (luminance(mean_emission.max(Vec3::ZERO)) as f64) * area as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_follows_power_and_density_integrates_to_one() {
        let power = [0.0, 1.0, 3.0, 0.0];
        let area = [1.0, 2.0, 0.5, 1.0];
        let ls = LightSet::new(&power, &area);
        assert_eq!(ls.len(), 2);
        assert_eq!(ls.pdf_area(0), 0.0);
        // Σ pdf_area · area = 1 over the lights.
        let s: f32 = (0..4).map(|i| ls.pdf_area(i) * area[i as usize]).sum();
        assert!((s - 1.0).abs() < 1e-6);
        let tri = |_| [Vec3::ZERO, Vec3::X, Vec3::Y];
        let n = 10_000;
        let hits = (0..n).filter(|i| ls.sample((*i as f32 + 0.5) / n as f32, Vec2::splat(0.5), tri).unwrap().prim == 2).count();
        assert_eq!(hits, 7_500);
        assert!(LightSet::new(&[0.0, 0.0], &[1.0, 1.0]).is_empty());
    }

    #[test]
    fn points_are_uniform_on_the_triangle() {
        // Mean of a uniform point on a triangle is its centroid; check with a fixed-seed MC bound.
        use crate::sampler::{StreamKind, StreamSampler};
        let ls = LightSet::new(&[1.0], &[0.5]);
        let verts = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let st = StreamSampler::new(1, StreamKind::Pt);
        let n = 40_000;
        let mut sum = Vec3::ZERO.as_dvec3();
        let mut inside_lower_half = 0;
        for i in 0..n {
            let s = ls.sample(0.3, st.sample(0, i).get2d(0), |_| verts).unwrap();
            sum += s.point.as_dvec3();
            // The region y < 0.5 holds 3/4 of the triangle's area.
            inside_lower_half += (s.point.y < 0.5) as u32;
        }
        let mean = sum / n as f64;
        let centroid = (verts[0] + verts[1] + verts[2]).as_dvec3() / 3.0;
        // Coordinates are bounded by 2, so sd of the mean ≤ 2/sqrt(n).
        assert!((mean - centroid).length() < 5.0 * 2.0 / (n as f64).sqrt(), "{mean} vs {centroid}");
        let p = inside_lower_half as f64 / n as f64;
        assert!((p - 0.75).abs() < 5.0 * (0.75f64 * 0.25 / n as f64).sqrt(), "{p}");
    }
}

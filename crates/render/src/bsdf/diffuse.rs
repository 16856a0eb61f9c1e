//! The BSDF of a purely Lambertian material (`specularFactor` 0, no metal, no transmission:
//! the Cornell box). It is the glTF model of [`super::pbr`] with only its diffuse lobe, worked
//! out with the same arithmetic, so images are the same bit for bit; it only skips what that
//! lobe does not need (lobe choice, Fresnel, the other lobes' state), which matters because
//! every vertex of such a scene builds, evaluates and samples one.
use super::pbr::{BsdfSample, SampleDraw};
use super::Frame;
use glam::Vec3A;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug)]
pub struct Diffuse {
    frame: Frame,
    /// Geometric normal (winding orientation), to reject light leaks through shading normals.
    ng: Vec3A,
    /// `wo`'s local z (cosine with the shading normal).
    wo_z: f32,
    /// Which side of the shading frame `wo` is on: the lobe is evaluated as if it were +z.
    side: f32,
    /// `wo · ng`, whose sign tells the geometric side `wo` is on.
    wo_dot_ng: f32,
    albedo: Vec3A,
}

impl Diffuse {
    /// `frame` around the shading normal in use, `wo_z` = `wo` · that normal, `albedo` ≥ 0.
    #[inline]
    pub(super) fn new(frame: Frame, ng: Vec3A, wo: Vec3A, wo_z: f32, albedo: Vec3A) -> Diffuse {
        Diffuse { frame, ng, wo_z, side: if wo_z < 0.0 { -1.0 } else { 1.0 }, wo_dot_ng: wo.dot(ng), albedo }
    }

    /// False for a black surface (nothing to sample or light).
    #[inline]
    pub fn is_lit(&self) -> bool {
        self.albedo.max_element() > 0.0
    }

    /// `(f · |cos θi|, pdf)` for the world direction `wi`.
    #[inline]
    pub fn eval_pdf(&self, wi: Vec3A) -> (Vec3A, f32) {
        let wi_z = wi.dot(self.frame.n);
        let geometric_reflection = wi.dot(self.ng) * self.wo_dot_ng > 0.0;
        let shading_reflection = wi_z * self.wo_z > 0.0;
        if geometric_reflection != shading_reflection || wi_z == 0.0 || !shading_reflection || !self.is_lit() {
            return (Vec3A::ZERO, 0.0);
        }
        // Both on the side of `wo`, which the lobe sees as +z (zero when `wo` grazes).
        let (o_z, i_z) = (self.wo_z * self.side, wi_z * self.side);
        if o_z > 0.0 && i_z > 0.0 {
            ((self.albedo * FRAC_1_PI) * wi_z.abs(), i_z * FRAC_1_PI)
        } else {
            (Vec3A::ZERO, 0.0)
        }
    }

    /// The cosine-weighted direction of `draw`, on the side of `wo`; its weight `f·cos/pdf` is
    /// the albedo. `None` for a black surface or a direction below the geometry.
    #[inline]
    pub fn sample_drawn(&self, draw: &SampleDraw) -> Option<BsdfSample> {
        if !self.is_lit() {
            return None;
        }
        let c = draw.cosine;
        let wi_l = Vec3A::new(c.x, c.y, c.z * self.side);
        let wi = self.frame.to_world(wi_l);
        if wi_l.z == 0.0 || wi.dot(self.ng) * self.wo_dot_ng <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi, weight: self.albedo, pdf: wi_l.z.abs() * FRAC_1_PI, delta: false, eta: 1.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::super::lambert;
    use super::super::pbr::{Bsdf, PbrParams};
    use super::*;

    #[test]
    fn the_diffuse_bsdf_agrees_with_the_pbr_model_without_specular() {
        // The same white Lambertian built by the general mixture (through its diffuse lobe
        // only, with the specular layer's weight at zero) and by `Diffuse` must agree exactly.
        use crate::sampler::{StreamKind, StreamSampler};
        let st = StreamSampler::new(11, StreamKind::Pt);
        let params = PbrParams { base_color: Vec3A::new(0.8, 0.5, 0.2), specular: 0.0, ..Default::default() };
        for i in 0..2000 {
            let s = st.sample(0, i);
            let unit = |u: glam::Vec2| lambert::sample(u) * if s.get1d(9) < 0.5 { 1.0 } else { -1.0 };
            let (ns, wo, wi) = (crate::vector::unit(unit(s.get2d(0)) + Vec3A::Z * 0.3), unit(s.get2d(2)), unit(s.get2d(4)));
            let Bsdf::Diffuse(d) = Bsdf::new(&params, ns, ns, wo) else { panic!("not the diffuse BSDF") };
            let m = Bsdf::mixture(&params, ns, ns, wo);
            assert_eq!(d.eval_pdf(wi), m.eval_pdf(wi), "eval at {wi}");
            // Sampling: the same direction and weight; the mixture's density comes back from
            // `eval_pdf` through the frame, so it may differ in the last bits.
            let draw = SampleDraw::new(0.5, s.get2d(6), 0.0);
            match (d.sample_drawn(&draw), m.sample_drawn(&draw)) {
                (Some(a), Some(b)) => {
                    assert_eq!(a.wi, b.wi);
                    // Densities are at most 1/π: an absolute bound.
                    assert!((a.pdf - b.pdf).abs() <= 1e-6 && (a.weight - b.weight).abs().max_element() <= 1e-5, "{a:?} vs {b:?}");
                }
                (None, None) => {}
                (a, b) => panic!("{a:?} vs {b:?}"),
            }
        }
    }
}

//! The BSDF of a purely Lambertian material (`specularFactor` 0, no metal, no transmission:
//! the Cornell box). It is the glTF model of [`super::pbr`] with only its diffuse lobe, worked
//! out with the same arithmetic, so images are the same bit for bit; it only skips what that
//! lobe does not need (lobe choice, Fresnel, the other lobes' state), which matters because
//! every vertex of such a scene builds, evaluates and samples one.
use super::frame::Frame;
use super::sample::{BsdfSample, SampleDraw};
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

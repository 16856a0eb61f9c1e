//! GGX microfacet reflection with Schlick Fresnel: glTF's specular layer and its metals.
use super::frame::reflect;
use super::fresnel::schlick;
use super::ggx::Ggx;
use crate::vector::unit;
use glam::{Vec2, Vec3A};

/// A rough reflective lobe: `f = D G F / (4 cos θo cos θi)`, `F = F0 + (F90 − F0)(1 − wo·h)⁵`.
#[derive(Clone, Copy, Debug)]
pub struct MicrofacetReflection {
    pub ggx: Ggx,
    pub f0: Vec3A,
    pub f90: f32,
}

impl MicrofacetReflection {
    #[inline]
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> Vec3A {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3A::ZERO;
        }
        let h = unit(wo + wi);
        let f = schlick(self.f0, self.f90, wo.dot(h));
        f * (self.ggx.d(h) * self.ggx.g2(wo, wi) / (4.0 * wo.z * wi.z))
    }

    /// Density of `wi` under visible-normal sampling: `G1(wo) D(h) / (4 cos θo)`.
    #[inline]
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = unit(wo + wi);
        self.ggx.g1(wo) * self.ggx.d(h) / (4.0 * wo.z)
    }

    /// A reflected direction, or `None` if it falls below the surface.
    #[inline]
    pub fn sample(&self, wo: Vec3A, u: Vec2) -> Option<Vec3A> {
        if wo.z <= 0.0 {
            return None;
        }
        let h = self.ggx.sample_visible(wo, u);
        let wi = reflect(wo, h);
        (wi.z > 0.0).then_some(wi)
    }
}

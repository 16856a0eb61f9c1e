//! Scattering functions. Each lobe lives in its own file and works in a local shading frame
//! (z = shading normal); [`pbr::Bsdf`] combines them into glTF's metallic-roughness model and
//! is the only type the integrator talks to.
//!
//! Conventions: `wo` points away from the surface towards the previous vertex, `wi` towards the
//! next one; both are unit vectors. `eval` returns `f(wo, wi)` *without* the cosine; the sampled
//! `weight` is `f · |cos θi| / pdf`. Transmission is scaled by `1/η²` for radiance transport.
#[cfg(test)]
mod chi2;
pub mod dielectric;
pub mod diffuse;
pub mod fresnel;
pub mod ggx;
pub mod lambert;
pub mod microfacet;
pub mod pbr;
#[cfg(test)]
mod reference;

use glam::Vec3A;

pub use pbr::{Bsdf, BsdfSample, PbrParams, SampleDraw};

/// An orthonormal basis around a normal: world ↔ local (z = normal).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3A,
    pub t: Vec3A,
    pub n: Vec3A,
}

impl Frame {
    /// A frame around the unit vector `n` (Duff et al. 2017 branchless basis).
    #[inline]
    pub fn from_normal(n: Vec3A) -> Frame {
        let (s, t) = n.any_orthonormal_pair();
        Frame { s, t, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Mirror `w` about the normal `n` (both pointing away from the surface).
#[inline]
pub fn reflect(w: Vec3A, n: Vec3A) -> Vec3A {
    2.0 * w.dot(n) * n - w
}

/// Rec. 709 luminance, used to weight lobes and lights.
#[inline]
pub fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

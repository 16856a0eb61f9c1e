//! Scattering functions. Each lobe lives in its own file and works in a local shading frame
//! (z = shading normal, [`frame`]); [`pbr::Bsdf`] combines them into glTF's metallic-roughness
//! model and is the only type the integrator talks to; [`sample`] holds what sampling one
//! draws and gives.
//!
//! Conventions: `wo` points away from the surface towards the previous vertex, `wi` towards the
//! next one; both are unit vectors. `eval` returns `f(wo, wi)` *without* the cosine; the sampled
//! `weight` is `f · |cos θi| / pdf`. Transmission is scaled by `1/η²` for radiance transport.
#[cfg(test)]
mod chi2;
pub mod dielectric;
pub mod diffuse;
pub mod frame;
pub mod fresnel;
pub mod ggx;
pub mod lambert;
pub mod microfacet;
pub mod pbr;
#[cfg(test)]
mod reference;
pub mod sample;

pub use frame::{reflect, Frame};
pub use pbr::Bsdf;
pub use sample::{BsdfSample, SampleDraw};

//! What one BSDF sample draws (its random numbers, and the cosine direction they give) and what
//! it gives (a direction with its Monte Carlo weight): shared by every BSDF.
use super::lambert;
use glam::{Vec2, Vec3A};

/// A sampled direction with its Monte Carlo weight.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// World-space direction (unit).
    pub wi: Vec3A,
    /// `f · |cos θi| / pdf`.
    pub weight: Vec3A,
    /// Solid-angle density of the non-delta lobes at `wi` (0 for a delta sample).
    pub pdf: f32,
    /// Sampled from a delta lobe: the next emitter hit must not be MIS-weighted.
    pub delta: bool,
    /// Relative index crossed (η_t/η_i), 1 unless refracted.
    pub eta: f32,
}

/// The random numbers of one BSDF sample, and the cosine-weighted local direction they give.
/// It depends on nothing at the surface, so the integrator works it out before tracing the
/// shadow ray: its division, polynomial and square root then overlap that work instead of
/// lying between one ray and the next.
#[derive(Clone, Copy, Debug)]
pub struct SampleDraw {
    pub u_lobe: f32,
    pub u: Vec2,
    pub u_choice: f32,
    /// `lambert::sample(u)`.
    pub cosine: Vec3A,
}

impl SampleDraw {
    #[inline]
    pub fn new(u_lobe: f32, u: Vec2, u_choice: f32) -> SampleDraw {
        SampleDraw { u_lobe, u, u_choice, cosine: lambert::sample(u) }
    }
}

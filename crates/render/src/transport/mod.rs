//! Light transport: how one sample's path through the scene is followed and what it carries.
//!
//! [`bsdf`] holds the scattering functions of the glTF material model, [`light_sample`]
//! next-event estimation's sample of one emitter, and [`integrator`] the path tracer's vertex
//! step (NEE + MIS, Russian roulette) and the radiance of one camera ray; `wavefront` follows
//! many paths at once, bounce by bounce, its common vertex 16 lanes at a time, with the same
//! bits. Random numbers come from [`crate::sampler`].
pub mod bsdf;
pub mod integrator;
pub mod light_sample;
#[cfg(test)]
mod light_tests;
pub(crate) mod wavefront;

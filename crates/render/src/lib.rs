//! cvtrace's path tracer: renders a glTF scene into two paired sample streams of the same
//! image, PT (independent random numbers per pixel) and CRN (sample `s` of every pixel uses
//! the same random vector), for the reconstruction stage.
//!
//! Data flow: [`Scene::load`] flattens a glTF file into world-space triangle arrays,
//! materials, textures and lights (emissive triangles, `KHR_lights_punctual`, and the
//! environment and render defaults of the [`sidecar`] file) → the caller builds an acceleration structure from
//! [`Scene::positions`]/[`Scene::triangles`] and implements [`Intersector`] (Embree in the root
//! crate, [`testing::BruteForce`] in tests) → [`render_streams`] traces every pixel's PT and
//! CRN samples in parallel tiles ([`integrator`], keyed by the counter-based [`sampler`]) and
//! returns a [`cvtrace_streams::StreamSet`]; [`render_reference_pass`] accumulates
//! progressive PT-only references. Nothing here depends on Embree.
pub mod bsdf;
pub mod camera;
pub mod error;
pub mod film;
mod fingerprint;
pub mod gltf_import;
pub mod integrator;
pub mod intersect;
pub mod light_sample;
#[cfg(test)]
mod light_tests;
pub mod lights;
pub mod material;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod select;
pub mod settings;
pub mod sidecar;
pub mod stream_file;
pub mod testing;
pub mod texture;
pub mod vector;
mod wavefront;

pub use camera::Camera;
pub use error::RenderError;
pub use intersect::{Hit, Intersector, Ray};
pub use lights::{Environment, Punctual};
pub use material::Material;
pub use render::{render_reference_pass, render_stream_part, render_streams, StreamRender};
pub use scene::{Scene, SceneError, SceneParts};
pub use settings::{RenderDefaults, RenderSettings};
pub use sidecar::{Define, Sidecar};
pub use texture::Texture;

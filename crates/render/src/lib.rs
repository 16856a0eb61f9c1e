//! cvtrace's path tracer: renders a glTF scene into two paired sample streams of the same
//! image, PT (independent random numbers per pixel) and CRN (sample `s` of every pixel uses
//! the same random vector), for the reconstruction stage.
//!
//! Data flow: [`Scene::load`] flattens a glTF file into world-space triangle arrays,
//! materials, textures and lights (emissive triangles, `KHR_lights_punctual`, and the
//! environment and render defaults of the [`scene::sidecar`] file) → the caller builds an
//! acceleration structure from [`Scene::positions`]/[`Scene::triangles`] and implements
//! [`Intersector`] (Embree in the root crate, [`testing::BruteForce`] in tests) →
//! [`render_streams`] traces every pixel's PT and CRN samples in parallel tiles
//! ([`transport::integrator`], keyed by the counter-based [`sampler`]) and returns a
//! [`cvtrace_streams::StreamSet`]; [`render_reference_pass`] accumulates progressive PT-only
//! references. Nothing here depends on Embree.
//!
//! The modules, whose code depends only on those before it: [`intersect`] (the ray caster's
//! contract), [`sampler`], [`vector`] and [`select`] (small shared helpers), [`error`] and
//! [`settings`] (what a render is asked for); [`scene`] (what is rendered), [`transport`] (how a
//! path is followed), [`film`] (how paths become images and files); [`testing`] (a brute-force
//! ray caster and small scenes). The files they read and write beyond the stream file (exact
//! sums, reference checkpoints, render parts) are `cvtrace_streams`'s.
//!
//! The only `unsafe` code is the SIMD builds of the wavefront's lane kernel
//! (`transport/wavefront/simd/`), behind tokens that only CPU-feature detection makes.
#![deny(unsafe_code)]
pub mod error;
pub mod film;
pub mod intersect;
pub mod sampler;
pub mod scene;
pub mod select;
pub mod settings;
pub mod testing;
pub mod transport;
pub mod vector;

pub use error::RenderError;
pub use film::driver::{render_reference_pass, render_stream_part, render_streams, StreamRender};
pub use intersect::{Hit, HitPacket, Intersector, Ray, RayPacket, PACKET};
pub use scene::camera::Camera;
pub use scene::error::SceneError;
pub use scene::lights::{Environment, Punctual};
pub use scene::material::Material;
pub use scene::sidecar::{Define, Sidecar};
pub use scene::texture::Texture;
pub use scene::world::{Scene, SceneParts};
pub use settings::{RenderDefaults, RenderSettings};

//! The scene as the renderer reads it: [`world::Scene`], flat world-space triangle arrays with
//! their materials, textures, lights and camera, and where it comes from.
//!
//! [`gltf_import`] reads a glTF 2.0 file into it ([`world::Scene::load`]) and [`sidecar`] the
//! scene's `<stem>.cvtrace.toml` (the environment light, the render defaults, `-D` overrides);
//! [`material`], [`texture`], [`camera`] and [`lights`] (every emitter and the distribution
//! next-event estimation picks them from) are what it holds; `fingerprint` serialises it for
//! the hash every output records. Nothing here traces a ray or samples a path.
pub mod camera;
pub mod error;
pub(crate) mod fingerprint;
pub mod gltf_import;
pub mod lights;
pub mod material;
pub mod sidecar;
pub mod texture;
pub mod world;

pub use camera::Camera;
pub use error::SceneError;
pub use lights::{Environment, Punctual};
pub use material::Material;
pub use sidecar::{Define, Sidecar};
pub use texture::Texture;
pub use world::{Scene, SceneParts, SurfacePoint};

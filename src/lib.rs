//! cvtrace's root library: the Embree ray-casting backend and the render session built on it.
//!
//! Everything that touches Embree lives in [`embree`]; the path tracer itself
//! (crates/render) only sees the [`cvtrace_render::Intersector`] trait, which
//! [`EmbreeScene`] implements. [`session::RenderSession`] loads a scene and builds its BVH
//! once, then renders stream files, references and plain PT images of it.
pub mod embree;
pub mod session;
pub mod throughput;

pub use embree::{set_flush_denormals, BuildOptions, BuildQuality, Device, EmbreeError, EmbreeScene};

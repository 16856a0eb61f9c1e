//! cvtrace's root library: the Embree ray-casting backend.
//!
//! Everything that touches Embree lives in [`embree`]; the path tracer itself
//! (crates/render) only sees the [`cvtrace_render::Intersector`] trait, which
//! [`EmbreeScene`] implements.
pub mod embree;

pub use embree::{set_flush_denormals, BuildOptions, BuildQuality, Device, EmbreeError, EmbreeScene};

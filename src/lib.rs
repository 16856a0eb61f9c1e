//! cvtrace's root library: the Embree ray-casting backend, the render session built on it, and
//! the estimators the program knows.
//!
//! Everything that touches Embree lives in [`embree`]; the path tracer itself
//! (crates/render) only sees the [`cvtrace_render::Intersector`] trait, which
//! [`EmbreeScene`] implements. [`session::RenderSession`] loads a scene and builds its BVH
//! once, then renders stream files, references and plain PT images of it.
pub mod embree;
pub mod session;
pub mod study_source;
pub mod throughput;
pub mod traversal_check;

use cvtrace_reconstruct::Registry;
use std::sync::OnceLock;

/// The estimators this program knows: the built-in ones, then those of other crates, each
/// added by one line here. Their order is the order of tables and the viewer.
pub fn registry() -> &'static Registry {
    static REGISTRY: OnceLock<Registry> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut r = Registry::builtin();
        r.register(&cvtrace_ivw::SPEC).expect("cvtrace-ivw's name is free");
        r
    })
}

pub use embree::{set_flush_denormals, BuildOptions, BuildQuality, Device, EmbreeError, EmbreeScene};

//! cvtrace's root library: the Embree ray-casting backend, and the estimators the program knows.
//!
//! Everything that touches Embree lives in [`embree`]; the path tracer itself
//! (crates/render) only sees the [`cvtrace_render::Intersector`] trait, which
//! [`EmbreeScene`] implements.
pub mod embree;

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

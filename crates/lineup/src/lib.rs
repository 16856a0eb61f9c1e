//! The estimators the program knows: [`Registry::builtin`]'s, then those of other crates, each
//! added by one line in [`registry`]. Their order is the order of tables and the viewer. The
//! command line, the study and the Python package all take their lineup from here.
#![forbid(unsafe_code)]
use cvtrace_reconstruct::Registry;
use std::sync::OnceLock;

/// The lineup, built once.
pub fn registry() -> &'static Registry {
    static REGISTRY: OnceLock<Registry> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut r = Registry::builtin();
        r.register(&cvtrace_ivw::SPEC).expect("cvtrace-ivw's name is free");
        for spec in cvtrace_denoise::SPECS {
            r.register(spec).expect("cvtrace-denoise's names are free");
        }
        r
    })
}

//! The denoiser every Embree user runs, Intel Open Image Denoise, in cvtrace's lineup, so that
//! it is compared with the control variates on the same samples:
//! - [`oidn`](oidn::SPEC): OIDN on one stream's mean (`n` spp), guided by the first-hit albedo
//!   and normal;
//! - [`pt2n-oidn`](pt2n_oidn::SPEC): OIDN on a real PT render of `2n` spp (the study's PT(2n)
//!   image): what a user would do instead of rendering the two streams, at their budget;
//! - [`blend`](blend::SPEC): `ours` and OIDN combined by shrinkage, `ours`' predicted
//!   variance telling where the denoiser can be trusted.
//!
//! The denoiser itself is `cvtrace-oidn`'s safe wrapper (through `cvtrace-oidn-sys`, which
//! checks at build time that the library is installed). Register the specs with
//! `registry.register(&cvtrace_denoise::oidn::SPEC)` and so on (cvtrace-lineup does).
#![forbid(unsafe_code)]
pub mod blend;
pub mod oidn;
pub mod pt2n_oidn;

/// Every estimator of this crate, in the order of tables and the viewer.
pub static SPECS: [&cvtrace_reconstruct::EstimatorSpec; 3] = [&oidn::SPEC, &pt2n_oidn::SPEC, &blend::SPEC];

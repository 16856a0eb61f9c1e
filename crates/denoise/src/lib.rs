//! The denoiser every Embree user runs, Intel Open Image Denoise, in cvtrace's lineup, so that
//! it is compared with the control variates on the same samples:
//! - [`oidn`](oidn::SPEC): OIDN on one stream's mean (`n` spp), guided by the first-hit albedo
//!   and normal;
//!
//! The denoiser itself is `cvtrace-oidn`'s safe wrapper (through `cvtrace-oidn-sys`, which
//! checks at build time that the library is installed). Register the specs with
//! `registry.register(&cvtrace_denoise::oidn::SPEC)` (cvtrace-lineup does).
#![forbid(unsafe_code)]
pub mod oidn;

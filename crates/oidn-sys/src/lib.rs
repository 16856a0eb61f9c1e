//! Intel Open Image Denoise 2 as the `oidn` crate binds it, with the library checked at build
//! time (see `build.rs`): depend on this crate rather than on `oidn` directly, so that a
//! missing library is an error that says how to install it, and a binary finds it without
//! LD_LIBRARY_PATH (`DEP_CVTRACE_OIDN_LIB_DIR`).
#![forbid(unsafe_code)]
pub use oidn;

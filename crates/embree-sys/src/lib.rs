//! Raw bindings to Embree 3 or 4, whichever `build.rs` found, and the calls whose form differs
//! between the two majors ([`intersect1`], [`intersect_coherent`], [`occluded1`] and the packet
//! calls [`intersect8`], [`occluded8`], [`intersect16`], [`occluded16`]), so that the safe
//! wrapper (`cvtrace-embree`) is written once for both.
//!
//! The bindings are bindgen's output for the installed headers, or, for an Embree 4 library
//! without headers (the PyPI wheel `embreex`), `src/bindings/embree4.rs`: bindgen's output for
//! Embree 4's headers with the configuration of Intel's release build (one instance level,
//! instance arrays), made by running this crate's build with `EMBREE_DIR` at a prefix with those
//! headers and `CVTRACE_EMBREE_SAVE_BINDINGS=src/bindings/embree4.rs`. Where a build option
//! of Embree could change a structure, the calls here pass one at least as large as any
//! configuration reads (see [`shim`]), and `cvtrace-embree`'s tests check the layout against
//! the library at run time.
#![allow(non_upper_case_globals, non_camel_case_types, non_snake_case, dead_code, clippy::all)]

/// bindgen's output (its bitfield accessors have unsafe blocks of its own making).
#[allow(clippy::undocumented_unsafe_blocks)]
mod raw {
    #[cfg(not(embree_pregenerated))]
    include!(concat!(env!("OUT_DIR"), "/embree_bindings.rs"));
    #[cfg(embree_pregenerated)]
    include!("bindings/embree4.rs");
}
pub use raw::*;

mod shim;
pub use shim::{intersect1, intersect16, intersect8, intersect_coherent, occluded1, occluded16, occluded8, Valid16, Valid8};

/// `RTC_INVALID_GEOMETRY_ID` is `((unsigned int)-1)` in C, a cast bindgen does not evaluate.
pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

/// The Embree major version these bindings are for.
#[cfg(embree_major = "3")]
pub const MAJOR: u32 = 3;
#[cfg(embree_major = "4")]
pub const MAJOR: u32 = 4;

/// How the build found Embree (`EMBREE_DIR=...`, `pkg-config embree4`, `/usr/include/embree3`).
pub const ORIGIN: &str = env!("CVTRACE_EMBREE_ORIGIN");

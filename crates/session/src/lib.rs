//! Rendering as a library: a [`RenderSession`] loads a scene once, builds its BVH (Embree, or
//! any [`Backend`]) and its render threads once, and renders jobs of it — stream files, progressive
//! references with checkpoints, parts of either for a farm, plain PT images — each output
//! recording its provenance, so that a later run can reuse, resume or extend it. [`source`]
//! makes a session the [`cvtrace_study::Source`] of a study (its files in the study folder,
//! reused when finished, one cell at a time for the farm). The command line, the Python package
//! and the examples are thin layers over this crate.
#![forbid(unsafe_code)]
mod session;
pub mod source;
pub mod throughput;

pub use session::*;
pub use source::RenderSource;

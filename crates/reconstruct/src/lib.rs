//! Reconstruction of one image from two paired renders: PT (independent random numbers per
//! pixel) and CRN (common random numbers: sample `s` of every pixel shares its random vector).
//!
//! Every method implements [`Estimator`]; [`build`] makes one from a [`Method`] and
//! [`Options`]. The input is a borrowed [`cvtrace_streams::StreamSet`] (stream means, batch
//! means, optional features) wrapped in an [`Input`], so a caller with buffers from any
//! renderer can reconstruct without files:
//!
//! ```
//! use cvtrace_reconstruct::{build, Input, Method, Options};
//! use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
//!
//! let set = SoftShadowScene::default()
//!     .render(&RenderSpec { width: 32, height: 32, spp: 16, batches: 8, seed: 1 })
//!     .unwrap();
//! let ours = build(Method::Ours, &Options::default()).unwrap();
//! let out = ours.reconstruct(&Input::new(&set)).unwrap();
//! assert_eq!(out.image.width, 32);
//! println!("{}", out.diagnostics);
//! ```
//!
//! With buffers from another renderer, [`stream_set_from_batches`] builds the stream set:
//!
//! ```
//! use cvtrace_reconstruct::{build, stream_set_from_batches, Image, Input, Method, Options};
//!
//! // B = 4 batch means per stream, all of one size (here constant images).
//! let batch = |v: f32| Image::from_fn(8, 8, |_, _| [v; 3]);
//! let pt = vec![batch(0.9), batch(1.1), batch(1.0), batch(1.0)];
//! let crn = vec![batch(0.8), batch(1.2), batch(1.05), batch(0.95)];
//! let set = stream_set_from_batches(pt, crn, 16, None).unwrap();
//! let out = build(Method::Iduw, &Options::default()).unwrap().reconstruct(&Input::new(&set)).unwrap();
//! assert!(out.diagnostics.get("gamma").is_some());
//! ```
//!
//! Methods and their defaults are documented, with measurements, in `docs/estimators.md`.

// Numeric kernels index several parallel arrays by one loop variable; iterator chains would
// hide that structure.
#![allow(clippy::needless_range_loop)]

mod batch_stats;
pub mod control_variate;
mod cv_pass;
mod diagnostics;
mod error;
mod estimator;
pub mod estimators;
mod fast_exp;
mod floor;
mod input;
mod method;
mod named;
mod panel;
mod penalty;
mod pt_error;
mod rng;
mod selection;
mod simd;
mod solve;
pub mod synthetic;
mod window;

pub use batch_stats::variance_of_mean;
/// The input types, re-exported so that library callers need no second import.
pub use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
pub use diagnostics::{DiagValue, Diagnostics};
pub use error::{ParseNameError, ReconError};
pub use estimator::{Estimator, Output};
pub use floor::{FloorMode, FloorSource};
pub use estimators::{CvOptions, IduwOptions, OursOptions, GAMMA_GRID};
pub use input::{stream_set_from_batches, BatchNeed, Input, Needs, MAX_VALUE};
pub use method::{build, Method, MethodChoice, Options};
pub use penalty::Penalty;
pub use pt_error::{CbfOptions, ErrorEstimate};
pub use selection::{Selection, MAX_SEARCH_WINDOW};
pub use solve::{MAX_BATCHES, MAX_K};

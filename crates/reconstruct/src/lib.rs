//! Reconstruction of one image from two paired renders: PT (independent random numbers per
//! pixel) and CRN (common random numbers: sample `s` of every pixel shares its random vector).
//!
//! Every estimator is one file: an [`Estimator`] implementation and an [`EstimatorSpec`] that
//! declares its name, label, parameters (with defaults, ranges and docs), what it reads and
//! how many samples its output stands for. A [`Registry`] holds the specs a program knows
//! ([`Registry::builtin`] has the six of this crate; another crate adds its own with
//! [`Registry::register`]) and builds an [`Instance`] from a name and `method.param=value`
//! [`Overrides`]. [`Instance::run`] checks the input against the declared needs, times the call
//! and knows every setting in effect, so no estimator repeats that. The input is a borrowed
//! [`cvtrace_streams::StreamSet`] (stream means, batch means, optional features) wrapped in an
//! [`Input`], so a caller with buffers from any renderer can reconstruct without files:
//!
//! ```
//! use cvtrace_reconstruct::{build, Input, Overrides};
//! use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
//!
//! let set = SoftShadowScene::default()
//!     .render(&RenderSpec { width: 32, height: 32, spp: 16, batches: 8, seed: 1 })
//!     .unwrap();
//! let ours = build("ours", &Overrides::default()).unwrap();
//! let out = ours.run(&Input::new(&set)).unwrap();
//! assert_eq!(out.image.width, 32);
//! println!("{}", out.diagnostics);
//! ```
//!
//! With buffers from another renderer, [`stream_set_from_batches`] builds the stream set:
//!
//! ```
//! use cvtrace_reconstruct::{build, stream_set_from_batches, Image, Input, Overrides};
//!
//! // B = 4 batch means per stream, all of one size (here constant images).
//! let batch = |v: f32| Image::from_fn(8, 8, |_, _| [v; 3]);
//! let pt = vec![batch(0.9), batch(1.1), batch(1.0), batch(1.0)];
//! let crn = vec![batch(0.8), batch(1.2), batch(1.05), batch(0.95)];
//! let set = stream_set_from_batches(pt, crn, 16, None).unwrap();
//! let iduw = build("iduw", &Overrides::parse(["iduw.window=5"]).unwrap()).unwrap();
//! let out = iduw.run(&Input::new(&set)).unwrap();
//! assert!(out.diagnostics.get("gamma").is_some());
//! ```
//!
//! The pieces the built-in estimators are made of are public in [`blocks`], for estimators
//! of other crates. Methods and their defaults are documented, with measurements, in
//! `docs/estimators.md`.

// Numeric kernels index several parallel arrays by one loop variable; iterator chains would
// hide that structure.
#![allow(clippy::needless_range_loop)]
// The vector kernels (`simd`) are the only code that needs `unsafe`: intrinsics that require
// their CPU features, raw-pointer loads and stores, and the cache-line-aligned buffer they read.
#![deny(unsafe_code)]

mod batch_stats;
pub mod control_variate;
mod cv_pass;
mod demodulate;
mod diagnostics;
mod error;
mod estimator;
pub mod estimators;
mod fast_exp;
mod floor;
mod input;
mod instance;
mod low_pass;
mod named;
mod panel;
mod penalty;
mod pt_error;
mod registry;
mod rng;
mod selection;
#[allow(unsafe_code)]
mod simd;
mod solve;
mod spec;
pub mod synthetic;
mod two_stage;
mod window;

pub use batch_stats::variance_of_mean;
pub use cv_pass::{Dof, Folds};
/// The input types, re-exported so that library callers need no second import.
pub use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
pub use demodulate::Demodulation;
pub use diagnostics::{DiagValue, Diagnostics};
pub use error::{ParseNameError, ReconError};
pub use estimator::{Estimator, Output};
pub use estimators::{ClassicCvOptions, IduwOptions, ImperfectCvOptions, GAMMA_GRID};
pub use floor::{FloorMode, FloorSource};
pub use input::{stream_set_from_batches, BatchNeed, Input, Needs, MAX_VALUE};
pub use instance::Instance;
pub use penalty::Penalty;
pub use pt_error::{CbfOptions, ErrorEstimate};
pub use registry::{build, Overrides, Registry, RESERVED_NAMES};
pub use selection::{Selection, MAX_SEARCH_WINDOW};
pub use solve::{MAX_BATCHES, MAX_K};
pub use spec::{Bounds, EstimatorSpec, ParamKind, ParamSpec, Params, Samples, Value, Variant};

/// The building blocks of the control-variate estimators, for estimators in other crates.
///
/// - [`Selector`](blocks::Selector): the `k` control-variate pixels of a centre pixel in its
///   search window (k-NN by CRN colour, spatial window, random, G-buffer), deterministic.
/// - [`BatchCube`](blocks::BatchCube) and [`variance_of_mean`],
///   [`group_means`](blocks::group_means): batch deviations, covariances and sub-buffers.
/// - [`Workspace`](blocks::Workspace): the small SPD solve of the coefficients
///   `(W + s·D·Dᵀ) β = s·D·d_c`, directly or through Woodbury, with an adaptive ridge.
/// - [`pt_errors`](blocks::pt_errors) and [`cross_bilateral`](blocks::cross_bilateral): PT
///   error estimates and the cross-bilateral filter guided by the CRN image and features.
/// - [`CvPass`](blocks::CvPass): the whole image pass of `ours` and `cv` (select, gather,
///   solve, combine), parallel over rows and bit-identical for any thread count; its
///   [`PassStats`](blocks::PassStats) report the shares of regularised and degenerate solves,
///   [`check_selection`](blocks::check_selection) checks the set size, search window and
///   ridge its callers declare.
/// - [`two_stage`](blocks::two_stage): the two-stage estimate of `cv` and `ours`, control
///   variates without the centre ([`centre_free_pass`](blocks::centre_free_pass), or
///   [`centre_free`](blocks::centre_free) inside a joint pass) combined with the centre's PT
///   mean by inverse variance ([`combine_with_centre`](blocks::combine_with_centre)), as an
///   [`Estimate`](blocks::Estimate) with its predicted variance.
/// - [`restore_low_frequencies`](blocks::restore_low_frequencies) and
///   [`low_pass_variance`](blocks::low_pass_variance): the low frequencies of an estimate from
///   the PT mean, and the variance that adds.
/// - [`Floor`](blocks::Floor) and [`Penalty`]: the noise floor of `ours` on
///   the CRN covariance, and the symmetric penalty on the neighbours' PT error estimates.
pub mod blocks {
    pub use crate::batch_stats::{group_means, variance_of_mean, BatchCube};
    pub use crate::cv_pass::{check_selection, CentreFree, CentreFreeOutput, CvPass, Dof, Folds, PassOutput, PassStats};
    pub use crate::floor::{Floor, FloorMode, FloorSource};
    pub use crate::low_pass::{low_pass_variance, restore_low_frequencies};
    pub use crate::penalty::Penalty;
    pub use crate::pt_error::{cross_bilateral, pt_errors, CbfOptions, ErrorEstimate};
    pub use crate::selection::{SelectScratch, Selection, Selector, MAX_SEARCH_WINDOW};
    pub use crate::solve::{Form, Outcome, Workspace, MAX_BATCHES, MAX_K};
    pub use crate::two_stage::{centre_free, centre_free_pass, combine_with_centre, two_stage, Estimate, Solve, CENTRE_FREE_RIDGE};
}

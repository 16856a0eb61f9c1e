//! Evaluation of cvtrace's estimators, following the paper's protocol
//! (docs/results.md):
//!
//! - [`metrics`]: relMSE (IDUW's definition, ε = 0.01) and MSE against a reference;
//! - [`flip`]: HDR-FLIP (NVIDIA's perceptual error) maps and means, beside relMSE;
//! - [`stats`]: per-method statistics over seeds — relMSE mean ± standard error and its
//!   split into squared bias and variance — from a streaming accumulator;
//! - [`reference_noise`]: how much relMSE the reference's own noise adds, with a warning;
//! - [`results`]: the one JSON-able tree a study produces, plus headline ratios;
//! - [`table`]: terminal, Markdown and CSV printers;
//! - [`compare`]: metrics of loose EXR files against a reference (`cvtrace compare`);
//! - [`falsecolor`], [`difference`], [`plots`]: relMSE maps and signed difference maps as PNG,
//!   convergence plots (against spp and against time) as SVG;
//! - [`pixels`]: the linear values of a study's images, for the viewer's pixel readout;
//! - [`report`]: the static, offline HTML comparison viewer;
//! - [`synthetic`]: a renderer-free synthetic study for tests, docs and trying the viewer.
//!
//! Nothing here renders or reconstructs; it depends only on `cvtrace-streams`.
#![forbid(unsafe_code)]

pub mod compare;
pub mod difference;
pub mod error;
pub mod falsecolor;
pub mod flip;
pub mod metrics;
pub mod palette;
pub mod pixels;
pub mod plots;
pub mod reference_noise;
pub mod report;
pub mod results;
mod rng;
pub mod stats;
pub mod synthetic;
pub mod table;

pub use error::EvalError;
pub use metrics::{Metrics, Reference};
pub use report::{write_report, ReportOptions};
pub use results::{
    keys, ConvergencePoint, DifferenceScale, ErrorMapScale, MethodResult, ReferenceInfo, SceneResult, StageTimes, StudyResults,
};
pub use stats::{SeedAccumulator, SeedStats};

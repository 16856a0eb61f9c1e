//! One file per reconstruction method.
mod average;
mod crn;
mod cv;
mod iduw;
mod ours;
mod pt;

pub use average::Average;
pub use crn::Crn;
pub use cv::{Cv, CvOptions};
pub use iduw::{Iduw, IduwOptions, GAMMA_GRID};
pub use ours::{Ours, OursOptions};
pub use pt::Pt;

use crate::{Diagnostics, Output};
use cvtrace_streams::Image;
use std::time::Instant;

/// Wraps an image and diagnostics with the time since `start`.
pub(crate) fn finish(image: Image, mut diagnostics: Diagnostics, start: Instant) -> Output {
    diagnostics.seconds = start.elapsed().as_secs_f64();
    Output { image, diagnostics }
}

//! The built-in estimators, one file each: the implementation and its [`EstimatorSpec`].
pub mod average;
pub mod crn;
pub mod cv;
pub mod iduw;
pub mod ours;
pub mod pt;

pub use average::Average;
pub use crn::Crn;
pub use cv::{ClassicCv, ClassicCvOptions};
pub use iduw::{Iduw, IduwOptions, GAMMA_GRID};
pub use ours::{ImperfectCv, ImperfectCvOptions};
pub use pt::Pt;

use crate::spec::EstimatorSpec;

/// The built-in specs in the order of tables and the viewer.
pub static BUILTIN: [&EstimatorSpec; 6] = [&pt::SPEC, &crn::SPEC, &average::SPEC, &iduw::SPEC, &cv::SPEC, &ours::SPEC];

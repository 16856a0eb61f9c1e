//! The one trait every reconstruction method implements, so that methods can be run
//! and compared side by side on the same input.
use crate::{Diagnostics, Input, Method, Needs, ReconError};
use cvtrace_streams::Image;

/// The reconstructed image and what the method reports about it.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub image: Image,
    pub diagnostics: Diagnostics,
}

pub trait Estimator: Send + Sync {
    fn method(&self) -> Method;

    /// The command-line name of the method (`pt`, `crn`, `average`, `iduw`, `cv`, `ours`).
    fn name(&self) -> &'static str {
        self.method().name()
    }

    /// What the input must provide; checked again by `reconstruct`.
    fn needs(&self) -> Needs;

    /// The options in effect, as (name, value) pairs, to record next to the output.
    fn settings(&self) -> Vec<(&'static str, String)> {
        Vec::new()
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError>;
}

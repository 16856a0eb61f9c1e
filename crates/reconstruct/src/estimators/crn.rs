//! `crn`: the CRN stream mean alone (unbiased per pixel, errors shared by neighbours).
use super::finish;
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use std::time::Instant;

#[derive(Clone, Copy, Debug, Default)]
pub struct Crn;

impl Estimator for Crn {
    fn method(&self) -> Method {
        Method::Crn
    }

    fn needs(&self) -> Needs {
        Needs::MEANS
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.name(), &self.needs())?;
        Ok(finish(input.streams.crn.mean.clone(), Diagnostics::default(), start))
    }
}

//! `pt`: the PT stream mean alone (independent per pixel, unbiased, noisy).
use super::finish;
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use std::time::Instant;

#[derive(Clone, Copy, Debug, Default)]
pub struct Pt;

impl Estimator for Pt {
    fn method(&self) -> Method {
        Method::Pt
    }

    fn needs(&self) -> Needs {
        Needs::MEANS
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.name(), &self.needs())?;
        Ok(finish(input.streams.pt.mean.clone(), Diagnostics::default(), start))
    }
}

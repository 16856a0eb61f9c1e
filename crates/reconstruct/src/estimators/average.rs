//! `average`: the mean of all samples of both streams, `(h̄ + ḡ) / 2` (both streams have
//! the same number of samples). The simplest use of the second stream.
use super::finish;
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use cvtrace_streams::Image;
use std::time::Instant;

#[derive(Clone, Copy, Debug, Default)]
pub struct Average;

impl Estimator for Average {
    fn method(&self) -> Method {
        Method::Average
    }

    fn needs(&self) -> Needs {
        Needs::MEANS
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.name(), &self.needs())?;
        let s = input.streams;
        let pixels = s.pt.mean.pixels.iter().zip(&s.crn.mean.pixels).map(|(h, g)| std::array::from_fn(|c| 0.5 * (h[c] + g[c]))).collect();
        Ok(finish(Image { width: s.width, height: s.height, pixels }, Diagnostics::default(), start))
    }
}

//! `average`: the mean of all samples of both streams, `(h̄ + ḡ) / 2` (both streams have
//! the same number of samples). The simplest use of the second stream.
use crate::spec::{EstimatorSpec, Samples};
use crate::{Estimator, Input, Needs, Output, ReconError};
use cvtrace_streams::Image;

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "average",
    label: "Average",
    short: "average",
    summary: "The mean of all samples of both streams, (PT + CRN) / 2.",
    colour: [0xed, 0xc9, 0x48],
    samples: Samples::BothStreams,
    params: &[],
    needs: |_| Needs::MEANS,
    build: |_| Ok(Box::new(Average)),
    variants: &[],
};

#[derive(Clone, Copy, Debug, Default)]
pub struct Average;

impl Estimator for Average {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let s = input.streams;
        let pixels = s.pt.mean.pixels.iter().zip(&s.crn.mean.pixels).map(|(h, g)| std::array::from_fn(|c| 0.5 * (h[c] + g[c]))).collect();
        Ok(Output::image(Image { width: s.width, height: s.height, pixels }))
    }
}

//! `pt`: the PT stream mean alone (independent per pixel, unbiased, noisy).
use crate::spec::{EstimatorSpec, Samples};
use crate::{Estimator, Input, Needs, Output, ReconError};

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "pt",
    label: "PT (n)",
    short: "PT(n)",
    summary: "The PT stream mean alone: independent per pixel, unbiased, noisy.",
    colour: [0xe1, 0x57, 0x59],
    samples: Samples::OneStream,
    params: &[],
    needs: |_| Needs::MEANS,
    build: |_| Ok(Box::new(Pt)),
    variants: &[],
};

#[derive(Clone, Copy, Debug, Default)]
pub struct Pt;

impl Estimator for Pt {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        Ok(Output::image(input.streams.pt.mean.clone()))
    }
}

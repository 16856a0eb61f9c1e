//! `crn`: the CRN stream mean alone (unbiased per pixel, errors shared by neighbours).
use crate::spec::{EstimatorSpec, Samples};
use crate::{Estimator, Input, Needs, Output, ReconError};

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "crn",
    label: "CRN (n)",
    short: "CRN(n)",
    summary: "The CRN stream mean alone: unbiased per pixel, with errors shared by neighbours.",
    colour: [0xf2, 0x8e, 0x2b],
    samples: Samples::OneStream,
    params: &[],
    needs: |_| Needs::MEANS,
    build: |_| Ok(Box::new(Crn)),
    variants: &[],
};

#[derive(Clone, Copy, Debug, Default)]
pub struct Crn;

impl Estimator for Crn {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        Ok(Output::image(input.streams.crn.mean.clone()))
    }
}

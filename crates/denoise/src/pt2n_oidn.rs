//! `pt2n-oidn`: Intel Open Image Denoise on a real PT render with the samples of both streams
//! (the study's PT(2n) image), guided by the stream file's first-hit albedo and normal: what a
//! user would do instead of rendering two streams, at the same sample budget. By default the
//! guides are prefiltered, the pipeline OIDN's documentation recommends for guides as noisy as
//! the image's, which measured stronger on the bundled scenes than raw guides
//! (docs/estimators.md).
use crate::oidn::{aux, denoised, options, AUX, QUALITY};
use cvtrace_oidn::DenoiseOptions;
use cvtrace_reconstruct::{BatchNeed, Diagnostics, Estimator, EstimatorSpec, Input, Needs, Output, Params, ReconError, Samples};

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "pt2n-oidn",
    label: "PT(2n) + OIDN",
    short: "PT(2n)+OIDN",
    summary: "Intel Open Image Denoise on a real PT render of 2n spp (the study's PT(2n) image; reconstruct --pt2n), guided by the stream file's first-hit albedo and normal.",
    colour: [0x4f, 0xb0, 0xc6],
    samples: Samples::Pt2n,
    params: &[QUALITY, AUX],
    needs: |p| Needs {
        batches: BatchNeed::None,
        features: (p.choice::<String>("aux") != "none").then_some("with guides (aux other than none)"),
        reference: false,
        spp: false,
        pt2n: true,
        bounded_values: false,
    },
    build: |p| Ok(Box::new(Pt2nOidn::from_params(p))),
    variants: &[],
};

/// The `pt2n-oidn` estimator.
#[derive(Clone, Debug)]
pub struct Pt2nOidn {
    options: DenoiseOptions,
}

impl Pt2nOidn {
    pub fn from_params(p: &Params) -> Self {
        Pt2nOidn { options: options(p) }
    }
}

impl Estimator for Pt2nOidn {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let image = input.pt2n.ok_or(ReconError::MissingPt2n { method: SPEC.name })?;
        Ok(Output::new(denoised(SPEC.name, image, aux(input), &self.options)?, Diagnostics::default()))
    }
}

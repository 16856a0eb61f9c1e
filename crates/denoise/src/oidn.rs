//! `oidn`: Intel Open Image Denoise on one stream's mean (the PT stream by default), guided by
//! the stream file's first-hit albedo and shading normal: what a renderer's user does with an
//! `n`-spp render. Biased (a denoiser trades variance for bias), and deterministic.
use cvtrace_oidn::{denoise, Aux, AuxMode, DenoiseOptions, Quality};
use cvtrace_reconstruct::{
    BatchNeed, Diagnostics, Estimator, EstimatorSpec, Image, Input, Needs, Output, ParamKind, ParamSpec, Params, ReconError, Samples,
};

/// The parameters `oidn` and the estimators built on it share.
pub const QUALITY: ParamSpec = ParamSpec {
    name: "quality",
    kind: ParamKind::Choice(Quality::NAMES),
    default: "high",
    doc: "OIDN's filter quality: high (its best), balanced or fast.",
    alias: None,
};
pub const AUX: ParamSpec = ParamSpec {
    name: "aux",
    kind: ParamKind::Choice(AuxMode::NAMES),
    default: "prefiltered",
    doc: "The guides, the stream file's first-hit albedo and shading normal (averaged over the PT samples): prefiltered (each denoised first, then trusted as clean: OIDN's recommended pipeline for guides as noisy as the image's), raw (as they are, OIDN allowing for their noise), clean (as they are, declared noise-free: OIDN's clean_aux) or none.",
    alias: None,
};

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "oidn",
    label: "OIDN (one stream)",
    short: "OIDN",
    summary: "Intel Open Image Denoise (RT filter, HDR) on one stream's mean, guided by the first-hit albedo and normal.",
    colour: [0x7f, 0xd8, 0xe6],
    samples: Samples::OneStream,
    params: &[
        ParamSpec {
            name: "image",
            kind: ParamKind::Choice(&["pt", "crn"]),
            default: "pt",
            doc: "Which stream's mean it denoises: pt (independent samples, what a renderer's user has) or crn.",
            alias: None,
        },
        QUALITY,
        AUX,
    ],
    needs: |p| Needs {
        batches: BatchNeed::None,
        features: (p.choice::<String>("aux") != "none").then_some("with guides (aux other than none)"),
        reference: false,
        spp: false,
        pt2n: false,
        bounded_values: false,
    },
    build: |p| Ok(Box::new(Oidn::from_params(p))),
    variants: &[],
};

/// Options of OIDN as the estimators here take them (`quality`, `aux`).
pub fn options(p: &Params) -> DenoiseOptions {
    DenoiseOptions {
        quality: Quality::parse(&p.choice::<String>("quality")).unwrap_or_default(),
        aux: AuxMode::parse(&p.choice::<String>("aux")).unwrap_or_default(),
    }
}

/// The guides of `input`, if it has features.
pub fn aux<'a>(input: &Input<'a>) -> Option<Aux<'a>> {
    let f = input.streams.features.as_ref()?;
    Some(Aux { albedo: &f.albedo, normal: &f.normal })
}

/// `image` denoised for `method` (an error names the method).
pub fn denoised(method: &'static str, image: &Image, aux: Option<Aux>, options: &DenoiseOptions) -> Result<Image, ReconError> {
    denoise(image, aux, options).map_err(|e| ReconError::Failed { method, message: e.to_string() })
}

/// The `oidn` estimator.
#[derive(Clone, Debug)]
pub struct Oidn {
    crn: bool,
    options: DenoiseOptions,
}

impl Oidn {
    pub fn from_params(p: &Params) -> Self {
        Oidn { crn: p.choice::<String>("image") == "crn", options: options(p) }
    }
}

impl Estimator for Oidn {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let s = input.streams;
        let image = if self.crn { &s.crn.mean } else { &s.pt.mean };
        Ok(Output::new(denoised(SPEC.name, image, aux(input), &self.options)?, Diagnostics::default()))
    }
}

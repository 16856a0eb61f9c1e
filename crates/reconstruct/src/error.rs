//! Errors of the reconstruction stage. Every message says what is wrong, where
//! (the stream file or reference, the channel, the pixel) and how to fix it.

/// An option value that is not one of the known names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} `{given}`; expected one of: {}", expected.join(", "))]
pub struct ParseNameError {
    pub what: &'static str,
    pub given: String,
    pub expected: &'static [&'static str],
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReconError {
    #[error("{origin}: the image is empty ({width}x{height})")]
    EmptyImage { origin: String, width: usize, height: usize },

    #[error("{origin}: `{layer}` is {width}x{height}, expected {expected_width}x{expected_height} like the rest of the stream set")]
    SizeMismatch { origin: String, layer: String, width: usize, height: usize, expected_width: usize, expected_height: usize },

    #[error("{origin}: pt has {pt} batches and crn has {crn}; both streams need the same number of batches")]
    BatchCountMismatch { origin: String, pt: usize, crn: usize },

    #[error("{origin}: `{method}` needs {requirement} batches per stream, but the streams have {found}; {hint}")]
    BatchCount { origin: String, method: &'static str, requirement: String, found: usize, hint: String },

    #[error("{origin}: channel `{channel}` holds a non-finite value ({value}) at pixel ({x}, {y}); re-render, or replace non-finite samples before reconstructing")]
    NonFinite { origin: String, channel: String, value: f32, x: usize, y: usize },

    #[error("{origin}: channel `{channel}` holds {value:e} at pixel ({x}, {y}); `{method}` squares differences of values in f32, which overflows beyond ±{limit:e}, so its image would be wrong: scale the image down (relative errors do not change)")]
    TooLarge { origin: String, method: &'static str, channel: String, value: f32, x: usize, y: usize, limit: f32 },

    #[error("{origin}: `{method}` produced a non-finite value at pixel ({x}, {y}), channel {channel}; the input holds values too large for f32 arithmetic (largest {largest:e})")]
    NonFiniteOutput { origin: String, method: String, x: usize, y: usize, channel: &'static str, largest: f32 },

    #[error("{origin}: `{method}` {why} needs first-hit features (channels `albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`), which are missing; re-render with features or choose another option")]
    MissingFeatures { origin: String, method: &'static str, why: &'static str },

    #[error("`{method}` with --errors oracle needs a reference image; pass one (--reference) or use --errors cbf or variance")]
    MissingReference { method: &'static str },

    #[error("`{method}` post-processes a plain PT render with the samples of both streams (2n spp), which was not given; pass one (reconstruct --pt2n FILE, rendered with `cvtrace render --reference --spp 2n`) or run it in a study, which renders it")]
    MissingPt2n { method: &'static str },

    #[error("reference {reference} is {width}x{height}, but the streams in {origin} are {expected_width}x{expected_height}; pass the reference of the same scene and resolution")]
    ReferenceSize { reference: String, origin: String, width: usize, height: usize, expected_width: usize, expected_height: usize },

    #[error("{origin}: `{method}` needs the samples per pixel of each stream, but it is 0 (StreamMeta::spp / attribute cvtrace.spp); set it to the spp the streams were rendered with")]
    MissingSpp { origin: String, method: &'static str },

    #[error("unknown estimator `{given}`; expected one of: {known}")]
    UnknownMethod { given: String, known: String },

    #[error("`{given}` is a variant of `{method}` for ablations, not an estimator: `cvtrace study --ablations` runs it beside the others, and `--method {method} {params}` runs it alone")]
    Variant { given: String, method: &'static str, params: String },

    #[error("`{method}` has no parameter `{param}`; its parameters: {known} (`cvtrace reconstruct --help-method {method}`)")]
    UnknownParam { method: String, param: String, known: String },

    #[error("{}", param_message(.method, .param, .alias, .value, .why))]
    InvalidParam { method: &'static str, param: &'static str, alias: Option<&'static str>, value: String, why: String },

    #[error("`{given}`: a parameter is given as METHOD.PARAM=VALUE, e.g. ours.k=25")]
    BadAssignment { given: String },

    #[error("estimator `{method}` cannot be registered: {why}")]
    BadSpec { method: String, why: String },

    #[error("invalid option --{option} {value}: {why}")]
    InvalidOption { option: &'static str, value: String, why: String },

    /// A library an estimator calls failed (its own words in `message`).
    #[error("`{method}`: {message}")]
    Failed { method: &'static str, message: String },
}

impl ReconError {
    pub(crate) fn option(option: &'static str, value: impl ToString, why: impl Into<String>) -> Self {
        ReconError::InvalidOption { option, value: value.to_string(), why: why.into() }
    }
}

/// `--k 0 (ours.k): why` where the parameter has a flag, `ours.window = 4: why` where not.
fn param_message(method: &str, param: &str, alias: &Option<&str>, value: &str, why: &str) -> String {
    match alias {
        Some(a) => format!("invalid option --{a} {value} ({method}.{param}): {why}"),
        None => format!("invalid parameter {method}.{param} = {value}: {why}"),
    }
}

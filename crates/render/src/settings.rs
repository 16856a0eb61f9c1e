//! What a render renders: its settings and their limits (what the files can record), the
//! path-length limits the integrator reads of them, and the defaults a scene asks for.
use crate::error::RenderError;
use cvtrace_streams::reference::ReferenceSettings;
use serde::Deserialize;

/// Largest accepted image side.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Most samples per pixel (per stream, or of a reference): the count is recorded as an EXR
/// `int` (`cvtrace.spp`, a checkpoint's `cvtrace.samplesDone`), so larger ones would wrap.
pub const MAX_SPP: u32 = i32::MAX as u32;
/// Most batches per stream: the stream file numbers them with two digits (`pt.b00.` …
/// `pt.b99.`, docs/stream-format.md). The estimators that use batches take at most 64.
pub const MAX_BATCHES: u32 = 100;
/// Largest Russian-roulette depth: a reference records it as an EXR `int` (`cvtrace.rrDepth`).
pub const MAX_RR_DEPTH: u32 = i32::MAX as u32;

/// What to render. `spp` is per stream; `max_depth` follows Mitsuba (−1 unlimited, see
/// [`crate::transport::integrator`]); Russian roulette starts at depth `rr_depth`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub batches: u32,
    pub seed: u64,
    pub max_depth: i32,
    pub rr_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings { width: 512, height: 512, spp: 64, batches: 4, seed: 0, max_depth: -1, rr_depth: 5 }
    }
}

impl RenderSettings {
    /// Checks image size, path-length limits and the batch split.
    pub fn validate(&self) -> Result<(), RenderError> {
        self.validate_image()?;
        let bad = |m: String| Err(RenderError::InvalidSettings(m));
        if self.spp == 0 {
            return bad("spp must be at least 1".into());
        }
        if self.spp > MAX_SPP {
            return bad(format!("spp {} is more than {MAX_SPP}, the largest sample count a file records", self.spp));
        }
        if self.batches == 0 {
            return bad("batches must be at least 1".into());
        }
        if self.batches > MAX_BATCHES {
            return bad(format!("batches {} is more than {MAX_BATCHES}, the most a stream file numbers (two digits)", self.batches));
        }
        if !self.spp.is_multiple_of(self.batches) {
            return bad(format!("spp ({}) must be a multiple of batches ({})", self.spp, self.batches));
        }
        Ok(())
    }

    /// The checks that also apply to reference renders (which ignore `spp` and `batches`).
    pub(crate) fn validate_image(&self) -> Result<(), RenderError> {
        let bad = |m: String| Err(RenderError::InvalidSettings(m));
        if self.width == 0 || self.height == 0 || self.width > MAX_IMAGE_SIDE || self.height > MAX_IMAGE_SIDE {
            return bad(format!("image size {}x{} must be between 1 and {MAX_IMAGE_SIDE} on each side", self.width, self.height));
        }
        if self.max_depth < -1 || self.max_depth == 0 {
            return bad(format!("max_depth {} must be -1 (unlimited) or at least 1", self.max_depth));
        }
        if self.rr_depth > MAX_RR_DEPTH {
            return bad(format!("rr_depth {} is more than {MAX_RR_DEPTH}, the largest a file records", self.rr_depth));
        }
        Ok(())
    }

    /// What a reference of these settings records with its sums (`batches` aside).
    pub fn reference(&self) -> ReferenceSettings {
        ReferenceSettings {
            width: self.width,
            height: self.height,
            spp: self.spp,
            seed: self.seed,
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
        }
    }

    /// The path-length limits of the integrator.
    pub(crate) fn limits(&self) -> PathLimits {
        PathLimits { max_depth: self.max_depth, rr_depth: self.rr_depth }
    }
}

/// Path-length limits: Mitsuba's `max_depth` (−1 unlimited) and the depth at which Russian
/// roulette starts (see [`crate::transport::integrator`]).
#[derive(Clone, Copy, Debug)]
pub struct PathLimits {
    pub max_depth: i32,
    pub rr_depth: u32,
}

/// Render settings a scene asks for; command-line flags override them. `None` = not given.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDefaults {
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Samples per pixel of each stream of `cvtrace render`.
    pub spp: Option<u32>,
    /// Mitsuba's convention: −1 unlimited, else at least 1.
    pub max_depth: Option<i32>,
    pub rr_depth: Option<u32>,
    /// Samples per pixel of reference renders (`render --reference`, `study`).
    pub reference_spp: Option<u32>,
}

impl RenderDefaults {
    /// Checks ranges; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if let Some(v) = v {
                if v == 0 || v > MAX_IMAGE_SIDE {
                    return Err(format!("[render] {key} = {v}: must be between 1 and {MAX_IMAGE_SIDE}"));
                }
            }
        }
        for (key, v) in [("spp", self.spp), ("reference_spp", self.reference_spp)] {
            if v == Some(0) {
                return Err(format!("[render] {key} = 0: must be at least 1"));
            }
        }
        if let Some(d) = self.max_depth {
            if d < -1 || d == 0 {
                return Err(format!("[render] max_depth = {d}: must be -1 (unlimited) or at least 1"));
            }
        }
        Ok(())
    }
}

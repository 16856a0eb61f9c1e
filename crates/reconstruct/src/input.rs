//! What an estimator reads: a borrowed stream set, an optional reference image, an optional
//! real PT render with the samples of both streams (the study's PT(2n) image), and the names to
//! use for them in error messages (file paths for the CLI, anything for a library
//! caller holding buffers from another renderer).
use crate::ReconError;
use cvtrace_streams::stream_set::batch_prefix;
use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
use rayon::prelude::*;

/// The input of every estimator.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    pub streams: &'a StreamSet,
    /// Ground truth, used only by analysis options (`--errors oracle`).
    pub reference: Option<&'a Image>,
    /// A plain PT image of the same view with `2n` samples per pixel, independent of the
    /// streams: what estimators that post-process a PT render (a denoiser) take instead of a
    /// stream, so that they are compared at the streams' sample budget.
    pub pt2n: Option<&'a Image>,
    /// Names the stream set in errors (typically its file path).
    pub streams_name: &'a str,
    /// Names the reference in errors (typically its file path).
    pub reference_name: &'a str,
    /// Names the PT(2n) image in errors (typically its file path).
    pub pt2n_name: &'a str,
}

impl<'a> Input<'a> {
    pub fn new(streams: &'a StreamSet) -> Self {
        Input {
            streams,
            reference: None,
            pt2n: None,
            streams_name: "<stream set>",
            reference_name: "<reference>",
            pt2n_name: "<PT(2n) image>",
        }
    }

    /// The PT(2n) image, named `name` in errors.
    pub fn with_pt2n(mut self, image: &'a Image, name: &'a str) -> Self {
        self.pt2n = Some(image);
        self.pt2n_name = name;
        self
    }

    pub fn with_reference(mut self, reference: &'a Image) -> Self {
        self.reference = Some(reference);
        self
    }

    /// Names for error messages, e.g. the file paths the data came from.
    pub fn named(mut self, streams_name: &'a str, reference_name: &'a str) -> Self {
        self.streams_name = streams_name;
        self.reference_name = reference_name;
        self
    }

    pub fn width(&self) -> usize {
        self.streams.width
    }

    pub fn height(&self) -> usize {
        self.streams.height
    }

    /// Checks that `image`, which `method` made from this input, is finite: finite inputs give
    /// a non-finite image only when they are too large for f32 arithmetic, and the error says so
    /// with the largest stream value. What `cvtrace reconstruct` checks before writing anything.
    pub fn check_output(&self, method: &str, image: &Image) -> Result<(), ReconError> {
        let Some((x, y, c)) = image.find_non_finite() else { return Ok(()) };
        let s = self.streams;
        let largest = s.pt.mean.pixels.iter().chain(&s.crn.mean.pixels).flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        Err(ReconError::NonFiniteOutput {
            origin: self.streams_name.to_string(),
            method: method.to_string(),
            x,
            y,
            channel: RGB[c],
            largest,
        })
    }

    /// Checks everything `needs` asks for and that every value the method reads is finite (and
    /// at most [`MAX_VALUE`] in magnitude where `needs.bounded_values`). Called by each
    /// estimator before any work, so that errors come early and clearly.
    pub fn check(&self, method: &'static str, needs: &Needs) -> Result<(), ReconError> {
        let s = self.streams;
        let origin = || self.streams_name.to_string();
        let (w, h) = (s.width, s.height);
        if w == 0 || h == 0 {
            return Err(ReconError::EmptyImage { origin: origin(), width: w, height: h });
        }
        let batches_needed = needs.batches != BatchNeed::None;
        let mut layers: Vec<(String, &Image)> = vec![("pt.".into(), &s.pt.mean), ("crn.".into(), &s.crn.mean)];
        if batches_needed {
            let (bp, bc) = (s.pt.batches.len(), s.crn.batches.len());
            if bp != bc {
                return Err(ReconError::BatchCountMismatch { origin: origin(), pt: bp, crn: bc });
            }
            needs.batches.check(origin(), method, bp)?;
            for (name, stream) in [("pt", &s.pt), ("crn", &s.crn)] {
                layers.extend(stream.batches.iter().enumerate().map(|(b, im)| (batch_prefix(name, b), im)));
            }
        }
        for (prefix, im) in &layers {
            if im.width != w || im.height != h || im.pixels.len() != w * h {
                return Err(ReconError::SizeMismatch {
                    origin: origin(),
                    layer: format!("{prefix}RGB"),
                    width: im.width,
                    height: im.height,
                    expected_width: w,
                    expected_height: h,
                });
            }
        }
        // One pass for both: every value finite, and within MAX_VALUE where the method asks.
        let limit = if needs.bounded_values { MAX_VALUE } else { f32::INFINITY };
        let too_large = |origin: String, channel: String, v: f32, x: usize, y: usize| {
            if v.is_finite() {
                ReconError::TooLarge { origin, method, channel, value: v, x, y, limit: MAX_VALUE }
            } else {
                ReconError::NonFinite { origin, channel, value: v, x, y }
            }
        };
        if let Some((i, (x, y, c, v))) = layers
            .par_iter()
            .map(|(_, im)| first_beyond(im, limit))
            .collect::<Vec<_>>()
            .into_iter()
            .enumerate()
            .find_map(|(i, r)| r.map(|r| (i, r)))
        {
            return Err(too_large(origin(), format!("{}{}", layers[i].0, RGB[c]), v, x, y));
        }
        if needs.spp && s.meta.spp == 0 {
            return Err(ReconError::MissingSpp { origin: origin(), method });
        }
        if let Some(why) = needs.features {
            let f = s.features.as_ref().ok_or(ReconError::MissingFeatures { origin: origin(), method, why })?;
            for (name, im) in [("albedo.", &f.albedo), ("normal.", &f.normal)] {
                if !im.same_size(&s.pt.mean) || im.pixels.len() != w * h {
                    return Err(ReconError::SizeMismatch {
                        origin: origin(),
                        layer: format!("{name}*"),
                        width: im.width,
                        height: im.height,
                        expected_width: w,
                        expected_height: h,
                    });
                }
                if let Some((x, y, c, v)) = first_non_finite(im) {
                    let channel = if name == "normal." { ["X", "Y", "Z"][c] } else { RGB[c] };
                    return Err(ReconError::NonFinite { origin: origin(), channel: format!("{name}{channel}"), value: v, x, y });
                }
            }
        }
        if needs.pt2n {
            let image = self.pt2n.ok_or(ReconError::MissingPt2n { method })?;
            if !image.same_size(&s.pt.mean) || image.pixels.len() != w * h {
                return Err(ReconError::SizeMismatch {
                    origin: self.pt2n_name.to_string(),
                    layer: "R,G,B".into(),
                    width: image.width,
                    height: image.height,
                    expected_width: w,
                    expected_height: h,
                });
            }
            if let Some((x, y, c, v)) = first_beyond(image, limit) {
                return Err(too_large(self.pt2n_name.to_string(), RGB[c].to_string(), v, x, y));
            }
        }
        if needs.reference {
            let r = self.reference.ok_or(ReconError::MissingReference { method })?;
            if r.width != w || r.height != h || r.pixels.len() != w * h {
                return Err(ReconError::ReferenceSize {
                    reference: self.reference_name.to_string(),
                    origin: origin(),
                    width: r.width,
                    height: r.height,
                    expected_width: w,
                    expected_height: h,
                });
            }
            if let Some((x, y, c, v)) = first_beyond(r, limit) {
                return Err(too_large(self.reference_name.to_string(), RGB[c].to_string(), v, x, y));
            }
        }
        Ok(())
    }
}

/// A stream set from another renderer's buffers: `B` batch means per stream (equal sample
/// counts per batch, batch `b` of every CRN pixel sharing its random numbers), `spp` the
/// samples per pixel of each stream (IDUW needs it; 0 if unknown). The stream means are the
/// means of the batches. Checks that there are batches and that every image has one size.
pub fn stream_set_from_batches(pt: Vec<Image>, crn: Vec<Image>, spp: u32, features: Option<Features>) -> Result<StreamSet, ReconError> {
    let origin = "<batch buffers>".to_string();
    let Some(first) = pt.first().or(crn.first()) else {
        return Err(ReconError::BatchCount {
            origin,
            method: "stream set",
            requirement: "at least 1".into(),
            found: 0,
            hint: "pass the batch means of both streams".into(),
        });
    };
    let (w, h) = (first.width, first.height);
    for (name, list) in [("pt", &pt), ("crn", &crn)] {
        for (b, im) in list.iter().enumerate() {
            if im.width != w || im.height != h || im.pixels.len() != w * h {
                return Err(ReconError::SizeMismatch {
                    origin,
                    layer: format!("{}RGB", batch_prefix(name, b)),
                    width: im.width,
                    height: im.height,
                    expected_width: w,
                    expected_height: h,
                });
            }
        }
    }
    if pt.len() != crn.len() {
        return Err(ReconError::BatchCountMismatch { origin, pt: pt.len(), crn: crn.len() });
    }
    Ok(StreamSet {
        width: w,
        height: h,
        pt: Stream::from_batches(pt),
        crn: Stream::from_batches(crn),
        features,
        meta: StreamMeta { spp, ..Default::default() },
    })
}

const RGB: [&str; 3] = ["R", "G", "B"];

/// The first value that is not finite or is beyond `limit` in magnitude.
fn first_beyond(im: &Image, limit: f32) -> Option<(usize, usize, usize, f32)> {
    let w = im.width.max(1);
    im.pixels
        .iter()
        .enumerate()
        .find_map(|(i, p)| p.iter().position(|v| !v.is_finite() || v.abs() > limit).map(|c| (i % w, i / w, c, p[c])))
}

fn first_non_finite(im: &Image) -> Option<(usize, usize, usize, f32)> {
    let w = im.width.max(1);
    im.pixels.iter().enumerate().find_map(|(i, p)| p.iter().position(|v| !v.is_finite()).map(|c| (i % w, i / w, c, p[c])))
}

/// What an estimator needs from its input, so a caller (the CLI) knows what to load and
/// can refuse early.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Needs {
    pub batches: BatchNeed,
    /// `Some(why)` when first-hit features are required (e.g. "with --select gbuffer").
    pub features: Option<&'static str>,
    /// A reference image (analysis options only).
    pub reference: bool,
    /// The samples per pixel of each stream (`StreamMeta::spp`).
    pub spp: bool,
    /// A PT(2n) image ([`Input::pt2n`]).
    pub pt2n: bool,
    /// Values (and the reference, if needed) at most [`MAX_VALUE`] in magnitude: the method
    /// forms squared differences of them in f32, which overflow beyond.
    pub bounded_values: bool,
}

impl Needs {
    /// Only the stream means.
    pub const MEANS: Needs =
        Needs { batches: BatchNeed::None, features: None, reference: false, spp: false, pt2n: false, bounded_values: false };
}

/// Largest magnitude of a value that `cv` and `ours` take. They square and sum differences of
/// values in f32; past the overflow their image is silently not the rescaled image of a
/// rescaled input (Cornell box streams ×1e19, values up to 1.7e20: `ours` 17% and `cv` 39%
/// off, with no error; ×1e18: exact to 1e-7). Differences of up to twice a value, squared and
/// summed over three channels, can overflow from about 5e18 on, hence the margin.
pub const MAX_VALUE: f32 = 1e18;

/// How many batches per stream a method can work with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BatchNeed {
    /// Batches are not read.
    None,
    /// At least `min` and at most `max` batches.
    Range { min: usize, max: usize },
    /// A positive multiple of the value.
    MultipleOf(usize),
}

impl BatchNeed {
    fn check(self, origin: String, method: &'static str, found: usize) -> Result<(), ReconError> {
        let fail =
            |requirement: String, hint: String| Err(ReconError::BatchCount { origin: origin.clone(), method, requirement, found, hint });
        match self {
            BatchNeed::None => Ok(()),
            BatchNeed::Range { min, .. } if found < min => fail(
                format!("at least {min}"),
                "batch covariances need several batch means; re-render with more batches (cvtrace render --batches 16)".into(),
            ),
            BatchNeed::Range { max, .. } if found > max => fail(
                format!("at most {max}"),
                format!("merge neighbouring batches into at most {max} (each batch is a mean of a fixed sample range)"),
            ),
            BatchNeed::MultipleOf(m) if found == 0 || !found.is_multiple_of(m) => fail(
                format!("a positive multiple of {m}"),
                format!("it forms {m} sub-buffers from consecutive batches; re-render with a batch count divisible by {m}"),
            ),
            _ => Ok(()),
        }
    }
}

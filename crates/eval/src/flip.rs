//! HDR-FLIP: the perceptual error of a test image against a reference, as NVIDIA's FLIP
//! defines it (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG
//! 2020; "Visualizing Errors in Rendered High Dynamic Range Images", Eurographics 2021).
//!
//! relMSE rewards blur; FLIP instead estimates what an observer flipping between the two
//! images would notice, so denoiser comparisons report both.
//!
//! # What is computed
//!
//! Both images are linear RGB (any non-negative range). HDR-FLIP tone maps them at several
//! exposures and takes, per pixel, the largest LDR-FLIP error over the exposures:
//!
//! 1. **Exposures** come from the reference, as NVIDIA's `flip-evaluator` computes them:
//!    with `Y` the luminance `0.2126 R + 0.7152 G + 0.0722 B` and `x_max` the input at which
//!    the ACES curve reaches 0.85, `c_start = log2(x_max / max Y)`,
//!    `c_stop = log2(x_max / median Y)` (the median is the `⌊n/2⌋`-th smallest value) and
//!    `N = max(2, ⌈c_stop − c_start⌉)` exposures evenly spaced from `c_start` to `c_stop`.
//! 2. **Per exposure** `c`, both images are scaled by `2^c`, tone mapped per channel by the
//!    ACES fit NVIDIA uses (Narkowicz's, with its 0.6 pre-exposure cancelled), clamped to
//!    [0, 1] and compared by LDR-FLIP:
//!    - *colour*: opponent space YCxCz, filtered by the contrast sensitivity functions of the
//!      achromatic and two chromatic channels (sums of Gaussians at `ppd` pixels per degree),
//!      back to linear RGB clamped to [0, 1], then CIELAB with the Hunt adjustment; the HyAB
//!      distance, raised to 0.7 and mapped to [0, 1] (95% of the range up to 0.4 of the
//!      largest distance, green to blue);
//!    - *features*: edges and points of the achromatic channel (first and second derivatives
//!      of a Gaussian of σ = 0.041 degrees), their difference `f` (normalised, raised to 0.5);
//!    - the error is `colour^(1 − f)`.
//! 3. The **error map** is the per-pixel maximum over the exposures, in [0, 1]; the **mean**
//!    is its pixel mean.
//!
//! The arithmetic follows NVIDIA's C++ in f32, operation by operation and in the same order
//! (filters separated the same way, edges clamped), so the exposures are identical and maps
//! differ from `flip-evaluator`'s only by rounding (on the test images of
//! `tests/flip_evaluator.rs`: means within 3e-7, pixels within 4e-5).
//!
//! # Parameters
//!
//! - `ppd`, pixels per degree of visual angle: [`DEFAULT_PPD`] = 67.02 as NVIDIA's tool (a
//!   0.7 m wide 3840-pixel monitor seen from 0.7 m).
//! - the exposures: computed from the reference as above unless given ([`Exposures`]).
//! - the tone mapper: ACES, NVIDIA's default (the only one here).
//!
//! # Where this departs from NVIDIA's tool
//!
//! Only where the tool has no finite answer: when at least half of the reference's pixels have
//! no positive luminance, `c_stop` would be infinite (and the tool returns an all-zero map), so
//! the median of the positive luminances is used instead; a reference with no positive
//! luminance at all gets `c_start = c_stop = 0`. Negative values are passed through the same
//! tone curve as the tool does (which maps large negative values to white, so a negative
//! pixel shows as an error). Non-finite values are refused.
//!
//! # Cost and determinism
//!
//! One exposure of a 1920×1080 pair costs about 0.38 s of CPU time (NVIDIA's tool: about 3 s),
//! and the number of exposures grows with `log2(max Y / median Y)` of the reference: 6 for a
//! typical render. The passes run in parallel over rows with rayon; every pixel is computed by
//! the same operations whatever the thread count, and the mean is summed in row order in f64,
//! so results are bit-identical for any number of threads.
use crate::EvalError;
use cvtrace_streams::Image;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;
use std::path::Path;

/// NVIDIA's default pixels per degree: a 0.7 m wide monitor of 3840 pixels seen from 0.7 m,
/// computed in f32 as their tool does (67.0206…).
pub const DEFAULT_PPD: f32 = 0.7 * (3840.0 / 0.7) * (PI / 180.0);

/// Name of the only tone mapper, as recorded in the results.
pub const TONEMAPPER: &str = "aces";

/// Name of the colour map of FLIP error maps, as recorded in the results.
pub const COLORMAP_NAME: &str = "magma";

/// ACES coefficients of `(a c² + b c + e) / (d c² + f c + g)`, in NVIDIA's order
/// `[a, b, e, d, f, g]`, with the 0.6 pre-exposure of Narkowicz's fit cancelled.
const ACES: [f32; 6] = [0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14];

// FLIP's constants (the paper's Table 1): colour exponent q_c, the cut-off p_c and the share
// p_t of [0, 1] below it, the feature filter width w (degrees) and the feature exponent q_f.
const GQC: f32 = 0.7;
const GPC: f32 = 0.4;
const GPT: f32 = 0.95;
const GW: f32 = 0.082;
const GQF: f32 = 0.5;

// The contrast sensitivity functions as sums of Gaussians a·√(π/b)·exp(−π²x²/b): per channel
// (achromatic, red-green, blue-yellow) the first and second term's a and b.
const A1: [f32; 3] = [1.0, 1.0, 34.1];
const B1: [f32; 3] = [0.0047, 0.0053, 0.04];
const A2: [f32; 3] = [0.0, 0.0, 13.5];
const B2: [f32; 3] = [1.0e-5, 1.0e-5, 0.025];

/// The D65 white point in XYZ and its reciprocal, as NVIDIA writes them.
const ILLUMINANT: [f32; 3] = [0.950_428_55, 1.0, 1.088_900_4];
const INV_ILLUMINANT: [f32; 3] = [1.052_156_9, 1.0, 0.918_357_7];

/// The exposures (in stops) at which the images are tone mapped and compared.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Exposures {
    pub start: f32,
    pub stop: f32,
    /// At least 2 (`start` and `stop` themselves).
    pub count: u32,
}

impl Exposures {
    /// The exposures NVIDIA's tool computes from a reference (see the module docs).
    pub fn from_reference(reference: &Image) -> Exposures {
        let lum: Vec<f32> = reference.pixels.iter().map(|p| luminance(*p)).collect();
        let y_max = lum.iter().fold(-1e30f32, |m, &v| max(v, m));
        let median = |mut v: Vec<f32>| -> Option<f32> {
            if v.is_empty() {
                return None;
            }
            let mid = v.len() / 2;
            Some(*v.select_nth_unstable_by(mid, f32::total_cmp).1)
        };
        let y_median = median(lum.clone()).filter(|m| *m > 0.0).or_else(|| median(lum.into_iter().filter(|v| *v > 0.0).collect()));
        let (start, stop) = match y_median {
            Some(y_median) if y_max > 0.0 => {
                let x_max = aces_input_at(0.85);
                (((x_max / y_max) as f64).log2() as f32, ((x_max / y_median) as f64).log2() as f32)
            }
            _ => (0.0, 0.0),
        };
        let count = max(2.0, (stop - start).ceil()) as u32;
        Exposures { start, stop, count }
    }

    /// The `count` exposures, in stops, as NVIDIA's tool steps them.
    pub fn values(&self) -> Vec<f32> {
        let n = self.count.max(2);
        let step = (self.stop - self.start) / (n - 1) as f32;
        (0..n).map(|i| self.start + i as f32 * step).collect()
    }
}

/// The settings of a FLIP evaluation, as recorded in the results.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlipSettings {
    /// Pixels per degree of visual angle.
    pub ppd: f32,
    pub start_exposure: f32,
    pub stop_exposure: f32,
    pub num_exposures: u32,
    /// The tone mapper ([`TONEMAPPER`]).
    pub tonemapper: String,
    /// The colour map of the error map images ([`COLORMAP_NAME`]).
    pub colormap: String,
}

/// A per-pixel FLIP error map in [0, 1] (row-major) and its mean.
#[derive(Clone, Debug, PartialEq)]
pub struct FlipMap {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
    pub mean: f64,
}

/// A reference prepared for HDR-FLIP: its exposures and the filters for a `ppd`.
#[derive(Clone, Debug)]
pub struct FlipReference {
    label: String,
    image: Image,
    ppd: f32,
    exposures: Exposures,
    filters: Filters,
}

impl FlipReference {
    /// The reference with NVIDIA's defaults: [`DEFAULT_PPD`] and the exposures computed from it.
    pub fn new(reference: &Image, label: impl Into<String>) -> Result<Self, EvalError> {
        Self::with_settings(reference, label, DEFAULT_PPD, None)
    }

    /// The reference at `ppd` pixels per degree, with the given exposures or (`None`) those
    /// computed from it. Errors name `label`: an empty or non-finite image, a bad `ppd`, bad
    /// exposures.
    pub fn with_settings(reference: &Image, label: impl Into<String>, ppd: f32, exposures: Option<Exposures>) -> Result<Self, EvalError> {
        let label = label.into();
        if reference.is_empty() || reference.pixels.len() != reference.width * reference.height {
            return Err(EvalError::invalid(&label, format!("FLIP needs a non-empty image, got {}x{}", reference.width, reference.height)));
        }
        crate::metrics::ensure_finite(reference, &label)?;
        // Beyond a few thousand pixels per degree the filters would be wider than any image.
        if !(ppd.is_finite() && ppd > 0.0 && ppd <= 4096.0) {
            return Err(EvalError::invalid(&label, format!("FLIP pixels per degree must be in (0, 4096], got {ppd}")));
        }
        let exposures = exposures.unwrap_or_else(|| Exposures::from_reference(reference));
        if !(exposures.start.is_finite() && exposures.stop.is_finite() && exposures.start <= exposures.stop && exposures.count >= 2) {
            return Err(EvalError::invalid(&label, format!("FLIP exposures need finite start <= stop and count >= 2, got {exposures:?}")));
        }
        Ok(FlipReference { label, image: reference.clone(), ppd, exposures, filters: Filters::new(ppd) })
    }

    pub fn exposures(&self) -> Exposures {
        self.exposures
    }

    pub fn ppd(&self) -> f32 {
        self.ppd
    }

    pub fn image(&self) -> &Image {
        &self.image
    }

    /// What the results record about this evaluation.
    pub fn settings(&self) -> FlipSettings {
        FlipSettings {
            ppd: self.ppd,
            start_exposure: self.exposures.start,
            stop_exposure: self.exposures.stop,
            num_exposures: self.exposures.count,
            tonemapper: TONEMAPPER.into(),
            colormap: COLORMAP_NAME.into(),
        }
    }

    /// The HDR-FLIP error map of `test` against this reference. Errors name `label` (and the
    /// reference) when the sizes differ or `test` holds a non-finite value.
    pub fn evaluate(&self, test: &Image, label: &str) -> Result<FlipMap, EvalError> {
        crate::metrics::ensure_same_size(test, label, &self.image, &self.label)?;
        crate::metrics::ensure_finite(test, label)?;
        let (w, h) = (self.image.width, self.image.height);
        let mut map = vec![0.0f32; w * h];
        let mut work = Work::new(w * h);
        for exposure in self.exposures.values() {
            let gain = 2.0f32.powf(exposure);
            work.ldr_flip(&self.image, test, gain, &self.filters, &mut map, w, h);
        }
        let mean = map.par_chunks(w).map(|row| row.iter().map(|v| *v as f64).sum::<f64>()).collect::<Vec<f64>>().iter().sum::<f64>()
            / map.len() as f64;
        Ok(FlipMap { width: w, height: h, values: map, mean })
    }
}

/// HDR-FLIP of `test` against `reference` with NVIDIA's defaults.
pub fn hdr_flip(reference: &Image, test: &Image) -> Result<FlipMap, EvalError> {
    FlipReference::new(reference, "reference")?.evaluate(test, "test image")
}

/// FLIP of several seeds of one method: the per-seed means and the per-pixel mean map.
#[derive(Clone, Debug)]
pub struct FlipAccumulator<'r> {
    reference: &'r FlipReference,
    sum: Vec<f32>,
    per_seed: Vec<f64>,
}

/// What [`FlipAccumulator::finish`] reports.
#[derive(Clone, Debug, PartialEq)]
pub struct FlipStats {
    pub mean: f64,
    /// Standard error of `mean` (sample standard deviation / √S); `None` for one seed.
    pub se: Option<f64>,
    pub per_seed: Vec<f64>,
}

impl<'r> FlipAccumulator<'r> {
    pub fn new(reference: &'r FlipReference) -> Self {
        FlipAccumulator { reference, sum: vec![0.0; reference.image.len()], per_seed: Vec::new() }
    }

    /// Adds the next seed's image; `label` names it in errors. Returns its FLIP mean.
    pub fn add(&mut self, image: &Image, label: &str) -> Result<f64, EvalError> {
        let map = self.reference.evaluate(image, label)?;
        self.sum.iter_mut().zip(&map.values).for_each(|(s, v)| *s += v);
        self.per_seed.push(map.mean);
        Ok(map.mean)
    }

    pub fn seeds(&self) -> usize {
        self.per_seed.len()
    }

    /// The per-pixel FLIP error averaged over the seeds added so far; its pixel mean is the
    /// mean of the per-seed means.
    pub fn mean_map(&self) -> Vec<f32> {
        let s = self.per_seed.len().max(1) as f32;
        self.sum.iter().map(|v| v / s).collect()
    }

    /// Mean ± standard error over the seeds added so far; `None` when none was added.
    pub fn finish(&self) -> Option<FlipStats> {
        let s = self.per_seed.len();
        if s == 0 {
            return None;
        }
        let mean = self.per_seed.iter().sum::<f64>() / s as f64;
        let se = (s >= 2).then(|| {
            let var = self.per_seed.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (s - 1) as f64;
            (var / s as f64).sqrt()
        });
        Some(FlipStats { mean, se, per_seed: self.per_seed.clone() })
    }
}

// ---- colour map ------------------------------------------------------------------------------

/// matplotlib's magma (CC0) at 17 evenly spaced points, as sRGB bytes; FLIP's error maps are
/// shown through it (black = no error, pale yellow = 1).
const MAGMA: [[u8; 3]; 17] = [
    [0, 0, 4],
    [10, 8, 34],
    [29, 17, 70],
    [54, 16, 106],
    [80, 18, 124],
    [105, 28, 129],
    [130, 38, 129],
    [156, 46, 127],
    [182, 55, 121],
    [207, 65, 112],
    [230, 81, 99],
    [245, 105, 92],
    [251, 135, 97],
    [254, 165, 113],
    [254, 195, 135],
    [253, 224, 162],
    [252, 253, 191],
];

/// The magma colour at `t ∈ [0, 1]` (clamped; NaN is 0) as sRGB bytes.
pub fn magma(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (MAGMA.len() - 1) as f64;
    let i = (x.floor() as usize).min(MAGMA.len() - 2);
    let f = x - i as f64;
    let (a, b) = (MAGMA[i], MAGMA[i + 1]);
    [0, 1, 2].map(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round() as u8)
}

/// A FLIP error map as sRGB bytes through [`magma`], on FLIP's own linear [0, 1] scale.
pub fn flip_rgb8(map: &[f32]) -> Vec<u8> {
    let lut: Vec<[u8; 3]> = (0..256).map(|i| magma(i as f64 / 255.0)).collect();
    map.iter().flat_map(|v| lut[(v.clamp(0.0, 1.0) * 255.0).round() as usize]).collect()
}

/// Writes a FLIP error map as a magma PNG, atomically.
pub fn write_flip_png(path: &Path, map: &[f32], width: usize, height: usize, overwrite: bool) -> Result<(), EvalError> {
    if map.len() != width * height {
        return Err(EvalError::invalid(
            path.display().to_string(),
            format!("FLIP map has {} values, expected {width}x{height}", map.len()),
        ));
    }
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &flip_rgb8(map), overwrite)?;
    Ok(())
}

/// A horizontal colour bar of [`magma`] (left = 0, right = 1) for legends.
pub fn write_flip_colorbar_png(path: &Path, width: usize, height: usize, overwrite: bool) -> Result<(), EvalError> {
    let row: Vec<u8> = (0..width).flat_map(|x| magma(x as f64 / (width.max(2) - 1) as f64)).collect();
    let bytes: Vec<u8> = (0..height).flat_map(|_| row.iter().copied()).collect();
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &bytes, overwrite)?;
    Ok(())
}

// ---- the computation ---------------------------------------------------------------------------

/// `x > y ? x : y`, as NVIDIA's macro (a NaN `x` gives `y`).
#[inline(always)]
fn max(x: f32, y: f32) -> f32 {
    if x > y {
        x
    } else {
        y
    }
}

/// `x > y ? y : x`, as NVIDIA's macro.
#[inline(always)]
fn min(x: f32, y: f32) -> f32 {
    if x > y {
        y
    } else {
        x
    }
}

#[inline(always)]
fn clamp01(v: f32) -> f32 {
    min(max(v, 0.0), 1.0)
}

#[inline(always)]
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The input at which the ACES curve reaches `t`: the larger root of
/// `(a − t d) x² + (b − t f) x + (e − t g) = 0`.
fn aces_input_at(t: f32) -> f32 {
    let a = ACES[0] - t * ACES[3];
    let b = ACES[1] - t * ACES[4];
    let c = ACES[2] - t * ACES[5];
    if a == 0.0 {
        return -c / b;
    }
    let d1 = -0.5 * (b / a);
    let d2 = ((d1 * d1) - (c / a)).sqrt();
    d1 + d2
}

#[inline(always)]
fn aces(c: f32) -> f32 {
    ((c * c) * ACES[0] + c * ACES[1] + ACES[2]) / (c * c * ACES[3] + c * ACES[4] + ACES[5])
}

// sRGB primaries, D65 (NVIDIA's rational forms, rounded to f32 as their compiler does).
const RGB_TO_XYZ: [[f32; 3]; 3] = [
    [10135552.0 / 24577794.0, 8788810.0 / 24577794.0, 4435075.0 / 24577794.0],
    [2613072.0 / 12288897.0, 8788810.0 / 12288897.0, 887015.0 / 12288897.0],
    [1425312.0 / 73733382.0, 8788810.0 / 73733382.0, 70074185.0 / 73733382.0],
];
const XYZ_TO_RGB: [[f32; 3]; 3] =
    [[3.241_003_3, -1.537_398_9, -0.498_615_87], [-0.969_224_3, 1.875_930_1, 0.041_554_224], [0.055_639_423, -0.204_011_2, 1.057_148_9]];

// Written out rather than with `array::map`, which the optimiser leaves as a loop here.
#[inline(always)]
fn mat(m: &[[f32; 3]; 3], c: [f32; 3]) -> [f32; 3] {
    [
        m[0][0] * c[0] + m[0][1] * c[1] + m[0][2] * c[2],
        m[1][0] * c[0] + m[1][1] * c[1] + m[1][2] * c[2],
        m[2][0] * c[0] + m[2][1] * c[1] + m[2][2] * c[2],
    ]
}

#[inline(always)]
fn xyz_to_ycxcz(c: [f32; 3]) -> [f32; 3] {
    let (x, y, z) = (c[0] * INV_ILLUMINANT[0], c[1] * INV_ILLUMINANT[1], c[2] * INV_ILLUMINANT[2]);
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

#[inline(always)]
fn ycxcz_to_xyz(c: [f32; 3]) -> [f32; 3] {
    let y = (c[0] + 16.0) / 116.0;
    let cx = c[1] / 500.0;
    let cz = c[2] / 200.0;
    [(y + cx) * ILLUMINANT[0], y * ILLUMINANT[1], (y - cz) * ILLUMINANT[2]]
}

#[inline(always)]
fn xyz_to_lab(c: [f32; 3]) -> [f32; 3] {
    let delta = 6.0f32 / 29.0;
    let delta_square = delta * delta;
    let delta_cube = delta * delta_square;
    let factor = 1.0 / (3.0 * delta_square);
    let term = 4.0f32 / 29.0;
    let f = |v: f32| if v > delta_cube { v.powf(1.0 / 3.0) } else { factor * v + term };
    let (x, y, z) = (f(c[0] * INV_ILLUMINANT[0]), f(c[1] * INV_ILLUMINANT[1]), f(c[2] * INV_ILLUMINANT[2]));
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// CIELAB with the Hunt adjustment of the chroma (scaled by 0.01 L).
#[inline(always)]
fn lab_hunt(c: [f32; 3]) -> [f32; 3] {
    [c[0], 0.01 * c[0] * c[1], 0.01 * c[0] * c[2]]
}

#[inline(always)]
fn hyab(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).abs() + ((a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])).sqrt()
}

/// The largest colour distance FLIP normalises by: green to blue, Hunt-adjusted HyAB^q_c.
fn max_color_distance() -> f32 {
    let green = lab_hunt(xyz_to_lab(mat(&RGB_TO_XYZ, [0.0, 1.0, 0.0])));
    let blue = lab_hunt(xyz_to_lab(mat(&RGB_TO_XYZ, [0.0, 0.0, 1.0])));
    hyab(green, blue).powf(GQC)
}

/// The separated filters for one `ppd`.
#[derive(Clone, Debug)]
struct Filters {
    /// The contrast sensitivity functions: achromatic, red-green, and the two Gaussians of
    /// blue-yellow (each the square root of its 2D term, so the 2D filter is the sum of the
    /// two outer products), normalised so the 2D filters sum to 1.
    y: Vec<f32>,
    cx: Vec<f32>,
    cz1: Vec<f32>,
    cz2: Vec<f32>,
    /// Gaussian, first and second derivative for edges and points, each normalised (the
    /// Gaussian to sum 1, the derivatives' positive and negative parts to ±1).
    g: Vec<f32>,
    dg: Vec<f32>,
    ddg: Vec<f32>,
    cmax: f32,
}

impl Filters {
    fn new(ppd: f32) -> Filters {
        let pi_sq = PI * PI;
        let gauss = |x2: f32, a: f32, b: f32| a * (PI / b).sqrt() * (-pi_sq * x2 / b).exp();
        let gauss_sqrt = |x2: f32, a: f32, b: f32| (a * (PI / b).sqrt()).sqrt() * (-pi_sq * x2 / b).exp();
        let widest = [B1[0], B1[1], B1[2], B2[0], B2[1], B2[2]].into_iter().fold(0.0f32, f32::max);
        let radius = (3.0 * (widest / (2.0 * pi_sq)).sqrt() * ppd).ceil() as i64;
        let delta_x = 1.0 / ppd;
        let (mut y, mut cx, mut cz1, mut cz2) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut sum_y, mut sum_cx, mut sum_cz1, mut sum_cz2) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for i in -radius..=radius {
            let ix = i as f32 * delta_x;
            let ix2 = ix * ix;
            let v = [gauss(ix2, A1[0], B1[0]), gauss(ix2, A1[1], B1[1]), gauss_sqrt(ix2, A1[2], B1[2]), gauss_sqrt(ix2, A2[2], B2[2])];
            y.push(v[0]);
            cx.push(v[1]);
            cz1.push(v[2]);
            cz2.push(v[3]);
            sum_y += v[0];
            sum_cx += v[1];
            sum_cz1 += v[2];
            sum_cz2 += v[3];
        }
        let (norm_y, norm_cx) = (1.0 / sum_y, 1.0 / sum_cx);
        let norm_cz = 1.0 / (sum_cz1 * sum_cz1 + sum_cz2 * sum_cz2).sqrt();
        y.iter_mut().for_each(|v| *v *= norm_y);
        cx.iter_mut().for_each(|v| *v *= norm_cx);
        cz1.iter_mut().for_each(|v| *v *= norm_cz);
        cz2.iter_mut().for_each(|v| *v *= norm_cz);

        let sd = 0.5 * GW * ppd;
        let radius = (3.0 * sd).ceil() as i64;
        let (mut g, mut dg, mut ddg) = (Vec::new(), Vec::new(), Vec::new());
        let (mut g_sum, mut dg_neg, mut dg_pos, mut ddg_neg, mut ddg_pos) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for i in -radius..=radius {
            let x = i as f32;
            let gv = (-(x * x) / (2.0 * sd * sd)).exp();
            g_sum += gv;
            let d = -x * gv;
            if d > 0.0 {
                dg_pos += d;
            } else {
                dg_neg -= d;
            }
            let dd = (x * x / (sd * sd) - 1.0) * gv;
            if dd > 0.0 {
                ddg_pos += dd;
            } else {
                ddg_neg -= dd;
            }
            g.push(gv);
            dg.push(d);
            ddg.push(dd);
        }
        g.iter_mut().for_each(|v| *v /= g_sum);
        dg.iter_mut().for_each(|v| *v /= if *v > 0.0 { dg_pos } else { dg_neg });
        ddg.iter_mut().for_each(|v| *v /= if *v > 0.0 { ddg_pos } else { ddg_neg });
        Filters { y, cx, cz1, cz2, g, dg, ddg, cmax: max_color_distance() }
    }
}

/// Planes reused across exposures: per image the opponent channels, then the horizontal
/// passes of the colour filters (4) and of the feature filters (3).
struct Work {
    planes: [[Vec<f32>; 3]; 2],
    horizontal: [[Vec<f32>; 7]; 2],
}

impl Work {
    fn new(n: usize) -> Work {
        let plane = || vec![0.0f32; n];
        Work {
            planes: [[plane(), plane(), plane()], [plane(), plane(), plane()]],
            horizontal: std::array::from_fn(|_| std::array::from_fn(|_| plane())),
        }
    }

    /// LDR-FLIP of `reference` and `test` exposed by `gain`, folded into `map` by maximum.
    #[allow(clippy::too_many_arguments)]
    fn ldr_flip(&mut self, reference: &Image, test: &Image, gain: f32, f: &Filters, map: &mut [f32], w: usize, h: usize) {
        // Expose, tone map, clamp, and move to YCxCz.
        for (planes, image) in self.planes.iter_mut().zip([reference, test]) {
            let [py, pcx, pcz] = planes;
            (py.par_chunks_mut(w), pcx.par_chunks_mut(w), pcz.par_chunks_mut(w), image.pixels.par_chunks(w)).into_par_iter().for_each(
                |(ry, rcx, rcz, src)| {
                    for (i, p) in src.iter().enumerate() {
                        let ldr = [clamp01(aces(p[0] * gain)), clamp01(aces(p[1] * gain)), clamp01(aces(p[2] * gain))];
                        let o = xyz_to_ycxcz(mat(&RGB_TO_XYZ, ldr));
                        (ry[i], rcx[i], rcz[i]) = (o[0], o[1], o[2]);
                    }
                },
            );
        }
        // Horizontal passes: colour filters on the opponent channels, feature filters on the
        // achromatic channel brought to [0, 1].
        for (planes, out) in self.planes.iter().zip(self.horizontal.iter_mut()) {
            let [o_y, o_cx, o_cz1, o_cz2, o_dx, o_ddx, o_g] = out;
            horizontal(&planes[0], w, &f.y, o_y, |v| v);
            horizontal(&planes[1], w, &f.cx, o_cx, |v| v);
            horizontal(&planes[2], w, &f.cz1, o_cz1, |v| v);
            horizontal(&planes[2], w, &f.cz2, o_cz2, |v| v);
            let normalise = |v: f32| v * (1.0 / 116.0) + 16.0 / 116.0;
            horizontal(&planes[0], w, &f.dg, o_dx, normalise);
            horizontal(&planes[0], w, &f.ddg, o_ddx, normalise);
            horizontal(&planes[0], w, &f.g, o_g, normalise);
        }
        // Vertical passes and the per-pixel error.
        let cmax = f.cmax;
        let pccmax = GPC * cmax;
        let below = GPT / pccmax;
        let feature_norm = 1.0 / 2.0f32.sqrt();
        let hz = &self.horizontal;
        map.par_chunks_mut(w).enumerate().for_each_init(
            || vec![vec![0.0f32; w]; 16],
            |acc, (y, out)| {
                // Per image: Y, Cx, Cz1, Cz2, dx, ddx, dy, ddy.
                for (k, hzi) in hz.iter().enumerate() {
                    let a = &mut acc[8 * k..8 * k + 8];
                    vertical(&hzi[0], w, h, y, &f.y, &mut a[0]);
                    vertical(&hzi[1], w, h, y, &f.cx, &mut a[1]);
                    vertical(&hzi[2], w, h, y, &f.cz1, &mut a[2]);
                    vertical(&hzi[3], w, h, y, &f.cz2, &mut a[3]);
                    vertical(&hzi[4], w, h, y, &f.g, &mut a[4]);
                    vertical(&hzi[5], w, h, y, &f.g, &mut a[5]);
                    vertical(&hzi[6], w, h, y, &f.dg, &mut a[6]);
                    vertical(&hzi[6], w, h, y, &f.ddg, &mut a[7]);
                }
                let (r, t) = acc.split_at(8);
                for x in 0..w {
                    let lab = |a: &[Vec<f32>]| {
                        let rgb = mat(&XYZ_TO_RGB, ycxcz_to_xyz([a[0][x], a[1][x], a[2][x] + a[3][x]]));
                        lab_hunt(xyz_to_lab(mat(&RGB_TO_XYZ, [clamp01(rgb[0]), clamp01(rgb[1]), clamp01(rgb[2])])))
                    };
                    let mut color = hyab(lab(r), lab(t)).powf(GQC);
                    color = if color < pccmax { color * below } else { GPT + ((color - pccmax) / (cmax - pccmax)) * (1.0 - GPT) };
                    let edge = |a: &[Vec<f32>]| (a[4][x] * a[4][x] + a[6][x] * a[6][x]).sqrt();
                    let point = |a: &[Vec<f32>]| (a[5][x] * a[5][x] + a[7][x] * a[7][x]).sqrt();
                    let edge_diff = (edge(r) - edge(t)).abs();
                    let point_diff = (point(r) - point(t)).abs();
                    let feature = (feature_norm * max(edge_diff, point_diff)).powf(GQF);
                    let error = color.powf(1.0 - feature);
                    if error > out[x] {
                        out[x] = error;
                    }
                }
            },
        );
    }
}

/// One horizontal pass over rows of `src` (of `transform`ed values), edges clamped:
/// `out[x] = Σ_k weights[k] · src[clamp(x + k − r)]`, summed in `k` order.
fn horizontal(src: &[f32], w: usize, weights: &[f32], out: &mut [f32], transform: impl Fn(f32) -> f32 + Sync) {
    let r = weights.len() / 2;
    out.par_chunks_mut(w).zip(src.par_chunks(w)).for_each_init(
        || vec![0.0f32; w + 2 * r],
        |padded, (out, row)| {
            for (j, p) in padded.iter_mut().enumerate() {
                *p = transform(row[j.saturating_sub(r).min(w - 1)]);
            }
            out.fill(0.0);
            for (k, &wk) in weights.iter().enumerate() {
                for (o, s) in out.iter_mut().zip(&padded[k..k + w]) {
                    *o += wk * s;
                }
            }
        },
    );
}

/// Row `y` of one vertical pass over `src`, edges clamped, into `acc`.
fn vertical(src: &[f32], w: usize, h: usize, y: usize, weights: &[f32], acc: &mut [f32]) {
    let r = weights.len() / 2;
    acc.fill(0.0);
    for (k, &wk) in weights.iter().enumerate() {
        let yy = (y + k).saturating_sub(r).min(h - 1);
        for (a, s) in acc.iter_mut().zip(&src[yy * w..(yy + 1) * w]) {
            *a += wk * s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize) -> Image {
        Image::from_fn(w, h, |x, y| {
            let u = x as f32 / w as f32;
            let v = y as f32 / h as f32;
            [2.0 * u + 0.1, 0.5 * v + 0.05, 0.3 + 0.2 * u * v]
        })
    }

    #[test]
    fn default_ppd_and_exposures_are_nvidias() {
        assert_eq!(DEFAULT_PPD, 67.020_645);
        // flip-evaluator 1.7 reports these for the same image (see tests/flip_evaluator.rs
        // for the full comparison); here: the rules, on an image with a known median.
        let img = Image::from_fn(4, 1, |x, _| [(x + 1) as f32; 3]);
        let e = Exposures::from_reference(&img);
        let x_max = aces_input_at(0.85);
        assert!((e.start - (x_max / 4.0).log2()).abs() < 1e-6, "{e:?}");
        assert!((e.stop - (x_max / 3.0).log2()).abs() < 1e-6, "median is the 2nd of 0-based sorted: {e:?}");
        assert_eq!(e.count, 2);
        let v = e.values();
        assert_eq!(v.len(), 2);
        assert_eq!((v[0], v[1]), (e.start, e.stop));
        // A wide range needs more exposures, one per stop.
        let wide = Image::from_fn(5, 1, |x, _| [10f32.powi(x as i32 - 2); 3]);
        let e = Exposures::from_reference(&wide);
        assert_eq!(e.count as f32, (e.stop - e.start).ceil());
    }

    #[test]
    fn degenerate_references_still_have_finite_exposures() {
        // Mostly black: the median of the positive luminances stands in.
        let mostly_black = Image::from_fn(5, 1, |x, _| if x < 3 { [0.0; 3] } else { [x as f32; 3] });
        let e = Exposures::from_reference(&mostly_black);
        assert!(e.start.is_finite() && e.stop.is_finite() && e.start <= e.stop, "{e:?}");
        let black = Image::new(4, 4);
        assert_eq!(Exposures::from_reference(&black), Exposures { start: 0.0, stop: 0.0, count: 2 });
        let f = hdr_flip(&black, &Image::from_fn(4, 4, |_, _| [1.0; 3])).unwrap();
        assert!(f.values.iter().all(|v| (0.0..=1.0).contains(v)) && f.mean > 0.5, "{}", f.mean);
    }

    #[test]
    fn identical_images_have_zero_error_and_errors_are_in_range() {
        let r = gradient(40, 30);
        let same = hdr_flip(&r, &r).unwrap();
        assert_eq!(same.mean, 0.0);
        assert!(same.values.iter().all(|v| *v == 0.0));
        let mut t = r.clone();
        for (i, p) in t.pixels.iter_mut().enumerate() {
            if i % 7 == 0 {
                p[1] += 0.5;
            }
        }
        let f = hdr_flip(&r, &t).unwrap();
        assert!(f.mean > 0.0 && f.mean < 1.0, "{}", f.mean);
        assert!(f.values.iter().all(|v| (0.0..=1.0).contains(v)));
        // More error, more FLIP.
        let mut worse = r.clone();
        for (i, p) in worse.pixels.iter_mut().enumerate() {
            if i % 7 == 0 {
                p[1] += 2.0;
            }
        }
        assert!(hdr_flip(&r, &worse).unwrap().mean > f.mean);
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let r = gradient(53, 37);
        let t = Image::from_fn(53, 37, |x, y| {
            let p = r.get(x, y);
            let n = ((x * 7919 + y * 104729) % 97) as f32 / 97.0 - 0.5;
            [p[0] * (1.0 + 0.3 * n), p[1], (p[2] + 0.2 * n).max(0.0)]
        });
        let run =
            |threads: usize| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| hdr_flip(&r, &t).unwrap());
        let one = run(1);
        for threads in [2, 3, 8] {
            let other = run(threads);
            assert_eq!(one.mean.to_bits(), other.mean.to_bits(), "{threads} threads");
            assert!(one.values.iter().zip(&other.values).all(|(a, b)| a.to_bits() == b.to_bits()), "{threads} threads");
        }
    }

    #[test]
    fn bad_inputs_are_errors_that_name_the_image() {
        let r = gradient(8, 8);
        let fr = FlipReference::new(&r, "ref.exr").unwrap();
        let e = fr.evaluate(&Image::new(8, 7), "small.exr").unwrap_err().to_string();
        assert!(e.contains("small.exr") && e.contains("ref.exr"), "{e}");
        let mut nan = r.clone();
        nan.pixels[5][2] = f32::NAN;
        assert!(fr.evaluate(&nan, "nan.exr").unwrap_err().to_string().contains("nan.exr"));
        assert!(FlipReference::new(&nan, "nanref.exr").unwrap_err().to_string().contains("nanref.exr"));
        assert!(FlipReference::new(&Image::new(0, 0), "empty.exr").unwrap_err().to_string().contains("empty.exr"));
        for ppd in [0.0, -1.0, f32::NAN, 1e9] {
            assert!(FlipReference::with_settings(&r, "r", ppd, None).is_err(), "{ppd}");
        }
        let bad = Exposures { start: 1.0, stop: 0.0, count: 3 };
        assert!(FlipReference::with_settings(&r, "r", DEFAULT_PPD, Some(bad)).unwrap_err().to_string().contains("exposures"));
    }

    #[test]
    fn accumulator_averages_seeds() {
        let r = gradient(24, 16);
        let fr = FlipReference::new(&r, "r").unwrap();
        let mut acc = FlipAccumulator::new(&fr);
        assert!(acc.finish().is_none());
        let noisy = |s: f32| Image::from_fn(24, 16, |x, y| r.get(x, y).map(|c| c * (1.0 + s * (((x + 3 * y) % 5) as f32 - 2.0) / 4.0)));
        let a = acc.add(&noisy(0.2), "a").unwrap();
        let stats = acc.finish().unwrap();
        assert_eq!((stats.mean, stats.se), (a, None));
        let b = acc.add(&noisy(0.5), "b").unwrap();
        let stats = acc.finish().unwrap();
        assert!((stats.mean - 0.5 * (a + b)).abs() < 1e-15);
        assert!((stats.se.unwrap() - (a - b).abs() / 2.0).abs() < 1e-12, "{stats:?}");
        let map = acc.mean_map();
        let mean = map.iter().map(|v| *v as f64).sum::<f64>() / map.len() as f64;
        assert!((mean - stats.mean).abs() < 1e-6, "{mean} vs {}", stats.mean);
    }

    #[test]
    fn magma_runs_from_black_to_pale_yellow_and_brightens() {
        assert_eq!(magma(0.0), MAGMA[0]);
        assert_eq!(magma(1.0), MAGMA[16]);
        assert_eq!(magma(f64::NAN), MAGMA[0]);
        let sum = |c: [u8; 3]| c.iter().map(|&v| v as u32).sum::<u32>();
        for k in 0..32 {
            assert!(sum(magma((k + 1) as f64 / 32.0)) > sum(magma(k as f64 / 32.0)), "{k}");
        }
        let rgb = flip_rgb8(&[0.0, 1.0, 2.0, -1.0]);
        assert_eq!(&rgb[0..3], &MAGMA[0]);
        assert_eq!(&rgb[3..6], &MAGMA[16]);
        assert_eq!(&rgb[6..9], &MAGMA[16]);
        assert_eq!(&rgb[9..12], &MAGMA[0]);
        let dir = tempfile::tempdir().unwrap();
        assert!(write_flip_png(&dir.path().join("bad.png"), &[0.0; 5], 3, 2, false).unwrap_err().to_string().contains("bad.png"));
        write_flip_png(&dir.path().join("ok.png"), &[0.0; 6], 3, 2, false).unwrap();
    }
}

//! `ours`: imperfect image-space control variates (Yang & Moon 2025).
//!
//! `F̂_c = ḡ_c − Σ_{i∈Ω_c} β_i (ḡ_i − h̄_i)` with `c ∈ Ω_c`, and β minimising the variance of
//! Eq. 7 of the supplement: `(V_g + V_h) β = V_fg`, where `V_g`/`V_fg` are CRN batch
//! covariances and `V_h` the (penalised) PT error estimates. Because the centre is in the
//! set, the estimator ranges over PT (`β = e_c`), CRN (`β = 0`) and every blend of
//! neighbours in between. By default the output averages this joint solve with the two-stage
//! estimate of `cv` (its control variates without the centre, then the centre's PT mean by
//! inverse variance): the two weight the centre differently, their errors are not the same, and
//! their average measured lower relMSE on the bundled scenes than either. See
//! docs/estimators.md for the defaults and their measurements.
use crate::batch_stats::{trimmed_variance_of_mean, variance_of_mean};
use crate::cv_pass::{check_selection, CvPass, Dof, Folds};
use crate::demodulate::{self, Demodulation};
use crate::floor::{cap_errors, capped_errors, median_3x3, Floor, FloorMode, FloorSource};
use crate::input::BatchNeed;
use crate::low_pass::{low_pass_variance, restore_low_frequencies};
use crate::penalty::Penalty;
use crate::pt_error::{cross_bilateral, cross_bilateral_sets, pt_errors, CbfOptions, ErrorEstimate, MAX_RADIUS};
use crate::selection::{Selection, Selector, MAX_SEARCH_WINDOW};
use crate::solve::{MAX_BATCHES, MAX_K};
use crate::spec::{Bounds, EstimatorSpec, ParamKind, ParamSpec, Params, Samples, Variant};
use crate::two_stage::{centre_free, combine_with_centre, two_stage, Estimate, Solve, CENTRE_FREE_RIDGE};
use crate::{Diagnostics, Estimator, Input, Needs, Output, ReconError, StreamSet};
use std::time::Instant;

const fn param(name: &'static str, kind: ParamKind, default: &'static str, doc: &'static str, alias: Option<&'static str>) -> ParamSpec {
    ParamSpec { name, kind, default, doc, alias }
}

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "ours",
    label: "Ours",
    short: "ours",
    summary: "Imperfect image-space control variates (Yang & Moon 2025): CRN corrected by a weighted set of PT−CRN differences, the PT errors modelled, the centre in the set.",
    colour: [0x59, 0xd9, 0x8e],
    samples: Samples::BothStreams,
    params: &[
        param("select", ParamKind::Choice(Selection::NAMES), "knn", "How the set Ω_c is chosen in the search window (gbuffer needs features).", Some("select")),
        param("k", ParamKind::Int { min: 1, max: MAX_K as i64 }, "49", "|Ω_c|, the centre included (the paper: 25).", Some("k")),
        param("search_window", ParamKind::Int { min: 1, max: MAX_SEARCH_WINDOW as i64 }, "15", "Side of the (odd) square window the k pixels are chosen from (the paper: 11).", Some("search-window")),
        param("errors", ParamKind::Choice(ErrorEstimate::NAMES), "cbf", "Where the PT error estimates V_h come from (oracle needs a reference).", Some("errors")),
        param("penalty", ParamKind::Choice(Penalty::NAMES), "avg", "The symmetric penalty on neighbours' error estimates.", Some("penalty")),
        param("ridge", ParamKind::Float(Bounds::at_least(0.0)), "0.001", "Ridge, relative to the mean diagonal of V_g + V_h.", Some("ridge")),
        param("shared_coefficients", ParamKind::Bool, "false", "One β for all three channels (minimising the summed variance) instead of one per channel.", Some("shared-coefficients")),
        param("cbf_radius", ParamKind::Int { min: 1, max: MAX_RADIUS as i64 }, "3", "Radius in pixels of the cross-bilateral filter of the PT variances (errors = cbf).", Some("cbf-radius")),
        param("cbf_sigma_colour", ParamKind::Float(Bounds::positive()), "0.25", "Tolerance of the filter's relative CRN colour difference.", Some("cbf-sigma-colour")),
        param("cbf_sigma_albedo", ParamKind::Float(Bounds::positive()), "0.1", "Tolerance of the filter's albedo difference.", Some("cbf-sigma-albedo")),
        param("cbf_sigma_normal", ParamKind::Float(Bounds::positive()), "0.2", "Tolerance of the filter's shading-normal difference.", Some("cbf-sigma-normal")),
        param("cbf_exclude_centre", ParamKind::Bool, "false", "Leave a pixel's own variance out of its filtered estimate (kept by default, so that a firefly pixel is not trusted).", Some("cbf-exclude-centre")),
        param("seed", ParamKind::Int { min: 0, max: i64::MAX }, "0", "Seed of `select = random`.", None),
        param("crn_floor", ParamKind::Float(Bounds::at_least(0.0)), "0.05", "τ of the floor on the CRN covariance, as a fraction of the floor's variance (0 = off).", Some("crn-floor")),
        param("crn_floor_mode", ParamKind::Choice(FloorMode::NAMES), "common", "Shape of the floor: common (noise shared by the set) or independent (diagonal).", Some("crn-floor-mode")),
        param("crn_floor_source", ParamKind::Choice(FloorSource::NAMES), "pt-capped", "The floor's variance: pt (the PT error estimates), pt-capped (the PT error estimates, at most crn_floor_cap times the filtered 3×3 median of the PT variance), crn (filtered CRN variance) or pt-trimmed (filtered PT variance without each pixel's farthest batch).", Some("crn-floor-source")),
        param("crn_floor_cap", ParamKind::Float(Bounds::positive()), "100", "pt-capped: how many times the filtered 3×3 median of the PT variance a pixel's floor variance may be.", Some("crn-floor-cap")),
        param("low_pass_sigma", ParamKind::Float(Bounds::at_least(0.0)), "8", "σ in pixels of the Gaussian below which the output's frequencies are taken from the PT mean, which removes the estimator's bias at coarser scales (0 = off).", Some("low-pass-sigma")),
        param("two_stage_weight", ParamKind::Float(Bounds::between(0.0, 1.0)), "0.5", "Weight of the two-stage estimate (cv without the centre, then the centre's PT mean by inverse variance) averaged into the joint one (0 = the joint solve alone; needs k ≥ 2).", Some("two-stage-weight")),
        param("two_stage_floor", ParamKind::Bool, "true", "Give the two-stage estimate's centre-free solve the joint solve's common CRN floor, so that it too does not take all-zero CRN batches for an exact CRN value.", None),
        param("variance_dof", ParamKind::Choice(Dof::NAMES), "mallows", "How the predicted variance allows for β fitted to the batches it is judged on: none, gcv (RSS/(1 − df/n)²), mallows (RSS·(n + df)/(n − df)), df the trace of the hat matrix, or press (Σ_b (r_b/(1 − H_bb))², each batch's residual as the fit without it would leave it); weights the two-stage estimate and fills the variance layer.", Some("variance-dof")),
        param("mix_correlation", ParamKind::Choice(MixCorrelation::NAMES), "bound", "The correlation of the joint and two-stage estimates in the variance layer of their mix: bound (1, the largest variance) or local (estimated from their squared differences, smoothed by the PT error filter). The image does not depend on it.", Some("mix-correlation")),
        param("folds", ParamKind::Choice(Folds::NAMES), "all", "Which CRN batches β is estimated from and applied to: all, or halves (each half's β applied to the other half's mean; even batch count ≥ 4).", Some("folds")),
        param("demodulate", ParamKind::Choice(Demodulation::NAMES), "auto", "Reconstruct illumination: both streams divided by the first-hit albedo (each channel at least 0.05), the output multiplied back; auto where the input has features, on (needs them) or off (radiance, as in the paper).", Some("demodulate")),
    ],
    needs: |p| needs(&ImperfectCvOptions::from_params(p)),
    build: |p| Ok(Box::new(ImperfectCv::new(ImperfectCvOptions::from_params(p))?)),
    variants: &[
        Variant { key: "ours-k25", label: "Ours, 25 pixels in 11×11 (the paper's set)", params: &[("k", "25"), ("search_window", "11")] },
        Variant { key: "ours-joint", label: "Ours, the joint solve alone", params: &[("two_stage_weight", "0")] },
        Variant { key: "ours-no-low-pass", label: "Ours, no low-pass correction", params: &[("low_pass_sigma", "0")] },
        Variant { key: "ours-no-penalty", label: "Ours, no penalty (CBF errors)", params: &[("penalty", "none")] },
        Variant { key: "ours-oracle", label: "Ours, oracle errors", params: &[("errors", "oracle")] },
        Variant { key: "ours-oracle-no-penalty", label: "Ours, oracle errors, no penalty", params: &[("errors", "oracle"), ("penalty", "none")] },
        Variant { key: "ours-window", label: "Ours, 5×5 window selection", params: &[("select", "window"), ("k", "25"), ("search_window", "5")] },
        Variant { key: "ours-random", label: "Ours, random selection", params: &[("select", "random")] },
        Variant { key: "ours-gbuffer", label: "Ours, G-buffer selection", params: &[("select", "gbuffer")] },
    ],
};

#[derive(Clone, Debug, PartialEq)]
pub struct ImperfectCvOptions {
    /// How `Ω_c` is chosen.
    pub select: Selection,
    /// `|Ω_c|`, the centre included.
    pub k: usize,
    /// Side of the (odd) square window the `k` pixels are chosen from.
    pub search_window: usize,
    /// Where the PT error estimates `V_h` come from.
    pub errors: ErrorEstimate,
    /// The symmetric penalty applied to neighbours' error estimates.
    pub penalty: Penalty,
    /// Ridge, relative to the mean diagonal of `V_g + V_h`.
    pub ridge: f64,
    /// One β for all three channels (minimising the summed variance) instead of one per channel.
    pub shared_coefficients: bool,
    /// The filter behind `errors = cbf`.
    pub cbf: CbfOptions,
    /// Seed of `select = random`.
    pub seed: u64,
    /// `τ` of the floor on the CRN covariance (0 = off): each pixel's CRN variance is raised to
    /// at least `τ` times its PT error estimate; see [`crate::FloorMode`] and docs/estimators.md.
    pub crn_floor: f64,
    /// How the floor is applied.
    pub crn_floor_mode: FloorMode,
    /// Where the floor's per-pixel variance comes from.
    pub crn_floor_source: FloorSource,
    /// `pt-capped`: the floor variance is at most this many times the filtered 3×3 median of
    /// the PT variance.
    pub crn_floor_cap: f64,
    /// Which CRN batches β is estimated from and applied to ([`Folds`]): with `halves` the
    /// coefficients are independent of the CRN values they weight.
    pub folds: Folds,
    /// σ (pixels) of the low-pass correction towards the PT mean
    /// ([`restore_low_frequencies`]); 0 = off.
    pub low_pass_sigma: f64,
    /// Weight of the two-stage estimate in the output (0 = the joint solve alone).
    pub two_stage_weight: f64,
    /// Whether the two-stage estimate's centre-free solve has the joint solve's `common` floor.
    pub two_stage_floor: bool,
    /// The degrees-of-freedom allowance of the variance layer's CRN part.
    pub variance_dof: Dof,
    /// The correlation of the two mixed estimates that the variance layer assumes.
    pub mix_correlation: MixCorrelation,
    /// Reconstruct illumination (radiance ÷ first-hit albedo) and multiply the albedo back
    /// ([`Demodulation`]).
    pub demodulate: Demodulation,
}

crate::named::named_enum! {
    /// The joint and the two-stage estimates share their samples, so the variance of their mix
    /// depends on a correlation nothing in the solve measures.
    pub enum MixCorrelation: "mix-correlation" {
        /// Correlation 1: `((1 − w)·σ_a + w·σ_b)²`, the largest the mix can have.
        Bound => "bound",
        /// From `E(a − b)² = σ_a² + σ_b² − 2ρσ_aσ_b`: the squared difference of the two estimates,
        /// relative to `σ_a² + σ_b²`, smoothed by the PT error filter.
        Local => "local",
    }
}

impl Default for ImperfectCvOptions {
    fn default() -> Self {
        ImperfectCvOptions::from_params(&Params::defaults(&SPEC))
    }
}

impl Default for CbfOptions {
    /// The filter of `ours`' declared defaults.
    fn default() -> Self {
        ImperfectCvOptions::default().cbf
    }
}

impl ImperfectCvOptions {
    /// The options of the declared parameters.
    pub fn from_params(p: &Params) -> Self {
        ImperfectCvOptions {
            select: p.choice("select"),
            k: p.usize("k"),
            search_window: p.usize("search_window"),
            errors: p.choice("errors"),
            penalty: p.choice("penalty"),
            ridge: p.float("ridge"),
            shared_coefficients: p.bool("shared_coefficients"),
            cbf: CbfOptions {
                radius: p.usize("cbf_radius"),
                sigma_colour: p.float("cbf_sigma_colour") as f32,
                sigma_albedo: p.float("cbf_sigma_albedo") as f32,
                sigma_normal: p.float("cbf_sigma_normal") as f32,
                exclude_centre: p.bool("cbf_exclude_centre"),
            },
            seed: p.int("seed") as u64,
            crn_floor: p.float("crn_floor"),
            crn_floor_mode: p.choice("crn_floor_mode"),
            crn_floor_source: p.choice("crn_floor_source"),
            crn_floor_cap: p.float("crn_floor_cap"),
            folds: p.choice("folds"),
            low_pass_sigma: p.float("low_pass_sigma"),
            two_stage_weight: p.float("two_stage_weight"),
            two_stage_floor: p.bool("two_stage_floor"),
            variance_dof: p.choice("variance_dof"),
            mix_correlation: p.choice("mix_correlation"),
            demodulate: p.choice("demodulate"),
        }
    }
}

fn needs(o: &ImperfectCvOptions) -> Needs {
    Needs {
        batches: BatchNeed::Range { min: o.folds.min_batches(), max: MAX_BATCHES },
        features: o.demodulate.needs_features().or((o.select == Selection::Gbuffer).then_some("with --select gbuffer")),
        reference: o.errors == ErrorEstimate::Oracle,
        spp: false,
        pt2n: false,
        bounded_values: true,
    }
}

impl ImperfectCvOptions {
    pub fn validate(&self) -> Result<(), ReconError> {
        check_selection(self.k, self.search_window, self.ridge, "ridge")?;
        if self.two_stage_weight > 0.0 && self.k < 2 {
            return Err(ReconError::option(
                "k",
                self.k,
                "the two-stage estimate needs at least one neighbour besides the centre: choose k ≥ 2 or --two-stage-weight 0",
            ));
        }
        if !(self.crn_floor >= 0.0 && self.crn_floor.is_finite()) {
            return Err(ReconError::option("crn-floor", self.crn_floor, "must be a finite number ≥ 0 (0 turns the floor off)"));
        }
        self.cbf.validate()
    }
}

/// Imperfect image-space control variates (the `ours` estimator).
#[derive(Clone, Debug)]
pub struct ImperfectCv {
    options: ImperfectCvOptions,
}

impl ImperfectCv {
    pub fn new(options: ImperfectCvOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(ImperfectCv { options })
    }

    pub fn options(&self) -> &ImperfectCvOptions {
        &self.options
    }
}

impl Estimator for ImperfectCv {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        self.reconstruct_with(input, Pass::Shared)
    }
}

/// How the two-stage estimate gets its control variates.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Pass {
    /// In the joint pass, from the same selection and gathered rows, wherever
    /// [`CvPass::fuses`] allows it.
    Shared,
    /// In a second pass of its own, as `cv-two-stage` computes it; kept to test that sharing
    /// changes no bit.
    #[cfg_attr(not(test), allow(dead_code))]
    Separate,
}

impl ImperfectCv {
    /// The estimate, demodulated if the options ask for it, then the low-pass correction on
    /// radiance: it takes the low frequencies from the PT mean in the units of the output, so
    /// it keeps the image mean whatever the demodulation did to the estimate's bias.
    fn reconstruct_with(&self, input: &Input, how: Pass) -> Result<Output, ReconError> {
        let o = &self.options;
        let divisor = demodulate::divisor_for(o.demodulate, SPEC.name, input)?;
        let (mut estimate, errors, mut d) = match &divisor {
            None => self.estimate(input, how)?,
            Some(q) => {
                let set = demodulate::demodulated(input.streams, q);
                let reference = input.reference.map(|r| demodulate::divided(r, q));
                let (mut estimate, mut errors, d) =
                    self.estimate(&Input { streams: &set, reference: reference.as_ref(), ..*input }, how)?;
                demodulate::remodulate(&mut estimate.image.pixels, q, 1);
                demodulate::remodulate(&mut estimate.variance.pixels, q, 2);
                demodulate::remodulate(&mut errors, q, 2);
                (estimate, errors, d)
            }
        };
        d.int("demodulated", i64::from(divisor.is_some()));
        let set = input.streams;
        let image = restore_low_frequencies(&estimate.image, &set.pt.mean, o.low_pass_sigma);
        for (v, add) in estimate.variance.pixels.iter_mut().zip(low_pass_variance(&errors, set.width, set.height, o.low_pass_sigma)) {
            for ch in 0..3 {
                v[ch] = (v[ch] as f64 + add[ch]) as f32;
            }
        }
        Ok(Output { image, diagnostics: d, aovs: vec![("variance".into(), estimate.variance)] })
    }

    /// The control-variate estimate before the low-pass correction, with the PT error
    /// estimates it used and its diagnostics.
    fn estimate(&self, input: &Input, how: Pass) -> Result<(Estimate, Vec<[f32; 3]>, Diagnostics), ReconError> {
        let start = Instant::now();
        let o = &self.options;
        let set = input.streams;
        o.folds.check(input.streams_name, SPEC.name, set.batch_count())?;
        let (errors, floor_variance) = if o.errors == ErrorEstimate::Cbf && o.crn_floor > 0.0 && o.crn_floor_source == FloorSource::PtCapped
        {
            // The errors and the cap both filter the PT batch variance (as it is, and its 3×3
            // median) with the same weights: one filter pass computes them for both.
            let v = variance_of_mean(&set.pt);
            let [errors, median] = cross_bilateral_sets([&v, &median_3x3(&v, set.width, set.height)], set, &o.cbf);
            let capped = cap_errors(&errors, &median, o.crn_floor_cap);
            (errors, Some(capped))
        } else {
            let errors = pt_errors(o.errors, set, input.reference, &o.cbf);
            let floor_variance = match o.crn_floor_source {
                _ if o.crn_floor <= 0.0 => None,
                FloorSource::Pt => None,
                FloorSource::Crn => Some(cross_bilateral(&variance_of_mean(&set.crn), set, &o.cbf)),
                FloorSource::PtTrimmed => Some(cross_bilateral(&trimmed_variance_of_mean(&set.pt), set, &o.cbf)),
                FloorSource::PtCapped => Some(capped_errors(&errors, set, &o.cbf, o.crn_floor_cap)),
            };
            (errors, floor_variance)
        };
        let floor = (o.crn_floor > 0.0).then(|| Floor {
            tau: o.crn_floor,
            mode: o.crn_floor_mode,
            values: floor_variance.as_deref().unwrap_or(&errors),
        });
        let t_prepare = start.elapsed().as_secs_f64();
        let mut pass = CvPass {
            set,
            selector: Selector::new(o.select, o.k, o.search_window, true, o.seed, set),
            k: o.k,
            errors: Some(&errors),
            penalty: o.penalty,
            ridge: o.ridge,
            shared: o.shared_coefficients,
            include_centre: true,
            floor,
            folds: o.folds,
            variance: true,
            dof: o.variance_dof,
            centre_free: (o.two_stage_weight > 0.0).then(|| centre_free(CENTRE_FREE_RIDGE, o.variance_dof, o.two_stage_floor)),
        };
        if how == Pass::Separate || !pass.fuses() {
            pass.centre_free = None;
        }
        let out = pass.run();
        let st = out.stats;
        let mut estimate = Estimate { image: out.image, variance: out.variance.expect("asked for the variance") };
        if o.two_stage_weight > 0.0 {
            let two = match out.centre_free {
                Some(f) => combine_with_centre(&f.image, &f.variance, &set.pt.mean, &errors),
                None => {
                    let neighbours = Selector::new(o.select, o.k - 1, o.search_window, false, o.seed, set);
                    let solve = Solve { neighbours: o.k - 1, ridge: CENTRE_FREE_RIDGE, shared: o.shared_coefficients, folds: Folds::All };
                    let floor = floor.filter(|f| o.two_stage_floor && f.mode == FloorMode::Common);
                    two_stage(set, neighbours, solve, &errors, o.variance_dof, floor).0
                }
            };
            estimate = match o.mix_correlation {
                MixCorrelation::Bound => mix(&estimate, &two, o.two_stage_weight),
                MixCorrelation::Local => mix_local(&estimate, &two, o.two_stage_weight, set, &o.cbf),
            };
        }
        let mut d = Diagnostics::default();
        d.float("centre_weight_mean", st.centre_weight / st.solves.max(1) as f64);
        st.report(&mut d);
        d.float("set_size_mean", st.set_size as f64 / st.pixels.max(1) as f64)
            .int("batches", set.batch_count() as i64)
            .float("seconds_prepare", t_prepare);
        Ok((estimate, errors, d))
    }
}

/// `(1 − w)·a + w·b` per pixel and channel, with the variance `var(i, c, σ_a², σ_b²)`.
fn blend(a: &Estimate, b: &Estimate, w: f64, var: impl Fn(usize, usize, f64, f64) -> f64) -> Estimate {
    let (mut image, mut variance) = (a.image.clone(), a.variance.clone());
    let pairs = image.pixels.iter_mut().zip(&mut variance.pixels).zip(&b.image.pixels).zip(&b.variance.pixels);
    for (i, (((x, v), xb), vb)) in pairs.enumerate() {
        for c in 0..3 {
            x[c] = ((1.0 - w) * f64::from(x[c]) + w * f64::from(xb[c])) as f32;
            v[c] = var(i, c, f64::from(v[c].max(0.0)), f64::from(vb[c].max(0.0))).max(0.0) as f32;
        }
    }
    Estimate { image, variance }
}

/// `(1 − w)·a + w·b` and a bound on its variance: both estimates come from the same samples, so
/// their correlation is unknown but at most 1, where the variance is `((1 − w)·σ_a + w·σ_b)²`.
fn mix(a: &Estimate, b: &Estimate, w: f64) -> Estimate {
    blend(a, b, w, |_, _, va, vb| ((1.0 - w) * va.sqrt() + w * vb.sqrt()).powi(2))
}

/// Caps one pixel's ratio before smoothing, so that one outlier does not set its neighbours'
/// correlation. With correlation 0 the ratio is about χ²₁, which exceeds 16 with probability 6·10⁻⁵.
const RATIO_CAP: f64 = 16.0;

/// `(1 − w)·a + w·b` with the variance at a local estimate of the correlation:
/// `Var = (1 − w)·σ_a² + w·σ_b² − w(1 − w)·E(a − b)²`, where `E(a − b)²` is the filtered ratio
/// `(a − b)² / (σ_a² + σ_b²)` times the pixel's own `σ_a² + σ_b²`, kept between the values of
/// correlation 1 and −1. The ratio is smoothed rather than the squared difference itself so that
/// a pixel with large variances does not lend them to its neighbours. Both estimates are treated
/// as having the same mean; where they do not, the difference of their biases enters as variance
/// and lowers the prediction.
fn mix_local(a: &Estimate, b: &Estimate, w: f64, set: &StreamSet, cbf: &CbfOptions) -> Estimate {
    let n = a.image.pixels.len();
    let ratio: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            std::array::from_fn(|c| {
                let d = f64::from(a.image.pixels[i][c]) - f64::from(b.image.pixels[i][c]);
                let s = f64::from(a.variance.pixels[i][c].max(0.0)) + f64::from(b.variance.pixels[i][c].max(0.0));
                if s > 0.0 {
                    (d * d / s).min(RATIO_CAP) as f32
                } else {
                    0.0
                }
            })
        })
        .collect();
    let ratio = cross_bilateral(&ratio, set, cbf);
    blend(a, b, w, |i, c, va, vb| {
        let (sa, sb) = (va.sqrt(), vb.sqrt());
        let diff = (f64::from(ratio[i][c]) * (va + vb)).clamp((sa - sb).powi(2), (sa + sb).powi(2));
        (1.0 - w) * va + w * vb - w * (1.0 - w) * diff
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{RenderSpec, SoftShadowScene};

    fn bits(im: &cvtrace_streams::Image) -> Vec<[u32; 3]> {
        im.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
    }

    /// Sharing the joint pass with the two-stage estimate's solve changes no bit of the image,
    /// the variance or the diagnostics, on every solver path: the panel at each width, the
    /// general solver (shared coefficients, B ≥ k), both floors and none, a penalty that
    /// differs from the two-stage one, every selection, and images smaller than the set.
    #[test]
    fn sharing_the_pass_changes_no_bit() {
        let d = ImperfectCvOptions::default;
        let cases: Vec<(usize, usize, u32, usize, ImperfectCvOptions)> = vec![
            (40, 33, 16, 16, d()),
            (40, 33, 16, 8, d()),
            (40, 33, 8, 4, d()),
            (40, 33, 32, 32, d()),
            (24, 20, 64, 64, d()),
            (40, 33, 24, 24, d()),
            (40, 33, 16, 16, ImperfectCvOptions { k: 17, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { k: 18, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { k: 2, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { k: 40, search_window: 9, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { shared_coefficients: true, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor_mode: FloorMode::Independent, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor: 0.0, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor_source: FloorSource::Crn, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor_source: FloorSource::PtTrimmed, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor_source: FloorSource::Pt, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { crn_floor_cap: 2.0, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { two_stage_floor: false, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { two_stage_floor: false, crn_floor_mode: FloorMode::Independent, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { penalty: Penalty::None, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { penalty: Penalty::Residual, shared_coefficients: true, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { errors: ErrorEstimate::Variance, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { select: Selection::Random, seed: 5, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { select: Selection::Window, k: 25, search_window: 5, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { select: Selection::Gbuffer, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { two_stage_weight: 0.3, low_pass_sigma: 0.0, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { folds: Folds::Halves, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { variance_dof: Dof::None, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { variance_dof: Dof::Gcv, shared_coefficients: true, ..d() }),
            (40, 33, 32, 32, ImperfectCvOptions { variance_dof: Dof::Gcv, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { variance_dof: Dof::Press, ..d() }),
            (40, 33, 16, 16, ImperfectCvOptions { variance_dof: Dof::Press, shared_coefficients: true, ..d() }),
            (3, 2, 16, 16, d()),
            (5, 1, 16, 16, d()),
        ];
        for (w, h, spp, batches, o) in cases {
            let set = SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp, batches, seed: 7 }).unwrap();
            let input = Input::new(&set);
            let est = ImperfectCv::new(o.clone()).unwrap();
            let shared = est.reconstruct_with(&input, Pass::Shared).unwrap();
            let separate = est.reconstruct_with(&input, Pass::Separate).unwrap();
            let case = format!("{w}x{h} B={batches} {o:?}");
            assert_eq!(bits(&shared.image), bits(&separate.image), "image of {case}");
            assert_eq!(bits(&shared.aovs[0].1), bits(&separate.aovs[0].1), "variance of {case}");
            let diag =
                |out: &Output| out.diagnostics.entries.iter().filter(|(n, _)| !n.starts_with("seconds")).cloned().collect::<Vec<_>>();
            assert_eq!(diag(&shared), diag(&separate), "diagnostics of {case}");
        }
    }

    /// Two estimates with known per-pixel σ and correlation ρ: the local estimate's variance
    /// averaged over the image matches `(1 − w)²σ_a² + w²σ_b² + 2w(1 − w)ρσ_aσ_b` for every ρ,
    /// where the bound at correlation 1 is up to 1.9× too high. The tolerance: the mean over
    /// 3 072 pixels of a smoothed χ²₁-like ratio has a relative sd of about √(2/3072) ≈ 2.6%, and
    /// the ratio carries at most a quarter of the variance (w(1 − w) ≤ ¼), so 3% is > 4 sd.
    #[test]
    fn local_mix_correlation_recovers_the_variance_of_the_mix() {
        use crate::rng::{hash4, uniform};
        let (w, h) = (64, 48);
        let set = SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 16, batches: 16, seed: 3 }).unwrap();
        let normal = |i: usize, c: usize, k: u64| {
            let (u1, u2) = (uniform(hash4(11, i as u64, c as u64, 2 * k)), uniform(hash4(11, i as u64, c as u64, 2 * k + 1)));
            (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let weight = 0.5;
        for rho in [0.0, 0.5, 0.9, 1.0] {
            let image = |f: &dyn Fn(usize, usize) -> f64| cvtrace_streams::Image {
                width: w,
                height: h,
                pixels: (0..w * h).map(|i| std::array::from_fn(|c| f(i, c) as f32)).collect(),
            };
            let sigma = |i: usize| 0.05 + 0.2 * ((i % w) as f64 / w as f64) + 0.1 * ((i / w) as f64 / h as f64);
            let a = Estimate { image: image(&|i, c| 1.0 + sigma(i) * normal(i, c, 0)), variance: image(&|i, _| sigma(i).powi(2)) };
            let b = Estimate {
                image: image(&|i, c| 1.0 + 1.5 * sigma(i) * (rho * normal(i, c, 0) + (1.0 - rho * rho).sqrt() * normal(i, c, 1))),
                variance: image(&|i, _| (1.5 * sigma(i)).powi(2)),
            };
            let truth: f64 = (0..w * h)
                .map(|i| {
                    let (sa, sb) = (sigma(i), 1.5 * sigma(i));
                    (1.0 - weight) * (1.0 - weight) * sa * sa + weight * weight * sb * sb + 2.0 * weight * (1.0 - weight) * rho * sa * sb
                })
                .sum();
            let total = |e: &Estimate| e.variance.pixels.iter().map(|p| p.iter().map(|v| f64::from(*v)).sum::<f64>() / 3.0).sum::<f64>();
            let local = total(&mix_local(&a, &b, weight, &set, &CbfOptions::default())) / truth;
            let bound = total(&mix(&a, &b, weight)) / truth;
            assert!((local - 1.0).abs() < 0.03, "ρ = {rho}: local estimate {local:.4} of the true variance (bound {bound:.4})");
            if rho == 0.0 {
                assert!(bound > 1.8, "the bound should overstate an uncorrelated mix: {bound:.4}");
            }
        }
    }
}

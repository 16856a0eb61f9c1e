//! `ours`: imperfect image-space control variates (Yang & Moon 2025).
//!
//! `F̂_c = ḡ_c − Σ_{i∈Ω_c} β_i (ḡ_i − h̄_i)` with `c ∈ Ω_c`, and β minimising the variance of
//! Eq. 7 of the supplement: `(V_g + V_h) β = V_fg`, where `V_g`/`V_fg` are CRN batch
//! covariances and `V_h` the (penalised) PT error estimates. Because the centre is in the
//! set, the estimator ranges over PT (`β = e_c`), CRN (`β = 0`) and every blend of
//! neighbours in between. See docs/estimators.md for the defaults and their measurements.
use super::finish;
use crate::batch_stats::variance_of_mean;
use crate::cv_pass::CvPass;
use crate::floor::{Floor, FloorMode, FloorSource};
use crate::input::BatchNeed;
use crate::penalty::Penalty;
use crate::pt_error::{cross_bilateral, pt_errors, CbfOptions, ErrorEstimate};
use crate::selection::{Selection, Selector, MAX_SEARCH_WINDOW};
use crate::solve::{MAX_BATCHES, MAX_K};
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use std::time::Instant;

#[derive(Clone, Debug, PartialEq)]
pub struct OursOptions {
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
    /// Cross-fitting: β estimated from one half of the CRN batches is applied to the other
    /// half's means (and vice versa, averaged), so that the coefficients are independent of
    /// the CRN values they weight. Needs an even number of batches, at least 4.
    pub cross_fit: bool,
}

impl Default for OursOptions {
    fn default() -> Self {
        OursOptions {
            select: Selection::Knn,
            k: 25,
            search_window: 11,
            errors: ErrorEstimate::Cbf,
            penalty: Penalty::Avg,
            ridge: 1e-3,
            shared_coefficients: false,
            cbf: CbfOptions::default(),
            seed: 0,
            crn_floor: 0.05,
            crn_floor_mode: FloorMode::Common,
            crn_floor_source: FloorSource::Pt,
            cross_fit: false,
        }
    }
}

/// Checks the options shared by `ours` and `cv`: `k` pixels per set, centre included, and the
/// ridge under its command-line name.
pub(crate) fn check_selection(k: usize, search_window: usize, ridge: f64, ridge_option: &'static str) -> Result<(), ReconError> {
    if k == 0 || k > MAX_K {
        return Err(ReconError::option("k", k, format!("must be between 1 and {MAX_K}")));
    }
    if search_window == 0 || search_window.is_multiple_of(2) || search_window > MAX_SEARCH_WINDOW {
        return Err(ReconError::option("search-window", search_window, format!("must be odd, between 1 and {MAX_SEARCH_WINDOW}")));
    }
    if k > search_window * search_window {
        return Err(ReconError::option(
            "k",
            k,
            format!("cannot choose more pixels than the {search_window}x{search_window} search window holds; raise --search-window"),
        ));
    }
    if !(ridge >= 0.0 && ridge.is_finite()) {
        return Err(ReconError::option(ridge_option, ridge, "must be a finite number ≥ 0"));
    }
    Ok(())
}

impl OursOptions {
    pub fn validate(&self) -> Result<(), ReconError> {
        check_selection(self.k, self.search_window, self.ridge, "ridge")?;
        if !(self.crn_floor >= 0.0 && self.crn_floor.is_finite()) {
            return Err(ReconError::option("crn-floor", self.crn_floor, "must be a finite number ≥ 0 (0 turns the floor off)"));
        }
        self.cbf.validate()
    }
}

#[derive(Clone, Debug)]
pub struct Ours {
    options: OursOptions,
}

impl Ours {
    pub fn new(options: OursOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(Ours { options })
    }

    pub fn options(&self) -> &OursOptions {
        &self.options
    }
}

impl Estimator for Ours {
    fn method(&self) -> Method {
        Method::Ours
    }

    fn needs(&self) -> Needs {
        Needs {
            batches: BatchNeed::Range { min: if self.options.cross_fit { 4 } else { 2 }, max: MAX_BATCHES },
            features: (self.options.select == Selection::Gbuffer).then_some("with --select gbuffer"),
            reference: self.options.errors == ErrorEstimate::Oracle,
            spp: false,
            bounded_values: true,
        }
    }

    fn settings(&self) -> Vec<(&'static str, String)> {
        let o = &self.options;
        vec![
            ("select", o.select.to_string()),
            ("k", o.k.to_string()),
            ("search_window", o.search_window.to_string()),
            ("errors", o.errors.to_string()),
            ("penalty", o.penalty.to_string()),
            ("ridge", o.ridge.to_string()),
            ("shared_coefficients", o.shared_coefficients.to_string()),
            ("cbf_radius", o.cbf.radius.to_string()),
            ("seed", o.seed.to_string()),
            ("crn_floor", o.crn_floor.to_string()),
            ("crn_floor_mode", o.crn_floor_mode.to_string()),
            ("crn_floor_source", o.crn_floor_source.to_string()),
            ("cross_fit", o.cross_fit.to_string()),
        ]
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.name(), &self.needs())?;
        let o = &self.options;
        let set = input.streams;
        if o.cross_fit && set.batch_count() % 2 == 1 {
            return Err(ReconError::BatchCount {
                origin: input.streams_name.to_string(),
                method: self.name(),
                requirement: "an even number of".into(),
                found: set.batch_count(),
                hint: "cross-fitting splits the batches into two equal halves; re-render with an even --batches or drop --cross-fit".into(),
            });
        }
        let errors = pt_errors(o.errors, set, input.reference, &o.cbf);
        let crn_variance = (o.crn_floor > 0.0 && o.crn_floor_source == FloorSource::Crn)
            .then(|| cross_bilateral(&variance_of_mean(&set.crn), set, &o.cbf));
        let floor = (o.crn_floor > 0.0).then(|| Floor {
            tau: o.crn_floor,
            mode: o.crn_floor_mode,
            values: crn_variance.as_deref().unwrap_or(&errors),
        });
        let t_prepare = start.elapsed().as_secs_f64();
        let pass = CvPass {
            set,
            selector: Selector::new(o.select, o.k, o.search_window, true, o.seed, set),
            k: o.k,
            errors: Some(&errors),
            penalty: o.penalty,
            ridge: o.ridge,
            shared: o.shared_coefficients,
            include_centre: true,
            floor,
            cross_fit: o.cross_fit,
        };
        let (image, st) = pass.run();
        let mut d = Diagnostics::default();
        d.float("centre_weight_mean", st.centre_weight / st.solves.max(1) as f64);
        st.report(&mut d);
        d.float("set_size_mean", st.set_size as f64 / st.pixels.max(1) as f64)
            .int("batches", set.batch_count() as i64)
            .float("seconds_prepare", t_prepare);
        Ok(finish(image, d, start))
    }
}

//! `cv`: the control-variate baseline, `F̂_c = ḡ_c − Σ_{i≠c} β_i (ḡ_i − h̄_i)` over the same
//! k-NN set as `ours` but **without the centre**: the centre's own PT value never enters, so the
//! estimator can only explain the centre's CRN value by its neighbours. That is the one thing
//! `ours` adds (with the centre, `β = e_c` returns PT), which is what makes `ours ÷ cv` the
//! effect of the centre in the set. Both default to 49 pixels in 15×15 (48 neighbours here),
//! chosen on the bundled scenes: without the centre a larger set dilutes the PT noise the
//! estimate copies in and finds more pixels that share the centre's CRN noise; the paper's 25 in
//! 11×11 is the `cv-k25` variant. With `centre = inverse-variance` the estimate is then
//! combined with the centre's own PT mean by inverse variance: an imperfect control variate in
//! two stages rather than the paper's baseline, kept as the `cv-two-stage` variant to compare
//! the joint solve of `ours` with.
//!
//! By default `β` solves `(V_g + V_h' + ridge) β = V_fg` with the covariances of `ours` (CRN
//! batch covariances, the PT error filter's estimates with the `avg` penalty) and the low-pass
//! correction of `ours`. The classic form (`pt_noise = false`, `low_pass_sigma = 0`, the
//! `cv-classic` variant) takes the PT means as exact expectations (`V_h = 0`); nothing then
//! guards against the PT noise it copies in, and with fewer batches than control variates `V_g`
//! is singular, so the ridge is essential. See docs/estimators.md for both, measured.
use crate::cv_pass::{check_selection, Dof, Folds};
use crate::input::BatchNeed;
use crate::low_pass::restore_low_frequencies;
use crate::pt_error::{pt_errors, CbfOptions, ErrorEstimate};
use crate::selection::{Selection, Selector, MAX_SEARCH_WINDOW};
use crate::solve::{MAX_BATCHES, MAX_K};
use crate::spec::{Bounds, EstimatorSpec, ParamKind, ParamSpec, Params, Samples, Variant};
use crate::two_stage::{centre_free_pass, two_stage, Solve};
use crate::{Diagnostics, Estimator, Input, Needs, Output, ReconError};

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "cv",
    label: "CV (baseline)",
    short: "CV",
    summary: "Classic image-space control variates: the PT means taken as exact expectations of the CRN neighbours.",
    colour: [0xb0, 0x7a, 0xe1],
    samples: Samples::BothStreams,
    params: &[
        ParamSpec {
            name: "select",
            kind: ParamKind::Choice(Selection::NAMES),
            default: "knn",
            doc: "How the control-variate pixels are chosen in the search window.",
            alias: Some("select"),
        },
        ParamSpec {
            name: "k",
            kind: ParamKind::Int { min: 2, max: MAX_K as i64 },
            default: "49",
            doc: "Pixels per set counted as in `ours`, centre included; `cv` leaves the centre out and uses the k − 1 neighbours.",
            alias: Some("k"),
        },
        ParamSpec {
            name: "search_window",
            kind: ParamKind::Int { min: 1, max: MAX_SEARCH_WINDOW as i64 },
            default: "15",
            doc: "Side of the (odd) square window the pixels are chosen from.",
            alias: Some("search-window"),
        },
        ParamSpec {
            name: "ridge",
            kind: ParamKind::Float(Bounds::at_least(0.0)),
            default: "0.3",
            doc: "Ridge, relative to the mean diagonal of V_g; essential with fewer batches than control variates.",
            alias: Some("cv-ridge"),
        },
        ParamSpec {
            name: "shared_coefficients",
            kind: ParamKind::Bool,
            default: "false",
            doc: "One coefficient vector for all three channels instead of one per channel.",
            alias: Some("shared-coefficients"),
        },
        ParamSpec {
            name: "pt_noise",
            kind: ParamKind::Bool,
            default: "true",
            doc: "Model the noise of the PT means as `ours` does (cross-bilateral error estimates, `avg` penalty) instead of taking them as exact expectations.",
            alias: Some("cv-pt-noise"),
        },
        ParamSpec {
            name: "low_pass_sigma",
            kind: ParamKind::Float(Bounds::at_least(0.0)),
            default: "8",
            doc: "σ in pixels of the Gaussian below which the output's frequencies are taken from the PT mean (0 = off).",
            alias: Some("cv-low-pass-sigma"),
        },
        ParamSpec {
            name: "centre",
            kind: ParamKind::Choice(Centre::NAMES),
            default: "out",
            doc: "The centre's own PT mean: out (left out, as in the paper's baseline) or inverse-variance (combined with the control-variate estimate by inverse variance, which makes this an imperfect control variate in two stages; needs pt_noise).",
            alias: Some("cv-centre"),
        },
        ParamSpec {
            name: "folds",
            kind: ParamKind::Choice(Folds::NAMES),
            default: "all",
            doc: "Which CRN batches β is estimated from and applied to: all, or halves (cross-fitting: each half's β applied to the other half's mean; even batch count ≥ 4).",
            alias: Some("cv-folds"),
        },
        ParamSpec {
            name: "seed",
            kind: ParamKind::Int { min: 0, max: i64::MAX },
            default: "0",
            doc: "Seed of `select = random`.",
            alias: None,
        },
    ],
    needs: |p| needs(&ClassicCvOptions::from_params(p)),
    build: |p| Ok(Box::new(ClassicCv::new(ClassicCvOptions::from_params(p))?)),
    variants: &[Variant {
        key: "cv-k25",
        label: "CV, 24 neighbours in 11×11 (the paper's set)",
        params: &[("k", "25"), ("search_window", "11")],
    }, Variant {
        key: "cv-classic",
        label: "CV, PT means as exact (classic)",
        params: &[("pt_noise", "false"), ("low_pass_sigma", "0"), ("centre", "out")],
    }, Variant {
        key: "cv-two-stage",
        label: "CV, then the centre's PT mean by inverse variance",
        params: &[("centre", "inverse-variance")],
    }],
};

crate::named::named_enum! {
    /// What `cv` does with the centre's own PT mean, which its control variates leave out.
    pub enum Centre: "centre" {
        /// Nothing: the output is the control-variate estimate alone, as in the paper's baseline.
        Out => "out",
        /// Combined with the control-variate estimate by inverse variance: the two are
        /// independent (the centre is not one of its own control variates), so weights
        /// `e_c / (e_c + v_F)` and `v_F / (e_c + v_F)` (with `e_c` the PT error estimate of the
        /// centre and `v_F` Eq. 7 at β) give the least variance of any mix of the two. Where the
        /// centre's CRN value carries a firefly its neighbours lack, `v_F` is large and the PT
        /// mean takes over.
        InverseVariance => "inverse-variance",
    }
}

fn needs(o: &ClassicCvOptions) -> Needs {
    Needs {
        batches: BatchNeed::Range { min: o.folds.min_batches(), max: MAX_BATCHES },
        features: (o.select == Selection::Gbuffer).then_some("with --select gbuffer"),
        reference: false,
        spp: false,
        pt2n: false,
        bounded_values: true,
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct ClassicCvOptions {
    pub select: Selection,
    /// Number of control variates: the neighbours, the centre not included.
    pub neighbours: usize,
    pub search_window: usize,
    /// Ridge, relative to the mean diagonal of `V_g`.
    pub ridge: f64,
    pub shared_coefficients: bool,
    /// Seed of `select = random`.
    pub seed: u64,
    /// Whether the solve models the PT means' noise (`V_h` from the error filter of `ours`).
    pub pt_noise: bool,
    /// σ (pixels) of the low-pass correction towards the PT mean; 0 = off.
    pub low_pass_sigma: f64,
    /// What the output does with the centre's own PT mean.
    pub centre: Centre,
    /// Which CRN batches β is estimated from and applied to.
    pub folds: Folds,
}

impl Default for ClassicCvOptions {
    fn default() -> Self {
        ClassicCvOptions::from_params(&Params::defaults(&SPEC))
    }
}

impl ClassicCvOptions {
    /// The options of the declared parameters.
    pub fn from_params(p: &Params) -> Self {
        ClassicCvOptions {
            select: p.choice("select"),
            neighbours: p.usize("k") - 1,
            search_window: p.usize("search_window"),
            ridge: p.float("ridge"),
            shared_coefficients: p.bool("shared_coefficients"),
            seed: p.int("seed") as u64,
            pt_noise: p.bool("pt_noise"),
            low_pass_sigma: p.float("low_pass_sigma"),
            centre: p.choice("centre"),
            folds: p.choice("folds"),
        }
    }

    pub fn validate(&self) -> Result<(), ReconError> {
        // The command line's `k` counts the centre too.
        if self.neighbours == 0 {
            return Err(ReconError::option("k", 1, "cv needs at least one neighbour besides the centre: at least 2"));
        }
        if self.centre == Centre::InverseVariance && !self.pt_noise {
            return Err(ReconError::option(
                "cv-centre",
                "inverse-variance",
                "the weights need the PT error estimates, which only pt_noise = true computes: choose --cv-pt-noise or --cv-centre out",
            ));
        }
        check_selection(self.neighbours + 1, self.search_window, self.ridge, "cv-ridge")
    }
}

/// Classic control variates (the `cv` estimator).
#[derive(Clone, Debug)]
pub struct ClassicCv {
    options: ClassicCvOptions,
}

impl ClassicCv {
    pub fn new(options: ClassicCvOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(ClassicCv { options })
    }
}

impl Estimator for ClassicCv {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let o = &self.options;
        let set = input.streams;
        o.folds.check(input.streams_name, SPEC.name, set.batch_count())?;
        let errors = o.pt_noise.then(|| pt_errors(ErrorEstimate::Cbf, set, None, &CbfOptions::default()));
        let selector = Selector::new(o.select, o.neighbours, o.search_window, false, o.seed, set);
        let (image, stats) = match (o.centre, errors.as_deref()) {
            (Centre::InverseVariance, Some(e)) => {
                let (two, stats) = two_stage(set, selector, o.solve(), e, Dof::None, None);
                (two.image, stats)
            }
            _ => {
                let out = centre_free_pass(set, selector, o.solve(), errors.as_deref(), None).run();
                (out.image, out.stats)
            }
        };
        let image = restore_low_frequencies(&image, &set.pt.mean, o.low_pass_sigma);
        let mut d = Diagnostics::default();
        stats.report(&mut d);
        d.int("batches", set.batch_count() as i64);
        Ok(Output::new(image, d))
    }
}

impl ClassicCvOptions {
    fn solve(&self) -> Solve {
        Solve { neighbours: self.neighbours, ridge: self.ridge, shared: self.shared_coefficients, folds: self.folds }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::two_stage::CENTRE_FREE_RIDGE;

    /// `ours` solves its two-stage estimate's first stage with `cv`'s default ridge.
    #[test]
    fn the_two_stage_ridge_is_the_declared_default() {
        assert_eq!(ClassicCvOptions::default().ridge.to_bits(), CENTRE_FREE_RIDGE.to_bits());
    }
}

//! The two-stage estimate: control variates without the centre
//! (`F̂_c = ḡ_c − Σ_{i≠c} β_i (ḡ_i − h̄_i)`), then combined with the centre's own PT mean by
//! inverse variance. The two are independent (the centre is not one of its own control
//! variates), so the weights `e_c / (e_c + v_F)` and `v_F / (e_c + v_F)` (with `e_c` the PT error
//! estimate of the centre and `v_F` Eq. 7 at β) give the least variance of any mix of the two.
//!
//! `cv` is its first stage alone, or, with `centre = inverse-variance`, the whole of it; `ours`
//! averages it with its joint solve, either in a pass of its own ([`two_stage`]) or as the
//! centre-free part of the joint pass ([`centre_free`], then [`combine_with_centre`]).
use crate::cv_pass::{CentreFree, CvPass, Dof, Folds, PassStats};
use crate::floor::Floor;
use crate::penalty::Penalty;
use crate::selection::Selector;
use cvtrace_streams::{Image, StreamSet};

/// The ridge of the centre-free solve in `ours`' two-stage estimate, relative to the mean
/// diagonal of the system: `cv`'s default (a test of `cv` checks that the two agree).
pub const CENTRE_FREE_RIDGE: f64 = 0.3;

/// The settings of a centre-free control-variate solve.
#[derive(Clone, Copy, Debug)]
pub struct Solve {
    /// Control variates per pixel (the centre not among them).
    pub neighbours: usize,
    /// Ridge, relative to the mean diagonal of the system.
    pub ridge: f64,
    /// One coefficient vector for the three channels.
    pub shared: bool,
    /// Which CRN batches β is estimated from and applied to.
    pub folds: Folds,
}

/// An estimate and its predicted variance per pixel and channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    pub image: Image,
    pub variance: Image,
}

/// The control-variate pass of the first stage, `cv`'s: the centre left out (`selector` must
/// leave it out), the PT noise modelled when `errors` are given (with the `avg` penalty);
/// `variance` asks for the predicted variance with that degrees-of-freedom allowance.
pub fn centre_free_pass<'a>(
    set: &'a StreamSet,
    selector: Selector<'a>,
    solve: Solve,
    errors: Option<&'a [[f32; 3]]>,
    variance: Option<Dof>,
) -> CvPass<'a> {
    CvPass {
        set,
        selector,
        k: solve.neighbours,
        errors,
        penalty: if errors.is_some() { Penalty::Avg } else { Penalty::None },
        ridge: solve.ridge,
        shared: solve.shared,
        include_centre: false,
        floor: None,
        folds: solve.folds,
        variance: variance.is_some(),
        dof: variance.unwrap_or(Dof::None),
        centre_free: None,
    }
}

/// The first stage of [`two_stage`] as the centre-free part of a joint pass with the same
/// selection (PT errors modelled, so the `avg` penalty of [`centre_free_pass`]).
pub fn centre_free(ridge: f64, dof: Dof, floored: bool) -> CentreFree {
    CentreFree { penalty: Penalty::Avg, ridge, dof, floored }
}

/// The two-stage estimate in a pass of its own: control variates without the centre
/// (`selector` must leave it out), then combined with the centre's PT mean by inverse
/// variance. `errors` are the PT error estimates (variances of the PT means); `dof` is the
/// allowance of the first stage's variance, which weights the two.
pub fn two_stage(
    set: &StreamSet,
    selector: Selector<'_>,
    solve: Solve,
    errors: &[[f32; 3]],
    dof: Dof,
    floor: Option<Floor<'_>>,
) -> (Estimate, PassStats) {
    let out = CvPass { floor, ..centre_free_pass(set, selector, solve, Some(errors), Some(dof)) }.run();
    let v_f = out.variance.expect("asked for the variance");
    (combine_with_centre(&out.image, &v_f, &set.pt.mean, errors), out.stats)
}

/// The inverse-variance combination of the control-variate estimate `f` (variance `v_f`) with the
/// centre's PT mean `h` (error estimate `e`), per pixel and channel, and its variance
/// `e·v_f / (e + v_f)`. Where both variances are 0 (a black, noiseless pixel) the two agree and
/// `f` is kept.
pub fn combine_with_centre(f: &Image, v_f: &Image, h: &Image, e: &[[f32; 3]]) -> Estimate {
    let (mut image, mut variance) = (f.clone(), v_f.clone());
    for ((((o, v), vf), hc), ec) in image.pixels.iter_mut().zip(&mut variance.pixels).zip(&v_f.pixels).zip(&h.pixels).zip(e) {
        for ch in 0..3 {
            let (vf, ec) = (f64::from(vf[ch].max(0.0)), f64::from(ec[ch].max(0.0)));
            let total = vf + ec;
            if total > 0.0 && total.is_finite() {
                o[ch] = ((ec * f64::from(o[ch]) + vf * f64::from(hc[ch])) / total) as f32;
                v[ch] = (ec * vf / total) as f32;
            }
        }
    }
    Estimate { image, variance }
}

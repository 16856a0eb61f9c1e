//! The options of `ours` that shape its joint solve: the floor on the CRN covariance and
//! cross-fitting (the two-stage mix is off here, so each test sees the joint solve alone).
//! Exact expectations on hand-made stream sets where the CRN batches are degenerate.
mod common;

use common::dense::{batch_mean, set_of, variance_of_mean, Fit, Rule};
use common::{normal, stream_set, stream_set_rgb};
use cvtrace_reconstruct::estimators::ImperfectCv;
use cvtrace_reconstruct::{
    ErrorEstimate, Estimator, FloorMode, FloorSource, Folds, ImperfectCvOptions, Input, Penalty, ReconError, Selection, StreamSet,
};

const W: usize = 21;
const M: f64 = 0.8;

/// CRN: every batch of every pixel is 0 (all 16 batches missed the light). PT: mean `M` in
/// every pixel, batches `M ± a` (half each), so every PT pixel has the same batch variance and
/// the filtered error estimate is exactly that constant.
fn degenerate_set() -> StreamSet {
    stream_set(W, W, 16, 64, |_| 0.0, |_, _| 0.0, |b, _| if b % 2 == 0 { M + 0.3 } else { M - 0.3 })
}

/// `ours` with the given changes and without the low-pass correction, so that a pixel's value
/// is the control-variate pass's alone; the paper's set of 25 in 11×11, which the expected
/// values below are written for.
fn ours(f: impl Fn(&mut ImperfectCvOptions)) -> ImperfectCv {
    let mut o = ImperfectCvOptions { low_pass_sigma: 0.0, two_stage_weight: 0.0, k: 25, search_window: 11, ..Default::default() };
    f(&mut o);
    ImperfectCv::new(o).unwrap()
}

fn centre_value(est: &ImperfectCv, set: &StreamSet) -> f64 {
    let out = est.reconstruct(&Input::new(set)).unwrap();
    out.image.pixels[(W / 2) * W + W / 2][1] as f64
}

#[test]
fn without_a_floor_degenerate_crn_batches_return_crn() {
    // The batch covariance says "CRN is exact", so β = 0 and the output is the CRN value 0:
    // the darkening of issue 5.
    let v = centre_value(&ours(|o| o.crn_floor = 0.0), &degenerate_set());
    assert!(v.abs() < 1e-6, "{v}");
}

#[test]
fn independent_floor_falls_back_to_the_pt_crn_inverse_variance_blend() {
    // V_g = diag(τ·e), V_fg = τ·e·e_c, V_h = e (penalty avg of equal errors): only the centre
    // can cancel independent noise, β = e_c·τ/(1+τ). With τ = 1 both inputs have variance e and
    // the output is their inverse-variance blend (h̄ + ḡ)/2 = M/2 (up to the 1e-3 ridge).
    for tau in [1.0, 3.0] {
        let est = ours(|o| {
            o.crn_floor = tau;
            o.crn_floor_mode = FloorMode::Independent;
        });
        let v = centre_value(&est, &degenerate_set());
        let want = M * tau / (1.0 + tau);
        assert!((v - want).abs() < 2e-3 * M, "τ = {tau}: {v} vs {want}");
    }
}

#[test]
fn common_floor_averages_the_neighbours_pt_values() {
    // V_g = τ·e·1·1ᵀ (noise shared by the set), V_fg = τ·e·1, V_h = e·I: β = τ/(1 + kτ)·1, so
    // the output is Σ_Ω h̄_i · τ/(1 + kτ) = M · kτ/(1 + kτ) with k = 25: the neighbours' PT
    // values replace the degenerate CRN values, and with a large τ the output tends to M.
    for tau in [0.5, 1.0, 10.0] {
        let v = centre_value(&ours(|o| o.crn_floor = tau), &degenerate_set());
        let want = M * 25.0 * tau / (1.0 + 25.0 * tau);
        assert!((v - want).abs() < 2e-3 * M, "τ = {tau}: {v} vs {want}");
    }
}

#[test]
fn the_two_stage_estimate_has_the_common_floor_too() {
    // The two-stage estimate alone (weight 1): its centre-free solve over the 24 neighbours, then
    // the centre's PT mean by inverse variance. Without the floor the all-zero CRN batches say
    // "CRN is exact", so the first stage returns CRN (0) with variance 0 and the combination keeps
    // it. With the common floor (τ = 1) the first stage is β = c·1 over the neighbours, from
    // (τe·1·1ᵀ + e·I + λ·I)·β = τe·1 with the two-stage ridge λ = 0.3·(e + τe) relative to the
    // mean diagonal: c = τ/(24τ + 1 + 0.3·(1 + τ)), the neighbours' PT mean shrunk to
    // 24c·M = 0.9375·M, with a variance > 0; the combination with the centre's PT value M lies
    // between the two.
    let two_stage = |floored: bool| {
        ours(|o| {
            o.crn_floor = 1.0;
            o.two_stage_weight = 1.0;
            o.two_stage_floor = floored;
        })
    };
    let v = centre_value(&two_stage(false), &degenerate_set());
    assert!(v.abs() < 1e-6, "{v}");
    let v = centre_value(&two_stage(true), &degenerate_set());
    let first_stage = M * 24.0 / (24.0 + 1.0 + 0.3 * 2.0);
    assert!(v >= first_stage * (1.0 - 1e-4) && v <= M * (1.0 + 1e-6), "{v} not in [{first_stage}, {M}]");
}

#[test]
fn floor_leaves_pixels_with_enough_batch_variance_alone() {
    // CRN with real batch variance (4× the PT variance): a floor of τ ≤ 1 lifts nothing, the
    // output is bit-identical to no floor, in both shapes and with either source.
    let set = stream_set(
        W,
        W,
        16,
        64,
        |i| 0.5 + (i % W) as f64 / 40.0,
        |b, i| 0.4 * (normal(1, b as u64) + 0.3 * normal(2, (b * 4096 + i) as u64)),
        |b, i| 0.1 * normal(3, (b * 4096 + i) as u64),
    );
    let base = ours(|o| o.crn_floor = 0.0).reconstruct(&Input::new(&set)).unwrap().image;
    for mode in FloorMode::ALL {
        for source in FloorSource::ALL {
            let est = ours(|o| {
                o.crn_floor = 0.2;
                o.crn_floor_mode = *mode;
                o.crn_floor_source = *source;
            });
            let got = est.reconstruct(&Input::new(&set)).unwrap().image;
            let worst =
                got.pixels.iter().zip(&base.pixels).flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs())).fold(0.0f32, f32::max);
            // The common floor rotates the batch deviations (same Gram matrix, other rounding).
            assert!(worst < 1e-5, "{mode}, source {source}: {worst}");
        }
    }
}

#[test]
fn crn_source_floors_from_the_filtered_crn_variance() {
    // All-zero CRN batches: the filtered CRN variance is 0 too, so a CRN-sourced floor cannot
    // lift anything and the output stays the CRN value (why the PT errors are the default source).
    let est = ours(|o| {
        o.crn_floor = 1.0;
        o.crn_floor_source = FloorSource::Crn;
    });
    assert!(centre_value(&est, &degenerate_set()).abs() < 1e-6);
}

#[test]
fn cross_fit_end_points_are_pt_and_crn() {
    // PT exact (zero batch variance, so the error estimates are 0 and only the ridge keeps the
    // system positive definite) and CRN noisy and independent per pixel: with k = 5 control
    // variates and 8 batches per half the half covariances have full rank, β = e_c in both
    // halves and the output is PT. With PT very noisy instead, β → 0 and the output is the mean
    // of the two half means of CRN, i.e. the CRN mean. (These streams have different
    // per-pixel variances, which real renders of one integrand never have, so the floor, whose
    // premise is Var(ḡ_i) = Var(h̄_i), is turned off.)
    let truth = |i: usize| 1.0 + (i % 5) as f64 * 0.1;
    let noisy_crn = stream_set(W, W, 16, 64, truth, |b, i| 0.3 * normal(7, (b * 4096 + i) as u64), |_, _| 0.0);
    let est = ours(|o| {
        o.folds = Folds::Halves;
        o.k = 5;
        o.crn_floor = 0.0;
    });
    let out = est.reconstruct(&Input::new(&noisy_crn)).unwrap().image;
    let c = (W / 2) * W + W / 2;
    assert!(
        (out.pixels[c][0] - noisy_crn.pt.mean.pixels[c][0]).abs() < 0.02,
        "{:?} vs PT {:?}",
        out.pixels[c],
        noisy_crn.pt.mean.pixels[c]
    );
    let noisy_pt =
        stream_set(W, W, 16, 64, truth, |b, i| 1e-3 * normal(7, (b * 4096 + i) as u64), |b, i| 3.0 * normal(8, (b * 4096 + i) as u64));
    let out = est.reconstruct(&Input::new(&noisy_pt)).unwrap().image;
    assert!(
        (out.pixels[c][0] - noisy_pt.crn.mean.pixels[c][0]).abs() < 1e-3,
        "{:?} vs CRN {:?}",
        out.pixels[c],
        noisy_pt.crn.mean.pixels[c]
    );
}

#[test]
fn cross_fit_applies_each_half_s_coefficients_to_the_other_half() {
    // B = 8 on a non-degenerate set (CRN noise half shared, half independent; PT noise). The
    // definition (cv_pass.rs): half A = batches 0..4, half B = 4..8; β_A solves the system of
    // ours from half A's deviations with s = 1/(2·4·3) (a half's covariance halved: the
    // covariance of the full mean) and the PT errors of all 8 batches; then
    // out = ½[(ḡ^B_c − Σ β_A,i (ḡ^B_i − h̄_i)) + (ḡ^A_c − Σ β_B,i (ḡ^A_i − h̄_i))],
    // ḡ^A, ḡ^B the half means. Checked against the dense f64 model to 1e-5 (f32 solve and
    // inputs), with window selection, raw-variance errors, no penalty and no floor.
    let (w, h, b) = (W, 15, 8);
    let n = (w * h * 3) as u64;
    let truth = |i: usize, ch: usize| 0.6 + 0.2 * ch as f64 + 0.4 * (i % w) as f64 / w as f64;
    let set = stream_set_rgb(
        w,
        h,
        b,
        32,
        |bb, i, ch| truth(i, ch) + 0.2 * (normal(31, (bb * 3 + ch) as u64) + normal(32, bb as u64 * n + (i * 3 + ch) as u64)),
        |bb, i, ch| truth(i, ch) + 0.15 * normal(33, bb as u64 * n + (i * 3 + ch) as u64),
    );
    let est = |folds: Folds| {
        ours(|o| {
            (o.select, o.errors, o.penalty, o.crn_floor, o.folds) = (Selection::Window, ErrorEstimate::Variance, Penalty::None, 0.0, folds);
        })
    };
    let fitted = est(Folds::Halves).reconstruct(&Input::new(&set)).unwrap().image;
    let plain = est(Folds::All).reconstruct(&Input::new(&set)).unwrap().image;
    let halves = [0..4, 4..8];
    let (mut gap_plain, mut gap_swapped) = (0.0f64, 0.0f64);
    for (x, y) in [(10, 7), (3, 4), (0, 0), (20, 14), (15, 1)] {
        let c = y * w + x;
        let omega = set_of(Rule::Window, &set.crn.mean, x, y, 25, 11, true);
        for ch in 0..3 {
            let w_h: Vec<f64> = omega.iter().map(|&i| variance_of_mean(&set.pt.batches, i, ch)).collect();
            let batches = &set.crn.batches;
            let half_mean = |k: usize| {
                let r = halves[k].clone();
                move |i: usize| batch_mean(&batches[r.clone()], i, ch)
            };
            let fit = |k: usize| Fit {
                set: &set,
                centre: c,
                omega: &omega,
                ch,
                fit: halves[k].clone(),
                s: 1.0 / 24.0,
                w: w_h.clone(),
                ridge: 1e-3,
            };
            let (beta_a, beta_b) = (fit(0).beta(), fit(1).beta());
            let want = 0.5 * (fit(0).apply(&beta_a, half_mean(1)) + fit(1).apply(&beta_b, half_mean(0)));
            // The same coefficients applied to their own half's means (no cross-fitting of the
            // values): what a swap of the halves would compute.
            let swapped = 0.5 * (fit(0).apply(&beta_a, half_mean(0)) + fit(1).apply(&beta_b, half_mean(1)));
            let got = fitted.pixels[c][ch] as f64;
            assert!((got - want).abs() < 1e-5 * want.abs().max(1.0), "pixel ({x}, {y}) ch {ch}: cross-fit {got} vs dense {want}");
            gap_plain = gap_plain.max((plain.pixels[c][ch] as f64 - want).abs());
            gap_swapped = gap_swapped.max((swapped - want).abs());
        }
    }
    // The check discriminates: without cross-fitting, or with the halves swapped, the output
    // would be off by far more than the tolerance.
    assert!(gap_plain > 1e-3 && gap_swapped > 1e-3, "largest gaps: plain {gap_plain}, swapped {gap_swapped}");
}

#[test]
fn bad_floor_and_cross_fit_settings_are_rejected() {
    for tau in [-0.5, f64::NAN, f64::INFINITY] {
        let e = ImperfectCv::new(ImperfectCvOptions { crn_floor: tau, ..Default::default() }).unwrap_err();
        assert!(e.to_string().contains("--crn-floor"), "{e}");
    }
    assert!("sideways".parse::<FloorMode>().unwrap_err().to_string().contains("common, independent"));
    assert!("oracle".parse::<FloorSource>().unwrap_err().to_string().contains("pt, crn"));
    // Cross-fitting needs two equal halves of at least two batches each.
    let est = cvtrace_reconstruct::build("ours", &cvtrace_reconstruct::Overrides::parse(["ours.folds=halves"]).unwrap()).unwrap();
    for (b, needle) in [(5usize, "even"), (2, "at least 4")] {
        let set =
            stream_set(8, 8, b, 16, |_| 1.0, |bb, i| 0.1 * normal(1, (bb * 64 + i) as u64), |bb, i| 0.1 * normal(2, (bb * 64 + i) as u64));
        let e = est.run(&Input::new(&set)).unwrap_err();
        assert!(matches!(e, ReconError::BatchCount { .. }) && e.to_string().contains(needle), "B = {b}: {e}");
    }
}

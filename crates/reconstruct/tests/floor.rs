//! The options of `ours` added for issue 5: the floor on the CRN covariance and cross-fitting.
//! Exact expectations on hand-made stream sets where the CRN batches are degenerate.
mod common;

use common::{normal, stream_set};
use cvtrace_reconstruct::estimators::Ours;
use cvtrace_reconstruct::{Estimator, FloorMode, FloorSource, Input, OursOptions, ReconError, StreamSet};

const W: usize = 21;
const M: f64 = 0.8;

/// CRN: every batch of every pixel is 0 (all 16 batches missed the light). PT: mean `M` in
/// every pixel, batches `M ± a` (half each), so every PT pixel has the same batch variance and
/// the filtered error estimate is exactly that constant.
fn degenerate_set() -> StreamSet {
    stream_set(W, W, 16, 64, |_| 0.0, |_, _| 0.0, |b, _| if b % 2 == 0 { M + 0.3 } else { M - 0.3 })
}

fn ours(f: impl Fn(&mut OursOptions)) -> Ours {
    let mut o = OursOptions::default();
    f(&mut o);
    Ours::new(o).unwrap()
}

fn centre_value(est: &Ours, set: &StreamSet) -> f64 {
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
        let est = ours(|o| {
            o.crn_floor = 0.2;
            o.crn_floor_mode = *mode;
            o.crn_floor_source = FloorSource::Pt;
        });
        let got = est.reconstruct(&Input::new(&set)).unwrap().image;
        let worst = got.pixels.iter().zip(&base.pixels).map(|(a, b)| (a[0] - b[0]).abs()).fold(0.0f32, f32::max);
        // The common floor rotates the batch deviations (same Gram matrix, other rounding).
        assert!(worst < 1e-5, "{mode}: {worst}");
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
fn cross_fit_applies_each_half_s_coefficients_to_the_other_half() {
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
        o.cross_fit = true;
        o.k = 5;
        o.crn_floor = 0.0;
    });
    let out = est.reconstruct(&Input::new(&noisy_crn)).unwrap().image;
    let c = (W / 2) * W + W / 2;
    assert!((out.pixels[c][0] - noisy_crn.pt.mean.pixels[c][0]).abs() < 0.02, "{:?} vs PT {:?}", out.pixels[c], noisy_crn.pt.mean.pixels[c]);
    let noisy_pt = stream_set(
        W,
        W,
        16,
        64,
        truth,
        |b, i| 1e-3 * normal(7, (b * 4096 + i) as u64),
        |b, i| 3.0 * normal(8, (b * 4096 + i) as u64),
    );
    let out = est.reconstruct(&Input::new(&noisy_pt)).unwrap().image;
    assert!((out.pixels[c][0] - noisy_pt.crn.mean.pixels[c][0]).abs() < 1e-3, "{:?} vs CRN {:?}", out.pixels[c], noisy_pt.crn.mean.pixels[c]);
}

#[test]
fn bad_floor_and_cross_fit_settings_are_rejected() {
    for tau in [-0.5, f64::NAN, f64::INFINITY] {
        let e = Ours::new(OursOptions { crn_floor: tau, ..Default::default() }).unwrap_err();
        assert!(e.to_string().contains("--crn-floor"), "{e}");
    }
    assert!("sideways".parse::<FloorMode>().unwrap_err().to_string().contains("common, independent"));
    assert!("oracle".parse::<FloorSource>().unwrap_err().to_string().contains("pt, crn"));
    // Cross-fitting needs two equal halves of at least two batches each.
    let est = ours(|o| o.cross_fit = true);
    for (b, needle) in [(5usize, "even"), (2, "at least 4")] {
        let set = stream_set(8, 8, b, 16, |_| 1.0, |bb, i| 0.1 * normal(1, (bb * 64 + i) as u64), |bb, i| 0.1 * normal(2, (bb * 64 + i) as u64));
        let e = est.reconstruct(&Input::new(&set)).unwrap_err();
        assert!(matches!(e, ReconError::BatchCount { .. }) && e.to_string().contains(needle), "B = {b}: {e}");
    }
}

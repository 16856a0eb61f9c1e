//! The control-variate pass of `ours` and of the `cv` baseline against an independent dense
//! f64 model (`common::dense`): the same β and the same output, pixel by pixel, on random
//! stream sets. Covers every panel width (8, 16, 32, 64) and the general solve.
mod common;

use common::dense::{set_of, variance_of_mean, Fit, Rule};
use common::{msd, normal, stream_set_rgb};
use cvtrace_reconstruct::{build, Input, Overrides, StreamSet};
use cvtrace_streams::Image;

/// A smooth image with CRN noise half shared by all pixels (per batch and channel) and half
/// independent, and independent PT noise; different levels per channel.
fn random_set(w: usize, h: usize, b: usize, seed: u64, crn: f64, pt: f64) -> StreamSet {
    let truth = move |i: usize, ch: usize| 0.4 + 0.3 * ch as f64 + ((i % w) as f64 / w as f64) * (0.5 + 0.2 * ch as f64);
    let n = (w * h * 3) as u64;
    stream_set_rgb(
        w,
        h,
        b,
        4 * b as u32,
        move |bb, i, ch| {
            let (bb, i, ch) = (bb as u64, i as u64, ch as u64);
            truth(i as usize, ch as usize) + crn * (normal(seed, bb * 3 + ch) + normal(seed + 1, (bb * n + i * 3 + ch) + 7))
        },
        move |bb, i, ch| {
            let (bb, i, ch) = (bb as u64, i as u64, ch as u64);
            truth(i as usize, ch as usize) + pt * (1.0 + 0.5 * ch as f64) * normal(seed + 2, bb * n + i * 3 + ch)
        },
    )
}

/// Pixels to check: interior, edge and corner (the window is shifted inside the image there).
fn probes(w: usize, h: usize) -> Vec<(usize, usize)> {
    vec![(w / 2, h / 2), (w / 2 + 3, h / 2 - 2), (0, 0), (w - 1, h / 2), (2, h - 1)]
}

/// Relative difference, with 1 as the floor of the scale (values here are of order 1).
fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1.0)
}

#[test]
fn ours_matches_a_dense_solve_of_eq7_from_the_batches() {
    // select = window, errors = variance, penalty = none, no floor, per-channel coefficients:
    // V_g = s·D·Dᵀ, V_fg = s·D·d_c with s = 1/(B(B−1)) (the covariance of the pixel means),
    // V_h = diag of the PT batch variances of the means (the centre's included: c ∈ Ω),
    // ridge λ = 10⁻³ · mean diag(V_g + V_h), and the output f̄_c − Σ β_i (ḡ_i − h̄_i).
    // Tolerance 1e-5 relative: the panel solves in f32 (β within 10⁻⁶ of f64) and the inputs
    // are f32.
    let base = Overrides::parse([
        "ours.select=window",
        "ours.errors=variance",
        "ours.penalty=none",
        "ours.crn_floor=0",
        "ours.shared_coefficients=false",
        "ours.low_pass_sigma=0",
        "ours.two_stage_weight=0",
    ])
    .unwrap();
    // (B, k): panel widths 8, 16, 32 and 64, then B ≥ k (the general f64 solve).
    for (b, k) in [(4usize, 25usize), (16, 25), (24, 25), (36, 37), (32, 25)] {
        let options = base.with("ours", &[("k", &k.to_string()), ("search_window", "11")]);
        let (w, h) = (17, 15);
        let set = random_set(w, h, b, 100 + b as u64, 0.2, 0.15);
        let out = build("ours", &options).unwrap().run(&Input::new(&set)).unwrap().image;
        let s = 1.0 / (b * (b - 1)) as f64;
        for (x, y) in probes(w, h) {
            let c = y * w + x;
            let omega = set_of(Rule::Window, &set.crn.mean, x, y, k, 11, true);
            assert_eq!((omega.len(), omega[0]), (k, c));
            for ch in 0..3 {
                let w_h: Vec<f64> = omega.iter().map(|&i| variance_of_mean(&set.pt.batches, i, ch)).collect();
                let fit = Fit { set: &set, centre: c, omega: &omega, ch, fit: 0..b, s, w: w_h, ridge: 1e-3 };
                let want = fit.apply(&fit.beta(), |i| set.crn.mean.pixels[i][ch] as f64);
                let got = out.pixels[c][ch] as f64;
                assert!(rel(got, want) < 1e-5, "B = {b}, k = {k}, pixel ({x}, {y}) ch {ch}: ours {got} vs dense {want}");
            }
        }
    }
}

#[test]
fn cv_matches_a_dense_solve_without_the_centre() {
    // The classic form: V_h = 0, no low-pass; Ω' the 48 pixels nearest by CRN colour (default)
    // or spatially in the 15×15 window, the centre left out; (V_g + λ·I) β = V_fg with
    // λ = 0.3 · mean diag(V_g) over Ω'.
    for (rule, select) in [(Rule::Knn, "knn"), (Rule::Window, "window")] {
        let options = Overrides::default().with("cv", &[("select", select), ("pt_noise", "false"), ("low_pass_sigma", "0")]);
        // Panel widths 16 and 32 (B < 48) and the general solve (B = 48).
        for b in [16usize, 32, 48] {
            let (w, h) = (17, 15);
            let set = random_set(w, h, b, 300 + b as u64, 0.2, 0.15);
            let out = build("cv", &options).unwrap().run(&Input::new(&set)).unwrap().image;
            let s = 1.0 / (b * (b - 1)) as f64;
            for (x, y) in probes(w, h) {
                let c = y * w + x;
                let omega = set_of(rule, &set.crn.mean, x, y, 48, 15, false);
                assert!(omega.len() == 48 && !omega.contains(&c));
                for ch in 0..3 {
                    let fit = Fit { set: &set, centre: c, omega: &omega, ch, fit: 0..b, s, w: vec![0.0; 48], ridge: 0.3 };
                    let want = fit.apply(&fit.beta(), |i| set.crn.mean.pixels[i][ch] as f64);
                    let got = out.pixels[c][ch] as f64;
                    assert!(rel(got, want) < 1e-5, "{rule:?}, B = {b}, pixel ({x}, {y}) ch {ch}: cv {got} vs dense {want}");
                }
            }
        }
    }
}

#[test]
fn cv_removes_shared_crn_noise_that_pt_cannot() {
    // The classic form. CRN noise fully shared by the pixels (σ = 0.3 per batch), independent PT noise (σ_h).
    // Then V_g ≈ σ²·1·1ᵀ over the 24 neighbours and β ≈ 1/(24 + 0.3) each (the ridge is 0.3 of
    // the mean diagonal), so F̂_c ≈ ḡ_c − mean(ḡ_i) + mean(h̄_i): the shared noise cancels up to
    // 1 − 24/24.3 of it and the PT noise is averaged over 24 pixels. Expected
    // MSE(cv)/MSE(PT) ≈ 1/24 + (0.3/24.3)²·σ²/σ_h² ≈ 0.05; required < 0.2. With the centre in
    // the set (β = e_c, "zero variance") the output would be PT and the ratio 1.
    let (w, h, b) = (25, 25, 16);
    let truth = |i: usize, ch: usize| 0.5 + 0.1 * ch as f64 + 0.3 * ((i % w) as f64 / w as f64);
    let set = stream_set_rgb(
        w,
        h,
        b,
        64,
        |bb, i, ch| truth(i, ch) + 0.3 * normal(21, (bb * 3 + ch) as u64),
        |bb, i, ch| truth(i, ch) + 0.2 * normal(22, (bb * w * h * 3 + i * 3 + ch) as u64),
    );
    let classic = Overrides::default().with("cv", &[("pt_noise", "false"), ("low_pass_sigma", "0")]);
    let out = build("cv", &classic).unwrap().run(&Input::new(&set)).unwrap().image;
    let truth_image = Image { width: w, height: h, pixels: (0..w * h).map(|i| std::array::from_fn(|ch| truth(i, ch) as f32)).collect() };
    let (e_cv, e_pt) = (msd(&out, &truth_image), msd(&set.pt.mean, &truth_image));
    assert!(e_cv < 0.2 * e_pt, "cv {e_cv:.3e} vs PT {e_pt:.3e}");
    // And the output is not PT: its distance to PT is about PT's own error.
    assert!(msd(&out, &set.pt.mean) > 0.5 * e_pt, "cv is PT");
}

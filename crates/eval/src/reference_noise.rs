//! How much of a measured relMSE is the reference's own noise.
//!
//! A reference `r = I + n` with noise of variance `v_j` (independent of the estimate)
//! inflates every method's expected relMSE by mean_j `w_j v_j`. When that is not small
//! next to the best method's relMSE the ranking is meaningless, so we estimate it and warn.
use crate::metrics::{ensure_finite, ensure_same_size, Reference};
use crate::EvalError;
use cvtrace_streams::Image;
use serde::{Deserialize, Serialize};

/// Above this fraction of the best method's relMSE, the reference is too noisy to rank them.
pub const TOO_NOISY_FRACTION: f64 = 0.1;

/// How the reference noise was estimated (recorded in the results JSON).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseSource {
    /// Two independent half-sample renders whose average is the reference.
    HalfReferences,
    /// `B` equal batch means whose average is the reference.
    BatchMeans,
    /// A per-pixel variance-of-the-mean image rendered alongside the reference.
    VarianceImage,
}

/// The relMSE the reference's noise contributes, and how it was estimated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceNoise {
    pub relmse: f64,
    pub source: NoiseSource,
}

/// From two independent renders `a`, `b` with equal spp whose average is the reference:
/// `((a − b)/2)²` is an unbiased estimate of the variance of `(a + b)/2`.
pub fn from_half_references(
    reference: &Reference,
    a: &Image,
    a_label: &str,
    b: &Image,
    b_label: &str,
) -> Result<ReferenceNoise, EvalError> {
    for (img, label) in [(a, a_label), (b, b_label)] {
        ensure_same_size(img, label, &reference.image, &reference.label)?;
        ensure_finite(img, label)?;
    }
    let w = reference.weights();
    let mut sum = 0.0f64;
    for ((pa, pb), w) in a.pixels.iter().zip(&b.pixels).zip(w) {
        for c in 0..3 {
            let d = (pa[c] as f64 - pb[c] as f64) / 2.0;
            sum += w * d * d;
        }
    }
    Ok(ReferenceNoise { relmse: sum / (3 * w.len()).max(1) as f64, source: NoiseSource::HalfReferences })
}

/// From `B ≥ 2` equal batch means whose average is the reference: the sample variance of
/// the batches over `B` estimates the variance of their mean.
pub fn from_batch_means(reference: &Reference, batches: &[Image], label: &str) -> Result<ReferenceNoise, EvalError> {
    let count = batches.len();
    if count < 2 {
        return Err(EvalError::invalid(label, format!("need at least 2 batch means to estimate noise, found {count}")));
    }
    for (k, img) in batches.iter().enumerate() {
        let name = format!("{label} batch {k}");
        ensure_same_size(img, &name, &reference.image, &reference.label)?;
        ensure_finite(img, &name)?;
    }
    let w = reference.weights();
    let bf = count as f64;
    let mut sum = 0.0f64;
    for (i, w) in w.iter().enumerate() {
        for c in 0..3 {
            let mean = batches.iter().map(|b| b.pixels[i][c] as f64).sum::<f64>() / bf;
            let var = batches.iter().map(|b| (b.pixels[i][c] as f64 - mean).powi(2)).sum::<f64>() / (bf - 1.0);
            sum += w * var / bf;
        }
    }
    Ok(ReferenceNoise { relmse: sum / (3 * w.len()).max(1) as f64, source: NoiseSource::BatchMeans })
}

/// From a per-pixel, per-channel variance of the reference's mean.
pub fn from_variance_image(reference: &Reference, variance: &Image, label: &str) -> Result<ReferenceNoise, EvalError> {
    ensure_same_size(variance, label, &reference.image, &reference.label)?;
    ensure_finite(variance, label)?;
    if let Some((i, c)) = variance.pixels.iter().enumerate().find_map(|(i, p)| p.iter().position(|v| *v < 0.0).map(|c| (i, c))) {
        return Err(EvalError::invalid(
            label,
            format!("negative variance at pixel ({}, {}), channel {c}", i % variance.width, i / variance.width),
        ));
    }
    let w = reference.weights();
    let sum: f64 = variance.pixels.iter().zip(w).map(|(p, w)| w * p.iter().map(|v| *v as f64).sum::<f64>()).sum();
    Ok(ReferenceNoise { relmse: sum / (3 * w.len()).max(1) as f64, source: NoiseSource::VarianceImage })
}

/// How many times more samples the reference needs for the warning below to go away. The best
/// method's measured relMSE `B` holds the reference's noise `N` too: with `k` times the samples
/// the noise is `N/k` and the best `B − N + N/k`, so `N/k ≤ f·(B − N + N/k)` needs
/// `k ≥ (1 − f)·N / (f·(B − N))` (9N/(B − N) for f = 1/10). `None` when `B ≤ N`.
pub fn more_reference_samples(noise_relmse: f64, best_method_relmse: f64) -> Option<u64> {
    let f = TOO_NOISY_FRACTION;
    let truth = best_method_relmse - noise_relmse;
    (truth > 0.0).then(|| ((1.0 - f) * noise_relmse / (f * truth)).ceil().max(2.0) as u64)
}

/// The warning to show when the reference noise is over [`TOO_NOISY_FRACTION`] of the best
/// (smallest) method relMSE, with how many times more samples the reference needs.
pub fn too_noisy_warning(noise_relmse: f64, best_method_relmse: f64) -> Option<String> {
    let limit = TOO_NOISY_FRACTION * best_method_relmse;
    if noise_relmse.is_nan() || noise_relmse <= limit {
        return None;
    }
    Some(format!(
        "reference too noisy to rank the methods: its own noise adds relMSE {noise_relmse:.3e} to every method, \
         more than 1/10 of the best method's {best_method_relmse:.3e}; render the reference with {}",
        match more_reference_samples(noise_relmse, best_method_relmse) {
            Some(k) => format!("{k}x more samples"),
            None => "far more samples (its noise is about all of the best method's error)".into(),
        }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng as TestRng;

    fn truth(w: usize, h: usize) -> Image {
        Image::from_fn(w, h, |x, y| {
            let v = 0.02 + ((x * 5 + y * 3) % 11) as f32 / 10.0;
            [v, 0.7 * v, 0.3]
        })
    }

    fn add_noise(t: &Image, sigma: &[f64], rng: &mut TestRng) -> Image {
        let mut out = t.clone();
        for (i, p) in out.pixels.iter_mut().enumerate() {
            for v in p.iter_mut() {
                *v = (*v as f64 + sigma[i] * rng.normal()) as f32;
            }
        }
        out
    }

    #[test]
    fn half_references_estimate_the_noise_the_reference_adds() {
        let t = truth(64, 48);
        let n = t.len();
        let sigma_half: Vec<f64> = (0..n).map(|i| 0.02 + 0.03 * ((i % 7) as f64 / 6.0)).collect();
        let mut rng = TestRng::new(11);
        let a = add_noise(&t, &sigma_half, &mut rng);
        let b = add_noise(&t, &sigma_half, &mut rng);
        let avg = Image::mean_of(&[a.clone(), b.clone()]);
        let reference = Reference::new(avg, "ref.exr").unwrap();
        let est = from_half_references(&reference, &a, "a.exr", &b, "b.exr").unwrap();
        assert_eq!(est.source, NoiseSource::HalfReferences);
        // Target: mean_j w_j Var(r_j) with Var(r_j) = σ²/2. For Gaussian halves a−b is
        // independent of a+b (hence of w), so the estimator is unbiased with
        // Var(((a−b)/2)²) = σ⁴/2 per pixel and channel.
        let w = reference.weights();
        let j = (3 * n) as f64;
        let target: f64 = (0..n).map(|i| 3.0 * w[i] * sigma_half[i].powi(2) / 2.0).sum::<f64>() / j;
        let sd: f64 = (0..n).map(|i| 3.0 * w[i] * w[i] * sigma_half[i].powi(4) / 2.0).sum::<f64>().sqrt() / j;
        assert!((est.relmse - target).abs() < 5.0 * sd, "{} vs {target} ± {sd}", est.relmse);
        // And it predicts what the noise does to a perfect image's measured relMSE.
        let perfect = reference.rel_mse(&t, "truth").unwrap();
        assert!((perfect - target).abs() < 5.0 * sd * 2.0, "perfect image relMSE {perfect} vs noise {target}");
    }

    #[test]
    fn batch_means_estimate_the_variance_of_their_mean() {
        let t = truth(48, 48);
        let n = t.len();
        let sigma_batch: Vec<f64> = (0..n).map(|i| 0.05 + 0.05 * ((i % 4) as f64 / 3.0)).collect();
        let mut rng = TestRng::new(12);
        let count = 8;
        let batches: Vec<Image> = (0..count).map(|_| add_noise(&t, &sigma_batch, &mut rng)).collect();
        let reference = Reference::new(Image::mean_of(&batches), "ref.exr").unwrap();
        let est = from_batch_means(&reference, &batches, "ref batches").unwrap();
        let w = reference.weights();
        let (j, bf) = ((3 * n) as f64, count as f64);
        let target: f64 = (0..n).map(|i| 3.0 * w[i] * sigma_batch[i].powi(2) / bf).sum::<f64>() / j;
        // Var(s²/B) = 2σ⁴ / ((B−1) B²).
        let sd: f64 = (0..n).map(|i| 3.0 * w[i] * w[i] * 2.0 * sigma_batch[i].powi(4) / ((bf - 1.0) * bf * bf)).sum::<f64>().sqrt() / j;
        assert!((est.relmse - target).abs() < 5.0 * sd, "{} vs {target} ± {sd}", est.relmse);
    }

    #[test]
    fn variance_image_is_weighted_like_relmse() {
        let reference = Reference::new(Image::from_fn(2, 1, |x, _| if x == 0 { [1.0; 3] } else { [0.0; 3] }), "r").unwrap();
        let var = Image::from_fn(2, 1, |x, _| if x == 0 { [0.3; 3] } else { [0.001; 3] });
        let est = from_variance_image(&reference, &var, "var.exr").unwrap();
        let expected = (0.3 / 1.01 + 0.001 / 0.01) / 2.0;
        assert!((est.relmse - expected).abs() < 1e-6);
        let mut neg = var.clone();
        neg.pixels[1][1] = -1.0;
        let err = from_variance_image(&reference, &neg, "var.exr").unwrap_err().to_string();
        assert!(err.contains("var.exr") && err.contains("negative"), "{err}");
    }

    #[test]
    fn warning_only_above_a_tenth_of_the_best_method() {
        assert!(too_noisy_warning(0.9e-4, 1e-3).is_none());
        let w = too_noisy_warning(3e-4, 1e-3).unwrap();
        assert!(w.contains("too noisy to rank") && w.contains("4x more samples"), "{w}");
        // The advice is just enough: with k times the samples the warning goes, with k − 1 not.
        let after = |n: f64, b: f64, k: f64| too_noisy_warning(n / k, b - n + n / k);
        for (n, b) in [(3e-4, 1e-3), (1.1e-4, 1e-3), (5e-4, 1e-3), (0.16, 1.0), (0.83, 1.0)] {
            let k = more_reference_samples(n, b).unwrap() as f64;
            assert!(after(n, b, k).is_none(), "{n} {b}: {k}x is not enough");
            assert!(k == 2.0 || after(n, b, k - 1.0).is_some(), "{n} {b}: {}x would do", k - 1.0);
        }
        assert!(too_noisy_warning(1e-3, 1e-3).unwrap().contains("far more samples"));
        assert!(too_noisy_warning(f64::NAN, 1e-3).is_none());
    }

    #[test]
    fn bad_inputs_name_the_file() {
        let reference = Reference::new(truth(4, 4), "ref.exr").unwrap();
        let err = from_half_references(&reference, &truth(4, 4), "a.exr", &truth(3, 4), "b.exr").unwrap_err();
        assert!(err.to_string().contains("b.exr"), "{err}");
        let err = from_batch_means(&reference, &[truth(4, 4)], "ref.exr").unwrap_err();
        assert!(err.to_string().contains("at least 2"), "{err}");
    }
}

//! Image error metrics, as in the papers' evaluations (and IDUW's code).
use cvtrace_streams::Image;

/// relMSE: the mean over pixels and channels of `(x − r)² / (r̄² + 0.01)`, with `r̄` the mean
/// of the reference's three channels at that pixel. Panics if the sizes differ.
pub fn rel_mse(x: &Image, reference: &Image) -> f64 {
    assert!(x.same_size(reference), "rel_mse: images of different sizes");
    let sum: f64 = x
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(p, r)| {
            let rbar = (r[0] as f64 + r[1] as f64 + r[2] as f64) / 3.0;
            let denom = rbar * rbar + 0.01;
            (0..3).map(|c| (p[c] as f64 - r[c] as f64).powi(2)).sum::<f64>() / denom
        })
        .sum();
    sum / (3 * x.pixels.len()).max(1) as f64
}

/// Plain MSE over pixels and channels.
pub fn mse(x: &Image, reference: &Image) -> f64 {
    assert!(x.same_size(reference), "mse: images of different sizes");
    let sum: f64 =
        x.pixels.iter().zip(&reference.pixels).map(|(p, r)| (0..3).map(|c| (p[c] as f64 - r[c] as f64).powi(2)).sum::<f64>()).sum();
    sum / (3 * x.pixels.len()).max(1) as f64
}

/// Splits the relMSE of several independent outputs of one method into relative squared
/// bias and variance: `(rel_bias², rel_variance)`, with `rel_mse ≈ bias² + variance·(m−1)/m`
/// averaged over the `m` outputs. Needs at least two outputs.
pub fn rel_bias_variance(outputs: &[Image], reference: &Image) -> (f64, f64) {
    let m = outputs.len();
    assert!(m >= 2, "rel_bias_variance needs at least two outputs");
    let (mut bias2, mut var) = (0.0, 0.0);
    for (i, r) in reference.pixels.iter().enumerate() {
        let rbar = (r[0] as f64 + r[1] as f64 + r[2] as f64) / 3.0;
        let denom = rbar * rbar + 0.01;
        for c in 0..3 {
            let mean = outputs.iter().map(|o| o.pixels[i][c] as f64).sum::<f64>() / m as f64;
            let v = outputs.iter().map(|o| (o.pixels[i][c] as f64 - mean).powi(2)).sum::<f64>() / (m - 1) as f64;
            // The squared mean error includes v/m of noise; remove it so bias² is unbiased.
            bias2 += ((mean - r[c] as f64).powi(2) - v / m as f64) / denom;
            var += v / denom;
        }
    }
    let n = (3 * reference.pixels.len()).max(1) as f64;
    (bias2 / n, var / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rel_mse_by_hand() {
        // Reference pixel (1, 2, 3): r̄ = 2, denominator 4.01. Errors 1, 0, -2 → (1 + 4) / 4.01 / 3.
        let r = Image::from_fn(1, 1, |_, _| [1.0, 2.0, 3.0]);
        let x = Image::from_fn(1, 1, |_, _| [2.0, 2.0, 1.0]);
        assert!((rel_mse(&x, &r) - 5.0 / 4.01 / 3.0).abs() < 1e-12);
        assert!((mse(&x, &r) - 5.0 / 3.0).abs() < 1e-12);
        assert_eq!(rel_mse(&r, &r), 0.0);
    }

    #[test]
    fn bias_variance_by_hand() {
        // Outputs 1 and 3 against reference 1 (black reference: denominator 0.01 per channel).
        let r = Image::from_fn(1, 1, |_, _| [1.0, 1.0, 1.0]);
        let outs = [Image::from_fn(1, 1, |_, _| [1.0; 3]), Image::from_fn(1, 1, |_, _| [3.0; 3])];
        let (b, v) = rel_bias_variance(&outs, &r);
        // mean 2, v = 2, bias² = 1 − 2/2 = 0, denominator 1.01.
        assert!((v - 2.0 / 1.01).abs() < 1e-12 && b.abs() < 1e-12, "{b} {v}");
    }
}

//! Restoring the low frequencies of an estimate from an unbiased, spatially independent one.
//!
//! A control-variate estimate whose coefficients come from the same samples as the values
//! they weight is biased: where a pixel's batches happen to be bright, its estimated variance
//! is large too and its values are trusted less, so bright realisations are down-weighted and
//! the image comes out darker. Estimating the coefficients out of sample removes the bias but
//! also the estimator's grip on its own outliers, and costs far more variance than the bias
//! it removes. Instead, `x ← x + G_σ ∗ (h̄ − x)` keeps the estimate's high frequencies and takes
//! its low ones from the PT mean `h̄`, which is unbiased and independent across pixels: the
//! bias is removed at every scale coarser than `σ`, and the PT noise that comes in is averaged
//! over `≈ 4πσ²` pixels. The Gaussian is truncated at 3σ and renormalised at the borders.
//!
//! Each output pixel is a fixed-order sum over its own footprint, so the result is
//! bit-identical for any thread count.
use crate::simd::{self, Kernel, Simd};
use cvtrace_streams::Image;
use rayon::prelude::*;

/// The 1-D Gaussian taps `w[0..=r]` (centre first), `r = ⌈3σ⌉`, no wider than the image.
fn taps(sigma: f64, longest_side: usize) -> Vec<f64> {
    let r = ((3.0 * sigma).ceil() as usize).min(longest_side);
    (0..=r).map(|d| (-0.5 * (d as f64 / sigma).powi(2)).exp()).collect()
}

/// One separable pass along rows or columns, renormalised at borders; with `squared`, the
/// squares of the normalised weights (what a blur does to independent variances).
fn blur_1d(src: &[[f64; 3]], w: usize, h: usize, taps: &[f64], along_columns: bool, squared: bool) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0f64; 3]; w * h];
    let pass = Pass { src, w, h, taps, along_columns, squared };
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| simd::dispatch(PassRow { pass: &pass, y, row }));
    out
}

/// One pass of [`blur_1d`] (its arguments).
struct Pass<'a> {
    src: &'a [[f64; 3]],
    w: usize,
    h: usize,
    taps: &'a [f64],
    along_columns: bool,
    squared: bool,
}

/// One output row of a [`Pass`], for [`simd::dispatch`]: plain loops the compiler
/// vectorises, at the width of the build's features.
struct PassRow<'a> {
    pass: &'a Pass<'a>,
    y: usize,
    row: &'a mut [[f64; 3]],
}

impl Kernel for PassRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd>(self, _: S) {
        self.pass.row(self.y, self.row);
    }
}

impl Pass<'_> {
    /// Output row `y` (zeros on entry). Each output value is `Σ_t a_t·v_t` over its footprint
    /// in increasing `t`, divided by the normalisation, as one pixel at a time computes it;
    /// where pixels share their footprint's weights (every pixel of a row in the pass along
    /// columns, the pixels clear of the borders in the pass along rows), the sums run over
    /// whole rows at once, element by element, and the compiler vectorises them.
    #[inline(always)]
    fn row(&self, y: usize, row: &mut [[f64; 3]]) {
        let (w, taps) = (self.w, self.taps);
        let r = taps.len() - 1;
        let weight = |d: usize| if self.squared { taps[d] * taps[d] } else { taps[d] };
        if self.along_columns {
            let (lo, hi) = (y.saturating_sub(r), (y + r).min(self.h - 1));
            let acc = row.as_flattened_mut();
            let mut norm = 0.0f64;
            for t in lo..=hi {
                let a = weight(t.abs_diff(y));
                for (o, v) in acc.iter_mut().zip(self.src[t * w..(t + 1) * w].as_flattened()) {
                    *o += a * v;
                }
                norm += taps[t.abs_diff(y)];
            }
            let norm = if self.squared { norm * norm } else { norm };
            acc.iter_mut().for_each(|o| *o /= norm);
            return;
        }
        let line = &self.src[y * w..(y + 1) * w];
        let inner = if w > 2 * r { r..w - r } else { 0..0 };
        for (x, px) in row.iter_mut().enumerate().filter(|(x, _)| !inner.contains(x)) {
            let (lo, hi) = (x.saturating_sub(r), (x + r).min(w - 1));
            let (mut acc, mut norm) = ([0.0f64; 3], 0.0f64);
            for t in lo..=hi {
                let a = weight(t.abs_diff(x));
                for ch in 0..3 {
                    acc[ch] += a * line[t][ch];
                }
                norm += taps[t.abs_diff(x)];
            }
            let norm = if self.squared { norm * norm } else { norm };
            *px = acc.map(|a| a / norm);
        }
        if inner.is_empty() {
            return;
        }
        // Clear of the borders, pixel x sums t = x − r … x + r: offset by offset for all.
        let acc = row[inner.clone()].as_flattened_mut();
        let mut norm = 0.0f64;
        for t0 in 0..=2 * r {
            let d = t0.abs_diff(r);
            let a = weight(d);
            for (o, v) in acc.iter_mut().zip(line[t0..t0 + inner.len()].as_flattened()) {
                *o += a * v;
            }
            norm += taps[d];
        }
        let norm = if self.squared { norm * norm } else { norm };
        acc.iter_mut().for_each(|o| *o /= norm);
    }
}

/// Whether `sigma` turns the correction on (a positive, finite width).
fn active(sigma: f64) -> bool {
    sigma.is_finite() && sigma > 0.0
}

/// `estimate + G_σ ∗ (unbiased − estimate)`, per channel; `sigma ≤ 0` (or not finite) returns the estimate.
pub fn restore_low_frequencies(estimate: &Image, unbiased: &Image, sigma: f64) -> Image {
    assert_eq!((estimate.width, estimate.height), (unbiased.width, unbiased.height), "images of different sizes");
    if !active(sigma) || estimate.is_empty() {
        return estimate.clone();
    }
    let (w, h) = (estimate.width, estimate.height);
    let taps = taps(sigma, w.max(h));
    let diff: Vec<[f64; 3]> =
        estimate.pixels.iter().zip(&unbiased.pixels).map(|(e, u)| std::array::from_fn(|ch| u[ch] as f64 - e[ch] as f64)).collect();
    let low = blur_1d(&blur_1d(&diff, w, h, &taps, false, false), w, h, &taps, true, false);
    let pixels = estimate.pixels.iter().zip(&low).map(|(e, l)| std::array::from_fn(|ch| (e[ch] as f64 + l[ch]) as f32)).collect();
    Image { width: w, height: h, pixels }
}

/// The variance [`restore_low_frequencies`] adds: `Σ_j G_σ(c, j)² e_j`, with `e` the PT mean's
/// per-pixel variance (independent across pixels). What the low-pass removes of the
/// estimate's own noise is left out: the estimate's noise is mostly of high frequency.
pub fn low_pass_variance(errors: &[[f32; 3]], w: usize, h: usize, sigma: f64) -> Vec<[f64; 3]> {
    if !active(sigma) || errors.is_empty() {
        return vec![[0.0; 3]; errors.len()];
    }
    let taps = taps(sigma, w.max(h));
    let e: Vec<[f64; 3]> = errors.iter().map(|v| v.map(|x| x as f64)).collect();
    blur_1d(&blur_1d(&e, w, h, &taps, false, true), w, h, &taps, true, true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};

    fn noise(w: usize, h: usize, seed: u64) -> Image {
        Image::from_fn(w, h, |x, y| std::array::from_fn(|ch| uniform(hash4(seed, x as u64, y as u64, ch as u64)) as f32))
    }

    #[test]
    fn a_constant_offset_is_removed_and_the_high_frequencies_are_kept() {
        let (w, h) = (40, 30);
        // A smooth truth, so that its own high frequencies (2% of which the estimate lacks)
        // do not blur the checker below.
        let truth = Image::from_fn(w, h, |x, y| [0.5 + 0.2 * (x as f32 / 9.0).sin() * (y as f32 / 7.0).cos(); 3]);
        // The estimate: the truth 2% too dark, plus a fine checker the unbiased image lacks.
        let est = Image::from_fn(w, h, |x, y| truth.pixels[y * w + x].map(|v| 0.98 * v + if (x + y) % 2 == 0 { 0.01 } else { -0.01 }));
        let out = restore_low_frequencies(&est, &truth, 4.0);
        let mean = |im: &Image| im.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / im.len() as f64;
        assert!((mean(&out) / mean(&truth) - 1.0).abs() < 1e-3, "{} vs {}", mean(&out), mean(&truth));
        // The checker survives almost untouched (a Gaussian of σ = 4 passes nothing at the
        // Nyquist frequency), far from the borders.
        let c = 15 * w + 20;
        let checker = out.pixels[c][0] - out.pixels[c + 1][0] - (truth.pixels[c][0] - truth.pixels[c + 1][0]);
        let want = if (20 + 15) % 2 == 0 { 0.02 } else { -0.02 };
        assert!((checker - want).abs() < 2e-3, "{checker} vs {want}");
    }

    #[test]
    fn the_added_variance_of_a_constant_is_that_of_the_weighted_mean() {
        // Far from the borders, Σ w² for a normalised 2-D Gaussian of σ = 3 is ≈ 1/(4πσ²).
        let v = low_pass_variance(&vec![[1.0; 3]; 61 * 61], 61, 61, 3.0);
        let got = v[30 * 61 + 30][0];
        let want = 1.0 / (4.0 * std::f64::consts::PI * 9.0);
        assert!((got / want - 1.0).abs() < 0.02, "{got} vs {want}");
        // At a corner the footprint is a quarter (centre row and column included), so per axis
        // Σw²/(Σw)² of the half kernel against the full one, squared for the two axes.
        let t: Vec<f64> = (0..=9).map(|d| (-0.5 * (d as f64 / 3.0).powi(2)).exp()).collect();
        let (h1, h2) = (t.iter().sum::<f64>(), t.iter().map(|x| x * x).sum::<f64>());
        let (s1, s2) = (2.0 * h1 - t[0], 2.0 * h2 - t[0] * t[0]);
        let corner = ((h2 / (h1 * h1)) / (s2 / (s1 * s1))).powi(2);
        assert!((v[0][0] / got / corner - 1.0).abs() < 1e-9, "{} vs {corner}", v[0][0] / got);
    }

    /// [`blur_1d`] one pixel at a time, as a reference for the row-wise sums.
    fn blur_1d_per_pixel(src: &[[f64; 3]], w: usize, h: usize, taps: &[f64], along_columns: bool, squared: bool) -> Vec<[f64; 3]> {
        let r = taps.len() - 1;
        let mut out = vec![[0.0f64; 3]; w * h];
        for y in 0..h {
            for x in 0..w {
                let (c, n) = if along_columns { (y, h) } else { (x, w) };
                let (lo, hi) = (c.saturating_sub(r), (c + r).min(n - 1));
                let (mut acc, mut norm) = ([0.0f64; 3], 0.0f64);
                for t in lo..=hi {
                    let wt = taps[t.abs_diff(c)];
                    let v = if along_columns { src[t * w + x] } else { src[y * w + t] };
                    let a = if squared { wt * wt } else { wt };
                    for ch in 0..3 {
                        acc[ch] += a * v[ch];
                    }
                    norm += wt;
                }
                let norm = if squared { norm * norm } else { norm };
                out[y * w + x] = acc.map(|a| a / norm);
            }
        }
        out
    }

    /// The row-wise sums give the bits of the per-pixel ones: images narrower, as wide as and
    /// wider than the kernel, both passes, plain and squared weights, in both builds.
    #[test]
    fn whole_row_sums_give_the_bits_of_the_per_pixel_ones() {
        let run = || {
            for (w, h, sigma) in [(40, 30, 3.0), (7, 19, 1.0), (7, 7, 1.0), (6, 5, 2.0), (1, 9, 0.7), (53, 2, 8.0)] {
                let taps = taps(sigma, w.max(h));
                let src: Vec<[f64; 3]> = noise(w, h, 9).pixels.iter().map(|p| p.map(|v| f64::from(v) - 0.4)).collect();
                for (cols, sq) in [(false, false), (true, false), (false, true), (true, true)] {
                    let bits = |v: Vec<[f64; 3]>| v.iter().map(|p| p.map(f64::to_bits)).collect::<Vec<_>>();
                    let (got, want) = (blur_1d(&src, w, h, &taps, cols, sq), blur_1d_per_pixel(&src, w, h, &taps, cols, sq));
                    assert_eq!(bits(got), bits(want), "{w}x{h} σ={sigma} along columns {cols} squared {sq}");
                }
            }
        };
        run();
        simd::force_portable(run);
    }

    #[test]
    fn equal_images_are_unchanged_and_sigma_zero_is_off() {
        let a = noise(17, 9, 2);
        let b = noise(17, 9, 3);
        let same = restore_low_frequencies(&a, &a, 3.0);
        assert!(same.pixels.iter().zip(&a.pixels).all(|(x, y)| (0..3).all(|c| (x[c] - y[c]).abs() < 1e-6)));
        assert_eq!(restore_low_frequencies(&a, &b, 0.0), a);
    }
}

//! Helpers shared by the integration tests: a counter-based normal generator and small
//! hand-made stream sets.
#![allow(dead_code)]
use cvtrace_streams::{Image, Stream, StreamMeta, StreamSet};

/// SplitMix64 of a seed and a counter.
pub fn hash(seed: u64, i: u64) -> u64 {
    let mut z = seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A standard normal number (Box–Muller), a pure function of (seed, i).
pub fn normal(seed: u64, i: u64) -> f64 {
    let u1 = ((hash(seed, 2 * i) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (hash(seed, 2 * i + 1) >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A stream set whose batch `b` of pixel `i` is `truth_i + crn(b, i)` (CRN) and
/// `truth_i + pt(b, i)` (PT), all channels equal.
pub fn stream_set(
    w: usize,
    h: usize,
    batches: usize,
    spp: u32,
    truth: impl Fn(usize) -> f64,
    crn: impl Fn(usize, usize) -> f64,
    pt: impl Fn(usize, usize) -> f64,
) -> StreamSet {
    let mk = |noise: &dyn Fn(usize, usize) -> f64| {
        let bs: Vec<Image> = (0..batches)
            .map(|b| Image { width: w, height: h, pixels: (0..w * h).map(|i| [(truth(i) + noise(b, i)) as f32; 3]).collect() })
            .collect();
        Stream::from_batches(bs)
    };
    StreamSet { width: w, height: h, pt: mk(&pt), crn: mk(&crn), features: None, meta: StreamMeta { spp, ..Default::default() } }
}

/// Mean squared difference over pixels and channels.
pub fn msd(a: &Image, b: &Image) -> f64 {
    a.pixels.iter().zip(&b.pixels).map(|(p, q)| (0..3).map(|c| (p[c] as f64 - q[c] as f64).powi(2)).sum::<f64>()).sum::<f64>()
        / (3 * a.pixels.len()) as f64
}

/// A stream set whose batch `b` of pixel `i` in channel `ch` is `crn(b, i, ch)` (CRN) and
/// `pt(b, i, ch)` (PT): channels differ, so a mix-up of channels shows.
pub fn stream_set_rgb(
    w: usize,
    h: usize,
    batches: usize,
    spp: u32,
    crn: impl Fn(usize, usize, usize) -> f64,
    pt: impl Fn(usize, usize, usize) -> f64,
) -> StreamSet {
    let mk = |v: &dyn Fn(usize, usize, usize) -> f64| {
        let bs: Vec<Image> = (0..batches)
            .map(|b| Image { width: w, height: h, pixels: (0..w * h).map(|i| std::array::from_fn(|ch| v(b, i, ch) as f32)).collect() })
            .collect();
        Stream::from_batches(bs)
    };
    StreamSet { width: w, height: h, pt: mk(&pt), crn: mk(&crn), features: None, meta: StreamMeta { spp, ..Default::default() } }
}

/// An independent f64 model of the control-variate pass (`ours` and `cv`), written from
/// docs/estimators.md and the definitions in the code comments, sharing no code with the crate:
/// `F̂_c = t_c − Σ_{i∈Ω} β_i (t_i − h̄_i)` with `(s·D·Dᵀ + W + λ·I) β = s·D·d_c`, `D` the CRN
/// batch deviations of `Ω` about their average over the batches `fit`, `d_c` the centre's,
/// `W` diagonal, `λ = ridge · mean diag(s·D·Dᵀ + W)`, and `t` the CRN means the coefficients
/// are applied to.
pub mod dense {
    use cvtrace_streams::{Image, StreamSet};
    use std::ops::Range;

    /// How the set `Ω` is chosen (the two data-independent-order rules of the crate).
    #[derive(Clone, Copy, Debug)]
    pub enum Rule {
        /// The `k` spatially nearest, ties by position in the window (row-major).
        Window,
        /// The `k` nearest by squared CRN colour difference (f32), then spatially, then position.
        Knn,
    }

    /// The crate's search window: `size` wide around `c`, shifted to lie inside `0..n`.
    fn shifted(c: usize, size: usize, n: usize) -> Range<usize> {
        let len = size.min(n);
        let start = (c as isize - (size / 2) as isize).clamp(0, (n - len) as isize) as usize;
        start..start + len
    }

    /// `Ω` of pixel (x, y): the centre first when `include_centre`, then `k` (ours: `k − 1`)
    /// others from the `search × search` window.
    pub fn set_of(rule: Rule, crn: &Image, x: usize, y: usize, k: usize, search: usize, include_centre: bool) -> Vec<usize> {
        let (w, h) = (crn.width, crn.height);
        let c = y * w + x;
        let (xr, yr) = (shifted(x, search, w), shifted(y, search, h));
        let mut cand: Vec<(u32, i64, usize, usize)> = vec![];
        for yy in yr.clone() {
            for xx in xr.clone() {
                let i = yy * w + xx;
                if i == c {
                    continue;
                }
                let (dx, dy) = (xx as i64 - x as i64, yy as i64 - y as i64);
                let colour = match rule {
                    Rule::Window => 0,
                    Rule::Knn => {
                        let (p, q) = (crn.pixels[c], crn.pixels[i]);
                        let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).to_bits()
                    }
                };
                cand.push((colour, dx * dx + dy * dy, (yy - yr.start) * xr.len() + xx - xr.start, i));
            }
        }
        cand.sort();
        let mut out = if include_centre { vec![c] } else { vec![] };
        let want = if include_centre { k - 1 } else { k };
        out.extend(cand.iter().take(want).map(|t| t.3));
        out
    }

    /// Mean over `batches` of pixel `i`'s batch means in channel `ch`.
    pub fn batch_mean(batches: &[Image], i: usize, ch: usize) -> f64 {
        batches.iter().map(|b| b.pixels[i][ch] as f64).sum::<f64>() / batches.len() as f64
    }

    /// `Σ_b (x^b − x̄)² / (B(B−1))`: the variance of the pixel mean from its batches.
    pub fn variance_of_mean(batches: &[Image], i: usize, ch: usize) -> f64 {
        let (m, b) = (batch_mean(batches, i, ch), batches.len() as f64);
        batches.iter().map(|im| (im.pixels[i][ch] as f64 - m).powi(2)).sum::<f64>() / (b * (b - 1.0))
    }

    /// Solves `A x = b` (`n×n` row-major) by Gaussian elimination with partial pivoting.
    pub fn solve(mut a: Vec<f64>, mut b: Vec<f64>) -> Vec<f64> {
        let n = b.len();
        for col in 0..n {
            let p = (col..n).max_by(|&r, &q| a[r * n + col].abs().total_cmp(&a[q * n + col].abs())).unwrap();
            if p != col {
                for j in 0..n {
                    a.swap(col * n + j, p * n + j);
                }
                b.swap(col, p);
            }
            let d = a[col * n + col];
            assert!(d.abs() > 0.0, "singular system");
            for r in col + 1..n {
                let f = a[r * n + col] / d;
                for j in col..n {
                    a[r * n + j] -= f * a[col * n + j];
                }
                b[r] -= f * b[col];
            }
        }
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|j| a[r * n + j] * b[j]).sum();
            b[r] = (b[r] - s) / a[r * n + r];
        }
        b
    }

    /// What one application of the pass needs.
    pub struct Fit<'a> {
        pub set: &'a StreamSet,
        /// Pixel index of the centre.
        pub centre: usize,
        /// `Ω` (for ours it holds the centre).
        pub omega: &'a [usize],
        pub ch: usize,
        /// The CRN batches `D` is estimated from.
        pub fit: Range<usize>,
        /// `s`, the scale of `s·D·Dᵀ`.
        pub s: f64,
        /// `W_i` for each member of `Ω`.
        pub w: Vec<f64>,
        pub ridge: f64,
    }

    impl Fit<'_> {
        /// β of `(s·D·Dᵀ + W + λ·I) β = s·D·d_c`.
        pub fn beta(&self) -> Vec<f64> {
            let batches = &self.set.crn.batches[self.fit.clone()];
            let dev = |i: usize| -> Vec<f64> {
                let m = batch_mean(batches, i, self.ch);
                batches.iter().map(|b| b.pixels[i][self.ch] as f64 - m).collect()
            };
            let d: Vec<Vec<f64>> = self.omega.iter().map(|&i| dev(i)).collect();
            let dc = dev(self.centre);
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let k = self.omega.len();
            let mut a = vec![0.0; k * k];
            for i in 0..k {
                for j in 0..k {
                    a[i * k + j] = self.s * dot(&d[i], &d[j]);
                }
                a[i * k + i] += self.w[i];
            }
            let lambda = self.ridge * (0..k).map(|i| a[i * k + i]).sum::<f64>() / k as f64;
            for i in 0..k {
                a[i * k + i] += lambda;
            }
            solve(a, d.iter().map(|r| self.s * dot(r, &dc)).collect())
        }

        /// `t_c − Σ β_i (t_i − h̄_i)`, `h̄` the PT stream mean.
        pub fn apply(&self, beta: &[f64], t: impl Fn(usize) -> f64) -> f64 {
            let h = |i: usize| self.set.pt.mean.pixels[i][self.ch] as f64;
            t(self.centre) - self.omega.iter().zip(beta).map(|(&i, b)| b * (t(i) - h(i))).sum::<f64>()
        }
    }
}

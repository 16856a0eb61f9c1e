//! Statistics of the batch means of a stream.
//!
//! A stream stores `B` batch means per pixel over fixed sample ranges (the same range in
//! every pixel, so CRN batch `b` of all pixels shares its random numbers). Their deviations
//! from the batch average give unbiased covariances of the pixel means:
//! `Cov(ḡ_i, ḡ_j) ≈ Σ_b (g_i^b − ḡ_i)(g_j^b − ḡ_j) / (B(B−1))`.
use crate::simd::Lines;
use cvtrace_streams::{Image, Stream};
use rayon::prelude::*;

/// Per pixel and channel, the deviations of the `B` batch means from their average,
/// laid out `[(pixel·3 + channel)·stride + batch]` so that one pixel's data is contiguous.
/// A `stride` above `B` pads every row with zeros, so that fixed-width kernels can copy
/// whole rows. The values start on a cache line ([`Lines`]), so that with a stride of 16 every
/// row is one line: gathering a pixel's rows touches three lines instead of four, and a
/// 16-wide load of a row is never split across two.
#[derive(Clone)]
pub struct BatchCube {
    pub batches: usize,
    pub stride: usize,
    pub data: Lines,
    /// Per pixel and channel, the sum of squared deviations.
    pub sq: Vec<[f32; 3]>,
}

impl BatchCube {
    pub fn deviations(stream: &Stream, stride: usize) -> Self {
        BatchCube::deviations_floored(stream, stride, None)
    }

    /// [`BatchCube::deviations`] followed by [`BatchCube::rotate_and_floor`] with `floor =
    /// (values, τ, s)`, each chunk of pixels rotated and floored right after its deviations,
    /// while they are in cache, instead of in a second pass over the whole cube: the same
    /// operations on every value in the same order, so the same bits.
    pub fn deviations_floored(stream: &Stream, stride: usize, floor: Option<(&[[f32; 3]], f64, f64)>) -> Self {
        const CHUNK: usize = 2048;
        let b = stream.batches.len();
        assert!(stride >= b);
        let n = stream.mean.pixels.len();
        let mut data = Lines::zeros(n * 3 * stride);
        let mut sq = vec![[0.0f32; 3]; n];
        if let Some((values, _, _)) = floor {
            assert!(b >= 2 && values.len() == n);
        }
        let coef = helmert(b);
        if b > 0 {
            // Each task streams through every batch image once for its pixel range.
            data.par_chunks_mut(3 * stride * CHUNK).zip(sq.par_chunks_mut(CHUNK)).enumerate().for_each(|(chunk, (out, sq))| {
                let start = chunk * CHUNK;
                let len = sq.len();
                let mut sum = vec![[0.0f64; 3]; len];
                for (bi, im) in stream.batches.iter().enumerate() {
                    for (local, p) in im.pixels[start..start + len].iter().enumerate() {
                        for ch in 0..3 {
                            out[(local * 3 + ch) * stride + bi] = p[ch];
                            sum[local][ch] += p[ch] as f64;
                        }
                    }
                }
                for (local, px) in out.chunks_mut(3 * stride).enumerate() {
                    for ch in 0..3 {
                        let mean = sum[local][ch] / b as f64;
                        let mut ss = 0.0f32;
                        for slot in &mut px[ch * stride..ch * stride + b] {
                            *slot = (*slot as f64 - mean) as f32;
                            ss += *slot * *slot;
                        }
                        sq[local][ch] = ss;
                    }
                    if let Some((values, tau, s)) = floor {
                        rotate_and_floor_pixel(px, &mut sq[local], values[start + local], &coef, b, stride, tau, s);
                    }
                }
            });
        }
        BatchCube { batches: b, stride, data, sq }
    }

    /// Frees the last batch column for a floor and fills it: every row's `B` deviations sum to
    /// zero, so rotating them by an orthonormal Helmert basis (first `B − 1` columns orthogonal
    /// to the all-ones vector, the last one along it) leaves `D·Dᵀ` unchanged and the last
    /// column zero. That column then holds `√(δ_i / s)`, `δ_i = max(0, τ·v_i − s·‖D_i‖²)`, so
    /// that `s·D·Dᵀ` gains the rank-one term `u·uᵀ`, `u_i = √δ_i` per channel: a noise
    /// component fully shared by the pixels of a set, the way CRN's rare bright paths are.
    /// `sq` is updated to the new row norms. Needs `B ≥ 2`.
    pub fn rotate_and_floor(&mut self, values: &[[f32; 3]], tau: f64, s: f64) {
        let (b, stride) = (self.batches, self.stride);
        assert!(b >= 2 && values.len() == self.sq.len());
        let coef = helmert(b);
        self.data.par_chunks_mut(3 * stride).zip(self.sq.par_iter_mut()).zip(values.par_iter()).for_each(|((px, sq), v)| {
            rotate_and_floor_pixel(px, sq, *v, &coef, b, stride, tau, s);
        });
    }

    /// The deviations of pixel `i` in channel `ch`.
    #[inline]
    pub fn row(&self, i: usize, ch: usize) -> &[f32] {
        let at = (i * 3 + ch) * self.stride;
        &self.data[at..at + self.batches]
    }

    /// The zero-padded row of pixel `i` in channel `ch`; needs `stride == P`.
    #[inline(always)]
    pub fn row_padded<const P: usize>(&self, i: usize, ch: usize) -> &[f32; P] {
        debug_assert_eq!(self.stride, P);
        let at = (i * 3 + ch) * P;
        self.data[at..at + P].try_into().expect("cube stride is P")
    }

    /// All three channels of pixel `i` (3·B values); needs `stride == B`.
    #[inline]
    pub fn pixel(&self, i: usize) -> &[f32] {
        debug_assert_eq!(self.stride, self.batches);
        let b = self.batches;
        &self.data[i * 3 * b..(i + 1) * 3 * b]
    }
}

/// The coefficients of the Helmert rotation of `b` deviations: `(1/√(j(j+1)), j)`, `j = 1..b−1`.
fn helmert(b: usize) -> Vec<(f64, f64)> {
    (1..b).map(|j| (1.0 / ((j * (j + 1)) as f64).sqrt(), j as f64)).collect()
}

/// [`BatchCube::rotate_and_floor`] of one pixel's three rows `px` (`stride` apart) and norms `sq`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn rotate_and_floor_pixel(px: &mut [f32], sq: &mut [f32; 3], v: [f32; 3], coef: &[(f64, f64)], b: usize, stride: usize, tau: f64, s: f64) {
    let mut z = [0.0f64; crate::solve::MAX_BATCHES];
    for ch in 0..3 {
        let row = &mut px[ch * stride..ch * stride + b];
        // Helmert: z_{j−1} = (Σ_{a<j} d_a − j·d_j) / √(j(j+1)), j = 1..B−1.
        let mut prefix = 0.0f64;
        let mut ss = 0.0f64;
        for j in 1..b {
            prefix += row[j - 1] as f64;
            let (c, jf) = coef[j - 1];
            z[j - 1] = (prefix - jf * row[j] as f64) * c;
            ss += z[j - 1] * z[j - 1];
        }
        let delta = (tau * v[ch] as f64 - s * ss).max(0.0);
        z[b - 1] = (delta / s).sqrt();
        for (dst, src) in row.iter_mut().zip(&z[..b]) {
            *dst = *src as f32;
        }
        sq[ch] = row.iter().map(|x| x * x).sum();
    }
}

#[cfg(test)]
mod floor_tests {
    use super::*;

    /// Flooring each chunk right after its deviations gives the bits of the second pass over the
    /// whole cube, on images across several chunks, floors that bind and floors that do not.
    #[test]
    fn floored_in_one_pass_gives_the_bits_of_two() {
        use crate::rng::{hash4, uniform};
        for (w, h, b, stride) in [(70, 61, 16, 16), (33, 7, 2, 8), (50, 90, 5, 8), (9, 5, 32, 32)] {
            let batches: Vec<Image> = (0..b)
                .map(|k| {
                    Image::from_fn(w, h, |x, y| {
                        std::array::from_fn(|c| {
                            let u = uniform(hash4(3, (y * w + x) as u64, k as u64, c as u64));
                            if c == 2 {
                                (u * u * u * 50.0) as f32
                            } else {
                                u as f32
                            }
                        })
                    })
                })
                .collect();
            let st = Stream::from_batches(batches);
            let values: Vec<[f32; 3]> =
                (0..w * h).map(|i| std::array::from_fn(|c| uniform(hash4(4, i as u64, c as u64, 0)) as f32 * 0.01)).collect();
            let (tau, s) = (0.05, 1.0 / (b * (b - 1)) as f64);
            let mut two = BatchCube::deviations(&st, stride);
            two.rotate_and_floor(&values, tau, s);
            let one = BatchCube::deviations_floored(&st, stride, Some((&values, tau, s)));
            let bits = |c: &BatchCube| {
                (c.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), c.sq.iter().map(|v| v.map(f32::to_bits)).collect::<Vec<_>>())
            };
            assert_eq!(bits(&one), bits(&two), "{w}x{h} B={b} stride {stride}");
        }
    }

    #[test]
    fn rotation_keeps_the_gram_matrix_and_the_floor_adds_u_ut() {
        let b = 6;
        let batches: Vec<Image> =
            (0..b).map(|k| Image::from_fn(3, 1, |x, _| [((k * 5 + x * 3) % 7) as f32 * 0.3, (k * x) as f32 * 0.1, 0.0])).collect();
        let s = Stream::from_batches(batches);
        let plain = BatchCube::deviations(&s, 8);
        let mut rot = BatchCube::deviations(&s, 8);
        // Zero floor: the Gram matrix of every channel is unchanged, the last column is 0.
        rot.rotate_and_floor(&[[0.0; 3]; 3], 1.0, 0.1);
        let gram = |c: &BatchCube, i: usize, j: usize, ch: usize| -> f64 {
            c.row(i, ch).iter().zip(c.row(j, ch)).map(|(a, b)| *a as f64 * *b as f64).sum()
        };
        for ch in 0..2 {
            for i in 0..3 {
                assert!(rot.row(i, ch)[b - 1].abs() < 1e-6);
                assert!((rot.sq[i][ch] as f64 - gram(&plain, i, i, ch)).abs() < 1e-4);
                for j in 0..3 {
                    assert!((gram(&rot, i, j, ch) - gram(&plain, i, j, ch)).abs() < 1e-4, "ch {ch} ({i},{j})");
                }
            }
        }
        // A floor of τ·v = 1 on an all-zero channel (ch 2): s·D·Dᵀ becomes u·uᵀ with u_i = 1.
        let mut fl = BatchCube::deviations(&s, 8);
        fl.rotate_and_floor(&[[0.0, 0.0, 0.5]; 3], 2.0, 0.1);
        for i in 0..3 {
            for j in 0..3 {
                assert!((0.1 * gram(&fl, i, j, 2) - 1.0).abs() < 1e-5);
            }
            // Channel 0 has real variance above a zero floor: unchanged.
            assert!((gram(&fl, i, i, 0) - gram(&plain, i, i, 0)).abs() < 1e-4);
        }
    }
}

/// The estimated variance of each pixel mean, `Σ_b (x^b − x̄)² / (B(B−1))`; zero for `B < 2`.
pub fn variance_of_mean(stream: &Stream) -> Vec<[f32; 3]> {
    batch_variance(stream, false)
}

/// As [`variance_of_mean`], but per pixel and channel without the batch farthest from the
/// mean: `Σ_{b≠k} (x^b − x̄')² / (B(B−2))`, `x̄'` the mean of the other `B − 1`. One batch that
/// caught a firefly then does not set the estimate; zero for `B < 3`.
pub fn trimmed_variance_of_mean(stream: &Stream) -> Vec<[f32; 3]> {
    batch_variance(stream, true)
}

fn batch_variance(stream: &Stream, trim: bool) -> Vec<[f32; 3]> {
    const CHUNK: usize = 4096;
    let b = stream.batches.len();
    let n = stream.mean.pixels.len();
    let mut out = vec![[0.0f32; 3]; n];
    if b < 2 + usize::from(trim) {
        return out;
    }
    let bf = b as f64;
    let norm = if trim { 1.0 / (bf * (bf - 2.0)) } else { 1.0 / (bf * (bf - 1.0)) };
    // Two passes over each task's pixel range, streaming through every batch image in turn.
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(chunk, out)| {
        let range = chunk * CHUNK..chunk * CHUNK + out.len();
        let mut mean = vec![[0.0f64; 3]; out.len()];
        for im in &stream.batches {
            for (m, p) in mean.iter_mut().zip(&im.pixels[range.clone()]) {
                for ch in 0..3 {
                    m[ch] += p[ch] as f64;
                }
            }
        }
        mean.iter_mut().for_each(|m| m.iter_mut().for_each(|v| *v /= bf));
        let mut ss = vec![[0.0f64; 3]; out.len()];
        // The largest squared deviation per pixel, kept only when trimming.
        let mut largest = vec![[0.0f64; 3]; if trim { out.len() } else { 0 }];
        for im in &stream.batches {
            for (i, ((s, m), p)) in ss.iter_mut().zip(&mean).zip(&im.pixels[range.clone()]).enumerate() {
                for ch in 0..3 {
                    let d2 = (p[ch] as f64 - m[ch]).powi(2);
                    s[ch] += d2;
                    if trim {
                        largest[i][ch] = largest[i][ch].max(d2);
                    }
                }
            }
        }
        for (i, (o, s)) in out.iter_mut().zip(&ss).enumerate() {
            // Leaving batch k out moves the mean by (x̄ − x^k)/(B − 1), which takes
            // (x^k − x̄)²·B/(B − 1) out of the sum of squares in all.
            *o = std::array::from_fn(|ch| {
                let s = if trim { (s[ch] - largest[i][ch] * bf / (bf - 1.0)).max(0.0) } else { s[ch] };
                (s * norm) as f32
            });
        }
    });
    out
}

/// Means of `groups` equal runs of consecutive batches (IDUW's sub-buffers).
/// The caller guarantees that the batch count is a multiple of `groups`.
pub fn group_means(stream: &Stream, groups: usize) -> Vec<Image> {
    let per = stream.batches.len() / groups;
    (0..groups).map(|g| Image::mean_of(&stream.batches[g * per..(g + 1) * per])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deviations_and_variance_by_hand() {
        // One pixel, batches 1, 2, 6 in R: mean 3, deviations -2, -1, 3, Σd² = 14,
        // variance of the mean 14 / (3·2) = 7/3.
        let batches = [1.0f32, 2.0, 6.0].iter().map(|&v| Image::from_fn(1, 1, |_, _| [v, 0.0, v * 2.0])).collect();
        let s = Stream::from_batches(batches);
        let cube = BatchCube::deviations(&s, 3);
        assert_eq!(cube.row(0, 0), &[-2.0, -1.0, 3.0]);
        assert_eq!(cube.row(0, 2), &[-4.0, -2.0, 6.0]);
        let v = variance_of_mean(&s);
        assert!((v[0][0] - 7.0 / 3.0).abs() < 1e-6 && v[0][1] == 0.0 && (v[0][2] - 28.0 / 3.0).abs() < 1e-5);
        let g = group_means(
            &Stream::from_batches(vec![s.batches[0].clone(), s.batches[1].clone(), s.batches[2].clone(), s.batches[2].clone()]),
            2,
        );
        assert_eq!(g[0].pixels[0][0], 1.5);
        assert_eq!(g[1].pixels[0][0], 6.0);
    }

    #[test]
    fn the_trimmed_variance_leaves_the_farthest_batch_out() {
        // R: batches 1, 2, 3, 1000 — without 1000: mean 2, Σd² = 2, 2 / (4·2) = 0.25.
        // G: all equal, 0. B: 4, 0, 0, 0 — without 4: 0.
        let values = [[1.0f32, 5.0, 4.0], [2.0, 5.0, 0.0], [3.0, 5.0, 0.0], [1000.0, 5.0, 0.0]];
        let s = Stream::from_batches(values.iter().map(|&v| Image::from_fn(1, 1, |_, _| v)).collect());
        let t = trimmed_variance_of_mean(&s);
        assert!((t[0][0] - 0.25).abs() < 1e-5, "{:?}", t[0]);
        assert!(t[0][1] == 0.0 && t[0][2].abs() < 1e-6, "{:?}", t[0]);
        // Against leaving each batch out by hand on random data: always the farthest one.
        use crate::rng::{hash4, uniform};
        let batches: Vec<Image> = (0..16u64)
            .map(|b| Image::from_fn(5, 3, |x, y| std::array::from_fn(|ch| uniform(hash4(7, b, (y * 5 + x) as u64, ch as u64)) as f32)))
            .collect();
        let s = Stream::from_batches(batches);
        let t = trimmed_variance_of_mean(&s);
        for (i, got) in t.iter().enumerate() {
            for ch in 0..3 {
                let x: Vec<f64> = s.batches.iter().map(|im| im.pixels[i][ch] as f64).collect();
                let m = x.iter().sum::<f64>() / 16.0;
                let k = (0..16).max_by(|&a, &b| (x[a] - m).abs().total_cmp(&(x[b] - m).abs())).unwrap();
                let rest: Vec<f64> = x.iter().enumerate().filter(|&(j, _)| j != k).map(|(_, v)| *v).collect();
                let mr = rest.iter().sum::<f64>() / 15.0;
                let want = rest.iter().map(|v| (v - mr).powi(2)).sum::<f64>() / (16.0 * 14.0);
                assert!((got[ch] as f64 - want).abs() <= 1e-5 * want.max(1e-6), "pixel {i} ch {ch}: {} vs {want}", got[ch]);
            }
        }
    }
}

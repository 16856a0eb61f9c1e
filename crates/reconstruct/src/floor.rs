//! The noise floor of `ours` on the CRN covariance.
//!
//! With `B` batches of a stream whose radiance comes from rare bright paths (indirect light),
//! most pixels' CRN batches are ≈ 0 in a given render, and those pixels' batch covariance says
//! "CRN is nearly exact". The solve then trusts CRN (`β → 0`) exactly where CRN came out low:
//! the estimated covariance is correlated with the values it weights, and the output inherits
//! CRN's low values (a darkening bias; see docs/estimators.md).
//!
//! The floor raises the diagonal of `V_g` to at least `τ·ṽ_i`, with `ṽ_i` a variance estimate
//! that does not come from the pixel's CRN batches: `δ_i = max(0, τ·ṽ_i − V_g,ii)` (pixels
//! whose batches report more keep their covariance). Because the centre is in the set and
//! `f̄_c = ḡ_c`, `V_fg` gains the matching terms. Two shapes of the extra covariance:
//!
//! - `common`: `u·uᵀ`, `u_i = √δ_i`, a noise component shared by the whole set — what CRN's
//!   rare bright paths are. At a pixel whose set has all-zero batches, β spreads over the set
//!   and the output tends to the mean of the neighbours' PT values. Implemented in the batch
//!   cube (see `BatchCube::rotate_and_floor`), free per pixel.
//! - `independent`: `diag(δ)`. The neighbours cannot cancel independent noise, so at a
//!   degenerate pixel the output tends to a blend of the centre's PT and CRN values only.
//!
//! `ṽ` (`source`): `pt`, the PT error estimates `V_h` before the penalty (both streams sample
//! the same integrand, so `Var(ḡ_i) = Var(h̄_i)`, and the PT estimate is independent of the CRN
//! stream); `pt-capped` (the default), the same capped where a PT firefly makes one pixel's
//! estimate stand far above its neighbourhood's, because a firefly's inflated estimate would
//! otherwise claim shared CRN noise around it that is not there; `crn`, the CRN batch variance
//! smoothed by the same cross-bilateral filter; or `pt-trimmed`.
//!
//! For `independent`, solving `(V_g + Δ + V_h' + λ) β = V_fg + δ_c·e_c` needs no second solve: with
//! `β'` the solution without the extra right-hand side (and `Δ` in the diagonal), the Woodbury
//! identity gives `β = (1 − a)·β' + a·e_c`, `a = δ_c / (w_c + λ)` with `w_c` the centre's full
//! diagonal weight. At a pixel whose batches are all zero, `β = e_c·τ/(1+τ)`: with `τ = 1` the
//! inverse-variance blend of PT and CRN, which both have variance `ṽ_c`.
use crate::batch_stats::variance_of_mean;
use crate::named::named_enum;
use crate::pt_error::{cross_bilateral, CbfOptions};
use crate::simd::{self, Kernel, Simd};
use cvtrace_streams::StreamSet;
use rayon::prelude::*;

named_enum! {
    /// The shape of the floor's extra covariance, `δ_i = max(0, τ·ṽ_i − V_g,ii)` on the diagonal.
    pub enum FloorMode: "floor mode" {
        /// `u·uᵀ` with `u_i = √δ_i`: noise shared by all pixels of the set (as CRN's rare bright
        /// paths are), so the neighbours can cancel it. Costs nothing per pixel: the floor is a
        /// batch column freed by a rotation of the deviations.
        Common => "common",
        /// `diag(δ)`: independent noise, which only the centre's own PT value can replace.
        Independent => "independent",
    }
}

named_enum! {
    /// Where the floor's per-pixel variance `ṽ_i` comes from.
    pub enum FloorSource: "floor source" {
        /// The PT error estimates (`--errors`), before the symmetric penalty.
        Pt => "pt",
        /// The CRN batch variance of the mean, smoothed by the cross-bilateral filter.
        Crn => "crn",
        /// The PT batch variance of the mean without each pixel's farthest batch, smoothed by
        /// the cross-bilateral filter: a PT firefly, one batch far from the rest, does not
        /// raise the floor of its neighbourhood.
        PtTrimmed => "pt-trimmed",
        /// The PT error estimates, each at most `cap` times the cross-bilateral filtered 3×3
        /// median of the PT batch variance. An isolated PT firefly, whose variance its
        /// neighbours do not share, then does not raise the floor of its neighbourhood by
        /// orders of magnitude, while variance that neighbouring pixels share keeps it.
        PtCapped => "pt-capped",
    }
}

/// Each pixel's value replaced, per channel, by the median of its 3×3 window (clipped at the
/// image border; of an even count, the lower of the two middle values). Ordered as
/// [`f32::total_cmp`] orders, so the median is one of the window's values, bit for bit.
pub fn median_3x3(values: &[[f32; 3]], width: usize, height: usize) -> Vec<[f32; 3]> {
    let mut out = vec![[0.0f32; 3]; values.len()];
    // The values as keys whose integer order is `total_cmp`'s, one plane per channel, so that
    // the interior pixels' medians run as a min/max network along a row.
    let keys: [Vec<i32>; 3] = std::array::from_fn(|ch| values.iter().map(|v| total_key(v[ch])).collect());
    out.par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
        simd::dispatch(MedianRow { values, keys: &keys, width, height, y, row });
    });
    out
}

/// [`f32::total_cmp`]'s order as an integer: flipping the magnitude bits of negative values
/// makes the signed integers order like the floats. It is its own inverse.
#[inline(always)]
fn total_key(v: f32) -> i32 {
    let b = v.to_bits() as i32;
    b ^ (((b >> 31) as u32) >> 1) as i32
}

/// The float of a [`total_key`].
#[inline(always)]
fn from_total_key(k: i32) -> f32 {
    f32::from_bits((k ^ (((k >> 31) as u32) >> 1) as i32) as u32)
}

/// The 5th smallest of nine keys: the exchange network of Paeth's median of nine (19 compare
/// and exchanges), which leaves it in `p[4]`.
#[inline(always)]
fn median9(mut p: [i32; 9]) -> i32 {
    let mut sort = |a: usize, b: usize| {
        let (lo, hi) = (p[a].min(p[b]), p[a].max(p[b]));
        (p[a], p[b]) = (lo, hi);
    };
    for (a, b) in [
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 1),
        (3, 4),
        (6, 7),
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 3),
        (5, 8),
        (4, 7),
        (3, 6),
        (1, 4),
        (2, 5),
        (4, 7),
        (4, 2),
        (6, 4),
        (4, 2),
    ] {
        sort(a, b);
    }
    p[4]
}

/// One output row of [`median_3x3`], for [`simd::dispatch`].
struct MedianRow<'a> {
    values: &'a [[f32; 3]],
    keys: &'a [Vec<i32>; 3],
    width: usize,
    height: usize,
    y: usize,
    row: &'a mut [[f32; 3]],
}

impl Kernel for MedianRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd>(self, _simd: S) {
        let MedianRow { values, keys, width, height, y, row } = self;
        let interior = |x: usize| y >= 1 && y + 1 < height && x >= 1 && x + 1 < width;
        for (x, o) in row.iter_mut().enumerate() {
            if interior(x) {
                continue;
            }
            let mut window = [[0.0f32; 9]; 3];
            let mut n = 0;
            for wy in y.saturating_sub(1)..(y + 2).min(height) {
                for wx in x.saturating_sub(1)..(x + 2).min(width) {
                    for ch in 0..3 {
                        window[ch][n] = values[wy * width + wx][ch];
                    }
                    n += 1;
                }
            }
            *o = std::array::from_fn(|ch| {
                let w = &mut window[ch][..n];
                *w.select_nth_unstable_by(n.saturating_sub(1) / 2, f32::total_cmp).1
            });
        }
        if y >= 1 && y + 1 < height && width >= 3 {
            for (ch, k) in keys.iter().enumerate() {
                let rows = [&k[(y - 1) * width..y * width], &k[y * width..(y + 1) * width], &k[(y + 1) * width..(y + 2) * width]];
                for x in 1..width - 1 {
                    let p = [
                        rows[0][x - 1],
                        rows[0][x],
                        rows[0][x + 1],
                        rows[1][x - 1],
                        rows[1][x],
                        rows[1][x + 1],
                        rows[2][x - 1],
                        rows[2][x],
                        rows[2][x + 1],
                    ];
                    row[x][ch] = from_total_key(median9(p));
                }
            }
        }
    }
}

/// `min(errors_i, cap·m_i)` per pixel and channel, with `m` the cross-bilateral filtered 3×3
/// median of the PT batch variance of the mean (the `pt-capped` floor variance).
pub fn capped_errors(errors: &[[f32; 3]], set: &StreamSet, cbf: &CbfOptions, cap: f64) -> Vec<[f32; 3]> {
    cap_errors(errors, &cross_bilateral(&median_3x3(&variance_of_mean(&set.pt), set.width, set.height), set, cbf), cap)
}

/// [`capped_errors`] with the filtered median `median` given.
pub fn cap_errors(errors: &[[f32; 3]], median: &[[f32; 3]], cap: f64) -> Vec<[f32; 3]> {
    errors.iter().zip(median).map(|(e, m)| std::array::from_fn(|ch| (e[ch] as f64).min(cap * m[ch] as f64) as f32)).collect()
}

/// The floor of one pass: `τ`, the mode and the per-pixel `ṽ`.
#[derive(Clone, Copy)]
pub struct Floor<'a> {
    pub tau: f64,
    pub mode: FloorMode,
    pub values: &'a [[f32; 3]],
}

impl Floor<'_> {
    /// `δ` for a pixel with floor variance `v` (already summed over channels when shared) and
    /// batch variance `s_ii`.
    #[inline(always)]
    pub fn delta(&self, v: f64, s_ii: f64) -> f64 {
        (self.tau * v - s_ii).max(0.0)
    }
}

/// Turns `β'` (the solution with `Δ` in the diagonal but without `δ_c` in `V_fg`) into the
/// solution with it: `β = (1 − a)·β' + a·e_c`, `a = δ_c·winv_c`, `winv_c = 1/(w_c + λ)`.
/// The centre must be `beta[0]`. Returns `1 − a` (1 where nothing changed): the fit's residual
/// `d_c − Σ β_j D_j` is `1 − a` times that of `β'`, because `D_c = d_c`.
#[inline]
pub(crate) fn blend_towards_centre(beta: &mut [f64], delta_c: f64, winv_c: f64) -> f64 {
    let a = delta_c * winv_c;
    if !(a > 0.0 && a.is_finite()) || beta.is_empty() {
        return 1.0;
    }
    for b in beta.iter_mut() {
        *b *= 1.0 - a;
    }
    beta[0] += a;
    1.0 - a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{Form, Workspace};

    /// The min/max network of the interior pixels picks the value `select_nth_unstable_by` with
    /// `total_cmp` picks, bit for bit: on random values with ties, signed zeros, infinities and
    /// NaNs of both signs, in both builds, on images down to 1 pixel wide or high.
    #[test]
    fn the_median_network_gives_the_selected_value() {
        use crate::rng::{hash4, uniform};
        let special = [0.0, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN, 1.0, -1.0, f32::MIN_POSITIVE];
        let value = |i: u64, ch: u64| {
            let r = hash4(17, i, ch, 0);
            match r % 4 {
                0 => special[(r >> 8) as usize % special.len()],
                1 => ((r >> 8) % 3) as f32,
                _ => (uniform(r) - 0.3) as f32 * 10.0,
            }
        };
        let run = || {
            for (w, h) in [(23, 17), (3, 3), (1, 5), (6, 1), (2, 2)] {
                let values: Vec<[f32; 3]> =
                    (0..w * h).map(|i| std::array::from_fn(|ch| value(i as u64 + 1000 * w as u64, ch as u64))).collect();
                let got = median_3x3(&values, w, h);
                for y in 0..h {
                    for x in 0..w {
                        let want: [f32; 3] = std::array::from_fn(|ch| {
                            let mut window: Vec<f32> = (y.saturating_sub(1)..(y + 2).min(h))
                                .flat_map(|wy| (x.saturating_sub(1)..(x + 2).min(w)).map(move |wx| wy * w + wx))
                                .map(|i| values[i][ch])
                                .collect();
                            let n = window.len();
                            *window.select_nth_unstable_by((n - 1) / 2, f32::total_cmp).1
                        });
                        assert_eq!(got[y * w + x].map(f32::to_bits), want.map(f32::to_bits), "{w}x{h} at ({x}, {y})");
                    }
                }
            }
        };
        run();
        crate::simd::force_portable(run);
    }

    #[test]
    fn delta_by_hand() {
        let lift = Floor { tau: 2.0, mode: FloorMode::Independent, values: &[] };
        assert_eq!(lift.delta(1.0, 0.5), 1.5);
        assert_eq!(lift.delta(1.0, 3.0), 0.0);
        assert_eq!("COMMON".parse::<FloorMode>().unwrap(), FloorMode::Common);
        assert!("max".parse::<FloorMode>().unwrap_err().to_string().contains("common, independent"));
        assert_eq!("crn".parse::<FloorSource>().unwrap(), FloorSource::Crn);
    }

    /// An isolated spike goes, an edge between two flat regions stays where it is, and the
    /// border windows take the lower middle of their even counts.
    #[test]
    fn median_3x3_by_hand() {
        let (w, h) = (5, 4);
        let mut v = vec![[0.0f32; 3]; w * h];
        for y in 0..h {
            for x in 0..w {
                v[y * w + x] = [if x >= 3 { 2.0 } else { 1.0 }, (y * w + x) as f32, 0.0];
            }
        }
        v[w + 1][0] = 1e6;
        v[2 * w + 2][2] = 7.0;
        let m = median_3x3(&v, w, h);
        for y in 0..h {
            for x in 0..w {
                // Channel 0: the spike is gone and the edge between x = 2 and x = 3 stays.
                assert_eq!(m[y * w + x][0], if x >= 3 { 2.0 } else { 1.0 }, "({x},{y})");
                assert_eq!(m[y * w + x][2], 0.0);
            }
        }
        // Channel 1 is the pixel index: an interior median is the centre, a corner's window
        // {0, 1, 5, 6} gives 1, an edge's {0, 1, 2, 5, 6, 7} gives 2.
        assert_eq!(m[2 * w + 2][1], (2 * w + 2) as f32);
        assert_eq!(m[0][1], 1.0);
        assert_eq!(m[1][1], 2.0);
    }

    /// An isolated PT firefly lifts the filtered PT errors of its neighbourhood by orders of
    /// magnitude; the capped floor variance stays within `cap` times the background, while a
    /// 5×5 block of pixels that share a high variance keeps its floor.
    #[test]
    fn the_cap_removes_an_isolated_firefly_and_keeps_shared_variance() {
        use cvtrace_streams::{Image, Stream, StreamMeta};
        let (w, h, b) = (32usize, 24usize, 16usize);
        let firefly = 6 * w + 6;
        let in_block = |i: usize| (20..25).contains(&(i % w)) && (12..17).contains(&(i / w));
        let pt: Vec<Image> = (0..b)
            .map(|k| {
                Image::from_fn(w, h, |x, y| {
                    let i = y * w + x;
                    let mut v = if k % 2 == 0 { 1.1 } else { 0.9 };
                    if k == 0 && i == firefly {
                        v += 1e4;
                    }
                    if k == 0 && in_block(i) {
                        v += 30.0;
                    }
                    [v; 3]
                })
            })
            .collect();
        let crn = vec![Image::from_fn(w, h, |_, _| [0.0; 3]); b];
        let set = StreamSet {
            width: w,
            height: h,
            pt: Stream::from_batches(pt),
            crn: Stream::from_batches(crn),
            features: None,
            meta: StreamMeta { spp: 64, ..Default::default() },
        };
        let cbf = CbfOptions::default();
        let errors = cross_bilateral(&variance_of_mean(&set.pt), &set, &cbf);
        let background = variance_of_mean(&set.pt)[0][0] as f64;
        let cap = 100.0;
        let capped = capped_errors(&errors, &set, &cbf, cap);
        // The firefly's neighbourhood (the block is more than a filter radius away).
        let near = |i: usize| (i % w).abs_diff(6) <= 5 && (i / w).abs_diff(6) <= 5;
        let worst = |v: &[[f32; 3]]| v.iter().enumerate().filter(|(i, _)| near(*i)).map(|(_, e)| e[1] as f64).fold(0.0, f64::max);
        assert!(worst(&errors) > 1e3 * background, "the firefly lifts its neighbourhood: {} vs {background}", worst(&errors));
        assert!(worst(&capped) <= cap * background * (1.0 + 1e-5), "{} vs {background}", worst(&capped));
        // Far from the firefly and the block nothing changes; the block's centre keeps its
        // floor, which is ~10³ times the background.
        assert_eq!(capped[h - 1], errors[h - 1]);
        let centre = 14 * w + 22;
        assert!(errors[centre][0] as f64 > 500.0 * background);
        assert_eq!(capped[centre], errors[centre]);
    }

    /// The closed form equals a direct solve of `(W + Δ + s·D·Dᵀ) β = s·D·d_c + δ_c·e_c`.
    #[test]
    fn blend_matches_the_system_with_the_centre_term() {
        let (k, m) = (9usize, 5usize);
        let s = 1.0 / (m * (m - 1)) as f64;
        let mut ws = Workspace::boxed();
        for j in 0..k {
            for b in 0..m {
                ws.d[j * m + b] = ((j * 7 + b * 3) % 11) as f64 / 11.0 - 0.45 + if j == 0 { 0.0 } else { 0.1 * b as f64 };
            }
            ws.w[j] = 0.02 + 0.01 * j as f64;
        }
        for b in 0..m {
            ws.dc[b] = ws.d[b];
        }
        let delta: Vec<f64> = (0..k).map(|j| 0.03 * (1 + j % 3) as f64).collect();
        for j in 0..k {
            ws.w[j] += delta[j];
        }
        // Dense reference: A = diag(w) + s·D·Dᵀ, rhs = s·D·d_c + δ_c e_0.
        let mut a = vec![0.0; k * k];
        let mut rhs = vec![0.0; k];
        for i in 0..k {
            for j in 0..k {
                a[i * k + j] = s * (0..m).map(|b| ws.d[i * m + b] * ws.d[j * m + b]).sum::<f64>();
            }
            a[i * k + i] += ws.w[i];
            rhs[i] = s * (0..m).map(|b| ws.d[i * m + b] * ws.dc[b]).sum::<f64>();
        }
        rhs[0] += delta[0];
        assert!(crate::solve::cholesky(&mut a, k));
        crate::solve::cholesky_solve(&a, k, &mut rhs);
        for form in [Form::Direct, Form::Woodbury] {
            let mut w2 = Workspace::boxed();
            w2.d = ws.d;
            w2.dc = ws.dc;
            w2.w = ws.w;
            w2.solve(k, m, s, 0.0, form);
            let mut beta = w2.beta[..k].to_vec();
            blend_towards_centre(&mut beta, delta[0], 1.0 / (w2.w[0] + w2.lambda));
            for j in 0..k {
                assert!((beta[j] - rhs[j]).abs() < 1e-10, "{form:?} j={j}: {} vs {}", beta[j], rhs[j]);
            }
        }
    }
}

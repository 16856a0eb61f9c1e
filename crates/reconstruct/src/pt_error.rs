//! Per-pixel error estimates of the PT means `h̄_i`: the diagonal `V_h` of `ours`.
//!
//! The target is `Var(h̄_i)`, the squared error a PT pixel mean makes on average. The raw
//! batch variance is unbiased for it but noisy (a χ² with `B − 1` degrees of freedom) and
//! correlated with the pixel's own realised error, which biases the weights: a PT pixel that
//! came out low also tends to report a low variance and gets trusted more. Averaging the
//! variance over similar pixels with a cross-bilateral filter removes most of both effects.
use crate::batch_stats::variance_of_mean;
use crate::named::named_enum;
use crate::simd::{self, Kernel, Simd};
use crate::ReconError;
use cvtrace_streams::{Image, StreamSet};
use rayon::prelude::*;

named_enum! {
    /// Where the PT error estimates come from.
    pub enum ErrorEstimate: "error estimate" {
        /// The batch variance of `h̄`, smoothed by a cross-bilateral filter guided by the
        /// CRN image and the features (our design; see [`CbfOptions`]).
        Cbf => "cbf",
        /// The raw per-pixel batch variance of `h̄`.
        Variance => "variance",
        /// Squared differences between `h̄` and a cross-bilateral-filtered PT image used as a
        /// pseudo-reference, smoothed by the same filter (an alternative we measured).
        CbfResidual => "cbf-residual",
        /// Realised squared errors `(h̄ − reference)²`: analysis only, needs a reference.
        Oracle => "oracle",
    }
}

/// The cross-bilateral filter that smooths the PT batch variance.
///
/// Weight of neighbour `j` for centre `c` (one weight for all three channels):
/// `exp(−|Δp|²/(2σ_s²) − δ_rgb/(2σ_c²) − ‖Δa‖²/(2σ_a²) − ‖Δn‖²/(2σ_n²))` with the *relative*
/// CRN colour distance `δ_rgb = Σ(ḡ_c − ḡ_j)² / (ε + Σ(ḡ_c² + ḡ_j²)/2)`, σ_s = radius. The CRN
/// image is the guide because its noise is shared by neighbours, so its local structure is far
/// cleaner than the PT image's; the relative distance makes the filter independent of exposure.
/// Feature terms are used when the stream set has features. The default is the filter of
/// `ours`' declared defaults, where its parameters are declared.
#[derive(Clone, Debug, PartialEq)]
pub struct CbfOptions {
    /// Window radius in pixels (window side 2·radius + 1).
    pub radius: usize,
    /// Tolerance of the relative CRN colour difference.
    pub sigma_colour: f32,
    /// Tolerance of the albedo difference (absolute).
    pub sigma_albedo: f32,
    /// Tolerance of the shading-normal difference (absolute).
    pub sigma_normal: f32,
    /// Leave a pixel's own variance out of its estimate, so that the estimate is independent
    /// of the pixel's own PT samples. Off by default: a firefly pixel then keeps its own huge
    /// variance and is not trusted, where leaving it out let the firefly through (on the real
    /// scenes, keeping the centre lowered relMSE by 29% at 96 + 96 and 41% at 32 + 32,
    /// docs/estimators.md).
    pub exclude_centre: bool,
}

/// Largest supported filter radius.
pub const MAX_RADIUS: usize = 15;

impl CbfOptions {
    pub fn validate(&self) -> Result<(), ReconError> {
        if self.radius == 0 || self.radius > MAX_RADIUS {
            return Err(ReconError::option("cbf-radius", self.radius, format!("must be between 1 and {MAX_RADIUS} pixels")));
        }
        for (name, v) in
            [("cbf-sigma-colour", self.sigma_colour), ("cbf-sigma-albedo", self.sigma_albedo), ("cbf-sigma-normal", self.sigma_normal)]
        {
            if !(v > 0.0 && v.is_finite()) {
                return Err(ReconError::option(name, v, "must be a positive finite number"));
            }
        }
        Ok(())
    }
}

/// The error estimate of every PT pixel mean, per channel. The caller has validated the input
/// (a reference of the right size is present for `Oracle`).
pub fn pt_errors(kind: ErrorEstimate, set: &StreamSet, reference: Option<&Image>, cbf: &CbfOptions) -> Vec<[f32; 3]> {
    match kind {
        ErrorEstimate::Variance => variance_of_mean(&set.pt),
        ErrorEstimate::Cbf => cross_bilateral(&variance_of_mean(&set.pt), set, cbf),
        ErrorEstimate::CbfResidual => {
            let pseudo = cross_bilateral(&set.pt.mean.pixels, set, cbf);
            let sq: Vec<[f32; 3]> =
                set.pt.mean.pixels.iter().zip(&pseudo).map(|(h, r)| std::array::from_fn(|c| (h[c] - r[c]) * (h[c] - r[c]))).collect();
            cross_bilateral(&sq, set, cbf)
        }
        ErrorEstimate::Oracle => {
            let r = reference.expect("oracle errors need a reference (checked by Input::check)");
            set.pt.mean.pixels.iter().zip(&r.pixels).map(|(h, r)| std::array::from_fn(|c| (h[c] - r[c]) * (h[c] - r[c]))).collect()
        }
    }
}

/// Smooths per-pixel values with the cross-bilateral filter described in [`CbfOptions`].
pub fn cross_bilateral(values: &[[f32; 3]], set: &StreamSet, o: &CbfOptions) -> Vec<[f32; 3]> {
    let [out] = cross_bilateral_sets([values], set, o);
    out
}

/// [`cross_bilateral`] of several value sets at once, each with the bits it gets on its own:
/// the weights depend only on the guide, so each is computed once for all the sets.
pub fn cross_bilateral_sets<const N: usize>(values: [&[[f32; 3]]; N], set: &StreamSet, o: &CbfOptions) -> [Vec<[f32; 3]>; N] {
    let (w, h) = (set.width, set.height);
    let filter = Filter::new(values, set, o);
    let mut out: [Vec<[f32; 3]>; N] = std::array::from_fn(|_| vec![[0.0f32; 3]; w * h]);
    let mut rows: Vec<[&mut [[f32; 3]]; N]> = Vec::with_capacity(h);
    let mut iters = out.each_mut().map(|o| o.chunks_mut(w.max(1)));
    for _ in 0..h {
        rows.push(iters.each_mut().map(|i| i.next().expect("one row per image row")));
    }
    rows.into_par_iter().enumerate().for_each(|(y, row)| simd::dispatch(FilterRow { filter: &filter, y, row }));
    out
}

/// Three planes, one per channel.
type Rgb = [Vec<f32>; 3];

/// Guide and value planes, one contiguous slice per quantity, so that a window row is a
/// contiguous run the compiler can vectorise.
struct Planes<const N: usize> {
    w: usize,
    h: usize,
    g: [Vec<f32>; 3],
    /// `1 / (ε + |ḡ|²/2)`-style normaliser input: `|ḡ|²` and ε.
    g2: Vec<f32>,
    eps: f32,
    features: Option<(Rgb, Rgb)>,
    /// The planes of each value set.
    v: [Rgb; N],
}

impl<const N: usize> Planes<N> {
    fn new(values: [&[[f32; 3]]; N], set: &StreamSet, eps: f32) -> Self {
        let plane = |im: &[[f32; 3]], c: usize| im.iter().map(|p| p[c]).collect::<Vec<f32>>();
        let g = &set.crn.mean.pixels;
        Planes {
            w: set.width,
            h: set.height,
            g: std::array::from_fn(|c| plane(g, c)),
            g2: g.iter().map(|p| p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).collect(),
            eps,
            features: set
                .features
                .as_ref()
                .map(|f| (std::array::from_fn(|c| plane(&f.albedo.pixels, c)), std::array::from_fn(|c| plane(&f.normal.pixels, c)))),
            v: values.map(|values| std::array::from_fn(|c| plane(values, c))),
        }
    }
}

struct Gains {
    colour: f32,
    albedo: f32,
    normal: f32,
}

/// The filter of one call: the planes, the gains of the exponent's terms, its spatial term per
/// offset `−r … r`, the radius `r`, and whether a pixel's own value is left out.
struct Filter<const N: usize> {
    planes: Planes<N>,
    gains: Gains,
    spatial: Vec<f32>,
    r: usize,
    exclude: bool,
}

/// One image row of the filter's output, for [`simd::dispatch`].
struct FilterRow<'a, const N: usize> {
    filter: &'a Filter<N>,
    y: usize,
    row: [&'a mut [[f32; 3]]; N],
}

impl<const N: usize> Kernel for FilterRow<'_, N> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd>(self, simd: S) {
        self.filter.row(simd, self.y, self.row);
    }
}

impl<const N: usize> Filter<N> {
    /// The filter of `o` for `values` guided by `set`.
    fn new(values: [&[[f32; 3]]; N], set: &StreamSet, o: &CbfOptions) -> Self {
        let g = &set.crn.mean.pixels;
        let mean_sq = g.iter().map(|p| p.iter().map(|v| (*v as f64).powi(2)).sum::<f64>()).sum::<f64>() / g.len().max(1) as f64;
        let r = o.radius;
        Filter {
            planes: Planes::new(values, set, (1e-3 * mean_sq).max(1e-30) as f32),
            gains: Gains {
                colour: 0.5 / (o.sigma_colour * o.sigma_colour),
                albedo: 0.5 / (o.sigma_albedo * o.sigma_albedo),
                normal: 0.5 / (o.sigma_normal * o.sigma_normal),
            },
            spatial: (0..=2 * r).map(|i| (i as f32 - r as f32).powi(2) * 0.5 / (r as f32 * r as f32)).collect(),
            r,
            exclude: o.exclude_centre,
        }
    }

    /// Output row `y` of each value set.
    #[inline(always)]
    fn row<S: Simd>(&self, simd: S, y: usize, mut row: [&mut [[f32; 3]]; N]) {
        let (p, r) = (&self.planes, self.r);
        // Centres whose window lies whole within the row go eight at a time, one per lane (see
        // `Filter::eight`); the others, near the left and right borders, one at a time.
        let mut x = 0;
        while x < p.w {
            if x >= r && x + 8 + r <= p.w {
                let out = self.eight(simd, y, x);
                for (row, out) in row.iter_mut().zip(out) {
                    row[x..x + 8].copy_from_slice(&out);
                }
                x += 8;
            } else {
                for (row, out) in row.iter_mut().zip(self.centre(simd, y, x)) {
                    row[x] = out;
                }
                x += 1;
            }
        }
    }

    /// The filter's value of each set at centre `(x, y)`.
    #[inline(always)]
    fn centre<S: Simd>(&self, simd: S, y: usize, x: usize) -> [[f32; 3]; N] {
        let (p, k, spatial, r, exclude) = (&self.planes, &self.gains, &self.spatial[..], self.r, self.exclude);
        let (w, h) = (p.w, p.h);
        let mut tbuf = [0.0f32; 2 * MAX_RADIUS + 1];
        let c = y * w + x;
        let (gc, g2c) = ([p.g[0][c], p.g[1][c], p.g[2][c]], p.g2[c]);
        // The weights, then each set's three weighted values.
        let mut acc_w = [0.0f32; 8];
        let mut acc = [[[0.0f32; 8]; 3]; N];
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            let dy2 = spatial[yy + r - y];
            let (a, b) = (yy * w + x0, yy * w + x1);
            let sp = &spatial[x0 + r - x..x1 + r - x];
            let (g0, g1, g2, n2) = (&p.g[0][a..b], &p.g[1][a..b], &p.g[2][a..b], &p.g2[a..b]);
            let n = b - a;
            // Exponents first (element-wise, vectorises), then weights, then the sums.
            let t = &mut tbuf[..n];
            for j in 0..n {
                t[j] = colour_exponent(p, k, gc, g2c, [g0[j], g1[j], g2[j]], n2[j]) + (sp[j] + dy2);
            }
            if let Some((al, nm)) = &p.features {
                let (ac, nc) = ([al[0][c], al[1][c], al[2][c]], [nm[0][c], nm[1][c], nm[2][c]]);
                for j in 0..n {
                    t[j] +=
                        feature_exponent(k, ac, nc, [al[0][a + j], al[1][a + j], al[2][a + j]], [nm[0][a + j], nm[1][a + j], nm[2][a + j]]);
                }
            }
            simd.exp_neg_in_place(t);
            for j in 0..n {
                acc_w[j % 8] += t[j];
            }
            for (acc, v) in acc.iter_mut().zip(&p.v) {
                let (v0, v1, v2) = (&v[0][a..b], &v[1][a..b], &v[2][a..b]);
                for j in 0..n {
                    let (l, wt) = (j % 8, t[j]);
                    acc[0][l] += wt * v0[j];
                    acc[1][l] += wt * v1[j];
                    acc[2][l] += wt * v2[j];
                }
            }
        }
        let sum = |a: &[f32; 8]| ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
        std::array::from_fn(|q| finish(&p.v[q], exclude, c, sum(&acc_w), acc[q].each_ref().map(sum)))
    }

    /// [`Filter::centre`] for the eight centres `x0 … x0 + 7` of row `y`, whose windows lie
    /// whole within the row (`x0 ≥ r`, `x0 + 7 + r < w`): lane `l` is centre `x0 + l`, so every
    /// window element is one vector operation for the eight, the exponentials run eight at a
    /// time, and the loads stream along the window's rows. Element `dx` of each window row goes
    /// to the centre's partial sum `dx mod 8`, in the order `Filter::centre` adds it: the same
    /// bits.
    #[inline(always)]
    fn eight<S: Simd>(&self, simd: S, y: usize, x0: usize) -> [[[f32; 3]; 8]; N] {
        let (p, k, spatial, r, exclude) = (&self.planes, &self.gains, &self.spatial[..], self.r, self.exclude);
        let (w, h) = (p.w, p.h);
        let c0 = y * w + x0;
        let lanes = |plane: &[f32], at: usize| -> [f32; 8] { plane[at..at + 8].try_into().expect("eight lanes") };
        let gc = [lanes(&p.g[0], c0), lanes(&p.g[1], c0), lanes(&p.g[2], c0)];
        let g2c = lanes(&p.g2, c0);
        let centre_features = p.features.as_ref().map(|(al, nm)| {
            ([lanes(&al[0], c0), lanes(&al[1], c0), lanes(&al[2], c0)], [lanes(&nm[0], c0), lanes(&nm[1], c0), lanes(&nm[2], c0)])
        });
        // [partial][lane] of the weights, [set][partial][weighted value][lane] of the values.
        let mut acc_w = [[0.0f32; 8]; 8];
        let mut acc = [[[[0.0f32; 8]; 3]; 8]; N];
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            let dy2 = spatial[yy + r - y];
            for dx in 0..=2 * r {
                let a = yy * w + x0 + dx - r;
                let (g, n2) = ([lanes(&p.g[0], a), lanes(&p.g[1], a), lanes(&p.g[2], a)], lanes(&p.g2, a));
                let sp = spatial[dx] + dy2;
                let mut t: [f32; 8] = std::array::from_fn(|l| {
                    colour_exponent(p, k, [gc[0][l], gc[1][l], gc[2][l]], g2c[l], [g[0][l], g[1][l], g[2][l]], n2[l]) + sp
                });
                if let (Some((al, nm)), Some((ac, nc))) = (&p.features, &centre_features) {
                    let (an, nn) =
                        ([lanes(&al[0], a), lanes(&al[1], a), lanes(&al[2], a)], [lanes(&nm[0], a), lanes(&nm[1], a), lanes(&nm[2], a)]);
                    for l in 0..8 {
                        t[l] += feature_exponent(
                            k,
                            [ac[0][l], ac[1][l], ac[2][l]],
                            [nc[0][l], nc[1][l], nc[2][l]],
                            [an[0][l], an[1][l], an[2][l]],
                            [nn[0][l], nn[1][l], nn[2][l]],
                        );
                    }
                }
                simd.exp_neg_in_place(&mut t);
                let part = &mut acc_w[dx % 8];
                for l in 0..8 {
                    part[l] += t[l];
                }
                for (acc, v) in acc.iter_mut().zip(&p.v) {
                    let (v0, v1, v2) = (lanes(&v[0], a), lanes(&v[1], a), lanes(&v[2], a));
                    let part = &mut acc[dx % 8];
                    for l in 0..8 {
                        part[0][l] += t[l] * v0[l];
                        part[1][l] += t[l] * v1[l];
                        part[2][l] += t[l] * v2[l];
                    }
                }
            }
        }
        let sum = |a: [[f32; 8]; 8], l: usize| ((a[0][l] + a[1][l]) + (a[2][l] + a[3][l])) + ((a[4][l] + a[5][l]) + (a[6][l] + a[7][l]));
        std::array::from_fn(|q| {
            std::array::from_fn(|l| {
                let values = std::array::from_fn(|ch| sum(std::array::from_fn(|part| acc[q][part][ch]), l));
                finish(&p.v[q], exclude, c0 + l, sum(acc_w, l), values)
            })
        })
    }
}

/// The colour term of a weight's exponent, `δ_rgb·k_colour`.
#[inline(always)]
fn colour_exponent<const N: usize>(p: &Planes<N>, k: &Gains, gc: [f32; 3], g2c: f32, g: [f32; 3], n2: f32) -> f32 {
    let d = [gc[0] - g[0], gc[1] - g[1], gc[2] - g[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / (p.eps + 0.5 * (g2c + n2)) * k.colour
}

/// The feature terms of a weight's exponent.
#[inline(always)]
fn feature_exponent(k: &Gains, ac: [f32; 3], nc: [f32; 3], a: [f32; 3], n: [f32; 3]) -> f32 {
    let da = [ac[0] - a[0], ac[1] - a[1], ac[2] - a[2]];
    let dn = [nc[0] - n[0], nc[1] - n[1], nc[2] - n[2]];
    (da[0] * da[0] + da[1] * da[1] + da[2] * da[2]) * k.albedo + (dn[0] * dn[0] + dn[1] * dn[1] + dn[2] * dn[2]) * k.normal
}

/// The filtered value from the weight sum `ws` and the weighted sums `s` of centre `c`, whose
/// values are the planes `v`.
#[inline(always)]
fn finish(v: &Rgb, exclude: bool, c: usize, mut ws: f32, mut s: [f32; 3]) -> [f32; 3] {
    if exclude {
        // The centre's own weight is exactly exp(0) = 1.
        ws -= 1.0;
        for ch in 0..3 {
            s[ch] -= v[ch][c];
        }
    }
    if ws > 1e-6 {
        [s[0] / ws, s[1] / ws, s[2] / ws]
    } else {
        [v[0][c], v[1][c], v[2][c]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::Portable;
    use cvtrace_streams::{Stream, StreamMeta};

    fn flat_set(crn: Image) -> StreamSet {
        StreamSet {
            width: crn.width,
            height: crn.height,
            pt: Stream { mean: crn.clone(), batches: vec![] },
            crn: Stream { mean: crn, batches: vec![] },
            features: None,
            meta: StreamMeta::default(),
        }
    }

    /// The eight-centre path gives every centre the bits of the one-centre path: with and
    /// without features, several radii, excluding the centre or not, images narrower than
    /// eight centres plus the window, in both builds.
    #[test]
    fn eight_centres_at_once_give_the_bits_of_one_at_a_time() {
        use crate::synthetic::{RenderSpec, SoftShadowScene};
        let run = || {
            for (w, h) in [(37, 23), (12, 9), (29, 3)] {
                let set = SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 8, batches: 4, seed: 5 }).unwrap();
                let mut plain = set.clone();
                plain.features = None;
                let values = variance_of_mean(&set.pt);
                for s in [&set, &plain] {
                    for (radius, exclude_centre) in [(3, false), (1, true), (5, false), (2, true)] {
                        let o = CbfOptions { radius, exclude_centre, ..Default::default() };
                        let got = cross_bilateral(&values, s, &o);
                        let filter = Filter::new([&values], s, &o);
                        let r = radius;
                        for y in 0..h {
                            for x in 0..w {
                                let [want] = filter.centre(Portable, y, x);
                                let features = s.features.is_some();
                                assert_eq!(
                                    got[y * w + x].map(f32::to_bits),
                                    want.map(f32::to_bits),
                                    "{w}x{h} r={r} exclude={exclude_centre} features={features} at ({x}, {y})"
                                );
                            }
                        }
                    }
                }
            }
        };
        run();
        simd::force_portable(run);
    }

    /// Value sets filtered together get the bits each gets on its own.
    #[test]
    fn sets_filtered_together_give_the_bits_of_each_alone() {
        use crate::synthetic::{RenderSpec, SoftShadowScene};
        let set = SoftShadowScene::default().render(&RenderSpec { width: 41, height: 13, spp: 8, batches: 4, seed: 9 }).unwrap();
        let a = variance_of_mean(&set.pt);
        let b = crate::floor::median_3x3(&variance_of_mean(&set.crn), 41, 13);
        for o in [CbfOptions::default(), CbfOptions { radius: 2, exclude_centre: true, ..Default::default() }] {
            let [ga, gb] = cross_bilateral_sets([&a, &b], &set, &o);
            let bits = |v: &[[f32; 3]]| v.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&ga), bits(&cross_bilateral(&a, &set, &o)));
            assert_eq!(bits(&gb), bits(&cross_bilateral(&b, &set, &o)));
        }
    }

    #[test]
    fn filter_averages_within_regions_and_keeps_edges() {
        // Two CRN regions of very different colour; values alternate 0/2 in a checker within
        // each region (mean 1 left, mean 10 right). The filter should return ≈ the region mean
        // and not mix the regions.
        let crn = Image::from_fn(16, 16, |x, _| if x < 8 { [0.1; 3] } else { [5.0; 3] });
        let set = flat_set(crn);
        let vals: Vec<[f32; 3]> = (0..256)
            .map(|i| {
                let (x, y) = (i % 16, i / 16);
                let base = if x < 8 { 1.0 } else { 10.0 };
                [if (x + y) % 2 == 0 { 0.0 } else { 2.0 * base }; 3]
            })
            .collect();
        let o = CbfOptions { radius: 3, ..Default::default() };
        let f = cross_bilateral(&vals, &set, &o);
        for y in 3..13 {
            for x in [2usize, 5, 10, 13] {
                let want = if x < 8 { 1.0 } else { 10.0 };
                let got = f[y * 16 + x][0];
                assert!((got - want).abs() < 0.2 * want, "({x},{y}) {got} vs {want}");
            }
        }
    }
}

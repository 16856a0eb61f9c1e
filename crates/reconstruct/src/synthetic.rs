//! A synthetic scene with a known ground truth, for tests, benches and the ablation study.
//!
//! A textured, partly bumpy ground plane seen from above, lit by a warm segment light and a
//! long blue "sky" segment, both partly blocked by three floating occluders (soft shadows).
//! Each sample draws a sub-pixel jitter (for the texture) and one point on each light. PT
//! draws these independently per pixel; CRN uses the same four numbers for sample `s` of every
//! pixel, so neighbouring CRN pixels share their shadow and aliasing errors — the structure a
//! real CRN render has. The ground truth is exact up to a 2048-point quadrature per light
//! (relative error < 1e-3), far below the Monte Carlo error of any test.
use crate::rng::{hash4, uniform};
use crate::ReconError;
use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
use rayon::prelude::*;

/// How to render the synthetic scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSpec {
    pub width: usize,
    pub height: usize,
    /// Samples per pixel of each stream.
    pub spp: u32,
    /// Batches per stream; must divide `spp`.
    pub batches: usize,
    pub seed: u64,
}

struct SegmentLight {
    a: [f64; 3],
    b: [f64; 3],
    colour: [f64; 3],
}

struct Occluder {
    x: [f64; 2],
    y: [f64; 2],
    z: f64,
}

/// The scene (see the module documentation). Resolution-independent: it lives on the unit square.
pub struct SoftShadowScene {
    lights: [SegmentLight; 2],
    occluders: [Occluder; 3],
}

impl Default for SoftShadowScene {
    fn default() -> Self {
        SoftShadowScene {
            lights: [
                SegmentLight { a: [0.20, 0.15, 1.0], b: [0.55, 0.30, 1.0], colour: [1.6, 1.3, 0.95] },
                SegmentLight { a: [-0.8, 0.9, 1.4], b: [1.8, 0.9, 1.4], colour: [0.45, 0.7, 1.3] },
            ],
            occluders: [
                Occluder { x: [0.30, 0.72], y: [0.44, 0.52], z: 0.35 },
                Occluder { x: [0.66, 0.84], y: [0.70, 0.88], z: 0.20 },
                Occluder { x: [0.08, 0.18], y: [0.70, 0.95], z: 0.50 },
            ],
        }
    }
}

const CHECKER: f64 = 0.125;
const STRIPES: f64 = 0.03;
const ALBEDO: [[f64; 3]; 3] = [[0.50, 0.46, 0.40], [0.28, 0.22, 0.16], [0.10, 0.12, 0.16]];
const QUADRATURE: usize = 2048;
const TAG_PT: u64 = 0x7074;
const TAG_CRN: u64 = 0x63726e;

/// A ±1 square wave of period `p`.
fn square(t: f64, p: f64) -> f64 {
    if (t / p).rem_euclid(1.0) < 0.5 {
        1.0
    } else {
        -1.0
    }
}

/// The exact mean of `square(·, p)` over `[a, b]` (its antiderivative is a triangle wave).
fn square_mean(a: f64, b: f64, p: f64) -> f64 {
    let tri = |t: f64| {
        let f = (t / p).rem_euclid(1.0);
        p * f.min(1.0 - f)
    };
    (tri(b) - tri(a)) / (b - a)
}

impl SoftShadowScene {
    fn normal(&self, u: f64, v: f64) -> [f64; 3] {
        let slope = if v > 0.62 { 0.5 * (2.0 * std::f64::consts::PI * u / 0.125).sin() } else { 0.0 };
        let len = (1.0 + slope * slope).sqrt();
        [-slope / len, 0.0, 1.0 / len]
    }

    fn albedo_at(&self, u: f64, v: f64) -> [f64; 3] {
        let (chk, str) = (square(u, CHECKER) * square(v, CHECKER), square(u, STRIPES));
        std::array::from_fn(|c| ALBEDO[0][c] + ALBEDO[1][c] * chk + ALBEDO[2][c] * str)
    }

    /// The albedo averaged over the pixel footprint `[u0,u1]×[v0,v1]` (exact).
    fn albedo_mean(&self, u0: f64, u1: f64, v0: f64, v1: f64) -> [f64; 3] {
        let chk = square_mean(u0, u1, CHECKER) * square_mean(v0, v1, CHECKER);
        let str = square_mean(u0, u1, STRIPES);
        std::array::from_fn(|c| ALBEDO[0][c] + ALBEDO[1][c] * chk + ALBEDO[2][c] * str)
    }

    /// Irradiance (times colour) at ground point (u, v) from light `li` at parameter t ∈ [0,1],
    /// divided by the uniform pdf of t.
    fn light_sample(&self, li: usize, u: f64, v: f64, n: &[f64; 3], t: f64) -> [f64; 3] {
        let l = &self.lights[li];
        let q: [f64; 3] = std::array::from_fn(|i| l.a[i] + t * (l.b[i] - l.a[i]));
        let d = [q[0] - u, q[1] - v, q[2]];
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let dist = d2.sqrt();
        let cos_p = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / dist;
        if cos_p <= 0.0 {
            return [0.0; 3];
        }
        for o in &self.occluders {
            let s = o.z / q[2];
            let (x, y) = (u + s * d[0], v + s * d[1]);
            if x >= o.x[0] && x <= o.x[1] && y >= o.y[0] && y <= o.y[1] {
                return [0.0; 3];
            }
        }
        let len = ((l.b[0] - l.a[0]).powi(2) + (l.b[1] - l.a[1]).powi(2) + (l.b[2] - l.a[2]).powi(2)).sqrt();
        let g = cos_p * (q[2] / dist) / d2 * len;
        std::array::from_fn(|c| l.colour[c] * g)
    }

    /// One sample: four uniform numbers (jitter x, jitter y, key light, sky light).
    fn sample(&self, x: usize, y: usize, w: usize, h: usize, r: [f64; 4]) -> [f64; 3] {
        let (uc, vc) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
        let a = self.albedo_at((x as f64 + r[0]) / w as f64, (y as f64 + r[1]) / h as f64);
        let n = self.normal(uc, vc);
        let k = self.light_sample(0, uc, vc, &n, r[2]);
        let s = self.light_sample(1, uc, vc, &n, r[3]);
        std::array::from_fn(|c| a[c] * (k[c] + s[c]))
    }

    /// The exact expected pixel values.
    pub fn reference(&self, width: usize, height: usize) -> Image {
        let pixels = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let (w, h) = (width as f64, height as f64);
                let (uc, vc) = ((x as f64 + 0.5) / w, (y as f64 + 0.5) / h);
                let n = self.normal(uc, vc);
                let mut e = [0.0f64; 3];
                for li in 0..2 {
                    for q in 0..QUADRATURE {
                        let v = self.light_sample(li, uc, vc, &n, (q as f64 + 0.5) / QUADRATURE as f64);
                        for c in 0..3 {
                            e[c] += v[c] / QUADRATURE as f64;
                        }
                    }
                }
                let a = self.albedo_mean(x as f64 / w, (x + 1) as f64 / w, y as f64 / h, (y + 1) as f64 / h);
                std::array::from_fn(|c| (a[c] * e[c]) as f32)
            })
            .collect();
        Image { width, height, pixels }
    }

    fn check(spec: &RenderSpec) -> Result<(), ReconError> {
        if spec.width == 0 || spec.height == 0 {
            return Err(ReconError::option("size", format!("{}x{}", spec.width, spec.height), "must be at least 1x1"));
        }
        if spec.batches == 0 || spec.spp == 0 || !(spec.spp as usize).is_multiple_of(spec.batches) {
            return Err(ReconError::option("batches", spec.batches, format!("must be positive and divide spp = {}", spec.spp)));
        }
        Ok(())
    }

    /// A stream; `crn` shares sample `s`'s random numbers across pixels, otherwise `stream`
    /// selects one of many independent PT streams.
    fn stream(&self, spec: &RenderSpec, crn: bool, stream: u64) -> Stream {
        let (w, h, b) = (spec.width, spec.height, spec.batches);
        let per = spec.spp as usize / b;
        let key = if crn { hash4(spec.seed, TAG_CRN, 0, 0) } else { hash4(spec.seed, TAG_PT, stream, 0) };
        let rows: Vec<Vec<[f32; 3]>> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut out = vec![[0.0f32; 3]; w * b];
                for x in 0..w {
                    let pixel = if crn { 0 } else { (y * w + x) as u64 };
                    for bi in 0..b {
                        let mut acc = [0.0f64; 3];
                        for s in bi * per..(bi + 1) * per {
                            let r = std::array::from_fn(|d| uniform(hash4(key, pixel, s as u64, d as u64)));
                            let v = self.sample(x, y, w, h, r);
                            for c in 0..3 {
                                acc[c] += v[c];
                            }
                        }
                        out[bi * w + x] = std::array::from_fn(|c| (acc[c] / per as f64) as f32);
                    }
                }
                out
            })
            .collect();
        let batches = (0..b)
            .map(|bi| Image { width: w, height: h, pixels: rows.iter().flat_map(|r| r[bi * w..(bi + 1) * w].iter().copied()).collect() })
            .collect();
        Stream::from_batches(batches)
    }

    /// Renders the paired PT and CRN streams with features.
    pub fn render(&self, spec: &RenderSpec) -> Result<StreamSet, ReconError> {
        Self::check(spec)?;
        let (w, h) = (spec.width, spec.height);
        let albedo = Image::from_fn(w, h, |x, y| {
            let (fw, fh) = (w as f64, h as f64);
            self.albedo_mean(x as f64 / fw, (x + 1) as f64 / fw, y as f64 / fh, (y + 1) as f64 / fh).map(|v| v as f32)
        });
        let normal = Image::from_fn(w, h, |x, y| self.normal((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64).map(|v| v as f32));
        Ok(StreamSet {
            width: w,
            height: h,
            pt: self.stream(spec, false, 0),
            crn: self.stream(spec, true, 0),
            features: Some(Features { albedo, normal, depth: vec![1.0; w * h] }),
            meta: StreamMeta {
                spp: spec.spp,
                seed: spec.seed,
                max_depth: 1,
                scene: "synthetic:soft-shadow".into(),
                version: env!("CARGO_PKG_VERSION").into(),
                non_finite_samples: 0,
                ..Default::default()
            },
        })
    }

    /// Another PT stream, independent of the one in [`render`](Self::render) for `stream ≥ 1`
    /// (e.g. to form "PT at 2n" for equal-sample comparisons).
    pub fn render_pt(&self, spec: &RenderSpec, stream: u64) -> Result<Stream, ReconError> {
        Self::check(spec)?;
        Ok(self.stream(spec, false, stream))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_mean_matches_fine_quadrature() {
        for (a, b) in [(0.0, 0.01), (0.05, 0.09), (0.3, 0.3317), (0.99, 1.07)] {
            let n = 200_000;
            let q: f64 = (0..n).map(|i| square(a + (b - a) * (i as f64 + 0.5) / n as f64, 0.03)).sum::<f64>() / n as f64;
            assert!((square_mean(a, b, 0.03) - q).abs() < 1e-4, "{a} {b}");
        }
    }

    #[test]
    fn streams_are_unbiased_for_the_reference() {
        // S = 400 independent seeds, every channel. Per pixel and channel the error over seeds
        // e = x − r has mean ē and standard error se = sd/√S.
        // - PT pixels are independent (own random numbers), so per channel T = Σ_i (ē_i/se_i)²
        //   is a sum of N independent t² variables with ν = S − 1 degrees of freedom: mean
        //   ν/(ν−2), variance 2ν²(ν−1)/((ν−2)²(ν−4)) each. Required: |T − E T| < 5·sd(T).
        //   A bias of b standard errors in every pixel adds ≈ N·b² to T: with N = 1024 (5·sd(T)
        //   = 228), b ≈ 0.5, i.e. 2.5% of one render's per-pixel noise, of either sign.
        // - CRN pixels share their random numbers, so their errors are correlated and T has no
        //   such null distribution; instead the mean error over the image and over each
        //   quadrant, whose spread is measured across the independent seeds, must be within
        //   5 standard errors of zero (as for PT). The image mean's standard error is 0.2% of
        //   the image mean here (channel 0), so a CRN bias of ≈ 1% is detected.
        let scene = SoftShadowScene::default();
        let (w, h, seeds) = (32usize, 32usize, 400u64);
        let spec = RenderSpec { width: w, height: h, spp: 16, batches: 1, seed: 0 };
        let r = scene.reference(w, h);
        let n = w * h;
        // Per stream: per pixel-channel Σe and Σe², and per seed the region means.
        // (name, columns, rows); a region's pixel list is computed once.
        let regions = [
            ("image", 0..w, 0..h),
            ("top left", 0..w / 2, 0..h / 2),
            ("top right", w / 2..w, 0..h / 2),
            ("bottom left", 0..w / 2, h / 2..h),
            ("bottom right", w / 2..w, h / 2..h),
        ];
        let members: Vec<Vec<usize>> =
            regions.iter().map(|(_, xs, ys)| (0..n).filter(|i| xs.contains(&(i % w)) && ys.contains(&(i / w))).collect()).collect();
        let mut sum = [vec![[0.0f64; 3]; n], vec![[0.0f64; 3]; n]];
        let mut sum2 = [vec![[0.0f64; 3]; n], vec![[0.0f64; 3]; n]];
        let mut region_means = [vec![], vec![]];
        for s in 0..seeds {
            let set = scene.render(&RenderSpec { seed: 1000 + s, ..spec.clone() }).unwrap();
            for (k, im) in [&set.pt.mean, &set.crn.mean].into_iter().enumerate() {
                let e: Vec<[f64; 3]> =
                    im.pixels.iter().zip(&r.pixels).map(|(a, b)| std::array::from_fn(|c| (a[c] - b[c]) as f64)).collect();
                for i in 0..n {
                    for c in 0..3 {
                        sum[k][i][c] += e[i][c];
                        sum2[k][i][c] += e[i][c] * e[i][c];
                    }
                }
                let per_region: Vec<[f64; 3]> =
                    members.iter().map(|px| std::array::from_fn(|c| px.iter().map(|i| e[*i][c]).sum::<f64>() / px.len() as f64)).collect();
                region_means[k].push(per_region);
            }
        }
        let sf = seeds as f64;
        for (k, name) in ["pt", "crn"].iter().enumerate() {
            for (ri, (region, _, _)) in regions.iter().enumerate() {
                for c in 0..3 {
                    let v: Vec<f64> = region_means[k].iter().map(|m| m[ri][c]).collect();
                    let mean = v.iter().sum::<f64>() / sf;
                    let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (sf - 1.0) / sf).sqrt();
                    assert!(se > 0.0 && mean.abs() < 5.0 * se, "{name}, {region}, channel {c}: mean error {mean:.3e} ± {se:.3e}");
                }
            }
        }
        let nu = sf - 1.0;
        let (m1, v1) = (nu / (nu - 2.0), 2.0 * nu * nu * (nu - 1.0) / ((nu - 2.0).powi(2) * (nu - 4.0)));
        for c in 0..3 {
            let t: f64 = (0..n)
                .map(|i| {
                    let mean = sum[0][i][c] / sf;
                    let var = (sum2[0][i][c] - sf * mean * mean) / (sf - 1.0);
                    assert!(var > 0.0, "PT pixel {i} channel {c} has no variance");
                    mean * mean / (var / sf)
                })
                .sum();
            let (expect, sd) = (n as f64 * m1, (n as f64 * v1).sqrt());
            assert!((t - expect).abs() < 5.0 * sd, "PT channel {c}: Σ(ē/se)² = {t:.1}, expected {expect:.1} ± {sd:.1}");
        }
    }

    #[test]
    fn crn_errors_are_correlated_between_neighbours_and_pt_errors_are_not() {
        let scene = SoftShadowScene::default();
        let spec = RenderSpec { width: 32, height: 32, spp: 8, batches: 8, seed: 9 };
        let set = scene.render(&spec).unwrap();
        let r = scene.reference(32, 32);
        let corr = |im: &Image| {
            let e: Vec<f64> = im.pixels.iter().zip(&r.pixels).map(|(a, b)| (a[0] - b[0]) as f64).collect();
            let (mut num, mut den) = (0.0, 0.0);
            for y in 0..32 {
                for x in 0..31 {
                    num += e[y * 32 + x] * e[y * 32 + x + 1];
                    den += e[y * 32 + x].powi(2);
                }
            }
            num / den
        };
        let (cp, cc) = (corr(&set.pt.mean), corr(&set.crn.mean));
        assert!(cc > 0.5, "CRN neighbour correlation {cc}");
        assert!(cp.abs() < 0.2, "PT neighbour correlation {cp}");
    }
}

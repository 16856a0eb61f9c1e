//! `iduw`: input-dependent uncorrelated weighting (Back et al. 2023), as described in
//! `method.md` (from their public code; the description, not the code, is what we follow).
//!
//! Per pixel `c` and channel, over a `W×W` window without the centre (mirrored at borders):
//! `out_c = h̄_c + 1/(W²−1) · Σ_{i≠c} w_i [(ḡ_c − ḡ_i) − (h̄_c − h̄_i)]`,
//! `w_i = exp(−γ · m · v_i)`, with `v_i` the squared difference of the two half-buffer
//! estimates of `ḡ_c − ḡ_i` and `m` the spp of a half-buffer. The four sub-buffers are means
//! of consecutive quarters of the batches; half A = sub-buffers 0 and 1, half B = 2 and 3.
//!
//! γ is chosen per image from a grid by minimising the image mean of
//! `(out^A − out^B)² / (P̄² + 0.01)`, where `out^A` is built from half A alone (its weights from
//! sub-buffers 0 vs 1, `m` = spp/4), `out^B` likewise from half B, and `P̄` is the window mean of
//! the PT image. Our one deviation for CPU cost: on large images the criterion is evaluated on a
//! regular sub-lattice of pixels (≥ 64k of them), an unbiased estimate of the image mean.
use super::finish;
use crate::batch_stats::group_means;
use crate::fast_exp::exp_neg;
use crate::input::BatchNeed;
use crate::window::mirror;
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use cvtrace_streams::Image;
use rayon::prelude::*;
use std::time::Instant;

/// The γ grid of the public IDUW code.
pub const GAMMA_GRID: [f32; 10] = [0.01, 0.025, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5, 2.0, 2.5];
const MAX_WINDOW: usize = 31;
/// Pixels used for γ selection on large images (the lattice stride is chosen to keep about this many).
const SELECTION_PIXELS: usize = 65_536;

#[derive(Clone, Debug, PartialEq)]
pub struct IduwOptions {
    /// Window side (odd).
    pub window: usize,
    /// Candidate γ values.
    pub gammas: Vec<f32>,
    /// A fixed γ, skipping the selection.
    pub gamma: Option<f32>,
    /// Stride of the γ-selection lattice; 0 picks one that keeps ≈ 65k pixels.
    pub selection_stride: usize,
}

impl Default for IduwOptions {
    fn default() -> Self {
        IduwOptions { window: 15, gammas: GAMMA_GRID.to_vec(), gamma: None, selection_stride: 0 }
    }
}

impl IduwOptions {
    pub fn validate(&self) -> Result<(), ReconError> {
        if self.window < 3 || self.window % 2 == 0 || self.window > MAX_WINDOW {
            return Err(ReconError::option("iduw-window", self.window, format!("must be odd, between 3 and {MAX_WINDOW}")));
        }
        if self.gammas.is_empty() {
            return Err(ReconError::option("iduw-gammas", "(empty)", "give at least one γ"));
        }
        for g in self.gammas.iter().chain(self.gamma.iter()) {
            if !(*g >= 0.0 && g.is_finite()) {
                return Err(ReconError::option("iduw-gamma", g, "γ must be a finite number ≥ 0"));
            }
        }
        Ok(())
    }
}

#[derive(Clone, Debug)]
pub struct Iduw {
    options: IduwOptions,
}

/// One way to combine: the estimates `h`, `g`, and the two CRN halves `x`, `y` whose
/// disagreement sets the weights, with `m` samples per half.
struct Pass<'a> {
    h: &'a [[f32; 3]],
    g: &'a [[f32; 3]],
    x: &'a [[f32; 3]],
    y: &'a [[f32; 3]],
    m: f32,
}

impl Pass<'_> {
    /// Fills `t_i = m·v_i` and `d_i = (g_c − g_i) − (h_c − h_i)` for the neighbours `nb`.
    #[inline]
    fn gather(&self, c: usize, nb: &[u32], ch: usize, t: &mut [f32], d: &mut [f32]) {
        let (hc, gc, xc, yc) = (self.h[c][ch], self.g[c][ch], self.x[c][ch], self.y[c][ch]);
        for ((&i, ti), di) in nb.iter().zip(t.iter_mut()).zip(d.iter_mut()) {
            let i = i as usize;
            let v = (xc - self.x[i][ch]) - (yc - self.y[i][ch]);
            *ti = self.m * v * v;
            *di = (gc - self.g[i][ch]) - (hc - self.h[i][ch]);
        }
    }
}

/// `(Σ exp(−γ t_i) d_i, Σ exp(−γ t_i))` with eight partial sums (vectorises, fixed order).
#[inline]
fn weighted(t: &[f32], d: &[f32], gamma: f32) -> (f32, f32) {
    let mut acc = [0.0f32; 8];
    let mut wacc = [0.0f32; 8];
    let (tc, dc) = (t.chunks_exact(8), d.chunks_exact(8));
    let (tr, dr) = (tc.remainder(), dc.remainder());
    for (t8, d8) in tc.zip(dc) {
        for l in 0..8 {
            let w = exp_neg(-gamma * t8[l]);
            acc[l] += w * d8[l];
            wacc[l] += w;
        }
    }
    for (l, (tv, dv)) in tr.iter().zip(dr).enumerate() {
        let w = exp_neg(-gamma * tv);
        acc[l] += w * dv;
        wacc[l] += w;
    }
    let sum = |a: [f32; 8]| ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
    (sum(acc), sum(wacc))
}

/// Indices of the mirrored window around (x, y), centre position excluded.
fn neighbours(x: usize, y: usize, w: usize, h: usize, radius: isize, out: &mut Vec<u32>) {
    out.clear();
    for dy in -radius..=radius {
        let yy = mirror(y as isize + dy, h);
        for dx in -radius..=radius {
            if dx == 0 && dy == 0 {
                continue;
            }
            out.push((yy * w + mirror(x as isize + dx, w)) as u32);
        }
    }
}

/// Per-task buffers (reused for every pixel).
struct Scratch {
    nb: Vec<u32>,
    t: Vec<f32>,
    d: Vec<f32>,
    t2: Vec<f32>,
    d2: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch { nb: Vec::with_capacity(n), t: vec![0.0; n], d: vec![0.0; n], t2: vec![0.0; n], d2: vec![0.0; n] }
    }
}

fn average(a: &Image, b: &Image) -> Vec<[f32; 3]> {
    a.pixels.iter().zip(&b.pixels).map(|(p, q)| std::array::from_fn(|c| 0.5 * (p[c] + q[c]))).collect()
}

/// Everything derived from the input that the passes read.
struct Prepared {
    pt_halves: [Vec<[f32; 3]>; 2],
    crn_halves: [Vec<[f32; 3]>; 2],
    crn_subs: Vec<Image>,
    spp: f32,
}

impl Iduw {
    pub fn new(options: IduwOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(Iduw { options })
    }

    pub fn options(&self) -> &IduwOptions {
        &self.options
    }

    fn prepare(&self, input: &Input) -> Result<Prepared, ReconError> {
        input.check(self.name(), &self.needs())?;
        let set = input.streams;
        let pt_subs = group_means(&set.pt, 4);
        let crn_subs = group_means(&set.crn, 4);
        Ok(Prepared {
            pt_halves: [average(&pt_subs[0], &pt_subs[1]), average(&pt_subs[2], &pt_subs[3])],
            crn_halves: [average(&crn_subs[0], &crn_subs[1]), average(&crn_subs[2], &crn_subs[3])],
            crn_subs,
            spp: set.meta.spp as f32,
        })
    }

    fn stride(&self, w: usize, h: usize) -> usize {
        match self.options.selection_stride {
            0 => (((w * h) as f64 / SELECTION_PIXELS as f64).sqrt().floor() as usize).max(1),
            s => s,
        }
    }

    /// The selection criterion for every γ of the grid, as (γ, criterion) pairs, and the
    /// number of pixels it was evaluated on.
    pub fn gamma_criteria(&self, input: &Input) -> Result<(Vec<(f32, f64)>, usize), ReconError> {
        let p = self.prepare(input)?;
        Ok(self.criteria(input, &p))
    }

    fn criteria(&self, input: &Input, p: &Prepared) -> (Vec<(f32, f64)>, usize) {
        let set = input.streams;
        let (w, h) = (set.width, set.height);
        let win = self.options.window;
        let radius = (win / 2) as isize;
        let gammas = &self.options.gammas;
        let stride = self.stride(w, h);
        let (xs, ys): (Vec<usize>, Vec<usize>) = ((stride / 2..w).step_by(stride).collect(), (stride / 2..h).step_by(stride).collect());
        let s = &p.crn_subs;
        let halves = [
            Pass { h: &p.pt_halves[0], g: &p.crn_halves[0], x: &s[0].pixels, y: &s[1].pixels, m: p.spp / 4.0 },
            Pass { h: &p.pt_halves[1], g: &p.crn_halves[1], x: &s[2].pixels, y: &s[3].pixels, m: p.spp / 4.0 },
        ];
        let pt = &set.pt.mean.pixels;
        let norm = 1.0 / (win * win - 1) as f32;
        let rows: Vec<Vec<f64>> = ys
            .par_iter()
            .map_init(
                || Scratch::new(win * win),
                |sc, &y| {
                    let mut crit = vec![0.0f64; gammas.len()];
                    for &x in &xs {
                        let c = y * w + x;
                        neighbours(x, y, w, h, radius, &mut sc.nb);
                        for ch in 0..3 {
                            let pbar = (pt[c][ch] + sc.nb.iter().map(|&i| pt[i as usize][ch]).sum::<f32>()) / (win * win) as f32;
                            let denom = (pbar * pbar) as f64 + 0.01;
                            halves[0].gather(c, &sc.nb, ch, &mut sc.t, &mut sc.d);
                            halves[1].gather(c, &sc.nb, ch, &mut sc.t2, &mut sc.d2);
                            let n = sc.nb.len();
                            for (gi, &gamma) in gammas.iter().enumerate() {
                                let oa = halves[0].h[c][ch] + weighted(&sc.t[..n], &sc.d[..n], gamma).0 * norm;
                                let ob = halves[1].h[c][ch] + weighted(&sc.t2[..n], &sc.d2[..n], gamma).0 * norm;
                                crit[gi] += ((oa - ob) as f64).powi(2) / denom;
                            }
                        }
                    }
                    crit
                },
            )
            .collect();
        let count = xs.len() * ys.len();
        let crit = (0..gammas.len()).map(|gi| rows.iter().map(|r| r[gi]).sum::<f64>() / (3 * count).max(1) as f64);
        (gammas.iter().copied().zip(crit).collect(), count)
    }
}

impl Estimator for Iduw {
    fn method(&self) -> Method {
        Method::Iduw
    }

    fn needs(&self) -> Needs {
        Needs { batches: BatchNeed::MultipleOf(4), features: None, reference: false, spp: true }
    }

    fn settings(&self) -> Vec<(&'static str, String)> {
        let o = &self.options;
        let grid = o.gammas.iter().map(|g| g.to_string()).collect::<Vec<_>>().join(",");
        vec![
            ("window", o.window.to_string()),
            ("gammas", grid),
            ("gamma_fixed", o.gamma.map(|g| g.to_string()).unwrap_or_else(|| "no".into())),
            ("selection_stride", o.selection_stride.to_string()),
        ]
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        let p = self.prepare(input)?;
        let set = input.streams;
        let (w, h) = (set.width, set.height);
        let mut d = Diagnostics::default();
        let gamma = match self.options.gamma {
            Some(g) => g,
            None => {
                let (crit, count) = self.criteria(input, &p);
                // First minimum, so ties resolve to the earlier grid value.
                let (best, (g, value)) =
                    crit.iter().enumerate().fold((0, crit[0]), |acc, (i, c)| if c.1 < acc.1 .1 { (i, *c) } else { acc });
                d.int("gamma_index", best as i64).float("gamma_criterion", value).int("selection_pixels", count as i64);
                g
            }
        };
        let win = self.options.window;
        let radius = (win / 2) as isize;
        let norm = 1.0 / (win * win - 1) as f32;
        let full = Pass { h: &set.pt.mean.pixels, g: &set.crn.mean.pixels, x: &p.crn_halves[0], y: &p.crn_halves[1], m: p.spp / 2.0 };
        let mut image = Image::new(w, h);
        let mut wsum = vec![0.0f64; h];
        image.pixels.par_chunks_mut(w).zip(wsum.par_iter_mut()).enumerate().for_each_init(
            || Scratch::new(win * win),
            |sc, (y, (row, ws))| {
                for (x, px) in row.iter_mut().enumerate() {
                    let c = y * w + x;
                    neighbours(x, y, w, h, radius, &mut sc.nb);
                    let n = sc.nb.len();
                    for ch in 0..3 {
                        full.gather(c, &sc.nb, ch, &mut sc.t[..n], &mut sc.d[..n]);
                        let (acc, wt) = weighted(&sc.t[..n], &sc.d[..n], gamma);
                        px[ch] = full.h[c][ch] + acc * norm;
                        *ws += (wt * norm) as f64;
                    }
                }
            },
        );
        d.float("gamma", gamma as f64)
            .float("neighbour_weight_mean", wsum.iter().sum::<f64>() / (3 * w * h) as f64)
            .int("window", win as i64);
        Ok(finish(image, d, start))
    }
}

//! The image pass shared by `ours` and the `cv` baseline: per pixel, select the control
//! variates, gather their CRN batch deviations, solve for β (per channel or shared) and
//! combine `F̂_c = f̄_c − Σ β_i (ḡ_i − h̄_i)`.
//!
//! Rows run in parallel; each task owns its buffers, so nothing is allocated per pixel, and
//! every pixel's arithmetic is independent of the others, so the image is bit-identical for
//! any thread count. Statistics are kept per row and summed in row order for the same reason.
//!
//! Per-channel solves with fewer batches than control variates (the default) use the
//! fixed-width [`Panel`] kernel, compiled a second time with AVX2 and picked at run time.
//! Without FMA contraction both builds do the same IEEE operations, so they agree bit for bit.
use crate::batch_stats::BatchCube;
use crate::control_variate::combine;
use crate::floor::{blend_towards_centre, Floor, FloorMode};
use crate::panel::{Panel, Rows};
use crate::penalty::Penalty;
use crate::selection::{SelectScratch, Selector};
use crate::simd::{Portable, Simd};
use crate::solve::{Form, Outcome, Workspace, MAX_BATCHES, MAX_K};
use cvtrace_streams::{Image, Stream, StreamSet};
use rayon::prelude::*;

pub struct CvPass<'a> {
    pub set: &'a StreamSet,
    pub selector: Selector<'a>,
    /// Largest set size the selector returns.
    pub k: usize,
    /// PT error estimates (`V_h` diagonal); `None` treats the PT means as exact (the baseline).
    pub errors: Option<&'a [[f32; 3]]>,
    pub penalty: Penalty,
    pub ridge: f64,
    pub shared: bool,
    /// Whether the selector puts the centre first in the set (ours) or leaves it out (cv).
    pub include_centre: bool,
    /// The noise floor on the CRN covariance (ours only: needs the centre first).
    pub floor: Option<Floor<'a>>,
    /// Cross-fitting: coefficients from one half of the batches, applied to the other half's
    /// CRN means, and the two results averaged (needs at least 4 batches).
    pub cross_fit: bool,
}

/// Sums over pixel-channel solves.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    pub solves: u64,
    pub centre_weight: f64,
    pub beta_sum: f64,
    pub regularised: u64,
    pub degenerate: u64,
    pub failed: u64,
    pub set_size: u64,
    pub pixels: u64,
}

impl PassStats {
    /// The shares every control-variate pass reports, per solved pixel-channel.
    pub fn report(&self, d: &mut crate::Diagnostics) {
        let solves = self.solves.max(1) as f64;
        d.float("beta_sum_mean", self.beta_sum / solves)
            .float("regularised_share", self.regularised as f64 / solves)
            .float("degenerate_share", self.degenerate as f64 / solves)
            .float("failed_share", self.failed as f64 / solves);
    }
}

impl PassStats {
    fn add(&mut self, o: &PassStats) {
        self.solves += o.solves;
        self.centre_weight += o.centre_weight;
        self.beta_sum += o.beta_sum;
        self.regularised += o.regularised;
        self.degenerate += o.degenerate;
        self.failed += o.failed;
        self.set_size += o.set_size;
        self.pixels += o.pixels;
    }

    fn record(&mut self, outcome: Outcome, beta: &mut [f64], include_centre: bool) {
        match outcome {
            Outcome::Solved => {}
            Outcome::Regularised => self.regularised += 1,
            Outcome::Degenerate => self.degenerate += 1,
            Outcome::Failed => {
                self.failed += 1;
                // Nothing to trust: the plain average of the two inputs when the centre is
                // in the set, the CRN value otherwise.
                beta.fill(0.0);
                if include_centre {
                    beta[0] = 0.5;
                }
            }
        }
        self.solves += 1;
        self.centre_weight += if include_centre { beta[0] } else { 0.0 };
        self.beta_sum += beta.iter().sum::<f64>();
    }
}

/// Per-task buffers. `P = 0` means the general f64 workspace (shared coefficients, or at
/// least as many batches as control variates).
struct Scratch<const P: usize> {
    select: SelectScratch,
    idx: [u32; MAX_K],
    gs: [f64; MAX_K],
    hs: [f64; MAX_K],
    gs3: [[f64; MAX_K]; 3],
    hs3: [[f64; MAX_K]; 3],
    panel: Option<Box<Panel<P>>>,
    ws: Option<Box<Workspace>>,
}

impl<const P: usize> Scratch<P> {
    fn new() -> Self {
        Scratch {
            select: SelectScratch::new(),
            idx: [0; MAX_K],
            gs: [0.0; MAX_K],
            hs: [0.0; MAX_K],
            gs3: [[0.0; MAX_K]; 3],
            hs3: [[0.0; MAX_K]; 3],
            panel: (P > 0).then(Panel::<P>::boxed),
            ws: (P == 0).then(Workspace::boxed),
        }
    }
}

/// The batches one set of coefficients is estimated from, and the CRN means it is applied to.
/// Without cross-fitting there is one half (all batches, the stream mean); with it, two
/// (batches `0..B/2` and `B/2..B`, each with its own mean), and the coefficients estimated on
/// one are applied to the other's means.
struct Half<'a> {
    cube: BatchCube,
    mean: &'a [[f32; 3]],
}

impl CvPass<'_> {
    pub fn run(&self) -> (Image, PassStats) {
        let b = self.set.batch_count();
        debug_assert!((2..=MAX_BATCHES).contains(&b));
        let crn = &self.set.crn;
        let split: Vec<Stream>;
        let parts: Vec<(&Stream, &[[f32; 3]])> = if self.cross_fit {
            let h = b / 2;
            split = vec![Stream::from_batches(crn.batches[..h].to_vec()), Stream::from_batches(crn.batches[h..2 * h].to_vec())];
            split.iter().map(|st| (st, st.mean.pixels.as_slice())).collect()
        } else {
            vec![(crn, crn.mean.pixels.as_slice())]
        };
        let bh = parts[0].0.batches.len();
        let s = 1.0 / (parts.len() * bh * (bh - 1)) as f64;
        let halves = |stride: usize| -> Vec<Half> {
            parts
                .iter()
                .map(|(st, mean)| {
                    let mut cube = BatchCube::deviations(st, stride);
                    if let Some(f) = self.floor.filter(|f| f.mode == FloorMode::Common) {
                        cube.rotate_and_floor(f.values, f.tau, s);
                    }
                    Half { cube, mean }
                })
                .collect()
        };
        if self.shared || bh >= self.k {
            return self.run_width::<0>(&halves(bh));
        }
        match bh {
            0..=8 => self.run_width::<8>(&halves(8)),
            9..=16 => self.run_width::<16>(&halves(16)),
            17..=32 => self.run_width::<32>(&halves(32)),
            _ => self.run_width::<64>(&halves(64)),
        }
    }

    fn run_width<const P: usize>(&self, halves: &[Half]) -> (Image, PassStats) {
        let (w, h) = (self.set.width, self.set.height);
        let mut image = Image::new(w, h);
        let mut rows = vec![PassStats::default(); h];
        image.pixels.par_chunks_mut(w).zip(rows.par_iter_mut()).enumerate().for_each_init(Scratch::<P>::new, |sc, (y, (row, st))| {
            #[cfg(target_arch = "x86_64")]
            if crate::simd::use_avx2() {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { self.row_avx2::<P>(halves, y, row, sc, st) };
                return;
            }
            self.row::<P, Portable>(halves, y, row, sc, st);
        });
        let mut total = PassStats::default();
        for r in &rows {
            total.add(r);
        }
        (image, total)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn row_avx2<const P: usize>(&self, halves: &[Half], y: usize, row: &mut [[f32; 3]], sc: &mut Scratch<P>, st: &mut PassStats) {
        self.row::<P, crate::simd::Avx2>(halves, y, row, sc, st);
    }

    #[inline(always)]
    fn row<const P: usize, S: Simd>(&self, halves: &[Half], y: usize, row: &mut [[f32; 3]], sc: &mut Scratch<P>, st: &mut PassStats) {
        for (x, px) in row.iter_mut().enumerate() {
            *px = self.pixel::<P, S>(halves, x, y, sc, st);
        }
    }

    /// `W` for control variate `i` of centre `c` in channel `ch` (summed over channels when shared).
    #[inline(always)]
    fn weight(&self, i: usize, c: usize, ch: usize) -> f64 {
        let Some(e) = self.errors else { return 0.0 };
        let (g, hm) = (&self.set.crn.mean.pixels, &self.set.pt.mean.pixels);
        let one = |ch: usize| {
            let (ei, ec) = (e[i][ch] as f64, e[c][ch] as f64);
            if i == c {
                ei
            } else if self.penalty == Penalty::Residual {
                let r = (hm[i][ch] - hm[c][ch]) as f64 - (g[i][ch] - g[c][ch]) as f64;
                self.penalty.apply(ei, ec, r)
            } else {
                self.penalty.apply(ei, ec, 0.0)
            }
        };
        if self.shared {
            one(0) + one(1) + one(2)
        } else {
            one(ch)
        }
    }

    #[inline(always)]
    fn pixel<const P: usize, S: Simd>(&self, halves: &[Half], x: usize, y: usize, sc: &mut Scratch<P>, st: &mut PassStats) -> [f32; 3] {
        let c = y * self.set.width + x;
        let n = self.selector.select(x, y, &mut sc.select, &mut sc.idx);
        let idx = &sc.idx[..n];
        let hm = &self.set.pt.mean.pixels;
        let nh = halves.len();
        let b = halves[0].cube.batches;
        // Covariances of the full CRN mean: with nh halves of b batches each, a half's batch
        // covariance Σd²/(b(b−1)) estimates the covariance of a half's mean, nh times that of
        // the full mean.
        let s = 1.0 / (nh * b * (b - 1)) as f64;
        st.pixels += 1;
        st.set_size += n as u64;
        if n == 0 {
            return self.set.crn.mean.pixels[c];
        }
        debug_assert!(self.floor.is_none() || (self.include_centre && idx[0] as usize == c));
        let mut acc = [0.0f64; 3];
        if let Some(p) = sc.panel.as_deref_mut() {
            for (hi, half) in halves.iter().enumerate() {
                let cube = &half.cube;
                let target = halves[(hi + 1) % nh].mean;
                let mut delta_c = [0.0f64; 3];
                let centre: [&[f32; P]; 3] = std::array::from_fn(|ch| cube.row_padded::<P>(c, ch));
                let mut rows = Rows { d: centre.map(|r| [r; MAX_K]), dc: centre };
                // One pass over the set gathers everything: rows, norms, weights and the values
                // the combination needs.
                for (j, &i) in idx.iter().enumerate() {
                    let i = i as usize;
                    let (gi, hi) = (target[i], hm[i]);
                    for ch in 0..3 {
                        rows.d[ch][j] = cube.row_padded::<P>(i, ch);
                        p.sq[ch][j] = cube.sq[i][ch];
                        sc.gs3[ch][j] = gi[ch] as f64;
                        sc.hs3[ch][j] = hi[ch] as f64;
                    }
                    p.w.iter_mut().enumerate().for_each(|(ch, w)| w[j] = self.weight(i, c, ch));
                    if let Some(f) = self.floor.filter(|f| f.mode == FloorMode::Independent) {
                        for ch in 0..3 {
                            let d = f.delta(f.values[i][ch] as f64, s * p.sq[ch][j] as f64);
                            p.w[ch][j] += d;
                            if j == 0 {
                                delta_c[ch] = d;
                            }
                        }
                    }
                }
                let outcomes = p.solve::<S>(&rows, n, s, self.ridge);
                for ch in 0..3 {
                    if matches!(outcomes[ch], Outcome::Solved | Outcome::Regularised) {
                        let winv = p.centre_winv(ch);
                        blend_towards_centre(&mut p.beta[ch][..n], delta_c[ch], winv);
                    }
                    let beta = &mut p.beta[ch][..n];
                    st.record(outcomes[ch], beta, self.include_centre);
                    acc[ch] += combine(target[c][ch] as f64, &sc.gs3[ch][..n], &sc.hs3[ch][..n], beta);
                }
            }
            return acc.map(|v| (v / nh as f64) as f32);
        }
        let ws = sc.ws.as_deref_mut().expect("general workspace");
        let channels: &[usize] = if self.shared { &[0] } else { &[0, 1, 2] };
        for (hi, half) in halves.iter().enumerate() {
            let cube = &half.cube;
            let target = halves[(hi + 1) % nh].mean;
            for &ch in channels {
                let m = if self.shared { 3 * b } else { b };
                let source = |i: usize| if self.shared { cube.pixel(i) } else { cube.row(i, ch) };
                for (j, &i) in idx.iter().enumerate() {
                    for (dst, v) in ws.d[j * m..(j + 1) * m].iter_mut().zip(source(i as usize)) {
                        *dst = *v as f64;
                    }
                    ws.w[j] = self.weight(i as usize, c, ch);
                }
                let mut delta_c = 0.0;
                if let Some(f) = self.floor.filter(|f| f.mode == FloorMode::Independent) {
                    for (j, &i) in idx.iter().enumerate() {
                        let v = f.values[i as usize];
                        let v = if self.shared { v.iter().map(|x| *x as f64).sum() } else { v[ch] as f64 };
                        let row = &ws.d[j * m..(j + 1) * m];
                        let d = f.delta(v, s * crate::solve::dot(row, row));
                        ws.w[j] += d;
                        if j == 0 {
                            delta_c = d;
                        }
                    }
                }
                for (dst, v) in ws.dc[..m].iter_mut().zip(source(c)) {
                    *dst = *v as f64;
                }
                let outcome = ws.solve(n, m, s, self.ridge, Form::Auto);
                if matches!(outcome, Outcome::Solved | Outcome::Regularised) {
                    blend_towards_centre(&mut ws.beta[..n], delta_c, 1.0 / (ws.w[0] + ws.lambda));
                }
                let beta = &mut ws.beta[..n];
                st.record(outcome, beta, self.include_centre);
                let out_channels: &[usize] = if self.shared { &[0, 1, 2] } else { std::slice::from_ref(&ch) };
                for &oc in out_channels {
                    for (j, &i) in idx.iter().enumerate() {
                        sc.gs[j] = target[i as usize][oc] as f64;
                        sc.hs[j] = hm[i as usize][oc] as f64;
                    }
                    acc[oc] += combine(target[c][oc] as f64, &sc.gs[..n], &sc.hs[..n], beta);
                }
            }
        }
        acc.map(|v| (v / nh as f64) as f32)
    }
}

//! The image pass shared by `ours` and the `cv` baseline: per pixel, select the control
//! variates, gather their CRN batch deviations, solve for β (per channel or shared) and
//! combine `F̂_c = f̄_c − Σ β_i (ḡ_i − h̄_i)`.
//!
//! With [`CentreFree`] set, the same pass also solves the centre-free system of the two-stage
//! estimate of `ours` on the pixel's selection minus the centre: a `Selector` asked for
//! `k − 1` pixels without the centre returns exactly the `k − 1` neighbours a `k`-pixel
//! selection with the centre returns, in the same order (it sorts the same unique keys with
//! the same `select_nth_unstable`), so selecting and gathering once gives both solves the
//! rows they would have gathered on their own, and the same bits.
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
use crate::panel::{Panel, Rows, System, MAX_SYSTEMS};
use crate::penalty::Penalty;
use crate::selection::{SelectScratch, Selector, MAX_SEARCH_WINDOW};
use crate::simd::{self, Kernel, Simd};
use crate::solve::{Form, Outcome, Workspace, MAX_BATCHES, MAX_K};
use crate::ReconError;
use cvtrace_streams::{Image, Stream, StreamSet};
use rayon::prelude::*;
use std::ops::Range;

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
    /// Which batches each set of coefficients is estimated from and applied to.
    pub folds: Folds,
    /// Also return each pixel's predicted variance (Eq. 7 at the chosen β).
    pub variance: bool,
    /// How the predicted variance's CRN part allows for β having been fitted to the same batches.
    pub dof: Dof,
    /// A second solve per pixel on the selection minus the centre (see [`CentreFree`]).
    pub centre_free: Option<CentreFree>,
}

/// The centre-free solve that [`CvPass`] can run next to its joint one: the control variates of
/// `cv` (`F̂_c = ḡ_c − Σ_{i≠c} β_i (ḡ_i − h̄_i)`) over the joint selection without the centre,
/// always with its predicted variance, from the CRN batches with the joint pass's `common` floor
/// (`floored`) or without any. It gives what a separate pass with `include_centre = false`,
/// `k − 1`, that floor and [`Folds::All`] gives.
/// Needs the centre first in the set, PT error estimates, [`Folds::All`] and the same solver as
/// the joint system (see [`CvPass::fuses`]).
#[derive(Clone, Copy, Debug)]
pub struct CentreFree {
    pub penalty: Penalty,
    pub ridge: f64,
    /// Solve on the joint pass's batch cube with its `common` floor column, so that the
    /// centre-free solve, like the joint one, does not read all-zero CRN batches as an exact
    /// CRN value. Without a `common` floor it makes no difference.
    pub floored: bool,
    /// The degrees-of-freedom allowance of its predicted variance.
    pub dof: Dof,
}

/// Checks the settings of a control-variate pass that `ours` and `cv` declare: `k` pixels per
/// set, centre included (at most [`MAX_K`] and what the window holds), an odd search window of
/// at most [`MAX_SEARCH_WINDOW`], and the ridge, reported under its command-line name
/// `ridge_option`.
pub fn check_selection(k: usize, search_window: usize, ridge: f64, ridge_option: &'static str) -> Result<(), ReconError> {
    if k == 0 || k > MAX_K {
        return Err(ReconError::option("k", k, format!("must be between 1 and {MAX_K}")));
    }
    if search_window == 0 || search_window.is_multiple_of(2) || search_window > MAX_SEARCH_WINDOW {
        return Err(ReconError::option("search-window", search_window, format!("must be odd, between 1 and {MAX_SEARCH_WINDOW}")));
    }
    if k > search_window * search_window {
        return Err(ReconError::option(
            "k",
            k,
            format!("cannot choose more pixels than the {search_window}x{search_window} search window holds; raise --search-window"),
        ));
    }
    if !(ridge >= 0.0 && ridge.is_finite()) {
        return Err(ReconError::option(ridge_option, ridge, "must be a finite number ≥ 0"));
    }
    Ok(())
}

/// What a pass returns: the image, its predicted variance when asked for, and the statistics.
pub struct PassOutput {
    pub image: Image,
    /// Per pixel and channel, `s·‖d_c − Σ β_j d_j‖² + Σ β_j² e_j`: the CRN batch covariance
    /// (with the floor, where one is set) and the PT error estimates `e` before the penalty,
    /// at the coefficients the pass used; averaged over the folds.
    pub variance: Option<Image>,
    pub stats: PassStats,
    /// The centre-free estimate, when [`CvPass::centre_free`] is set.
    pub centre_free: Option<CentreFreeOutput>,
}

/// The centre-free estimate of a pass: its image, predicted variance and statistics.
pub struct CentreFreeOutput {
    pub image: Image,
    pub variance: Image,
    pub stats: PassStats,
}

crate::named::named_enum! {
    /// How the CRN batches are split between estimating β and the CRN values β weights.
    pub enum Folds: "folds" {
        /// β from all batches, applied to the stream mean.
        All => "all",
        /// β from one half of the batches applied to the other half's mean, and vice versa,
        /// the two results averaged (needs an even batch count ≥ 4): the coefficients never
        /// see the values they weight.
        Halves => "halves",
    }
}

crate::named::named_enum! {
    /// The in-sample residual of the CRN batches underestimates the variance of `ḡ` at the fitted
    /// β, by the degrees of freedom `df = tr(H)` the fit spent of the `n` the batches have.
    pub enum Dof: "variance-dof" {
        /// The in-sample residual as it is.
        None => "none",
        /// Generalised cross-validation: `RSS / (1 − df/n)²`.
        Gcv => "gcv",
        /// Mallows' Cp: `RSS·(n + df)/(n − df)`.
        Mallows => "mallows",
        /// Leave-one-batch-out: `Σ_b (r_b / (1 − H_bb))²`, each batch's residual as the fit
        /// without it would leave it; unlike the two above it weighs a batch that carries the fit
        /// (a firefly in one batch) by its own leverage.
        Press => "press",
    }
}

impl Folds {
    /// Cross-fitting splits the batches into two equal halves, so it needs an even count.
    pub fn check(self, origin: &str, method: &'static str, batches: usize) -> Result<(), ReconError> {
        if self == Folds::Halves && batches % 2 == 1 {
            return Err(ReconError::BatchCount {
                origin: origin.to_string(),
                method,
                requirement: "an even number of".into(),
                found: batches,
                hint: "cross-fitting splits the batches into two equal halves; re-render with an even --batches or choose other folds"
                    .into(),
            });
        }
        Ok(())
    }

    /// The fewest batches the folds work with.
    pub fn min_batches(self) -> usize {
        match self {
            Folds::All => 2,
            Folds::Halves => 4,
        }
    }
}

impl Dof {
    /// The factor on the in-sample residual `rss` for `df` of `n`, or the leave-one-out
    /// residual `press` relative to it.
    fn factor(self, df: f64, n: f64, rss: f64, press: f64) -> f64 {
        let df = df.clamp(0.0, n - 0.5);
        match self {
            Dof::None => 1.0,
            Dof::Gcv => 1.0 / (1.0 - df / n).powi(2),
            Dof::Mallows => (n + df) / (n - df),
            Dof::Press if rss > 0.0 && press.is_finite() => press / rss,
            Dof::Press => 1.0,
        }
    }

    /// Whether the solve must find the trace of its hat matrix.
    fn wants_trace(self) -> bool {
        matches!(self, Dof::Gcv | Dof::Mallows)
    }

    /// Whether the solve must find its leave-one-out residual.
    fn wants_press(self) -> bool {
        self == Dof::Press
    }
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
        PassStats::settle(outcome, beta, include_centre);
        let centre = if include_centre { beta[0] } else { 0.0 };
        self.count(outcome, centre, beta.iter().sum::<f64>());
    }

    /// What a solve's β is taken to be: as solved, except where the solve failed.
    fn settle(outcome: Outcome, beta: &mut [f64], include_centre: bool) {
        if outcome == Outcome::Failed {
            // Nothing to trust: the plain average of the two inputs when the centre is in the
            // set, the CRN value otherwise.
            beta.fill(0.0);
            if include_centre {
                beta[0] = 0.5;
            }
        }
    }

    /// Counts a solve with its settled β: the centre's coefficient (0 without a centre) and
    /// `Σ β`.
    fn count(&mut self, outcome: Outcome, centre: f64, beta_sum: f64) {
        match outcome {
            Outcome::Solved | Outcome::Failed => {}
            Outcome::Regularised => self.regularised += 1,
            Outcome::Degenerate => self.degenerate += 1,
        }
        self.failed += u64::from(outcome == Outcome::Failed);
        self.solves += 1;
        self.centre_weight += centre;
        self.beta_sum += beta_sum;
    }
}

/// Per-task buffers. `P = 0` means the general f64 solve (shared coefficients, or at least as
/// many batches as control variates).
struct Scratch<'h, const P: usize> {
    select: SelectScratch,
    idx: [u32; MAX_K],
    gs3: [[f64; MAX_K]; 3],
    hs3: [[f64; MAX_K]; 3],
    /// The joint solve's three channels, and the centre-free one's next to them.
    panel: Option<Box<Panel<P>>>,
    /// The panel's rows, overwritten pixel by pixel (as far as each pixel's set reaches).
    rows: Option<Box<Rows<'h, P>>>,
    general: Option<General>,
}

/// The buffers of the general solve: its workspace, and one channel's CRN and PT means of the
/// control variates.
struct General {
    ws: Box<Workspace>,
    gs: [f64; MAX_K],
    hs: [f64; MAX_K],
}

impl<'h, const P: usize> Scratch<'h, P> {
    /// `cube` is any cube of the pass; its first row fills the rows until a pixel sets them.
    fn new(cube: &'h BatchCube) -> Self {
        Scratch {
            select: SelectScratch::new(),
            idx: [0; MAX_K],
            gs3: [[0.0; MAX_K]; 3],
            hs3: [[0.0; MAX_K]; 3],
            panel: (P > 0).then(Panel::<P>::boxed),
            rows: (P > 0).then(|| {
                let r = cube.row_padded::<P>(0, 0);
                Box::new(Rows { d: [[r; MAX_K]; MAX_SYSTEMS], dc: [r; MAX_SYSTEMS] })
            }),
            general: (P == 0).then(|| General { ws: Workspace::boxed(), gs: [0.0; MAX_K], hs: [0.0; MAX_K] }),
        }
    }
}

/// The batches one set of coefficients is estimated from (as a deviation cube), and the CRN
/// values it is applied to; the pass averages the folds' results with equal weights.
struct Half<'a> {
    cube: BatchCube,
    mean: &'a [[f32; 3]],
    /// The deviations without the floor, for the centre-free solve, when `cube` has a
    /// `common` floor.
    plain: Option<BatchCube>,
}

impl Half<'_> {
    fn plain(&self) -> &BatchCube {
        self.plain.as_ref().unwrap_or(&self.cube)
    }
}

/// The deviations one solve's coefficients are estimated from, and the CRN values they weight:
/// a [`Half`]'s cube (or, for the centre-free solve, its deviations without the floor) and mean.
#[derive(Clone, Copy)]
struct Fold<'a> {
    cube: &'a BatchCube,
    target: &'a [[f32; 3]],
}

/// One stage's results for a pixel: its sums over the folds (the combination and its predicted
/// variance, per channel), and the row's statistics its solves are counted in.
struct Tally<'s> {
    value: [f64; 3],
    variance: [f64; 3],
    stats: &'s mut PassStats,
}

impl<'s> Tally<'s> {
    fn new(stats: &'s mut PassStats) -> Self {
        Tally { value: [0.0; 3], variance: [0.0; 3], stats }
    }

    /// The average over `folds` folds: the pixel's value and predicted variance.
    fn finish(&self, folds: usize) -> ([f32; 3], [f32; 3]) {
        (self.value.map(|v| (v / folds as f64) as f32), self.variance.map(|v| (v / folds as f64) as f32))
    }
}

/// What the joint and the centre-free solves of a pixel do differently.
#[derive(Clone, Copy)]
struct Stage<'f> {
    penalty: Penalty,
    ridge: f64,
    floor: Option<Floor<'f>>,
    include_centre: bool,
    variance: bool,
    dof: Dof,
}

/// One image row of the outputs: the joint estimate and the centre-free one, of which the
/// pixels `xs` are computed.
struct RowOut<'r> {
    xs: Range<usize>,
    image: &'r mut [[f32; 3]],
    variance: &'r mut [[f32; 3]],
    free_image: &'r mut [[f32; 3]],
    free_variance: &'r mut [[f32; 3]],
}

/// A pixel's joint and centre-free estimates, each (value, predicted variance).
type PixelOut = [([f32; 3], [f32; 3]); 2];

/// One image row of a pass (its pixels `out.xs`), with the task's buffers and the row's
/// statistics (joint, centre-free): what [`simd::dispatch`] runs.
struct Row<'a, 'h, const P: usize> {
    pass: &'a CvPass<'a>,
    halves: &'h [Half<'h>],
    y: usize,
    out: RowOut<'a>,
    sc: &'a mut Scratch<'h, P>,
    st: &'a mut [PassStats; 2],
}

impl<const P: usize> Kernel for Row<'_, '_, P> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd>(self, simd: S) {
        let Row { pass, halves, y, out, sc, st } = self;
        let fused = pass.centre_free.is_some();
        for x in out.xs.clone() {
            let [(value, variance), (free_value, free_variance)] = pass.pixel::<P, S>(simd, halves, x, y, sc, st);
            out.image[x] = value;
            out.variance[x] = variance;
            if fused {
                out.free_image[x] = free_value;
                out.free_variance[x] = free_variance;
            }
        }
    }
}

/// Columns per strip of the pass (see [`CvPass::run_width`]).
const STRIP: usize = 64;

/// `s` of `V = s·Σ d·dᵀ`: the covariance of the full mean of `batches` batches estimated from
/// the deviations of `m` of them (a single batch's covariance is `Σ d·dᵀ/(m − 1)`).
fn scale(batches: usize, m: usize) -> f64 {
    1.0 / (batches * (m - 1)) as f64
}

impl CvPass<'_> {
    /// Whether [`CvPass::centre_free`] can share this pass: the centre first, PT error
    /// estimates, all batches, and the same solver as a separate centre-free pass would pick
    /// (the panel kernel needs fewer batches than control variates, so with `B = k − 1`
    /// the joint system takes the panel and the centre-free one the general solver).
    pub fn fuses(&self) -> bool {
        let b = self.set.batch_count();
        self.include_centre
            && self.errors.is_some()
            && self.folds == Folds::All
            && self.k >= 2
            && (self.shared || b >= self.k) == (self.shared || b >= self.k - 1)
    }

    pub fn run(&self) -> PassOutput {
        let b = self.set.batch_count();
        debug_assert!((2..=MAX_BATCHES).contains(&b));
        assert!(self.centre_free.is_none() || self.fuses(), "the centre-free solve cannot share this pass (see CvPass::fuses)");
        let crn = &self.set.crn;
        // (coefficient batches, the values they are applied to)
        let coefficient_streams: Vec<Stream>;
        let parts: Vec<(&Stream, &[[f32; 3]])> = match self.folds {
            Folds::All => vec![(crn, crn.mean.pixels.as_slice())],
            Folds::Halves => {
                let h = b / 2;
                coefficient_streams =
                    vec![Stream::from_batches(crn.batches[..h].to_vec()), Stream::from_batches(crn.batches[h..2 * h].to_vec())];
                vec![
                    (&coefficient_streams[0], coefficient_streams[1].mean.pixels.as_slice()),
                    (&coefficient_streams[1], coefficient_streams[0].mean.pixels.as_slice()),
                ]
            }
        };
        let bh = parts[0].0.batches.len();
        let s = scale(b, bh);
        let halves = |stride: usize| -> Vec<Half> {
            parts
                .iter()
                .map(|(st, mean)| {
                    let common = self.floor.filter(|f| f.mode == FloorMode::Common);
                    if let Some(f) = common.filter(|_| self.centre_free.is_some_and(|f| !f.floored)) {
                        let plain = BatchCube::deviations(st, stride);
                        let mut cube = plain.clone();
                        cube.rotate_and_floor(f.values, f.tau, s);
                        Half { cube, mean, plain: Some(plain) }
                    } else {
                        // Floored chunk by chunk while the deviations are in cache.
                        let cube = BatchCube::deviations_floored(st, stride, common.map(|f| (f.values, f.tau, s)));
                        Half { cube, mean, plain: None }
                    }
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

    fn run_width<const P: usize>(&self, halves: &[Half]) -> PassOutput {
        let (w, h) = (self.set.width, self.set.height);
        let mut image = Image::new(w, h);
        let mut variance = Image::new(w, h);
        // Zeroed lazily by the allocator, so untouched (and free) without the centre-free solve.
        let mut free_image = Image::new(w, h);
        let mut free_variance = Image::new(w, h);
        let mut rows = vec![[PassStats::default(); 2]; h];
        let fused = self.centre_free.is_some();
        // Strips of columns, one after the other, each a parallel pass over the rows: a
        // thread's consecutive rows then share 14 of their 15 window rows within a few hundred
        // KB of cube data, which stays in L2, where whole rows of a wide image would not. Each
        // row's pixels and statistics still run in column order, so no bit depends on it.
        for x0 in (0..w).step_by(STRIP) {
            let xs = x0..(x0 + STRIP).min(w);
            image
                .pixels
                .par_chunks_mut(w)
                .zip(variance.pixels.par_chunks_mut(w))
                .zip(free_image.pixels.par_chunks_mut(w).zip(free_variance.pixels.par_chunks_mut(w)))
                .zip(rows.par_iter_mut())
                .enumerate()
                .for_each_init(
                    || Scratch::<P>::new(&halves[0].cube),
                    |sc, (y, (((image, variance), (free_image, free_variance)), st))| {
                        let out = RowOut { xs: xs.clone(), image, variance, free_image, free_variance };
                        simd::dispatch(Row { pass: self, halves, y, out, sc, st });
                    },
                );
        }
        let (mut stats, mut free_stats) = (PassStats::default(), PassStats::default());
        for [r, f] in &rows {
            stats.add(r);
            free_stats.add(f);
        }
        PassOutput {
            image,
            variance: self.variance.then_some(variance),
            stats,
            centre_free: fused.then_some(CentreFreeOutput { image: free_image, variance: free_variance, stats: free_stats }),
        }
    }

    /// The joint solve's settings.
    fn joint(&self) -> Stage<'_> {
        Stage {
            penalty: self.penalty,
            ridge: self.ridge,
            floor: self.floor,
            include_centre: self.include_centre,
            variance: self.variance,
            dof: self.dof,
        }
    }

    /// Eq. 7 at `beta` for channel `ch`: `s·‖d_c − Σ β_j d_j‖² + Σ β_j² e_j`, the CRN part
    /// from the fold's deviations (so it includes the floor's column) and the PT part from
    /// the unpenalised error estimates.
    #[inline(always)]
    fn predicted_variance(&self, cube: &BatchCube, c: usize, idx: &[u32], beta: &[f64], ch: usize, s: f64) -> (f64, f64) {
        let mut residual = [0.0f64; MAX_BATCHES];
        let r = &mut residual[..cube.batches];
        for (dst, v) in r.iter_mut().zip(cube.row(c, ch)) {
            *dst = *v as f64;
        }
        for (&i, &b) in idx.iter().zip(beta) {
            for (dst, v) in r.iter_mut().zip(cube.row(i as usize, ch)) {
                *dst -= b * *v as f64;
            }
        }
        (s * r.iter().map(|x| x * x).sum::<f64>(), self.pt_variance(idx, beta, ch))
    }

    /// Eq. 7's PT part at `beta` for channel `ch`: `Σ β_j² e_j`, from the unpenalised error
    /// estimates.
    #[inline(always)]
    fn pt_variance(&self, idx: &[u32], beta: &[f64], ch: usize) -> f64 {
        let Some(e) = self.errors else { return 0.0 };
        idx.iter().zip(beta).map(|(&i, &b)| b * b * e[i as usize][ch] as f64).sum()
    }

    /// For the joint systems (0–2, control variates `idx`) and, when `free`, the centre-free
    /// ones (3–5, control variates `idx[1..]`), with the panel's β: `[Σ β_j, Σ β_j·(g_j − h_j),
    /// Σ β_j²·e_j]`, what [`PassStats::count`], [`combine`] and [`CvPass::pt_variance`] sum. Each
    /// sum runs in `j` order from −0 as `Iterator::sum` does, so the bits are theirs; the
    /// eighteen sums run side by side instead of one after the other.
    #[inline(always)]
    fn side_by_side_sums<const P: usize>(
        &self,
        p: &Panel<P>,
        idx: &[u32],
        gs: &[[f64; MAX_K]; 3],
        hs: &[[f64; MAX_K]; 3],
        free: bool,
    ) -> [[f64; 3]; MAX_SYSTEMS] {
        let mut sums = [[-0.0f64; 3]; MAX_SYSTEMS];
        for (j, &i) in idx.iter().enumerate() {
            let e = self.errors.map(|e| e[i as usize]);
            for ch in 0..3 {
                let d = gs[ch][j] - hs[ch][j];
                let e = e.map_or(0.0, |e| e[ch] as f64);
                let b = p.beta[ch][j];
                let [bs, cs, ps] = &mut sums[ch];
                (*bs, *cs, *ps) = (*bs + b, *cs + b * d, *ps + b * b * e);
                if free && j > 0 {
                    let b = p.beta[3 + ch][j - 1];
                    let [bs, cs, ps] = &mut sums[3 + ch];
                    (*bs, *cs, *ps) = (*bs + b, *cs + b * d, *ps + b * b * e);
                }
            }
        }
        if self.errors.is_none() {
            sums.iter_mut().for_each(|s| s[2] = 0.0);
        }
        sums
    }

    /// `W` for control variate `i` of centre `c` in channel `ch` (summed over channels when shared).
    #[inline(always)]
    fn weight(&self, penalty: Penalty, i: usize, c: usize, ch: usize) -> f64 {
        let Some(e) = self.errors else { return 0.0 };
        if self.shared {
            self.channel_weight(e, penalty, i, c, 0) + self.channel_weight(e, penalty, i, c, 1) + self.channel_weight(e, penalty, i, c, 2)
        } else {
            self.channel_weight(e, penalty, i, c, ch)
        }
    }

    /// One channel's `W`; a method rather than a closure so that `inline(always)` applies and
    /// the gathering loop does not make a call per neighbour and channel.
    #[inline(always)]
    fn channel_weight(&self, e: &[[f32; 3]], penalty: Penalty, i: usize, c: usize, ch: usize) -> f64 {
        let (ei, ec) = (e[i][ch] as f64, e[c][ch] as f64);
        if i == c {
            ei
        } else if penalty == Penalty::Residual {
            let (g, hm) = (&self.set.crn.mean.pixels, &self.set.pt.mean.pixels);
            let r = (hm[i][ch] - hm[c][ch]) as f64 - (g[i][ch] - g[c][ch]) as f64;
            penalty.apply(ei, ec, r)
        } else {
            penalty.apply(ei, ec, 0.0)
        }
    }

    #[inline(always)]
    fn pixel<'h, const P: usize, S: Simd>(
        &self,
        simd: S,
        halves: &'h [Half],
        x: usize,
        y: usize,
        sc: &mut Scratch<'h, P>,
        st: &mut [PassStats; 2],
    ) -> PixelOut {
        let c = y * self.set.width + x;
        let n = self.selector.select_with(simd, x, y, &mut sc.select, &mut sc.idx);
        let idx = &sc.idx[..n];
        let hm = &self.set.pt.mean.pixels;
        let nh = halves.len();
        let b = halves[0].cube.batches;
        let s = scale(self.set.batch_count(), b);
        let crn_only = (self.set.crn.mean.pixels[c], [0.0; 3]);
        // The centre-free solve's control variates are the joint ones after the centre.
        let free = self.centre_free.map(|f| Stage {
            penalty: f.penalty,
            ridge: f.ridge,
            floor: self.floor.filter(|fl| f.floored && fl.mode == FloorMode::Common),
            include_centre: false,
            variance: true,
            dof: f.dof,
        });
        st[0].pixels += 1;
        st[0].set_size += n as u64;
        if free.is_some() {
            st[1].pixels += 1;
            st[1].set_size += n.saturating_sub(1) as u64;
        }
        if n == 0 {
            return [crn_only; 2];
        }
        // The independent floor blends towards the centre, which must come first.
        debug_assert!(self.floor.filter(|f| f.mode == FloorMode::Independent).is_none() || (self.include_centre && idx[0] as usize == c));
        debug_assert!(free.is_none() || (nh == 1 && idx[0] as usize == c));
        let free = free.filter(|_| n >= 2);
        let [joint_stats, free_stats] = st;
        let mut tally = Tally::new(joint_stats);
        let mut free_tally = Tally::new(free_stats);
        if let Some(p) = sc.panel.as_deref_mut() {
            for half in halves {
                let cube = &half.cube;
                let plain = half.plain();
                let target = half.mean;
                let mut delta_c = [0.0f64; 3];
                // Systems 0–2 are the joint solve's channels, 3–5 the centre-free one's.
                let rows = sc.rows.as_deref_mut().expect("panel rows");
                rows.dc = std::array::from_fn(|q| if q < 3 { cube.row_padded::<P>(c, q) } else { plain.row_padded::<P>(c, q - 3) });
                // One pass over the set gathers everything for both solves: rows, norms,
                // weights and the values the combination needs.
                for (j, &i) in idx.iter().enumerate() {
                    let i = i as usize;
                    let (gi, hi) = (target[i], hm[i]);
                    for ch in 0..3 {
                        simd::prefetch(cube.row_padded::<P>(i, ch));
                        simd::prefetch(plain.row_padded::<P>(i, ch));
                    }
                    for ch in 0..3 {
                        rows.d[ch][j] = cube.row_padded::<P>(i, ch);
                        p.sq[ch][j] = cube.sq[i][ch];
                        sc.gs3[ch][j] = gi[ch] as f64;
                        sc.hs3[ch][j] = hi[ch] as f64;
                    }
                    for ch in 0..3 {
                        p.w[ch][j] = self.weight(self.penalty, i, c, ch);
                    }
                    if let Some(f) = free {
                        if j > 0 {
                            for ch in 0..3 {
                                rows.d[3 + ch][j - 1] = plain.row_padded::<P>(i, ch);
                                p.sq[3 + ch][j - 1] = plain.sq[i][ch];
                                p.w[3 + ch][j - 1] = if f.penalty == self.penalty { p.w[ch][j] } else { self.weight(f.penalty, i, c, ch) };
                            }
                        }
                    }
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
                let joint = System {
                    k: n,
                    ridge: self.ridge,
                    want_trace: self.variance && self.dof.wants_trace(),
                    want_press: self.variance && self.dof.wants_press(),
                };
                let mut systems = [joint; MAX_SYSTEMS];
                if let Some(f) = free {
                    systems[3..].fill(System {
                        k: n - 1,
                        ridge: f.ridge,
                        want_trace: f.dof.wants_trace(),
                        want_press: f.dof.wants_press(),
                    });
                }
                let outcomes = p.solve(simd, rows, &systems[..if free.is_some() { 6 } else { 3 }], s);
                let solved = outcomes.map(|o| matches!(o, Outcome::Solved | Outcome::Regularised));
                let mut shrink = [1.0; 3];
                for ch in 0..3 {
                    if solved[ch] {
                        let winv = p.centre_winv(ch);
                        shrink[ch] = blend_towards_centre(&mut p.beta[ch][..n], delta_c[ch], winv);
                    }
                    PassStats::settle(outcomes[ch], &mut p.beta[ch][..n], self.include_centre);
                    if free.is_some() {
                        PassStats::settle(outcomes[3 + ch], &mut p.beta[3 + ch][..n - 1], false);
                    }
                }
                // Per system, Σ β_j, Σ β_j·(ḡ_j − h̄_j) and Σ β_j²·e_j: each in j order as a
                // sequential sum, all of them side by side.
                let sums = self.side_by_side_sums(p, idx, &sc.gs3, &sc.hs3, free.is_some());
                // Observations per channel: B − 1 deviations, and the common floor's column.
                let common = self.floor.is_some_and(|f| f.mode == FloorMode::Common);
                let n_obs = (b - 1 + usize::from(common)) as f64;
                for ch in 0..3 {
                    let [beta_sum, correction, pt] = sums[ch];
                    tally.stats.count(outcomes[ch], if self.include_centre { p.beta[ch][0] } else { 0.0 }, beta_sum);
                    tally.value[ch] += target[c][ch] as f64 - correction;
                    if self.variance {
                        let factor =
                            if solved[ch] { self.dof.factor(P as f64 - p.trace_inv[ch], n_obs, p.resid_sq[ch], p.press[ch]) } else { 1.0 };
                        let crn = s * if solved[ch] { shrink[ch] * shrink[ch] * p.resid_sq[ch] } else { f64::from(cube.sq[c][ch]) };
                        tally.variance[ch] += factor * crn + pt;
                    }
                }
                if let Some(f) = free {
                    // No centre to blend towards; B − 1 observations per channel, and the
                    // common floor's column when the solve has it.
                    let n_obs = (b - 1 + usize::from(f.floor.is_some())) as f64;
                    for ch in 0..3 {
                        let q = 3 + ch;
                        let [beta_sum, correction, pt] = sums[q];
                        let factor =
                            if solved[q] { f.dof.factor(P as f64 - p.trace_inv[q], n_obs, p.resid_sq[q], p.press[q]) } else { 1.0 };
                        free_tally.stats.count(outcomes[q], 0.0, beta_sum);
                        free_tally.value[ch] += target[c][ch] as f64 - correction;
                        let crn = s * if solved[q] { p.resid_sq[q] } else { f64::from(plain.sq[c][ch]) };
                        free_tally.variance[ch] += factor * crn + pt;
                    }
                }
            }
        } else {
            let bufs = sc.general.as_mut().expect("general buffers");
            let joint = self.joint();
            for half in halves {
                self.general(&joint, Fold { cube: &half.cube, target: half.mean }, idx, c, bufs, &mut tally);
            }
            if let Some(f) = free {
                let half = &halves[0];
                self.general(&f, Fold { cube: half.plain(), target: half.mean }, &idx[1..], c, bufs, &mut free_tally);
            }
        }
        let free_out = if free.is_some() { free_tally.finish(1) } else { crn_only };
        [tally.finish(nh), free_out]
    }

    /// One fold's solve in the general f64 workspace (shared coefficients, or at least as many
    /// batches as control variates) for centre `c`: gathers the rows of the control variates
    /// `idx` from the fold's cube, solves with the `stage`'s settings and adds the combination
    /// and its variance to `tally`.
    #[inline(always)]
    fn general(&self, stage: &Stage, fold: Fold, idx: &[u32], c: usize, bufs: &mut General, tally: &mut Tally) {
        let Fold { cube, target } = fold;
        let General { ws, gs, hs } = bufs;
        let n = idx.len();
        let b = cube.batches;
        let s = scale(self.set.batch_count(), b);
        let hm = &self.set.pt.mean.pixels;
        let channels: &[usize] = if self.shared { &[0] } else { &[0, 1, 2] };
        for &ch in channels {
            let m = if self.shared { 3 * b } else { b };
            let source = |i: usize| if self.shared { cube.pixel(i) } else { cube.row(i, ch) };
            for (j, &i) in idx.iter().enumerate() {
                for (dst, v) in ws.d[j * m..(j + 1) * m].iter_mut().zip(source(i as usize)) {
                    *dst = *v as f64;
                }
                ws.w[j] = self.weight(stage.penalty, i as usize, c, ch);
            }
            let mut delta_c = 0.0;
            if let Some(f) = stage.floor.filter(|f| f.mode == FloorMode::Independent) {
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
            ws.want_df = stage.variance && stage.dof.wants_trace();
            ws.want_press = stage.variance && stage.dof.wants_press();
            let outcome = ws.solve(n, m, s, stage.ridge, Form::Auto);
            let solved = matches!(outcome, Outcome::Solved | Outcome::Regularised);
            let common = stage.floor.is_some_and(|f| f.mode == FloorMode::Common);
            let n_obs = (m / b * (b - 1 + usize::from(common))) as f64;
            let factor = if solved && (ws.want_df || ws.want_press) { stage.dof.factor(ws.df, n_obs, ws.rss, ws.press) } else { 1.0 };
            if matches!(outcome, Outcome::Solved | Outcome::Regularised) {
                blend_towards_centre(&mut ws.beta[..n], delta_c, 1.0 / (ws.w[0] + ws.lambda));
            }
            let beta = &mut ws.beta[..n];
            tally.stats.record(outcome, beta, stage.include_centre);
            let out_channels: &[usize] = if self.shared { &[0, 1, 2] } else { std::slice::from_ref(&ch) };
            for &oc in out_channels {
                for (j, &i) in idx.iter().enumerate() {
                    gs[j] = target[i as usize][oc] as f64;
                    hs[j] = hm[i as usize][oc] as f64;
                }
                tally.value[oc] += combine(target[c][oc] as f64, &gs[..n], &hs[..n], beta);
                if stage.variance {
                    let (crn, pt) = self.predicted_variance(cube, c, idx, beta, oc, s);
                    tally.variance[oc] += factor * crn + pt;
                }
            }
        }
    }
}

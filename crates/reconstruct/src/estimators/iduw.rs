//! `iduw`: input-dependent uncorrelated weighting (Back et al. 2023), as described in
//! docs/estimators.md (from their public code; the description, not the code, is what we follow).
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
//! regular sub-lattice of pixels (≥ 32k of them), an unbiased estimate of the image mean.
use crate::batch_stats::group_means;
use crate::input::BatchNeed;
use crate::simd::{self, IduwPlanes, Kernel, Pairs, SharedWeights, Simd, Windows};
use crate::spec::{Bounds, EstimatorSpec, ParamKind, ParamSpec, Params, Samples};
use crate::window::mirror;
use crate::{Diagnostics, Estimator, Input, Needs, Output, ReconError};
use cvtrace_streams::Image;
use rayon::prelude::*;

/// The γ grid of the public IDUW code.
pub const GAMMA_GRID: [f32; 10] = [0.01, 0.025, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5, 2.0, 2.5];
const MAX_WINDOW: usize = 31;
/// Pixels used for γ selection on large images (the lattice stride is chosen to keep about this many).
const SELECTION_PIXELS: usize = 32_768;

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "iduw",
    label: "IDUW",
    short: "IDUW",
    summary:
        "Input-dependent uncorrelated weighting (Back et al. 2023): PT plus weighted CRN differences over a window, γ chosen per image.",
    colour: [0x76, 0xb7, 0xf2],
    samples: Samples::BothStreams,
    params: &[
        ParamSpec {
            name: "window",
            kind: ParamKind::Int { min: 3, max: MAX_WINDOW as i64 },
            default: "15",
            doc: "Side of the square window of neighbours (odd).",
            alias: Some("iduw-window"),
        },
        ParamSpec {
            name: "gammas",
            kind: ParamKind::FloatList(Bounds::at_least(0.0)),
            default: "0.01,0.025,0.05,0.1,0.2,0.5,1,1.5,2,2.5",
            doc: "Candidate γ values of the per-image selection (the public code's grid).",
            alias: None,
        },
        ParamSpec {
            name: "gamma",
            kind: ParamKind::AutoFloat(Bounds::at_least(0.0)),
            default: "auto",
            doc: "A fixed γ instead of choosing one from `gammas`.",
            alias: Some("iduw-gamma"),
        },
        ParamSpec {
            name: "selection_stride",
            kind: ParamKind::Int { min: 0, max: 1 << 16 },
            default: "0",
            doc: "Stride of the pixel lattice the γ criterion is evaluated on; 0 picks one that keeps at least 32k pixels.",
            alias: None,
        },
    ],
    needs: |_| NEEDS,
    build: |p| Ok(Box::new(Iduw::new(IduwOptions::from_params(p))?)),
    variants: &[],
};

/// IDUW forms four sub-buffers of consecutive batches and weights by the spp of a half.
const NEEDS: Needs =
    Needs { batches: BatchNeed::MultipleOf(4), features: None, reference: false, spp: true, pt2n: false, bounded_values: false };

#[derive(Clone, Debug, PartialEq)]
pub struct IduwOptions {
    /// Window side (odd).
    pub window: usize,
    /// Candidate γ values.
    pub gammas: Vec<f32>,
    /// A fixed γ, skipping the selection.
    pub gamma: Option<f32>,
    /// Stride of the γ-selection lattice; 0 picks one that keeps at least 32k pixels.
    pub selection_stride: usize,
}

impl Default for IduwOptions {
    fn default() -> Self {
        IduwOptions::from_params(&Params::defaults(&SPEC))
    }
}

impl IduwOptions {
    /// The options of the declared parameters.
    pub fn from_params(p: &Params) -> Self {
        IduwOptions {
            window: p.usize("window"),
            gammas: p.float_list("gammas").iter().map(|&g| g as f32).collect(),
            gamma: p.auto_float("gamma").map(|g| g as f32),
            selection_stride: p.usize("selection_stride"),
        }
    }

    pub fn validate(&self) -> Result<(), ReconError> {
        if self.window < 3 || self.window.is_multiple_of(2) || self.window > MAX_WINDOW {
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

/// One way to combine, for one colour channel: the estimates `h` (PT) and `g` (CRN), and the
/// two CRN halves `x`, `y` whose disagreement sets the weights, with `m` samples per half (the
/// planes the vector kernels read).
type Pass<'a> = IduwPlanes<'a>;

impl Pass<'_> {
    /// Fills `t = m·v` and `d = (g_c − g_i) − (h_c − h_i)` for every position of the mirrored
    /// window around (cx, cy), row by row. The centre is included: its `d` is exactly 0, so it
    /// adds nothing to `Σ w·d` (and exactly 1 to `Σ w`). Interior rows are contiguous slices.
    #[inline(always)]
    fn window(&self, cx: usize, cy: usize, geo: Geometry, t: &mut [f32], d: &mut [f32]) {
        let Geometry { w, h, r, .. } = geo;
        let c = cy * w + cx;
        let (hc, gc, xc, yc) = (self.h[c], self.g[c], self.x[c], self.y[c]);
        let side = 2 * r + 1;
        let interior = cx >= r && cx + r < w;
        for (row, dy) in (0..side).zip(-(r as isize)..) {
            let base = mirror(cy as isize + dy, h) * w;
            let (tr, dr) = (&mut t[row * side..(row + 1) * side], &mut d[row * side..(row + 1) * side]);
            if interior {
                let a = base + cx - r;
                let (hs, gs, xs, ys) = (&self.h[a..a + side], &self.g[a..a + side], &self.x[a..a + side], &self.y[a..a + side]);
                for i in 0..side {
                    let v = (xc - xs[i]) - (yc - ys[i]);
                    tr[i] = self.m * v * v;
                    dr[i] = (gc - gs[i]) - (hc - hs[i]);
                }
            } else {
                for (i, dx) in (0..side).zip(-(r as isize)..) {
                    let j = base + mirror(cx as isize + dx, w);
                    let v = (xc - self.x[j]) - (yc - self.y[j]);
                    tr[i] = self.m * v * v;
                    dr[i] = (gc - self.g[j]) - (hc - self.h[j]);
                }
            }
        }
    }
}

/// Window mean of a plane around (cx, cy), mirrored.
#[inline(always)]
fn window_mean(p: &[f32], cx: usize, cy: usize, w: usize, h: usize, r: usize) -> f32 {
    let mut s = 0.0f32;
    for dy in -(r as isize)..=r as isize {
        let base = mirror(cy as isize + dy, h) * w;
        for dx in -(r as isize)..=r as isize {
            s += p[base + mirror(cx as isize + dx, w)];
        }
    }
    s / ((2 * r + 1) * (2 * r + 1)) as f32
}

/// One channel of everything IDUW reads, as planes. The buffers are refilled for each channel
/// and pass: fresh ones of this size (80 MB at 1920×1080) would cost as much in page faults
/// as the final pass's arithmetic.
struct Planes {
    pt: Vec<f32>,
    crn: Vec<f32>,
    pt_halves: [Vec<f32>; 2],
    crn_halves: [Vec<f32>; 2],
    crn_subs: [Vec<f32>; 4],
}

fn fill_plane(dst: &mut Vec<f32>, im: &Image, ch: usize) {
    dst.clear();
    dst.extend(im.pixels.iter().map(|p| p[ch]));
}

fn fill_half(dst: &mut Vec<f32>, a: &Image, b: &Image, ch: usize) {
    dst.clear();
    dst.extend(a.pixels.iter().zip(&b.pixels).map(|(p, q)| 0.5 * (p[ch] + q[ch])));
}

/// Sub-buffer images (means of consecutive quarters of the batches) of both streams.
struct Prepared {
    pt_subs: Vec<Image>,
    crn_subs: Vec<Image>,
    spp: f32,
}

impl Planes {
    fn new() -> Self {
        Planes { pt: vec![], crn: vec![], pt_halves: Default::default(), crn_halves: Default::default(), crn_subs: Default::default() }
    }

    /// Channel `ch` of the planes the γ criterion reads (`criterion`) or the final pass reads
    /// (the full means and the two CRN halves).
    fn fill(&mut self, p: &Prepared, set: &cvtrace_streams::StreamSet, ch: usize, criterion: bool) {
        let (ps, cs) = (&p.pt_subs, &p.crn_subs);
        fill_half(&mut self.crn_halves[0], &cs[0], &cs[1], ch);
        fill_half(&mut self.crn_halves[1], &cs[2], &cs[3], ch);
        if criterion {
            fill_half(&mut self.pt_halves[0], &ps[0], &ps[1], ch);
            fill_half(&mut self.pt_halves[1], &ps[2], &ps[3], ch);
            for (dst, sub) in self.crn_subs.iter_mut().zip(cs) {
                fill_plane(dst, sub, ch);
            }
        }
        fill_plane(&mut self.pt, &set.pt.mean, ch);
        fill_plane(&mut self.crn, &set.crn.mean, ch);
    }
}

/// Per-task buffers (reused for every pixel).
struct Scratch {
    t: Vec<f32>,
    d: Vec<f32>,
    t2: Vec<f32>,
    d2: Vec<f32>,
    /// Window element offsets of the current image row (see [`row_offsets`]).
    offsets: Vec<usize>,
    /// Per half and γ, the eight centres' `Σ w·d`; per γ their `Σ w`.
    acc: [Vec<[f32; 8]>; 2],
    wt: Vec<[f32; 8]>,
    /// Per half and γ, one centre's `(Σ w·d, Σ w)`.
    sums: [Vec<(f32, f32)>; 2],
}

impl Scratch {
    fn new(n: usize, gammas: usize) -> Self {
        Scratch {
            t: vec![0.0; n],
            d: vec![0.0; n],
            t2: vec![0.0; n],
            d2: vec![0.0; n],
            offsets: Vec::with_capacity(n),
            acc: [vec![[0.0; 8]; gammas], vec![[0.0; 8]; gammas]],
            wt: vec![[0.0; 8]; gammas],
            sums: [vec![(0.0, 0.0); gammas], vec![(0.0, 0.0); gammas]],
        }
    }
}

/// The window elements of the centres of image row `y`, in window order, as offsets from
/// the pixel index of the window's left column (`y·w + cx − r` minus the row part): the
/// rows are mirrored at the top and bottom borders, the columns are not, so they serve
/// every centre whose window lies inside the image horizontally.
fn row_offsets(y: usize, geo: Geometry, out: &mut Vec<usize>) {
    out.clear();
    let side = 2 * geo.r + 1;
    for dy in -(geo.r as isize)..=geo.r as isize {
        let base = mirror(y as isize + dy, geo.h) * geo.w;
        out.extend(base..base + side);
    }
}

/// Whether the eight centres `x..x + 8` have horizontally unmirrored windows.
#[inline(always)]
fn interior8(x: usize, geo: Geometry) -> bool {
    x >= geo.r && x + 7 + geo.r < geo.w
}

/// [`window_mean`] for a centre with an unmirrored window: the same sum in the same order.
#[inline(always)]
fn window_mean_interior(p: &[f32], left: usize, offsets: &[usize]) -> f32 {
    let mut s = 0.0f32;
    for &o in offsets {
        s += p[left + o];
    }
    s / offsets.len() as f32
}

/// Geometry shared by the passes.
#[derive(Clone, Copy)]
struct Geometry {
    w: usize,
    h: usize,
    r: usize,
    /// 1 / (W² − 1).
    norm: f32,
}

/// Where a row's blocks of eight centres get their sums.
enum Blocks<'a> {
    /// [`Simd::iduw_sums8`] for every block whose windows are not mirrored horizontally.
    Kernel,
    /// Precomputed, for the blocks from column `first` on.
    Given { first: usize, sums: &'a [([f32; 8], [f32; 8])] },
}

/// The final output of one channel: the planes, the window, γ, the channel `ch` it writes,
/// and whether rows whose windows are not mirrored vertically share pair weights (see
/// [`PairRing`]).
#[derive(Clone, Copy)]
struct Final<'a> {
    pass: &'a Pass<'a>,
    geo: Geometry,
    gamma: f32,
    ch: usize,
    pairs: bool,
}

/// The final output of one image row; returns Σ of the normalised weights, added centre by
/// centre in column order. Blocks of eight centres take their sums from `blocks`, the other
/// centres the per-centre kernel.
#[inline(always)]
fn row_outputs<S: Simd>(simd: S, fin: &Final, y: usize, out: &mut [[f32; 3]], sc: &mut Scratch, blocks: Blocks) -> f64 {
    let Final { pass, geo, gamma, ch, .. } = *fin;
    let n = (2 * geo.r + 1).pow(2);
    let mut wsum = 0.0f64;
    let mut x = 0;
    while x < geo.w {
        let c = y * geo.w + x;
        let sums = match blocks {
            Blocks::Kernel if interior8(x, geo) => {
                let win = Windows { c0: c, n0: x - geo.r, offsets: &sc.offsets };
                simd.iduw_sums8(pass, win, &[gamma], &mut sc.acc[0], &mut sc.wt);
                Some((sc.acc[0][0], sc.wt[0]))
            }
            Blocks::Given { first, sums } if x >= first && x < first + 8 * sums.len() => Some(sums[(x - first) / 8]),
            _ => None,
        };
        if let Some((acc, wt)) = sums {
            for l in 0..8 {
                out[x + l][ch] = pass.h[c + l] + acc[l] * geo.norm;
                wsum += ((wt[l] - 1.0) * geo.norm) as f64;
            }
            x += 8;
            continue;
        }
        pass.window(x, y, geo, &mut sc.t[..n], &mut sc.d[..n]);
        let (acc, wt) = simd.exp_weighted(&sc.t[..n], &sc.d[..n], gamma);
        out[x][ch] = pass.h[c] + acc * geo.norm;
        wsum += ((wt - 1.0) * geo.norm) as f64;
        x += 1;
    }
    wsum
}

/// The final output of one image row, every centre computing its own weights; returns Σ of the
/// normalised weights.
#[inline(always)]
fn final_row<S: Simd>(simd: S, fin: &Final, y: usize, out: &mut [[f32; 3]], sc: &mut Scratch) -> f64 {
    row_offsets(y, fin.geo, &mut sc.offsets);
    row_outputs(simd, fin, y, out, sc, Blocks::Kernel)
}

/// The final pass's weights of pairs of pixels, kept until both centres of a pair have used
/// them. A pair's weight is symmetric (`v` only changes sign when centre and neighbour swap,
/// and `t = (m·v)·v` does not), so it is computed once, at the pair's upper (or, in the same
/// row, left) pixel `p` along its offset `o = q − p` (`o` in the lower half of the window), and
/// read back by `q` as its neighbour at `−o`, up to `r` rows later. Per offset the ring holds
/// the weights of `r + 1` image rows; an extra plane holds the centre's own weight.
struct PairRing {
    /// The lower half of the window, `(dy, dx)` with `dy > 0`, or `dy = 0` and `dx > 0`.
    offsets: Vec<(usize, isize)>,
    /// `[plane][row mod (r + 1)][x]`.
    weights: Vec<f32>,
    /// Per window element, its weight's index in `weights` for a centre in column `r` of the
    /// current row.
    src: Vec<usize>,
    /// Per block of eight centres of a row, the partial sums and the sums.
    part: Vec<[[f32; 8]; 16]>,
    sums: Vec<([f32; 8], [f32; 8])>,
    geo: Geometry,
}

impl PairRing {
    fn new(geo: Geometry) -> Self {
        let r = geo.r as isize;
        let offsets: Vec<(usize, isize)> = (0..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dy, dx)))
            .filter(|&(dy, dx)| dy > 0 || dx > 0)
            .map(|(dy, dx)| (dy as usize, dx))
            .collect();
        let planes = offsets.len() + 1;
        PairRing {
            weights: vec![0.0; planes * Self::plane_stride(geo)],
            src: Vec::with_capacity((2 * geo.r + 1).pow(2)),
            part: vec![],
            sums: vec![],
            offsets,
            geo,
        }
    }

    /// The plane of offset `(dy, dx)` of the lower half.
    fn plane(&self, dy: usize, dx: isize) -> usize {
        let r = self.geo.r;
        if dy == 0 {
            dx as usize - 1
        } else {
            r + (dy - 1) * (2 * r + 1) + (dx + r as isize) as usize
        }
    }

    /// Floats per plane: `r + 1` rows and one cache line more, so that the planes' rows do
    /// not all fall on the same cache sets (a multiple of 4 KiB apart, they would evict each
    /// other while a centre reads its window's weights from all of them).
    fn plane_stride(geo: Geometry) -> usize {
        (geo.r + 1) * geo.w + 16
    }

    fn start(&self, plane: usize, y: usize) -> usize {
        plane * Self::plane_stride(self.geo) + (y % (self.geo.r + 1)) * self.geo.w
    }

    /// The centre's own weight (`v = 0`), computed by the same kernel as every other weight.
    #[inline(always)]
    fn fill_centre<S: Simd>(&mut self, simd: S, pass: &Pass, gamma: f32) {
        let at = self.start(self.offsets.len(), 0);
        let w = self.geo.w;
        simd.iduw_pair_weights(pass, Pairs { p0: 0, off: 0, n: w }, gamma, &mut self.weights[at..at + w]);
    }

    /// The weights of every pair whose upper pixel lies in row `y` (which needs `y + r < h`).
    #[inline(always)]
    fn fill_row<S: Simd>(&mut self, simd: S, pass: &Pass, gamma: f32, y: usize) {
        let w = self.geo.w;
        for (k, &(dy, dx)) in self.offsets.iter().enumerate() {
            // Every p whose partner q = p + (dy, dx) lies in the image.
            let (lo, hi) = ((-dx).max(0) as usize, (w as isize - dx).min(w as isize) as usize);
            let at = self.start(k, y) + lo;
            let off = (dy * w) as isize + dx;
            let pairs = Pairs { p0: y * w + lo, off: off as usize, n: hi - lo };
            simd.iduw_pair_weights(pass, pairs, gamma, &mut self.weights[at..at + hi - lo]);
        }
    }

    /// `src` for the centres of row `y`, in window order (rows, then columns).
    fn sources(&mut self, y: usize) {
        let r = self.geo.r as isize;
        self.src.clear();
        for ey in -r..=r {
            for ex in -r..=r {
                let (plane, row, col) = if ey == 0 && ex == 0 {
                    (self.offsets.len(), 0, r)
                } else if ey > 0 || (ey == 0 && ex > 0) {
                    (self.plane(ey as usize, ex), y, r)
                } else {
                    (self.plane((-ey) as usize, -ex), (y as isize + ey) as usize, r + ex)
                };
                let s = self.start(plane, row) + col as usize;
                self.src.push(s);
            }
        }
    }
}

/// [`final_row`] for a row whose windows are not mirrored vertically, from the pair weights of
/// `ring` (filled up to row `y`): the same outputs, bit for bit.
#[inline(always)]
fn paired_row<S: Simd>(simd: S, fin: &Final, y: usize, out: &mut [[f32; 3]], sc: &mut Scratch, ring: &mut PairRing) -> f64 {
    let geo = fin.geo;
    row_offsets(y, geo, &mut sc.offsets);
    ring.sources(y);
    // The blocks of eight centres from column r on whose windows are not mirrored (as
    // `interior8` says of each), all at once.
    let blocks = (geo.w - 2 * geo.r) / 8;
    ring.sums.resize(blocks, ([0.0; 8], [0.0; 8]));
    ring.part.resize(blocks, [[0.0; 8]; 16]);
    let win = Windows { c0: y * geo.w + geo.r, n0: 0, offsets: &sc.offsets };
    let weights = SharedWeights { values: &ring.weights, src: &ring.src };
    simd.iduw_row_sums_weighted(fin.pass, win, weights, &mut ring.part, &mut ring.sums);
    row_outputs(simd, fin, y, out, sc, Blocks::Given { first: geo.r, sums: &ring.sums })
}

/// The final output for the rows `y0..y0 + wsum.len()` (`out` holds them), with the task's
/// buffers; adds each row's Σ of normalised weights to `wsum`. With [`Final::pairs`], rows
/// whose windows are not mirrored vertically take their weights from a [`PairRing`] (the ring
/// is warmed up on the `r` rows above the band), which halves the exponentials and changes no
/// bit.
struct Band<'a> {
    fin: &'a Final<'a>,
    y0: usize,
    out: &'a mut [[f32; 3]],
    wsum: &'a mut [f64],
    sc: &'a mut Scratch,
    ring: &'a mut Option<PairRing>,
}

impl Kernel for Band<'_> {
    type Output = ();

    #[inline(always)]
    fn run<S: Simd>(self, simd: S) {
        let Band { fin, y0, out, wsum, sc, ring } = self;
        let Final { pass, geo, gamma, .. } = *fin;
        let (w, h, r) = (geo.w, geo.h, geo.r);
        let rows = y0..y0 + wsum.len();
        let paired = fin.pairs && h > 2 * r && w >= 2 * r + 8;
        let interior = rows.start.max(r)..rows.end.min(h.saturating_sub(r));
        let mut ring = if paired && !interior.is_empty() {
            let ring = ring.get_or_insert_with(|| PairRing::new(geo));
            ring.fill_centre(simd, pass, gamma);
            Some(ring)
        } else {
            None
        };
        let mut next = interior.start.saturating_sub(r);
        for (k, y) in rows.enumerate() {
            let row = &mut out[k * w..(k + 1) * w];
            match ring.as_deref_mut().filter(|_| interior.contains(&y)) {
                Some(ring) => {
                    while next <= y {
                        ring.fill_row(simd, pass, gamma, next);
                        next += 1;
                    }
                    wsum[k] += paired_row(simd, fin, y, row, sc, ring);
                }
                None => wsum[k] += final_row(simd, fin, y, row, sc),
            }
        }
    }
}

/// The final output of channel `fin.ch` into `image`, in bands of `band` rows run in parallel;
/// `wsum` receives each row's Σ of normalised weights. The bits depend on neither `band`,
/// `fin.pairs` nor the thread count.
fn final_pass(fin: &Final, image: &mut Image, wsum: &mut [f64], band: usize) {
    let n = (2 * fin.geo.r + 1).pow(2);
    let w = fin.geo.w;
    image.pixels.par_chunks_mut(w * band).zip(wsum.par_chunks_mut(band)).enumerate().for_each_init(
        || (Scratch::new(n, 1), None),
        |(sc, ring), (b, (out, wsum))| simd::dispatch(Band { fin, y0: b * band, out, wsum, sc, ring }),
    );
}

/// Rows per band of the final pass: about four bands per thread, each at least `4r` rows so
/// that the ring's warm-up (`r` rows of half the work) stays a small share.
fn band_rows(h: usize, r: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    h.div_ceil(4 * threads).max(4 * r).clamp(1, h.max(1))
}

/// The γ criterion of one channel: the two halves' planes, the PT plane, the window, the γ
/// values, and the lattice columns `xs` it is evaluated at in every lattice row.
struct Criterion<'a> {
    halves: [Pass<'a>; 2],
    pt: &'a [f32],
    geo: Geometry,
    gammas: &'a [f32],
    xs: &'a [usize],
}

/// The criterion over the lattice pixels of row `y`, added to `crit`, with the task's buffers.
struct CriterionRow<'a> {
    criterion: &'a Criterion<'a>,
    y: usize,
    crit: &'a mut [f64],
    sc: &'a mut Scratch,
}

impl Kernel for CriterionRow<'_> {
    type Output = ();

    /// Runs of eight adjacent lattice pixels (stride 1) with unmirrored windows go at once.
    #[inline(always)]
    fn run<S: Simd>(self, simd: S) {
        let CriterionRow { criterion, y, crit, sc } = self;
        let Criterion { halves, pt, geo, gammas, xs } = criterion;
        let geo = *geo;
        let n = (2 * geo.r + 1).pow(2);
        row_offsets(y, geo, &mut sc.offsets);
        let mut k = 0;
        while k < xs.len() {
            let x = xs[k];
            let c = y * geo.w + x;
            if k + 8 <= xs.len() && xs[k + 7] == x + 7 && interior8(x, geo) {
                for (half, acc) in halves.iter().zip(&mut sc.acc) {
                    let win = Windows { c0: c, n0: x - geo.r, offsets: &sc.offsets };
                    simd.iduw_sums8(half, win, gammas, acc, &mut sc.wt);
                }
                for l in 0..8 {
                    let pbar = window_mean_interior(pt, x + l - geo.r, &sc.offsets);
                    let denom = (pbar * pbar) as f64 + 0.01;
                    for (gi, cr) in crit.iter_mut().enumerate() {
                        let oa = halves[0].h[c + l] + sc.acc[0][gi][l] * geo.norm;
                        let ob = halves[1].h[c + l] + sc.acc[1][gi][l] * geo.norm;
                        *cr += ((oa - ob) as f64).powi(2) / denom;
                    }
                }
                k += 8;
                continue;
            }
            // The same sum in the same order; the interior form skips a mirror per element.
            let pbar = if x >= geo.r && x + geo.r < geo.w {
                window_mean_interior(pt, x - geo.r, &sc.offsets)
            } else {
                window_mean(pt, x, y, geo.w, geo.h, geo.r)
            };
            let denom = (pbar * pbar) as f64 + 0.01;
            halves[0].window(x, y, geo, &mut sc.t[..n], &mut sc.d[..n]);
            halves[1].window(x, y, geo, &mut sc.t2[..n], &mut sc.d2[..n]);
            simd.exp_weighted_gammas(&sc.t[..n], &sc.d[..n], gammas, &mut sc.sums[0]);
            simd.exp_weighted_gammas(&sc.t2[..n], &sc.d2[..n], gammas, &mut sc.sums[1]);
            for (gi, cr) in crit.iter_mut().enumerate() {
                let oa = halves[0].h[c] + sc.sums[0][gi].0 * geo.norm;
                let ob = halves[1].h[c] + sc.sums[1][gi].0 * geo.norm;
                *cr += ((oa - ob) as f64).powi(2) / denom;
            }
            k += 1;
        }
    }
}

impl Iduw {
    pub fn new(options: IduwOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(Iduw { options })
    }

    pub fn options(&self) -> &IduwOptions {
        &self.options
    }

    fn prepare(&self, input: &Input) -> Prepared {
        let set = input.streams;
        Prepared { pt_subs: group_means(&set.pt, 4), crn_subs: group_means(&set.crn, 4), spp: set.meta.spp as f32 }
    }

    fn geometry(&self, w: usize, h: usize) -> Geometry {
        let win = self.options.window;
        Geometry { w, h, r: win / 2, norm: 1.0 / (win * win - 1) as f32 }
    }

    fn stride(&self, w: usize, h: usize) -> usize {
        match self.options.selection_stride {
            0 => (((w * h) as f64 / SELECTION_PIXELS as f64).sqrt().floor() as usize).max(1),
            s => s,
        }
    }

    /// The selection criterion for every γ of the grid, as (γ, criterion) pairs, and the
    /// number of pixels it was evaluated on. Checks the input as [`crate::Instance::run`] does.
    pub fn gamma_criteria(&self, input: &Input) -> Result<(Vec<(f32, f64)>, usize), ReconError> {
        input.check(SPEC.name, &NEEDS)?;
        let p = self.prepare(input);
        Ok(self.criteria(input, &p, &mut Planes::new()))
    }

    fn criteria(&self, input: &Input, p: &Prepared, pl: &mut Planes) -> (Vec<(f32, f64)>, usize) {
        let set = input.streams;
        let (w, h) = (set.width, set.height);
        let geo = self.geometry(w, h);
        let gammas = &self.options.gammas;
        let stride = self.stride(w, h);
        let (xs, ys): (Vec<usize>, Vec<usize>) = ((stride / 2..w).step_by(stride).collect(), (stride / 2..h).step_by(stride).collect());
        let n = (2 * geo.r + 1).pow(2);
        let mut total = vec![0.0f64; gammas.len()];
        for ch in 0..3 {
            pl.fill(p, set, ch, true);
            let pl = &*pl;
            let s = &pl.crn_subs;
            let criterion = Criterion {
                halves: [
                    Pass { h: &pl.pt_halves[0], g: &pl.crn_halves[0], x: &s[0], y: &s[1], m: p.spp / 4.0 },
                    Pass { h: &pl.pt_halves[1], g: &pl.crn_halves[1], x: &s[2], y: &s[3], m: p.spp / 4.0 },
                ],
                pt: &pl.pt,
                geo,
                gammas,
                xs: &xs,
            };
            let rows: Vec<Vec<f64>> = ys
                .par_iter()
                .map_init(
                    || Scratch::new(n, gammas.len()),
                    |sc, &y| {
                        let mut crit = vec![0.0f64; gammas.len()];
                        simd::dispatch(CriterionRow { criterion: &criterion, y, crit: &mut crit, sc });
                        crit
                    },
                )
                .collect();
            for r in &rows {
                for (t, v) in total.iter_mut().zip(r) {
                    *t += v;
                }
            }
        }
        let count = xs.len() * ys.len();
        (gammas.iter().copied().zip(total.iter().map(|c| c / (3 * count).max(1) as f64)).collect(), count)
    }
}

impl Estimator for Iduw {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = std::time::Instant::now();
        let p = self.prepare(input);
        let set = input.streams;
        let (w, h) = (set.width, set.height);
        let mut d = Diagnostics::default();
        d.float("seconds_prepare", start.elapsed().as_secs_f64());
        let mut planes = Planes::new();
        let gamma = match self.options.gamma {
            Some(g) => g,
            None => {
                let started = std::time::Instant::now();
                let (crit, count) = self.criteria(input, &p, &mut planes);
                // First minimum, so ties resolve to the earlier grid value.
                let (best, (g, value)) =
                    crit.iter().enumerate().fold((0, crit[0]), |acc, (i, c)| if c.1 < acc.1 .1 { (i, *c) } else { acc });
                d.int("gamma_index", best as i64)
                    .float("gamma_criterion", value)
                    .int("selection_pixels", count as i64)
                    .float("seconds_gamma", started.elapsed().as_secs_f64());
                g
            }
        };
        let geo = self.geometry(w, h);
        let mut image = Image::new(w, h);
        let mut wsum = vec![0.0f64; h];
        let band = band_rows(h, geo.r);
        for ch in 0..3 {
            planes.fill(&p, set, ch, false);
            let pl = &planes;
            let full = Pass { h: &pl.pt, g: &pl.crn, x: &pl.crn_halves[0], y: &pl.crn_halves[1], m: p.spp / 2.0 };
            final_pass(&Final { pass: &full, geo, gamma, ch, pairs: true }, &mut image, &mut wsum, band);
        }
        let win = self.options.window;
        d.float("gamma", gamma as f64)
            .float("neighbour_weight_mean", wsum.iter().sum::<f64>() / (3 * w * h) as f64)
            .int("window", win as i64);
        Ok(Output::new(image, d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};

    /// The final pass with the pair ring against every centre computing its own weights, bit
    /// for bit (image and weight sums), in both builds: images with and without unmirrored rows
    /// and columns, bands of one row up to the whole image, γ = 0 and the grid's ends.
    #[test]
    fn sharing_pair_weights_changes_no_bit() {
        let run = || {
            let mut compared = 0;
            for &(w, h) in &[(23usize, 19usize), (40, 30), (22, 15), (64, 41), (30, 14), (21, 20), (37, 16)] {
                let u = |p: u64, i: usize| uniform(hash4(17, p, i as u64, (w * h) as u64)) as f32;
                let planes: Vec<Vec<f32>> = (0..4).map(|p| (0..w * h).map(|i| u(p, i) * 3.0 - 1.0).collect()).collect();
                let pass = Pass { h: &planes[0], g: &planes[1], x: &planes[2], y: &planes[3], m: 4.0 };
                let geo = Geometry { w, h, r: 7, norm: 1.0 / 224.0 };
                for &gamma in &[0.0f32, 0.01, 2.5] {
                    let mut want = Image::new(w, h);
                    let mut want_sum = vec![0.0f64; h];
                    final_pass(&Final { pass: &pass, geo, gamma, ch: 1, pairs: false }, &mut want, &mut want_sum, h);
                    for band in [1, 3, 16, h] {
                        let mut got = Image::new(w, h);
                        let mut got_sum = vec![0.0f64; h];
                        final_pass(&Final { pass: &pass, geo, gamma, ch: 1, pairs: true }, &mut got, &mut got_sum, band);
                        let differ = got.pixels.iter().zip(&want.pixels).filter(|(a, b)| a[1].to_bits() != b[1].to_bits()).count();
                        assert_eq!(differ, 0, "{w}×{h}, γ {gamma}, band {band}: {differ} pixels differ");
                        assert_eq!(
                            got_sum.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                            want_sum.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                        );
                        assert!(want.pixels.iter().all(|p| p[0] == 0.0 && p[2] == 0.0 && p[1].is_finite()));
                        compared += 1;
                    }
                }
            }
            compared
        };
        assert_eq!(run(), 84);
        assert_eq!(simd::force_portable(run), 84);
    }
}

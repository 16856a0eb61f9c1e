//! The few vector kernels of the image passes, in builds with identical arithmetic: portable,
//! AVX2, and AVX-512 for one kernel of the AVX2 build.
//!
//! The compiler does not reliably vectorise these fixed-size loops at full width, so the
//! AVX2 build uses explicit intrinsics. The portable build performs the same IEEE operations
//! in the same order per element (no fused multiply-add anywhere, fixed lane structure for
//! sums), so every build produces bit-identical results and the output does not depend on the
//! CPU.
//!
//! A build is a value of a type that implements [`Simd`]: [`Portable`] anywhere, and on x86_64
//! [`Avx2`] and [`Avx512`], tokens with a private field whose only constructor is their
//! `detect`, which checks the CPU. Holding a token proves that its instructions exist, so its
//! safe methods may run them. An image pass is written once, generic over the build, as a
//! [`Kernel`]; [`dispatch`] runs it with the best build the CPU has, the AVX2 one inside a
//! function compiled with AVX2, into which the kernel and the token's methods are inlined.
//!
//! This module tree holds all of the crate's `unsafe` (the intrinsics, which need their CPU
//! features, and raw-pointer loads and stores): every other file calls its safe methods.
#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod portable;

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;
#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::Avx512;
pub(crate) use portable::Portable;

/// A computation written once for every build: an image pass's row, band or block.
pub(crate) trait Kernel {
    type Output;
    /// Runs the computation with the build `simd`. Implementations are `#[inline(always)]`
    /// (as are the functions they call with `simd`), so that under [`dispatch`] the whole of
    /// it is compiled inside the AVX2 entry point, with its features.
    fn run<S: Simd>(self, simd: S) -> Self::Output;
}

/// Runs `kernel` with the AVX2 build on CPUs that have it (unless a unit test has forced the
/// portable build, see [`force_portable`]), with the portable build otherwise.
#[inline(always)]
pub(crate) fn dispatch<K: Kernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = Avx2::detect().filter(|_| !portable_forced()) {
        return avx2.run(kernel);
    }
    kernel.run(Portable)
}

#[cfg(test)]
static FORCE_PORTABLE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Runs `f` with the portable build forced on every thread (tests only): [`dispatch`] picks it
/// meanwhile. Both builds are bit-identical, so other tests running meanwhile are unaffected;
/// calls are serialised.
#[cfg(test)]
pub(crate) fn force_portable<T>(f: impl FnOnce() -> T) -> T {
    use std::sync::atomic::Ordering;
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    FORCE_PORTABLE.store(true, Ordering::SeqCst);
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            FORCE_PORTABLE.store(false, Ordering::SeqCst);
        }
    }
    let _reset = Reset;
    f()
}

/// Whether a unit test has forced the portable build (see [`force_portable`]; outside
/// `cfg(test)` never).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn portable_forced() -> bool {
    #[cfg(test)]
    return FORCE_PORTABLE.load(std::sync::atomic::Ordering::SeqCst);
    #[cfg(not(test))]
    false
}

/// Asks for the cache line of `v` ahead of its use (a hint: no effect on results).
#[inline(always)]
pub(crate) fn prefetch<T>(v: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and SSE is part of x86_64.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((v as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// One colour channel of IDUW's inputs, as planes: the estimates `h` (PT) and `g` (CRN), and
/// the two CRN halves `x`, `y` whose disagreement sets the weights, with `m` samples per half.
#[derive(Clone, Copy)]
pub(crate) struct IduwPlanes<'a> {
    pub h: &'a [f32],
    pub g: &'a [f32],
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub m: f32,
}

/// The windows of horizontally adjacent centres, in blocks of eight: lane `l` of block `b` is
/// centre `c0 + 8b + l`, and its window element `i` is pixel `n0 + 8b + offsets[i] + l`.
#[derive(Clone, Copy)]
pub(crate) struct Windows<'a> {
    pub c0: usize,
    pub n0: usize,
    pub offsets: &'a [usize],
}

/// The pairs `(p, p + off)` for `p` in `p0..p0 + n`.
#[derive(Clone, Copy)]
pub(crate) struct Pairs {
    pub p0: usize,
    pub off: usize,
    pub n: usize,
}

/// Weights computed once per pair and read by both of its centres: window element `i` of lane
/// `l` of block `b` (see [`Windows`]) has weight `values[8b + src[i] + l]`.
#[derive(Clone, Copy)]
pub(crate) struct SharedWeights<'a> {
    pub values: &'a [f32],
    pub src: &'a [usize],
}

/// The `n` k-NN candidates `p0 … p0 + n − 1` of one window row: candidate `l` lies at
/// `(dx0 + l, dy)` from the centre (`offset = [dx0, dy]`) and at position `local0 + l` of the
/// window.
#[derive(Clone, Copy)]
pub(crate) struct CandidateRow {
    pub p0: usize,
    pub n: usize,
    pub offset: [i32; 2],
    pub local0: u32,
}

/// Vector kernels over fixed-width rows (`P` a multiple of 8). The methods take the build's
/// value, which for the CPU-specific builds proves that the CPU has their instructions.
pub(crate) trait Simd: Copy + Send + Sync {
    /// For `q < 8`, `l < 8`: `Σ_j e_j[a0+q] · d_j[b0+l]` over the rows, summed in `j` order,
    /// where `e_j` is `d_j` scaled by its weight. Eight rows of the block at once: each
    /// accumulator is a chain of `k` dependent additions, and eight independent chains keep
    /// the adder busy where four left it waiting on their latency.
    fn gram_block<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8];
    /// Every 8×8 block of `Σ_j e_j·d_jᵀ` that touches the lower triangle, as
    /// [`Simd::gram_block`] forms it, into `out` (rows along `a`); the other blocks are left as
    /// they are.
    #[inline(always)]
    fn gram_lower<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
        for a0 in (0..P).step_by(8) {
            for b0 in (0..=a0).step_by(8) {
                let acc = self.gram_block(d, e, a0, b0);
                for (dst, src) in out[a0..a0 + 8].iter_mut().zip(&acc) {
                    dst[b0..b0 + 8].copy_from_slice(src);
                }
            }
        }
    }
    /// `Σ a[l]·b[l]` with eight lane sums combined pairwise.
    fn dot32<const P: usize>(self, a: &[f32; P], b: &[f32; P]) -> f32;
    /// [`Simd::dot32`] of eight rows with one vector, the same bits: the eight rows' lane sums
    /// are combined side by side instead of one horizontal sum per row.
    fn dot32x8<const P: usize>(self, rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8];
    /// `out[l][r] = m[r][l]`.
    fn transpose8(self, m: [&[f32; 8]; 8]) -> [[f32; 8]; 8];
    /// The k-NN selection keys of the candidates `row`: candidate `l`'s key, as [`knn_key`]
    /// builds it from the squared CRN colour distance `dist2(centre, planes[·][p0 + l])`, goes
    /// to `out[l]`. Works in whole vectors: the planes must hold and `out` must take
    /// [`KNN_KEYS_SLACK`] values more than `n` (what lies beyond `n` in `out` is overwritten
    /// with unused keys).
    fn knn_keys(self, planes: [&[f32]; 3], centre: [f32; 3], row: CandidateRow, out: &mut [u64]);

    /// Eight f32 lanes (the panel's systems side by side), for the element-wise operations
    /// below; each is one IEEE operation per lane, so the builds agree bit for bit.
    type V: Copy;
    fn load8(self, a: &[f32; 8]) -> Self::V;
    fn store8(self, a: &mut [f32; 8], v: Self::V);
    fn splat8(self, x: f32) -> Self::V;
    fn add8(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub8(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul8(self, a: Self::V, b: Self::V) -> Self::V;
    fn div8(self, a: Self::V, b: Self::V) -> Self::V;
    fn sqrt8(self, a: Self::V) -> Self::V;
    /// `−a` (the sign flipped, exactly).
    fn neg8(self, a: Self::V) -> Self::V;
    /// `acc[l] += f64(v[l])²`.
    fn square_add8(self, acc: &mut [f64; 8], v: Self::V);
    /// `(Σ e^(−γ·t_i)·d_i, Σ e^(−γ·t_i))`: element `i` goes to lane `i mod 8` of chunk-wise
    /// partial sums (the tail of fewer than 8 to lanes 0…), combined pairwise.
    fn exp_weighted(self, t: &[f32], d: &[f32], gamma: f32) -> (f32, f32);
    /// [`Simd::exp_weighted`] for each of `gammas` (`out[q]` for `gammas[q]`), the same bits;
    /// the γ values' exponentials of an element are independent, so they run side by side.
    fn exp_weighted_gammas(self, t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]);
    /// `t_i ← e^(−t_i)`.
    fn exp_neg_in_place(self, t: &mut [f32]);
    /// IDUW's window sums for the eight centres of the first block of `win`: for centre
    /// `c0 + l` window element `i` is pixel `n0 + offsets[i] + l` of the planes,
    /// `t_i = (m·v_i)·v_i` with `v_i = (x_c − x_i) − (y_c − y_i)` and
    /// `d_i = (g_c − g_i) − (h_c − h_i)`, and for every `gammas[q]` lane `l` of `acc[q]` and
    /// `wsum[q]` receives exactly what [`Simd::exp_weighted`] returns for that centre's window.
    ///
    /// Vectorising across centres instead of along the window needs no window buffer and no
    /// horizontal sums, and shares the window's loads and differences among the γ values;
    /// element `i` still goes to partial sum `i mod 8`, in the same order, so the bits agree.
    fn iduw_sums8(self, p: &IduwPlanes, win: Windows, gammas: &[f32], acc: &mut [[f32; 8]], wsum: &mut [[f32; 8]]);
    /// IDUW's weights of one image row's `pairs`: for each pair `(p, q)`,
    /// `out[p − p0] = e^(−γ·t)`, `t = (m·v)·v`, `v = (x_p − x_q) − (y_p − y_q)`: exactly the
    /// weight [`Simd::iduw_sums8`] and [`Simd::exp_weighted`] give neighbour `q` of centre `p`,
    /// and, because `v` only changes sign when the two swap, neighbour `p` of centre `q` too.
    fn iduw_pair_weights(self, p: &IduwPlanes, pairs: Pairs, gamma: f32, out: &mut [f32]);
    /// [`Simd::iduw_sums8`] for one γ with the weights given, for `out.len()` blocks of `win`:
    /// `out[b]` receives `(Σ w·d, Σ w)` per lane, with the weights of `weights`. The same
    /// partial sums in the same order as [`Simd::exp_weighted`], so the same bits when the
    /// weights are the ones [`Simd::iduw_pair_weights`] computes. Element by element across
    /// the blocks, so that every load streams along a row; `part` (at least as long as `out`)
    /// holds the partial sums.
    fn iduw_row_sums_weighted(
        self,
        p: &IduwPlanes,
        win: Windows,
        weights: SharedWeights,
        part: &mut [[[f32; 8]; 16]],
        out: &mut [([f32; 8], [f32; 8])],
    );
}

/// Most γ values [`Simd::iduw_sums8`] keeps partial sums for at once; longer lists run in
/// chunks of this many.
const IDUW_GAMMAS_AT_ONCE: usize = 10;
/// Most window elements [`Simd::iduw_sums8`] takes (a 31×31 window).
pub(crate) const IDUW_MAX_WINDOW: usize = 31 * 31;

/// Checks the contract of [`Simd::iduw_sums8`] that keeps its loads in bounds.
#[inline(always)]
fn check_iduw_bounds(p: &IduwPlanes, win: &Windows, gammas: usize, acc: usize, wsum: usize) {
    let len = [p.h, p.g, p.x, p.y].iter().map(|p| p.len()).min().unwrap_or(0);
    let far = win.offsets.iter().copied().max().unwrap_or(0);
    assert!(
        win.offsets.len() <= IDUW_MAX_WINDOW && win.c0 + 8 <= len && win.n0 + far + 8 <= len && acc >= gammas && wsum >= gammas,
        "IDUW window outside the planes"
    );
}

/// Checks the contract of [`Simd::iduw_row_sums_weighted`] that keeps its loads in bounds;
/// returns the number of blocks.
#[inline(always)]
fn check_row_bounds(p: &IduwPlanes, win: &Windows, weights: &SharedWeights, part: usize, out: usize) -> usize {
    let len = p.h.len().min(p.g.len());
    let far = win.offsets.iter().copied().max().unwrap_or(0);
    let far_w = weights.src.iter().copied().max().unwrap_or(0);
    let span = 8 * out;
    assert!(
        weights.src.len() == win.offsets.len()
            && part >= out
            && win.c0 + span <= len
            && win.n0 + far + span <= len
            && far_w + span <= weights.values.len(),
        "IDUW window or weights outside their planes"
    );
    out
}

/// Checks the contract of [`Simd::iduw_pair_weights`].
#[inline(always)]
fn check_pair_bounds(p: &IduwPlanes, pairs: &Pairs, out: &[f32]) {
    assert!(pairs.p0 + pairs.off + pairs.n <= p.x.len().min(p.y.len()) && pairs.n <= out.len(), "IDUW pair outside the planes");
}

/// Extra values [`Simd::knn_keys`] may read from each plane and write to its output.
pub(crate) const KNN_KEYS_SLACK: usize = 8;

/// Checks the contract of [`Simd::knn_keys`] that keeps its loads and stores in bounds.
#[inline(always)]
fn check_knn_bounds(planes: &[&[f32]; 3], row: &CandidateRow, out: &[u64]) {
    let len = planes.iter().map(|p| p.len()).min().unwrap_or(0);
    assert!(row.p0 + row.n + KNN_KEYS_SLACK <= len && row.n + KNN_KEYS_SLACK <= out.len(), "k-NN keys outside their planes");
}

/// A k-NN candidate's sort key: the primary distance's bits, then the squared spatial distance
/// (capped), then the position in the window.
#[inline(always)]
pub(crate) fn knn_key(primary: u32, spatial: u64, local: u64) -> u64 {
    (primary as u64) << 32 | spatial.min(0xfff) << 20 | local
}

/// The squared distance of two colours (or feature vectors).
#[inline]
pub(crate) fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[inline(always)]
fn lane_sum(a: [f32; 8]) -> f32 {
    ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
}

/// The image passes give the same bits whichever build the dispatch picks: every estimator
/// that uses the kernels (the CBF error filter, every panel width and the general solve of the
/// control-variate pass, IDUW's criterion and output), run once dispatched (AVX2 here) and once
/// with the portable build forced.
#[cfg(all(test, target_arch = "x86_64"))]
mod dispatch_tests {
    use crate::synthetic::{RenderSpec, SoftShadowScene};
    use crate::{build, Input, Overrides};
    use cvtrace_streams::Image;

    fn images(runs: &[(&str, &[&str], usize)]) -> Vec<Image> {
        let scene = SoftShadowScene::default();
        runs.iter()
            .map(|(m, o, b)| {
                let spec = RenderSpec { width: 23, height: 19, spp: 2 * *b as u32, batches: *b, seed: 40 + *b as u64 };
                let set = scene.render(&spec).unwrap();
                build(m, &Overrides::parse(o.iter()).unwrap()).unwrap().run(&Input::new(&set)).unwrap().image
            })
            .collect()
    }

    #[test]
    fn ours_cv_and_iduw_images_are_bit_identical_with_the_portable_build_forced() {
        if super::Avx2::detect().is_none() {
            eprintln!("no AVX2 on this CPU: both runs would be portable");
            return;
        }
        let runs: Vec<(&str, &[&str], usize)> = vec![
            ("ours", &[], 16),                                                          // panel width 16, CBF errors, common floor
            ("ours", &["ours.crn_floor_mode=independent", "ours.penalty=residual"], 8), // width 8
            ("ours", &[], 24),                                                          // width 32
            ("ours", &["ours.k=40"], 36),                                               // width 64
            ("ours", &[], 32),                                                          // B ≥ k: the general f64 solve
            ("ours", &["ours.shared_coefficients=true"], 16),                           // general, 3·B columns
            ("ours", &["ours.folds=halves"], 16),                                       // two halves, width 8
            ("cv", &[], 16),
            ("iduw", &[], 16), // γ criterion and output
        ];
        let dispatched = images(&runs);
        let portable = super::force_portable(|| images(&runs));
        for ((m, o, b), (a, p)) in runs.iter().zip(dispatched.iter().zip(&portable)) {
            let differ = a.pixels.iter().zip(&p.pixels).filter(|(x, y)| x.map(f32::to_bits) != y.map(f32::to_bits)).count();
            assert_eq!(differ, 0, "{m} B = {b} {o:?}: {differ} pixels differ between the AVX2 and the portable build");
        }
    }
}

/// One cache line of values.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
struct Line([f32; 16]);

/// Zero-initialised f32 values that start on a 64-byte boundary; derefs to `[f32]`.
#[derive(Clone)]
pub struct Lines {
    lines: Vec<Line>,
    len: usize,
}

impl Lines {
    /// `len` zeros (the pages are zeroed by the allocator, as `vec![0.0; len]` would be).
    pub fn zeros(len: usize) -> Self {
        Lines { lines: bytemuck::zeroed_vec(len.div_ceil(16)), len }
    }
}

impl std::ops::Deref for Lines {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        &bytemuck::cast_slice(&self.lines)[..self.len]
    }
}

impl std::ops::DerefMut for Lines {
    fn deref_mut(&mut self) -> &mut [f32] {
        &mut bytemuck::cast_slice_mut(&mut self.lines)[..self.len]
    }
}

//! The few vector kernels of the per-pixel solve, in two builds with identical arithmetic.
//!
//! The compiler does not reliably vectorise these fixed-size loops at full width, so the
//! AVX2 build uses explicit intrinsics. The portable build performs the same IEEE operations
//! in the same order per element (no fused multiply-add anywhere, fixed lane structure for
//! sums), so both produce bit-identical results and the output does not depend on the CPU.
use crate::fast_exp::exp_neg;
#[cfg(target_arch = "x86_64")]
use crate::fast_exp::{exp_neg8_avx2, exp_neg8xn_avx2};

/// Whether the image passes run the AVX2 build: on CPUs that have it, unless a unit test has
/// forced the portable build (see [`force_portable`]; outside `cfg(test)` this is just the CPU
/// check).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn use_avx2() -> bool {
    #[cfg(test)]
    if FORCE_PORTABLE.load(std::sync::atomic::Ordering::SeqCst) {
        return false;
    }
    std::is_x86_feature_detected!("avx2")
}

#[cfg(test)]
static FORCE_PORTABLE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Runs `f` with the portable build forced on every thread (tests only). Both builds are
/// bit-identical, so other tests running meanwhile are unaffected; calls are serialised.
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

/// Vector kernels over fixed-width rows (`P` a multiple of 8).
pub(crate) trait Simd {
    /// For `q < 8`, `l < 8`: `Σ_j e_j[a0+q] · d_j[b0+l]` over the rows, summed in `j` order,
    /// where `e_j` is `d_j` scaled by its weight. Eight rows of the block at once: each
    /// accumulator is a chain of `k` dependent additions, and eight independent chains keep
    /// the adder busy where four left it waiting on their latency.
    fn gram_block<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8];
    /// Every 8×8 block of `Σ_j e_j·d_jᵀ` that touches the lower triangle, as
    /// [`Simd::gram_block`] forms it, into `out` (rows along `a`); the other blocks are left as
    /// they are.
    #[inline(always)]
    fn gram_lower<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
        for a0 in (0..P).step_by(8) {
            for b0 in (0..=a0).step_by(8) {
                let acc = Self::gram_block(d, e, a0, b0);
                for (dst, src) in out[a0..a0 + 8].iter_mut().zip(&acc) {
                    dst[b0..b0 + 8].copy_from_slice(src);
                }
            }
        }
    }
    /// `Σ a[l]·b[l]` with eight lane sums combined pairwise.
    fn dot32<const P: usize>(a: &[f32; P], b: &[f32; P]) -> f32;
    /// [`Simd::dot32`] of eight rows with one vector, the same bits: the eight rows' lane sums
    /// are combined side by side instead of one horizontal sum per row.
    fn dot32x8<const P: usize>(rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8];
    /// `out[l][r] = m[r][l]`.
    fn transpose8(m: [&[f32; 8]; 8]) -> [[f32; 8]; 8];
    /// The k-NN selection keys of the `n` candidates `p0 … p0 + n − 1` of one window row, whose
    /// offsets from the centre are `dx0 + l` and `dy` and whose window positions are
    /// `local0 + l`: candidate `l`'s key, as [`crate::selection::knn_key`] builds it from the
    /// squared CRN colour distance `dist2(centre, planes[·][p0 + l])`, goes to `out[l]`. Works
    /// in whole vectors: the planes must hold and `out` must take [`KNN_KEYS_SLACK`] values
    /// more than `n` (what lies beyond `n` in `out` is overwritten with unused keys).
    #[allow(clippy::too_many_arguments)]
    fn knn_keys(planes: [&[f32]; 3], centre: [f32; 3], p0: usize, n: usize, offset: [i32; 2], local0: u32, out: &mut [u64]);

    /// Eight f32 lanes (the panel's systems side by side), for the element-wise operations
    /// below; each is one IEEE operation per lane, so the builds agree bit for bit.
    type V: Copy;
    fn load8(a: &[f32; 8]) -> Self::V;
    fn store8(a: &mut [f32; 8], v: Self::V);
    fn splat8(x: f32) -> Self::V;
    fn add8(a: Self::V, b: Self::V) -> Self::V;
    fn sub8(a: Self::V, b: Self::V) -> Self::V;
    fn mul8(a: Self::V, b: Self::V) -> Self::V;
    fn div8(a: Self::V, b: Self::V) -> Self::V;
    fn sqrt8(a: Self::V) -> Self::V;
    /// `−a` (the sign flipped, exactly).
    fn neg8(a: Self::V) -> Self::V;
    /// `acc[l] += f64(v[l])²`.
    fn square_add8(acc: &mut [f64; 8], v: Self::V);
    /// `(Σ e^(−γ·t_i)·d_i, Σ e^(−γ·t_i))`: element `i` goes to lane `i mod 8` of chunk-wise
    /// partial sums (the tail of fewer than 8 to lanes 0…), combined pairwise.
    fn exp_weighted(t: &[f32], d: &[f32], gamma: f32) -> (f32, f32);
    /// [`Simd::exp_weighted`] for each of `gammas` (`out[q]` for `gammas[q]`), the same bits;
    /// the γ values' exponentials of an element are independent, so they run side by side.
    fn exp_weighted_gammas(t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]);
    /// `t_i ← e^(−t_i)`.
    fn exp_neg_in_place(t: &mut [f32]);
    /// IDUW's window sums for eight horizontally adjacent centres at once: for centre
    /// `c0 + l` (`l < 8`) window element `i` is pixel `n0 + offsets[i] + l` of the planes
    /// `[h, g, x, y]`, `t_i = (m·v_i)·v_i` with `v_i = (x_c − x_i) − (y_c − y_i)` and
    /// `d_i = (g_c − g_i) − (h_c − h_i)`, and for every `gammas[q]` lane `l` of `acc[q]` and
    /// `wsum[q]` receives exactly what [`Simd::exp_weighted`] returns for that centre's window.
    ///
    /// Vectorising across centres instead of along the window needs no window buffer and no
    /// horizontal sums, and shares the window's loads and differences among the γ values;
    /// element `i` still goes to partial sum `i mod 8`, in the same order, so the bits agree.
    #[allow(clippy::too_many_arguments)]
    fn iduw_sums8(
        planes: [&[f32]; 4],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        m: f32,
        gammas: &[f32],
        acc: &mut [[f32; 8]],
        wsum: &mut [[f32; 8]],
    );
    /// IDUW's weights of one image row's pairs along one offset: for `p` in `p0..p0 + n`,
    /// `out[p − p0] = e^(−γ·t)`, `t = (m·v)·v`, `v = (x_p − x_q) − (y_p − y_q)`, `q = p + off`:
    /// exactly the weight [`Simd::iduw_sums8`] and [`Simd::exp_weighted`] give neighbour `q` of
    /// centre `p`, and, because `v` only changes sign when the two swap, neighbour `p` of
    /// centre `q` too.
    #[allow(clippy::too_many_arguments)]
    fn iduw_pair_weights(x: &[f32], y: &[f32], p0: usize, off: usize, n: usize, m: f32, gamma: f32, out: &mut [f32]);
    /// [`Simd::iduw_sums8`] for one γ with the weights given, for `blocks` runs of eight
    /// centres along a row: lane `l` of block `b` is centre `c0 + 8b + l`, its window element
    /// `i` is neighbour `n0 + 8b + offsets[i] + l` with weight `weights[8b + src[i] + l]`, and
    /// `out[b]` receives `(Σ w·d, Σ w)` per lane (`blocks = out.len()`). The same partial sums
    /// in the same order as [`Simd::exp_weighted`], so the same bits when the weights are the
    /// ones [`Simd::iduw_pair_weights`] computes. Element by element across the blocks, so
    /// that every load streams along a row; `part` (at least `blocks` long) holds the partial
    /// sums.
    #[allow(clippy::too_many_arguments)]
    fn iduw_row_sums_weighted(
        h: &[f32],
        g: &[f32],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        weights: &[f32],
        src: &[usize],
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
fn check_iduw_bounds(planes: &[&[f32]; 4], c0: usize, n0: usize, offsets: &[usize], gammas: usize, acc: usize, wsum: usize) {
    let len = planes.iter().map(|p| p.len()).min().unwrap_or(0);
    let far = offsets.iter().copied().max().unwrap_or(0);
    assert!(
        offsets.len() <= IDUW_MAX_WINDOW && c0 + 8 <= len && n0 + far + 8 <= len && acc >= gammas && wsum >= gammas,
        "IDUW window outside the planes"
    );
}

/// Checks the contract of [`Simd::iduw_row_sums_weighted`] that keeps its loads in bounds;
/// returns the number of blocks.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn check_row_bounds(
    h: &[f32],
    g: &[f32],
    c0: usize,
    n0: usize,
    offsets: &[usize],
    weights: &[f32],
    src: &[usize],
    part: usize,
    out: usize,
) -> usize {
    let len = h.len().min(g.len());
    let far = offsets.iter().copied().max().unwrap_or(0);
    let far_w = src.iter().copied().max().unwrap_or(0);
    let span = 8 * out;
    assert!(
        src.len() == offsets.len() && part >= out && c0 + span <= len && n0 + far + span <= len && far_w + span <= weights.len(),
        "IDUW window or weights outside their planes"
    );
    out
}

/// Checks the contract of [`Simd::iduw_pair_weights`].
#[inline(always)]
fn check_pair_bounds(x: &[f32], y: &[f32], p0: usize, off: usize, n: usize, out: &[f32]) {
    assert!(p0 + off + n <= x.len().min(y.len()) && n <= out.len(), "IDUW pair outside the planes");
}

/// Extra values [`Simd::knn_keys`] may read from each plane and write to its output.
pub(crate) const KNN_KEYS_SLACK: usize = 8;

/// Checks the contract of [`Simd::knn_keys`] that keeps its loads and stores in bounds.
#[inline(always)]
fn check_knn_bounds(planes: &[&[f32]; 3], p0: usize, n: usize, out: &[u64]) {
    let len = planes.iter().map(|p| p.len()).min().unwrap_or(0);
    assert!(p0 + n + KNN_KEYS_SLACK <= len && n + KNN_KEYS_SLACK <= out.len(), "k-NN keys outside their planes");
}

#[inline(always)]
fn lane_sum(a: [f32; 8]) -> f32 {
    ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
}

pub(crate) struct Portable;

impl Simd for Portable {
    type V = [f32; 8];

    #[inline(always)]
    fn load8(a: &[f32; 8]) -> [f32; 8] {
        *a
    }

    #[inline(always)]
    fn store8(a: &mut [f32; 8], v: [f32; 8]) {
        *a = v;
    }

    #[inline(always)]
    fn splat8(x: f32) -> [f32; 8] {
        [x; 8]
    }

    #[inline(always)]
    fn add8(a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] + b[l])
    }

    #[inline(always)]
    fn sub8(a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] - b[l])
    }

    #[inline(always)]
    fn mul8(a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] * b[l])
    }

    #[inline(always)]
    fn div8(a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] / b[l])
    }

    #[inline(always)]
    fn sqrt8(a: [f32; 8]) -> [f32; 8] {
        a.map(f32::sqrt)
    }

    #[inline(always)]
    fn neg8(a: [f32; 8]) -> [f32; 8] {
        a.map(|x| -x)
    }

    #[inline(always)]
    fn square_add8(acc: &mut [f64; 8], v: [f32; 8]) {
        for (a, x) in acc.iter_mut().zip(v) {
            *a += f64::from(x) * f64::from(x);
        }
    }

    #[inline(always)]
    fn exp_weighted(t: &[f32], d: &[f32], gamma: f32) -> (f32, f32) {
        let (mut acc, mut wacc) = ([0.0f32; 8], [0.0f32; 8]);
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
        (lane_sum(acc), lane_sum(wacc))
    }

    #[inline(always)]
    fn exp_weighted_gammas(t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        for (o, &gamma) in out.iter_mut().zip(gammas) {
            *o = Portable::exp_weighted(t, d, gamma);
        }
    }

    #[inline(always)]
    fn exp_neg_in_place(t: &mut [f32]) {
        for v in t {
            *v = exp_neg(-*v);
        }
    }

    #[inline(always)]
    fn iduw_sums8(
        planes: [&[f32]; 4],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        m: f32,
        gammas: &[f32],
        acc: &mut [[f32; 8]],
        wsum: &mut [[f32; 8]],
    ) {
        check_iduw_bounds(&planes, c0, n0, offsets, gammas.len(), acc.len(), wsum.len());
        let [h, g, x, y] = planes;
        let n = offsets.len();
        let (mut tb, mut db) = ([0.0f32; IDUW_MAX_WINDOW], [0.0f32; IDUW_MAX_WINDOW]);
        let (t, d) = (&mut tb[..n], &mut db[..n]);
        for l in 0..8 {
            let c = c0 + l;
            for (i, &o) in offsets.iter().enumerate() {
                let j = n0 + o + l;
                let v = (x[c] - x[j]) - (y[c] - y[j]);
                t[i] = m * v * v;
                d[i] = (g[c] - g[j]) - (h[c] - h[j]);
            }
            for (q, &gamma) in gammas.iter().enumerate() {
                (acc[q][l], wsum[q][l]) = Portable::exp_weighted(t, d, gamma);
            }
        }
    }

    #[inline(always)]
    fn iduw_pair_weights(x: &[f32], y: &[f32], p0: usize, off: usize, n: usize, m: f32, gamma: f32, out: &mut [f32]) {
        check_pair_bounds(x, y, p0, off, n, out);
        for (k, o) in out[..n].iter_mut().enumerate() {
            let (p, q) = (p0 + k, p0 + k + off);
            let v = (x[p] - x[q]) - (y[p] - y[q]);
            *o = exp_neg(-gamma * (m * v * v));
        }
    }

    #[inline(always)]
    fn iduw_row_sums_weighted(
        h: &[f32],
        g: &[f32],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        weights: &[f32],
        src: &[usize],
        part: &mut [[[f32; 8]; 16]],
        out: &mut [([f32; 8], [f32; 8])],
    ) {
        let blocks = check_row_bounds(h, g, c0, n0, offsets, weights, src, part.len(), out.len());
        let part = &mut part[..blocks];
        part.fill([[0.0; 8]; 16]);
        for (i, (&o, &s)) in offsets.iter().zip(src).enumerate() {
            let a = i % 8;
            for (b, pb) in part.iter_mut().enumerate() {
                for l in 0..8 {
                    let (c, j) = (c0 + 8 * b + l, n0 + 8 * b + o + l);
                    let w = weights[8 * b + s + l];
                    pb[a][l] += w * ((g[c] - g[j]) - (h[c] - h[j]));
                    pb[8 + a][l] += w;
                }
            }
        }
        for (o, pb) in out.iter_mut().zip(part.iter()) {
            for l in 0..8 {
                o.0[l] = lane_sum(std::array::from_fn(|a| pb[a][l]));
                o.1[l] = lane_sum(std::array::from_fn(|a| pb[8 + a][l]));
            }
        }
    }

    #[inline(always)]
    fn gram_block<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8] {
        let mut acc = [[0.0f32; 8]; 8];
        for (r, ej) in d.iter().zip(e) {
            for q in 0..8 {
                let ra = ej[a0 + q];
                for l in 0..8 {
                    acc[q][l] += ra * r[b0 + l];
                }
            }
        }
        acc
    }

    #[inline(always)]
    fn dot32<const P: usize>(a: &[f32; P], b: &[f32; P]) -> f32 {
        let mut acc = [0.0f32; 8];
        for i in (0..P).step_by(8) {
            for l in 0..8 {
                acc[l] += a[i + l] * b[i + l];
            }
        }
        ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    }

    #[inline(always)]
    fn dot32x8<const P: usize>(rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8] {
        rows.map(|r| Portable::dot32(r, b))
    }

    #[inline(always)]
    fn transpose8(m: [&[f32; 8]; 8]) -> [[f32; 8]; 8] {
        std::array::from_fn(|l| std::array::from_fn(|r| m[r][l]))
    }

    #[inline(always)]
    fn knn_keys(planes: [&[f32]; 3], centre: [f32; 3], p0: usize, n: usize, [dx0, dy]: [i32; 2], local0: u32, out: &mut [u64]) {
        check_knn_bounds(&planes, p0, n, out);
        for (l, key) in out[..n].iter_mut().enumerate() {
            let p = p0 + l;
            let primary = crate::selection::dist2(&centre, &[planes[0][p], planes[1][p], planes[2][p]]).to_bits();
            let (dx, dy) = ((dx0 + l as i32) as i64, dy as i64);
            *key = crate::selection::knn_key(primary, (dx * dx + dy * dy) as u64, (local0 + l as u32) as u64);
        }
    }
}

/// AVX2 build; only used after `is_x86_feature_detected!("avx2")`, from functions compiled
/// with `#[target_feature(enable = "avx2")]`.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx2;

#[cfg(target_arch = "x86_64")]
impl Simd for Avx2 {
    type V = std::arch::x86_64::__m256;

    // SAFETY (all lane operations): AVX2 is available (see the type's contract); loads and
    // stores are of whole `[f32; 8]`s.
    #[inline(always)]
    fn load8(a: &[f32; 8]) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_loadu_ps(a.as_ptr()) }
    }

    #[inline(always)]
    fn store8(a: &mut [f32; 8], v: Self::V) {
        unsafe { std::arch::x86_64::_mm256_storeu_ps(a.as_mut_ptr(), v) }
    }

    #[inline(always)]
    fn splat8(x: f32) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_set1_ps(x) }
    }

    #[inline(always)]
    fn add8(a: Self::V, b: Self::V) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_add_ps(a, b) }
    }

    #[inline(always)]
    fn sub8(a: Self::V, b: Self::V) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_sub_ps(a, b) }
    }

    #[inline(always)]
    fn mul8(a: Self::V, b: Self::V) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_mul_ps(a, b) }
    }

    #[inline(always)]
    fn div8(a: Self::V, b: Self::V) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_div_ps(a, b) }
    }

    #[inline(always)]
    fn sqrt8(a: Self::V) -> Self::V {
        unsafe { std::arch::x86_64::_mm256_sqrt_ps(a) }
    }

    #[inline(always)]
    fn neg8(a: Self::V) -> Self::V {
        use std::arch::x86_64::*;
        unsafe { _mm256_xor_ps(a, _mm256_set1_ps(-0.0)) }
    }

    #[inline(always)]
    fn square_add8(acc: &mut [f64; 8], v: Self::V) {
        use std::arch::x86_64::*;
        unsafe {
            let lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
            let hi = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v));
            let (a0, a1) = (acc.as_mut_ptr(), acc.as_mut_ptr().add(4));
            _mm256_storeu_pd(a0, _mm256_add_pd(_mm256_loadu_pd(a0), _mm256_mul_pd(lo, lo)));
            _mm256_storeu_pd(a1, _mm256_add_pd(_mm256_loadu_pd(a1), _mm256_mul_pd(hi, hi)));
        }
    }

    #[inline(always)]
    fn exp_weighted(t: &[f32], d: &[f32], gamma: f32) -> (f32, f32) {
        use std::arch::x86_64::*;
        let n = t.len().min(d.len());
        let full = n / 8 * 8;
        let (mut acc, mut wacc) = ([0.0f32; 8], [0.0f32; 8]);
        // SAFETY: AVX2 is available (see the type's contract); loads stay below `full ≤ len`.
        unsafe {
            let g = _mm256_set1_ps(-gamma);
            let (mut a, mut wa) = (_mm256_setzero_ps(), _mm256_setzero_ps());
            for i in (0..full).step_by(8) {
                let w = exp_neg8_avx2(_mm256_mul_ps(g, _mm256_loadu_ps(t.as_ptr().add(i))));
                a = _mm256_add_ps(a, _mm256_mul_ps(w, _mm256_loadu_ps(d.as_ptr().add(i))));
                wa = _mm256_add_ps(wa, w);
            }
            _mm256_storeu_ps(acc.as_mut_ptr(), a);
            _mm256_storeu_ps(wacc.as_mut_ptr(), wa);
        }
        for (l, i) in (full..n).enumerate() {
            let w = exp_neg(-gamma * t[i]);
            acc[l] += w * d[i];
            wacc[l] += w;
        }
        (lane_sum(acc), lane_sum(wacc))
    }

    #[inline(always)]
    fn exp_weighted_gammas(t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        assert!(out.len() >= gammas.len(), "one output per γ");
        // Three chains side by side keep the core busy without spilling registers (five spill).
        let mut q = 0;
        while q < gammas.len() {
            let left = gammas.len() - q;
            let take = if left == 4 { 2 } else { left.min(3) };
            let (gs, o) = (&gammas[q..q + take], &mut out[q..q + take]);
            match take {
                1 => exp_weighted_n::<1>(t, d, gs, o),
                2 => exp_weighted_n::<2>(t, d, gs, o),
                _ => exp_weighted_n::<3>(t, d, gs, o),
            }
            q += take;
        }
    }

    #[inline(always)]
    fn exp_neg_in_place(t: &mut [f32]) {
        use std::arch::x86_64::*;
        let full = t.len() / 8 * 8;
        // SAFETY: AVX2 is available; loads and stores stay below `full ≤ len`.
        unsafe {
            let sign = _mm256_set1_ps(-0.0);
            for i in (0..full).step_by(8) {
                let p = t.as_mut_ptr().add(i);
                _mm256_storeu_ps(p, exp_neg8_avx2(_mm256_xor_ps(_mm256_loadu_ps(p), sign)));
            }
        }
        for v in &mut t[full..] {
            *v = exp_neg(-*v);
        }
    }

    #[inline(always)]
    fn iduw_sums8(
        planes: [&[f32]; 4],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        m: f32,
        gammas: &[f32],
        acc: &mut [[f32; 8]],
        wsum: &mut [[f32; 8]],
    ) {
        use std::arch::x86_64::*;
        check_iduw_bounds(&planes, c0, n0, offsets, gammas.len(), acc.len(), wsum.len());
        let [h, g, x, y] = planes;
        let n = offsets.len();
        for (chunk, gs) in gammas.chunks(IDUW_GAMMAS_AT_ONCE).enumerate() {
            let q0 = chunk * IDUW_GAMMAS_AT_ONCE;
            // SAFETY: AVX2 is available (see the type's contract); every load reads 8 values
            // starting at `c0` or at `n0 + offsets[i]`, in bounds by the check above.
            unsafe {
                let zero = _mm256_setzero_ps();
                let ld = |p: &[f32], at: usize| _mm256_loadu_ps(p.as_ptr().add(at));
                let (hc, gc, xc, yc) = (ld(h, c0), ld(g, c0), ld(x, c0), ld(y, c0));
                let mv = _mm256_set1_ps(m);
                let mut neg = [zero; IDUW_GAMMAS_AT_ONCE];
                for (v, &gamma) in neg.iter_mut().zip(gs) {
                    *v = _mm256_set1_ps(-gamma);
                }
                // Partial sum `a` of every centre holds the elements i ≡ a (mod 8), in order.
                let mut part = [[zero; 8]; IDUW_GAMMAS_AT_ONCE];
                let mut wpart = [[zero; 8]; IDUW_GAMMAS_AT_ONCE];
                for a in 0..8 {
                    let mut sa = [zero; IDUW_GAMMAS_AT_ONCE];
                    let mut wa = [zero; IDUW_GAMMAS_AT_ONCE];
                    for &o in offsets[a.min(n)..].iter().step_by(8) {
                        let j = n0 + o;
                        let v = _mm256_sub_ps(_mm256_sub_ps(xc, ld(x, j)), _mm256_sub_ps(yc, ld(y, j)));
                        let t = _mm256_mul_ps(_mm256_mul_ps(mv, v), v);
                        let d = _mm256_sub_ps(_mm256_sub_ps(gc, ld(g, j)), _mm256_sub_ps(hc, ld(h, j)));
                        for q in 0..gs.len() {
                            let w = exp_neg8_avx2(_mm256_mul_ps(neg[q], t));
                            sa[q] = _mm256_add_ps(sa[q], _mm256_mul_ps(w, d));
                            wa[q] = _mm256_add_ps(wa[q], w);
                        }
                    }
                    for q in 0..gs.len() {
                        part[q][a] = sa[q];
                        wpart[q][a] = wa[q];
                    }
                }
                let pairwise = |p: &[__m256; 8]| {
                    _mm256_add_ps(
                        _mm256_add_ps(_mm256_add_ps(p[0], p[1]), _mm256_add_ps(p[2], p[3])),
                        _mm256_add_ps(_mm256_add_ps(p[4], p[5]), _mm256_add_ps(p[6], p[7])),
                    )
                };
                for q in 0..gs.len() {
                    _mm256_storeu_ps(acc[q0 + q].as_mut_ptr(), pairwise(&part[q]));
                    _mm256_storeu_ps(wsum[q0 + q].as_mut_ptr(), pairwise(&wpart[q]));
                }
            }
        }
    }

    #[inline(always)]
    fn iduw_pair_weights(x: &[f32], y: &[f32], p0: usize, off: usize, n: usize, m: f32, gamma: f32, out: &mut [f32]) {
        use std::arch::x86_64::*;
        check_pair_bounds(x, y, p0, off, n, out);
        let full = n / 32 * 32;
        // SAFETY: AVX2 is available (see the type's contract); loads read below
        // `p0 + off + n ≤ len` and stores write below `n ≤ out.len()`, by the check above.
        unsafe {
            let (mv, neg) = (_mm256_set1_ps(m), _mm256_set1_ps(-gamma));
            let ld = |p: &[f32], at: usize| _mm256_loadu_ps(p.as_ptr().add(at));
            for k in (0..full).step_by(32) {
                // No closures over intrinsics here (they would not inherit AVX2).
                let mut arg = [_mm256_setzero_ps(); 4];
                for (u, a) in arg.iter_mut().enumerate() {
                    let (p, q) = (p0 + k + 8 * u, p0 + k + 8 * u + off);
                    let v = _mm256_sub_ps(_mm256_sub_ps(ld(x, p), ld(x, q)), _mm256_sub_ps(ld(y, p), ld(y, q)));
                    *a = _mm256_mul_ps(neg, _mm256_mul_ps(_mm256_mul_ps(mv, v), v));
                }
                let e = exp_neg8xn_avx2(arg);
                for (u, e) in e.iter().enumerate() {
                    _mm256_storeu_ps(out.as_mut_ptr().add(k + 8 * u), *e);
                }
            }
            for k in (full..n / 8 * 8).step_by(8) {
                let (p, q) = (p0 + k, p0 + k + off);
                let v = _mm256_sub_ps(_mm256_sub_ps(ld(x, p), ld(x, q)), _mm256_sub_ps(ld(y, p), ld(y, q)));
                let t = _mm256_mul_ps(_mm256_mul_ps(mv, v), v);
                _mm256_storeu_ps(out.as_mut_ptr().add(k), exp_neg8_avx2(_mm256_mul_ps(neg, t)));
            }
        }
        for k in n / 8 * 8..n {
            let (p, q) = (p0 + k, p0 + k + off);
            let v = (x[p] - x[q]) - (y[p] - y[q]);
            out[k] = exp_neg(-gamma * (m * v * v));
        }
    }

    #[inline(always)]
    fn iduw_row_sums_weighted(
        h: &[f32],
        g: &[f32],
        c0: usize,
        n0: usize,
        offsets: &[usize],
        weights: &[f32],
        src: &[usize],
        part: &mut [[[f32; 8]; 16]],
        out: &mut [([f32; 8], [f32; 8])],
    ) {
        use std::arch::x86_64::*;
        let blocks = check_row_bounds(h, g, c0, n0, offsets, weights, src, part.len(), out.len());
        let part = &mut part[..blocks];
        part.fill([[0.0; 8]; 16]);
        // SAFETY: AVX2 is available (see the type's contract); the loads read 8 values at
        // `c0 + 8b`, `n0 + 8b + offsets[i]` and `8b + src[i]` for b < blocks, in bounds by
        // the check above, and the partial sums are whole `[f32; 8]`s of `part`. Plain loops
        // (no closures over intrinsics: a closure would not inherit AVX2).
        unsafe {
            // Chunks of blocks whose partial sums stay in the L1 cache while the window's
            // elements go past.
            const CHUNK: usize = 16;
            for (k, chunk) in part.chunks_mut(CHUNK).enumerate() {
                let b0 = k * CHUNK;
                for (i, (&o, &s)) in offsets.iter().zip(src).enumerate() {
                    let a = i % 8;
                    for (db, pb) in chunk.iter_mut().enumerate() {
                        let b = b0 + db;
                        let (c, j) = (c0 + 8 * b, n0 + 8 * b + o);
                        let w = _mm256_loadu_ps(weights.as_ptr().add(8 * b + s));
                        let gd = _mm256_sub_ps(_mm256_loadu_ps(g.as_ptr().add(c)), _mm256_loadu_ps(g.as_ptr().add(j)));
                        let hd = _mm256_sub_ps(_mm256_loadu_ps(h.as_ptr().add(c)), _mm256_loadu_ps(h.as_ptr().add(j)));
                        let d = _mm256_sub_ps(gd, hd);
                        let (sa, wa) = (pb[a].as_mut_ptr(), pb[8 + a].as_mut_ptr());
                        _mm256_storeu_ps(sa, _mm256_add_ps(_mm256_loadu_ps(sa), _mm256_mul_ps(w, d)));
                        _mm256_storeu_ps(wa, _mm256_add_ps(_mm256_loadu_ps(wa), w));
                    }
                }
            }
            for (o, pb) in out.iter_mut().zip(part.iter()) {
                let mut p = [_mm256_setzero_ps(); 16];
                for (v, src) in p.iter_mut().zip(pb) {
                    *v = _mm256_loadu_ps(src.as_ptr());
                }
                let s = _mm256_add_ps(
                    _mm256_add_ps(_mm256_add_ps(p[0], p[1]), _mm256_add_ps(p[2], p[3])),
                    _mm256_add_ps(_mm256_add_ps(p[4], p[5]), _mm256_add_ps(p[6], p[7])),
                );
                let w = _mm256_add_ps(
                    _mm256_add_ps(_mm256_add_ps(p[8], p[9]), _mm256_add_ps(p[10], p[11])),
                    _mm256_add_ps(_mm256_add_ps(p[12], p[13]), _mm256_add_ps(p[14], p[15])),
                );
                _mm256_storeu_ps(o.0.as_mut_ptr(), s);
                _mm256_storeu_ps(o.1.as_mut_ptr(), w);
            }
        }
    }

    /// At `P = 16` on CPUs with AVX-512 the rows go through [`gram16_avx512`]: one
    /// kernel with explicit AVX-512 loops, where compiling the whole pass for AVX-512 would let
    /// the compiler turn plain loops into gathers and scatters.
    #[inline(always)]
    fn gram_lower<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
        if P == 16 && has_avx512() {
            // SAFETY: P is 16, so the casts only rename the types; AVX-512F/VL were detected.
            unsafe {
                let d16 = std::slice::from_raw_parts(d.as_ptr().cast::<&[f32; 16]>(), d.len());
                let e16 = std::slice::from_raw_parts(e.as_ptr().cast::<[f32; 16]>(), e.len());
                gram16_avx512(d16, e16, &mut *(out as *mut [[f32; P]; P]).cast::<[[f32; 16]; 16]>());
            }
            return;
        }
        for a0 in (0..P).step_by(8) {
            for b0 in (0..=a0).step_by(8) {
                let acc = Avx2::gram_block(d, e, a0, b0);
                for (dst, src) in out[a0..a0 + 8].iter_mut().zip(&acc) {
                    dst[b0..b0 + 8].copy_from_slice(src);
                }
            }
        }
    }

    #[inline(always)]
    fn gram_block<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8] {
        use std::arch::x86_64::*;
        assert!(a0 + 8 <= P && b0 + 8 <= P);
        // SAFETY: AVX2 is available (see the type's contract); loads stay inside each row
        // (asserted above).
        unsafe {
            let mut acc = [_mm256_setzero_ps(); 8];
            for (r, ej) in d.iter().zip(e) {
                let rb = _mm256_loadu_ps(r.as_ptr().add(b0));
                for (q, a) in acc.iter_mut().enumerate() {
                    let ra = _mm256_set1_ps(ej[a0 + q]);
                    *a = _mm256_add_ps(*a, _mm256_mul_ps(ra, rb));
                }
            }
            let mut out = [[0.0f32; 8]; 8];
            for (o, a) in out.iter_mut().zip(acc) {
                _mm256_storeu_ps(o.as_mut_ptr(), a);
            }
            out
        }
    }

    #[inline(always)]
    fn dot32<const P: usize>(a: &[f32; P], b: &[f32; P]) -> f32 {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is available; P is a multiple of 8.
        unsafe {
            let mut acc = _mm256_setzero_ps();
            for i in (0..P).step_by(8) {
                acc = _mm256_add_ps(acc, _mm256_mul_ps(_mm256_loadu_ps(a.as_ptr().add(i)), _mm256_loadu_ps(b.as_ptr().add(i))));
            }
            let mut l = [0.0f32; 8];
            _mm256_storeu_ps(l.as_mut_ptr(), acc);
            ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]))
        }
    }

    #[inline(always)]
    fn dot32x8<const P: usize>(rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8] {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is available; P is a multiple of 8.
        unsafe {
            // Row r's eight lane sums, each started from zero as in `dot32`.
            let mut v = [_mm256_setzero_ps(); 8];
            for (acc, r) in v.iter_mut().zip(rows) {
                for i in (0..P).step_by(8) {
                    let p = _mm256_mul_ps(_mm256_loadu_ps(r.as_ptr().add(i)), _mm256_loadu_ps(b.as_ptr().add(i)));
                    *acc = _mm256_add_ps(*acc, p);
                }
            }
            // hadd(x, y) = [x0+x1, x2+x3, y0+y1, y2+y3 | x4+x5, x6+x7, y4+y5, y6+y7]: two levels
            // give rows 0–3 (and 4–7) as [(l0+l1)+(l2+l3) per row | (l4+l5)+(l6+l7) per row],
            // and the last addition joins the halves, in `dot32`'s order.
            let q0 = _mm256_hadd_ps(_mm256_hadd_ps(v[0], v[1]), _mm256_hadd_ps(v[2], v[3]));
            let q1 = _mm256_hadd_ps(_mm256_hadd_ps(v[4], v[5]), _mm256_hadd_ps(v[6], v[7]));
            let lo = _mm256_permute2f128_ps::<0x20>(q0, q1);
            let hi = _mm256_permute2f128_ps::<0x31>(q0, q1);
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), _mm256_add_ps(lo, hi));
            out
        }
    }

    #[inline(always)]
    fn transpose8(m: [&[f32; 8]; 8]) -> [[f32; 8]; 8] {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is available; every row is eight values.
        unsafe {
            let mut r = [_mm256_setzero_ps(); 8];
            for (v, row) in r.iter_mut().zip(m) {
                *v = _mm256_loadu_ps(row.as_ptr());
            }
            let t0 = _mm256_unpacklo_ps(r[0], r[1]);
            let t1 = _mm256_unpackhi_ps(r[0], r[1]);
            let t2 = _mm256_unpacklo_ps(r[2], r[3]);
            let t3 = _mm256_unpackhi_ps(r[2], r[3]);
            let t4 = _mm256_unpacklo_ps(r[4], r[5]);
            let t5 = _mm256_unpackhi_ps(r[4], r[5]);
            let t6 = _mm256_unpacklo_ps(r[6], r[7]);
            let t7 = _mm256_unpackhi_ps(r[6], r[7]);
            let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
            let u1 = _mm256_shuffle_ps::<0xee>(t0, t2);
            let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
            let u3 = _mm256_shuffle_ps::<0xee>(t1, t3);
            let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
            let u5 = _mm256_shuffle_ps::<0xee>(t4, t6);
            let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
            let u7 = _mm256_shuffle_ps::<0xee>(t5, t7);
            let o = [
                _mm256_permute2f128_ps::<0x20>(u0, u4),
                _mm256_permute2f128_ps::<0x20>(u1, u5),
                _mm256_permute2f128_ps::<0x20>(u2, u6),
                _mm256_permute2f128_ps::<0x20>(u3, u7),
                _mm256_permute2f128_ps::<0x31>(u0, u4),
                _mm256_permute2f128_ps::<0x31>(u1, u5),
                _mm256_permute2f128_ps::<0x31>(u2, u6),
                _mm256_permute2f128_ps::<0x31>(u3, u7),
            ];
            let mut out = [[0.0f32; 8]; 8];
            for (dst, v) in out.iter_mut().zip(o) {
                _mm256_storeu_ps(dst.as_mut_ptr(), v);
            }
            out
        }
    }

    #[inline(always)]
    fn knn_keys(planes: [&[f32]; 3], centre: [f32; 3], p0: usize, n: usize, [dx0, dy]: [i32; 2], local0: u32, out: &mut [u64]) {
        use std::arch::x86_64::*;
        check_knn_bounds(&planes, p0, n, out);
        // SAFETY: AVX2 is available (see the type's contract); each chunk reads and writes 8
        // values from `p0 + l` and `l < n`, in bounds by the check above.
        unsafe {
            let [r, g, b] = planes;
            let (cr, cg, cb) = (_mm256_set1_ps(centre[0]), _mm256_set1_ps(centre[1]), _mm256_set1_ps(centre[2]));
            let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
            let (dy2, cap) = (_mm256_set1_epi32(dy * dy), _mm256_set1_epi32(0xfff));
            for l in (0..n).step_by(8) {
                let p = p0 + l;
                let dr = _mm256_sub_ps(cr, _mm256_loadu_ps(r.as_ptr().add(p)));
                let dg = _mm256_sub_ps(cg, _mm256_loadu_ps(g.as_ptr().add(p)));
                let db = _mm256_sub_ps(cb, _mm256_loadu_ps(b.as_ptr().add(p)));
                let d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dr, dr), _mm256_mul_ps(dg, dg)), _mm256_mul_ps(db, db));
                let dx = _mm256_add_epi32(_mm256_set1_epi32(dx0 + l as i32), lanes);
                let spatial = _mm256_min_epu32(_mm256_add_epi32(_mm256_mullo_epi32(dx, dx), dy2), cap);
                let local = _mm256_add_epi32(_mm256_set1_epi32((local0 + l as u32) as i32), lanes);
                let low = _mm256_or_si256(_mm256_slli_epi32::<20>(spatial), local);
                let high = _mm256_castps_si256(d2);
                // (low, high) pairs as u64: keys 0, 1, 4, 5 and 2, 3, 6, 7, then in order.
                let (a, c) = (_mm256_unpacklo_epi32(low, high), _mm256_unpackhi_epi32(low, high));
                let dst = out.as_mut_ptr().add(l).cast::<__m256i>();
                _mm256_storeu_si256(dst, _mm256_permute2x128_si256::<0x20>(a, c));
                _mm256_storeu_si256(dst.add(1), _mm256_permute2x128_si256::<0x31>(a, c));
            }
        }
    }
}

/// Whether the CPU has the AVX-512 subsets [`gram16_avx512`] uses (unless a unit test has
/// forced the portable build, which never calls it).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_avx512() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512vl")
}

/// [`Simd::gram_lower`] at `P = 16` with AVX-512: rows 8–15 of both lower blocks are one
/// 16-wide accumulator each, so every `e_j[8 + q]` is broadcast once for the two blocks, and
/// the broadcasts fold into the multiplications. Each element is still `Σ_j e_j[a]·d_j[b]`
/// in `j` order, no FMA: the bits of [`Simd::gram_block`]. A function of its own, so that
/// only these explicit loops are compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
#[inline(never)]
unsafe fn gram16_avx512(d: &[&[f32; 16]], e: &[[f32; 16]], out: &mut [[f32; 16]; 16]) {
    use std::arch::x86_64::*;
    // SAFETY: AVX-512F/VL are available (the caller's contract); every load and store is one
    // whole row of 8 or 16 values.
    unsafe {
        let mut lo = [_mm256_setzero_ps(); 8];
        let mut hi = [_mm512_setzero_ps(); 8];
        for (r, ej) in d.iter().zip(e) {
            let r8 = _mm256_loadu_ps(r.as_ptr());
            let r16 = _mm512_loadu_ps(r.as_ptr());
            for q in 0..8 {
                lo[q] = _mm256_add_ps(lo[q], _mm256_mul_ps(_mm256_set1_ps(ej[q]), r8));
                hi[q] = _mm512_add_ps(hi[q], _mm512_mul_ps(_mm512_set1_ps(ej[8 + q]), r16));
            }
        }
        for q in 0..8 {
            _mm256_storeu_ps(out[q].as_mut_ptr(), lo[q]);
            _mm512_storeu_ps(out[8 + q].as_mut_ptr(), hi[q]);
        }
    }
}

/// [`Simd::exp_weighted`] for `N` γ values at once (`gammas.len() == N`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn exp_weighted_n<const N: usize>(t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
    use std::arch::x86_64::*;
    let n = t.len().min(d.len());
    let full = n / 8 * 8;
    let (mut acc, mut wacc) = ([[0.0f32; 8]; N], [[0.0f32; 8]; N]);
    // SAFETY: only called from the AVX2 build (see `Avx2`'s contract); loads stay below
    // `full ≤ len`.
    unsafe {
        let mut g = [_mm256_setzero_ps(); N];
        for q in 0..N {
            g[q] = _mm256_set1_ps(-gammas[q]);
        }
        let (mut a, mut wa) = ([_mm256_setzero_ps(); N], [_mm256_setzero_ps(); N]);
        for i in (0..full).step_by(8) {
            let (tv, dv) = (_mm256_loadu_ps(t.as_ptr().add(i)), _mm256_loadu_ps(d.as_ptr().add(i)));
            let mut arg = g;
            for q in 0..N {
                arg[q] = _mm256_mul_ps(g[q], tv);
            }
            let w = exp_neg8xn_avx2(arg);
            for q in 0..N {
                a[q] = _mm256_add_ps(a[q], _mm256_mul_ps(w[q], dv));
                wa[q] = _mm256_add_ps(wa[q], w[q]);
            }
        }
        for q in 0..N {
            _mm256_storeu_ps(acc[q].as_mut_ptr(), a[q]);
            _mm256_storeu_ps(wacc[q].as_mut_ptr(), wa[q]);
        }
    }
    for (q, &gamma) in gammas.iter().enumerate() {
        for (l, i) in (full..n).enumerate() {
            let w = exp_neg(-gamma * t[i]);
            acc[q][l] += w * d[i];
            wacc[q][l] += w;
        }
        out[q] = (lane_sum(acc[q]), lane_sum(wacc[q]));
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};

    type Kernels = ([[f32; 8]; 8], f32, [f32; 8], [f32; 8], [[f32; 8]; 8]);

    #[target_feature(enable = "avx2")]
    fn avx_results(d: &[&[f32; 16]], c: &[[f32; 16]], y: &[f32; 16], e: &[&[f32; 32]], m: [&[f32; 8]; 8]) -> Kernels {
        let rows: [&[f32; 16]; 8] = std::array::from_fn(|r| d[3 + r]);
        let wide: [&[f32; 32]; 8] = std::array::from_fn(|r| e[r]);
        let z: &[f32; 32] = e[8];
        (Avx2::gram_block(d, c, 8, 0), Avx2::dot32(d[0], d[1]), Avx2::dot32x8(rows, y), Avx2::dot32x8(wide, z), Avx2::transpose8(m))
    }

    #[target_feature(enable = "avx2")]
    fn avx_gram_lower(d: &[&[f32; 16]], c: &[[f32; 16]], out: &mut [[f32; 16]; 16]) {
        Avx2::gram_lower(d, c, out);
    }

    #[target_feature(enable = "avx2")]
    fn avx_exp(t: &[f32], d: &[f32]) -> ((f32, f32), Vec<f32>) {
        let mut tt = t.to_vec();
        Avx2::exp_neg_in_place(&mut tt);
        (Avx2::exp_weighted(t, d, 0.7), tt)
    }

    #[target_feature(enable = "avx2")]
    fn avx_exp_gammas(t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        Avx2::exp_weighted_gammas(t, d, gammas, out);
    }

    #[target_feature(enable = "avx2")]
    fn avx_iduw(planes: [&[f32]; 4], c0: usize, n0: usize, offsets: &[usize], gammas: &[f32]) -> (Vec<[f32; 8]>, Vec<[f32; 8]>) {
        let (mut acc, mut ws) = (vec![[0.0; 8]; gammas.len()], vec![[0.0; 8]; gammas.len()]);
        Avx2::iduw_sums8(planes, c0, n0, offsets, 0.75, gammas, &mut acc, &mut ws);
        (acc, ws)
    }

    /// The eight-centre IDUW kernel against [`Simd::exp_weighted`] of each centre's window,
    /// bit for bit, in both builds; with more γ values than the kernel keeps at once.
    #[test]
    fn iduw_window_sums_match_the_per_centre_sums() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let (w, h, r) = (40usize, 20usize, 7usize);
        let u = |a: u64, b: u64| uniform(hash4(11, a, b, 0)) as f32;
        let planes: Vec<Vec<f32>> = (0..4).map(|p| (0..w * h).map(|i| u(p, i as u64) * 2.0).collect()).collect();
        let [ph, pg, px, py] = [&planes[0][..], &planes[1][..], &planes[2][..], &planes[3][..]];
        let side = 2 * r + 1;
        let offsets: Vec<usize> = (0..side).flat_map(|row| (0..side).map(move |col| (row + 2) * w + col)).collect();
        let gammas: Vec<f32> = (0..13).map(|i| 0.05 + 0.3 * i as f32).collect();
        let (x0, y) = (9usize, 9usize);
        let (c0, n0) = (y * w + x0, x0 - r);
        // SAFETY: AVX2 detected above.
        let (acc, ws) = unsafe { avx_iduw([ph, pg, px, py], c0, n0, &offsets, &gammas) };
        let (mut pacc, mut pws) = (vec![[0.0; 8]; gammas.len()], vec![[0.0; 8]; gammas.len()]);
        Portable::iduw_sums8([ph, pg, px, py], c0, n0, &offsets, 0.75, &gammas, &mut pacc, &mut pws);
        for l in 0..8 {
            let c = c0 + l;
            let (t, d): (Vec<f32>, Vec<f32>) = offsets
                .iter()
                .map(|&o| {
                    let j = n0 + o + l;
                    let v = (px[c] - px[j]) - (py[c] - py[j]);
                    (0.75 * v * v, (pg[c] - pg[j]) - (ph[c] - ph[j]))
                })
                .unzip();
            for (q, &gamma) in gammas.iter().enumerate() {
                let (a, s) = Portable::exp_weighted(&t, &d, gamma);
                assert_eq!((acc[q][l].to_bits(), ws[q][l].to_bits()), (a.to_bits(), s.to_bits()), "AVX2, centre {l}, γ {gamma}");
                assert_eq!((pacc[q][l].to_bits(), pws[q][l].to_bits()), (a.to_bits(), s.to_bits()), "portable, centre {l}, γ {gamma}");
            }
        }
    }

    #[test]
    fn avx2_and_portable_agree_bit_for_bit() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let u = |a: u64, b: u64| uniform(hash4(5, a, b, 0)) - 0.5;
        let d: Vec<[f32; 16]> = (0..25).map(|j| std::array::from_fn(|b| u(j, b as u64) as f32)).collect();
        let c: Vec<[f32; 16]> = (0..25).map(|j| std::array::from_fn(|b| u(99, 16 * j + b as u64) as f32 + 1.0)).collect();
        let y: [f32; 16] = std::array::from_fn(|i| (u(8, i as u64) * 1e-3) as f32);
        let d: Vec<&[f32; 16]> = d.iter().collect();
        // Rows of 32 (two chunks per lane sum), with exact zeros and a negative zero among them.
        let mut e: Vec<[f32; 32]> = (0..9).map(|j| std::array::from_fn(|b| u(77 + j, b as u64) as f32)).collect();
        e[2][5] = 0.0;
        e[2][13] = -0.0;
        e[8][13] = 0.0;
        let e: Vec<&[f32; 32]> = e.iter().collect();
        let m: Vec<[f32; 8]> = (0..8).map(|r| std::array::from_fn(|l| (8 * r + l) as f32)).collect();
        let m: [&[f32; 8]; 8] = std::array::from_fn(|r| &m[r]);
        // SAFETY: AVX2 detected above.
        let (g, d32, dots, wide, t) = unsafe { avx_results(&d, &c, &y, &e, m) };
        assert_eq!(g, Portable::gram_block(&d, &c, 8, 0));
        // The whole lower triangle (with AVX-512 where the CPU has it) against the portable
        // blocks; the blocks above the diagonal are not formed.
        let (mut lower, mut want) = ([[0.0f32; 16]; 16], [[0.0f32; 16]; 16]);
        // SAFETY: AVX2 detected above.
        unsafe { avx_gram_lower(&d, &c, &mut lower) };
        Portable::gram_lower(&d, &c, &mut want);
        for a in 0..16 {
            let formed = if a < 8 { 8 } else { 16 };
            assert_eq!(
                lower[a][..formed].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want[a][..formed].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                "row {a} (AVX-512: {})",
                has_avx512()
            );
        }
        assert_eq!(d32.to_bits(), Portable::dot32(d[0], d[1]).to_bits());
        // Eight dot products at once: each the bits of `dot32`, in both builds.
        for r in 0..8 {
            let one = Portable::dot32(d[3 + r], &y).to_bits();
            assert_eq!((dots[r].to_bits(), Portable::dot32x8(std::array::from_fn(|q| d[3 + q]), &y)[r].to_bits()), (one, one), "row {r}");
            let one = Portable::dot32(e[r], e[8]).to_bits();
            assert_eq!(
                (wide[r].to_bits(), Portable::dot32x8(std::array::from_fn(|q| e[q]), e[8])[r].to_bits()),
                (one, one),
                "wide row {r}"
            );
        }
        let want: [[f32; 8]; 8] = std::array::from_fn(|l| std::array::from_fn(|r| (8 * r + l) as f32));
        assert_eq!((t, Portable::transpose8(m)), (want, want));
        let t: Vec<f32> = (0..229).map(|i| (u(3, i) + 0.5) as f32 * 4.0).collect();
        let dd: Vec<f32> = (0..229).map(|i| u(4, i) as f32).collect();
        // SAFETY: AVX2 detected above.
        let (ew, mut tt) = unsafe { avx_exp(&t, &dd) };
        let mut pt = t.clone();
        Portable::exp_neg_in_place(&mut pt);
        let pw = Portable::exp_weighted(&t, &dd, 0.7);
        assert_eq!((ew.0.to_bits(), ew.1.to_bits()), (pw.0.to_bits(), pw.1.to_bits()));
        // Several γ at once: each the one-γ sums, in both builds, for every chunking of the list.
        let gammas: Vec<f32> = (0..10).map(|q| 0.01 + 0.27 * q as f32).collect();
        for len in [229usize, 225, 7] {
            for count in 1..=gammas.len() {
                let (mut a, mut p) = (vec![(0.0, 0.0); count], vec![(0.0, 0.0); count]);
                // SAFETY: AVX2 detected above.
                unsafe { avx_exp_gammas(&t[..len], &dd[..len], &gammas[..count], &mut a) };
                Portable::exp_weighted_gammas(&t[..len], &dd[..len], &gammas[..count], &mut p);
                for q in 0..count {
                    let one = Portable::exp_weighted(&t[..len], &dd[..len], gammas[q]);
                    let bits = |v: (f32, f32)| (v.0.to_bits(), v.1.to_bits());
                    assert_eq!((bits(a[q]), bits(p[q])), (bits(one), bits(one)), "{len} elements, {count} γ, γ #{q}");
                }
            }
        }
        assert!(tt.iter_mut().zip(&pt).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
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
        if !std::is_x86_feature_detected!("avx2") {
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

//! The AVX2 build: the kernels with explicit 256-bit intrinsics, and the entry point that
//! compiles a [`Kernel`] with AVX2.
use super::{
    check_iduw_bounds, check_knn_bounds, check_pair_bounds, check_row_bounds, lane_sum, Avx512, CandidateRow, IduwPlanes, Kernel, Pairs,
    SharedWeights, Simd, Windows, IDUW_GAMMAS_AT_ONCE,
};
use crate::fast_exp::exp_neg;
use std::arch::x86_64::*;

/// The AVX2 build. Only [`Avx2::detect`] makes one, on CPUs with AVX2, so a value proves that
/// the CPU runs AVX2 instructions: that is what makes its methods, which run them, safe.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx2 {
    _detected: (),
}

impl Avx2 {
    /// The build, if this CPU has AVX2.
    #[inline]
    pub(crate) fn detect() -> Option<Self> {
        std::is_x86_feature_detected!("avx2").then_some(Avx2 { _detected: () })
    }

    /// Runs `kernel` with this build, compiled with AVX2: the kernel and the methods it calls
    /// are inlined into a function with the feature enabled, so the intrinsics inline too.
    #[inline(always)]
    pub(crate) fn run<K: Kernel>(self, kernel: K) -> K::Output {
        // SAFETY: `self` exists, so `detect` found AVX2 on this CPU, the one feature
        // `run_avx2` is compiled with.
        unsafe { run_avx2(self, kernel) }
    }

    /// Eight [`exp_neg`]s, the same IEEE operations in the same order (bit-identical).
    #[inline(always)]
    fn exp_neg8(self, x: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2; the intrinsics only compute on values, with no memory
        // access.
        unsafe {
            const ROUND: f32 = 12_582_912.0;
            let c = |v: f32| _mm256_set1_ps(v);
            let x = _mm256_max_ps(_mm256_min_ps(x, c(0.0)), c(-87.0));
            let kf = _mm256_add_ps(_mm256_mul_ps(x, c(std::f32::consts::LOG2_E)), c(ROUND));
            let n = _mm256_sub_ps(kf, c(ROUND));
            let r = _mm256_sub_ps(_mm256_sub_ps(x, _mm256_mul_ps(n, c(0.693_145_75))), _mm256_mul_ps(n, c(1.428_606_8e-6)));
            let mut p = _mm256_add_ps(c(0.008_333_452), _mm256_mul_ps(r, c(0.001_388_720_5)));
            for k in [0.041_666_668, 0.166_666_67, 0.5, 1.0, 1.0] {
                p = _mm256_add_ps(c(k), _mm256_mul_ps(r, p));
            }
            let bits = _mm256_slli_epi32::<23>(_mm256_add_epi32(
                _mm256_sub_epi32(_mm256_castps_si256(kf), _mm256_set1_epi32(ROUND.to_bits() as i32)),
                _mm256_set1_epi32(127),
            ));
            _mm256_mul_ps(p, _mm256_castsi256_ps(bits))
        }
    }

    /// `N` independent [`Avx2::exp_neg8`]s computed step by step together, the same bits per
    /// lane. One exponential is a chain of about twenty dependent operations; a loop of them
    /// fills the core's floating-point scheduler with one chain at a time, so interleaving
    /// independent ones keeps more of them in flight.
    #[inline(always)]
    fn exp_neg8xn<const N: usize>(self, x: [__m256; N]) -> [__m256; N] {
        // Plain loops, no closures: a closure does not inherit the caller's AVX2 and would call
        // every intrinsic instead of inlining it.
        // SAFETY: as for `exp_neg8`: `self` proves AVX2, and nothing touches memory.
        unsafe {
            const ROUND: f32 = 12_582_912.0;
            let (lo, hi) = (_mm256_set1_ps(-87.0), _mm256_setzero_ps());
            let (log2e, round) = (_mm256_set1_ps(std::f32::consts::LOG2_E), _mm256_set1_ps(ROUND));
            let (ln2_hi, ln2_lo) = (_mm256_set1_ps(0.693_145_75), _mm256_set1_ps(1.428_606_8e-6));
            let mut kf = x;
            let mut r = x;
            let mut p = x;
            for i in 0..N {
                let xi = _mm256_max_ps(_mm256_min_ps(x[i], hi), lo);
                kf[i] = _mm256_add_ps(_mm256_mul_ps(xi, log2e), round);
                let n = _mm256_sub_ps(kf[i], round);
                r[i] = _mm256_sub_ps(_mm256_sub_ps(xi, _mm256_mul_ps(n, ln2_hi)), _mm256_mul_ps(n, ln2_lo));
                p[i] = _mm256_add_ps(_mm256_set1_ps(0.008_333_452), _mm256_mul_ps(r[i], _mm256_set1_ps(0.001_388_720_5)));
            }
            for k in [0.041_666_668, 0.166_666_67, 0.5, 1.0, 1.0] {
                let kv = _mm256_set1_ps(k);
                for i in 0..N {
                    p[i] = _mm256_add_ps(kv, _mm256_mul_ps(r[i], p[i]));
                }
            }
            let (bias, one27) = (_mm256_set1_epi32(ROUND.to_bits() as i32), _mm256_set1_epi32(127));
            for i in 0..N {
                let bits = _mm256_slli_epi32::<23>(_mm256_add_epi32(_mm256_sub_epi32(_mm256_castps_si256(kf[i]), bias), one27));
                p[i] = _mm256_mul_ps(p[i], _mm256_castsi256_ps(bits));
            }
            p
        }
    }

    /// [`Simd::exp_weighted`] for `N` γ values at once (`gammas.len() == N`).
    #[inline(always)]
    fn exp_weighted_n<const N: usize>(self, t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        let n = t.len().min(d.len());
        let full = n / 8 * 8;
        let (mut acc, mut wacc) = ([[0.0f32; 8]; N], [[0.0f32; 8]; N]);
        // SAFETY: `self` proves AVX2; loads stay below `full ≤ len`, stores are of whole
        // `[f32; 8]`s.
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
                let w = self.exp_neg8xn(arg);
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
}

/// `kernel` with the AVX2 build, compiled with AVX2 (see [`Avx2::run`]).
#[target_feature(enable = "avx2")]
fn run_avx2<K: Kernel>(simd: Avx2, kernel: K) -> K::Output {
    kernel.run(simd)
}

impl Simd for Avx2 {
    type V = __m256;

    #[inline(always)]
    fn load8(self, a: &[f32; 8]) -> __m256 {
        // SAFETY: `self` proves AVX2; the load reads one whole `[f32; 8]`.
        unsafe { _mm256_loadu_ps(a.as_ptr()) }
    }

    #[inline(always)]
    fn store8(self, a: &mut [f32; 8], v: __m256) {
        // SAFETY: `self` proves AVX2; the store writes one whole `[f32; 8]`.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) }
    }

    #[inline(always)]
    fn splat8(self, x: f32) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_set1_ps(x) }
    }

    #[inline(always)]
    fn add8(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_add_ps(a, b) }
    }

    #[inline(always)]
    fn sub8(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_sub_ps(a, b) }
    }

    #[inline(always)]
    fn mul8(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_mul_ps(a, b) }
    }

    #[inline(always)]
    fn div8(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_div_ps(a, b) }
    }

    #[inline(always)]
    fn sqrt8(self, a: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_sqrt_ps(a) }
    }

    #[inline(always)]
    fn neg8(self, a: __m256) -> __m256 {
        // SAFETY: `self` proves AVX2.
        unsafe { _mm256_xor_ps(a, _mm256_set1_ps(-0.0)) }
    }

    #[inline(always)]
    fn square_add8(self, acc: &mut [f64; 8], v: __m256) {
        // SAFETY: `self` proves AVX2; the loads and stores are the two halves of `acc`.
        unsafe {
            let lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
            let hi = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v));
            let (a0, a1) = (acc.as_mut_ptr(), acc.as_mut_ptr().add(4));
            _mm256_storeu_pd(a0, _mm256_add_pd(_mm256_loadu_pd(a0), _mm256_mul_pd(lo, lo)));
            _mm256_storeu_pd(a1, _mm256_add_pd(_mm256_loadu_pd(a1), _mm256_mul_pd(hi, hi)));
        }
    }

    #[inline(always)]
    fn exp_weighted(self, t: &[f32], d: &[f32], gamma: f32) -> (f32, f32) {
        let n = t.len().min(d.len());
        let full = n / 8 * 8;
        let (mut acc, mut wacc) = ([0.0f32; 8], [0.0f32; 8]);
        // SAFETY: `self` proves AVX2; loads stay below `full ≤ len`, stores are of whole
        // `[f32; 8]`s.
        unsafe {
            let g = _mm256_set1_ps(-gamma);
            let (mut a, mut wa) = (_mm256_setzero_ps(), _mm256_setzero_ps());
            for i in (0..full).step_by(8) {
                let w = self.exp_neg8(_mm256_mul_ps(g, _mm256_loadu_ps(t.as_ptr().add(i))));
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
    fn exp_weighted_gammas(self, t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        assert!(out.len() >= gammas.len(), "one output per γ");
        // Three chains side by side keep the core busy without spilling registers (five spill).
        let mut q = 0;
        while q < gammas.len() {
            let left = gammas.len() - q;
            let take = if left == 4 { 2 } else { left.min(3) };
            let (gs, o) = (&gammas[q..q + take], &mut out[q..q + take]);
            match take {
                1 => self.exp_weighted_n::<1>(t, d, gs, o),
                2 => self.exp_weighted_n::<2>(t, d, gs, o),
                _ => self.exp_weighted_n::<3>(t, d, gs, o),
            }
            q += take;
        }
    }

    #[inline(always)]
    fn exp_neg_in_place(self, t: &mut [f32]) {
        let full = t.len() / 8 * 8;
        // SAFETY: `self` proves AVX2; loads and stores stay below `full ≤ len`.
        unsafe {
            let sign = _mm256_set1_ps(-0.0);
            for i in (0..full).step_by(8) {
                let p = t.as_mut_ptr().add(i);
                _mm256_storeu_ps(p, self.exp_neg8(_mm256_xor_ps(_mm256_loadu_ps(p), sign)));
            }
        }
        for v in &mut t[full..] {
            *v = exp_neg(-*v);
        }
    }

    #[inline(always)]
    fn iduw_sums8(self, p: &IduwPlanes, win: Windows, gammas: &[f32], acc: &mut [[f32; 8]], wsum: &mut [[f32; 8]]) {
        check_iduw_bounds(p, &win, gammas.len(), acc.len(), wsum.len());
        let IduwPlanes { h, g, x, y, m } = *p;
        let Windows { c0, n0, offsets } = win;
        let n = offsets.len();
        for (chunk, gs) in gammas.chunks(IDUW_GAMMAS_AT_ONCE).enumerate() {
            let q0 = chunk * IDUW_GAMMAS_AT_ONCE;
            // SAFETY: `self` proves AVX2; every load reads 8 values starting at `c0` or at
            // `n0 + offsets[i]`, in bounds by the check above, and every store writes one
            // whole `[f32; 8]` of `acc` or `wsum`, which hold one per γ (checked too).
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
                            let w = self.exp_neg8(_mm256_mul_ps(neg[q], t));
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
    fn iduw_pair_weights(self, p: &IduwPlanes, pairs: Pairs, gamma: f32, out: &mut [f32]) {
        check_pair_bounds(p, &pairs, out);
        let (x, y, m) = (p.x, p.y, p.m);
        let Pairs { p0, off, n } = pairs;
        let full = n / 32 * 32;
        // SAFETY: `self` proves AVX2; loads read below `p0 + off + n ≤ len` and stores write
        // below `n ≤ out.len()`, by the check above.
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
                let e = self.exp_neg8xn(arg);
                for (u, e) in e.iter().enumerate() {
                    _mm256_storeu_ps(out.as_mut_ptr().add(k + 8 * u), *e);
                }
            }
            for k in (full..n / 8 * 8).step_by(8) {
                let (p, q) = (p0 + k, p0 + k + off);
                let v = _mm256_sub_ps(_mm256_sub_ps(ld(x, p), ld(x, q)), _mm256_sub_ps(ld(y, p), ld(y, q)));
                let t = _mm256_mul_ps(_mm256_mul_ps(mv, v), v);
                _mm256_storeu_ps(out.as_mut_ptr().add(k), self.exp_neg8(_mm256_mul_ps(neg, t)));
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
        self,
        p: &IduwPlanes,
        win: Windows,
        weights: SharedWeights,
        part: &mut [[[f32; 8]; 16]],
        out: &mut [([f32; 8], [f32; 8])],
    ) {
        let blocks = check_row_bounds(p, &win, &weights, part.len(), out.len());
        let (h, g) = (p.h, p.g);
        let Windows { c0, n0, offsets } = win;
        let SharedWeights { values: weights, src } = weights;
        let part = &mut part[..blocks];
        part.fill([[0.0; 8]; 16]);
        // SAFETY: `self` proves AVX2; the loads read 8 values at `c0 + 8b`,
        // `n0 + 8b + offsets[i]` and `8b + src[i]` for b < blocks, in bounds by the check
        // above, and the partial sums and outputs are whole `[f32; 8]`s of `part` and `out`.
        // Plain loops (no closures over intrinsics: a closure would not inherit AVX2).
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

    /// At `P = 16` on CPUs with AVX-512 the rows go through [`Avx512::gram16`]: one kernel
    /// with explicit AVX-512 loops, where compiling the whole pass for AVX-512 would let the
    /// compiler turn plain loops into gathers and scatters.
    #[inline(always)]
    fn gram_lower<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
        if P == 16 {
            if let Some(avx512) = Avx512::detect() {
                avx512.gram16(d, e, out);
                return;
            }
        }
        for a0 in (0..P).step_by(8) {
            for b0 in (0..=a0).step_by(8) {
                let acc = self.gram_block(d, e, a0, b0);
                for (dst, src) in out[a0..a0 + 8].iter_mut().zip(&acc) {
                    dst[b0..b0 + 8].copy_from_slice(src);
                }
            }
        }
    }

    #[inline(always)]
    fn gram_block<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8] {
        assert!(a0 + 8 <= P && b0 + 8 <= P);
        // SAFETY: `self` proves AVX2; loads stay inside each row (asserted above), stores are
        // of whole `[f32; 8]`s.
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
    fn dot32<const P: usize>(self, a: &[f32; P], b: &[f32; P]) -> f32 {
        // SAFETY: `self` proves AVX2; P is a multiple of 8, so the loads stay inside the rows.
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
    fn dot32x8<const P: usize>(self, rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8] {
        // SAFETY: `self` proves AVX2; P is a multiple of 8, so the loads stay inside the rows.
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
    fn transpose8(self, m: [&[f32; 8]; 8]) -> [[f32; 8]; 8] {
        // SAFETY: `self` proves AVX2; every row loaded or stored is eight values.
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
    fn knn_keys(self, planes: [&[f32]; 3], centre: [f32; 3], row: CandidateRow, out: &mut [u64]) {
        check_knn_bounds(&planes, &row, out);
        let CandidateRow { p0, n, offset: [dx0, dy], local0 } = row;
        // SAFETY: `self` proves AVX2; each chunk reads and writes 8 values from `p0 + l` and
        // `l < n`, in bounds by the check above.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};
    use crate::simd::Portable;

    /// The two exponential kernels give [`exp_neg`]'s bits in every lane, also for arguments
    /// above 0 (clamped) and for −0.
    #[test]
    fn exponentials_are_bit_identical_to_the_scalar_ones() {
        let Some(avx2) = Avx2::detect() else { return };
        for i in 0..20_000 {
            let x: [f32; 8] = std::array::from_fn(|l| -(i as f32 * 8.0 + l as f32) * 0.0006 + if i % 7 == 0 { 1.0 } else { 0.0 });
            let v = avx2.load8(&x);
            let mut out = [0.0f32; 8];
            avx2.store8(&mut out, avx2.exp_neg8(v));
            assert_eq!(out.map(f32::to_bits), x.map(|v| exp_neg(v).to_bits()), "{x:?}");
            let mut three = [[0.0f32; 8]; 3];
            let got = avx2.exp_neg8xn([v, avx2.mul8(v, avx2.splat8(0.5)), avx2.splat8(-0.0)]);
            for (o, g) in three.iter_mut().zip(got) {
                avx2.store8(o, g);
            }
            assert_eq!(three[0].map(f32::to_bits), out.map(f32::to_bits));
            assert_eq!(three[1].map(f32::to_bits), x.map(|v| exp_neg(v * 0.5).to_bits()));
            assert_eq!(three[2], [1.0; 8]);
        }
    }

    /// The eight-centre IDUW kernel against [`Simd::exp_weighted`] of each centre's window,
    /// bit for bit, in both builds; with more γ values than the kernel keeps at once.
    #[test]
    fn iduw_window_sums_match_the_per_centre_sums() {
        let Some(avx2) = Avx2::detect() else { return };
        let (w, h, r) = (40usize, 20usize, 7usize);
        let u = |a: u64, b: u64| uniform(hash4(11, a, b, 0)) as f32;
        let planes: Vec<Vec<f32>> = (0..4).map(|p| (0..w * h).map(|i| u(p, i as u64) * 2.0).collect()).collect();
        let [ph, pg, px, py] = [&planes[0][..], &planes[1][..], &planes[2][..], &planes[3][..]];
        let p = IduwPlanes { h: ph, g: pg, x: px, y: py, m: 0.75 };
        let side = 2 * r + 1;
        let offsets: Vec<usize> = (0..side).flat_map(|row| (0..side).map(move |col| (row + 2) * w + col)).collect();
        let gammas: Vec<f32> = (0..13).map(|i| 0.05 + 0.3 * i as f32).collect();
        let (x0, y) = (9usize, 9usize);
        let (c0, n0) = (y * w + x0, x0 - r);
        let win = Windows { c0, n0, offsets: &offsets };
        let (mut acc, mut ws) = (vec![[0.0; 8]; gammas.len()], vec![[0.0; 8]; gammas.len()]);
        avx2.iduw_sums8(&p, win, &gammas, &mut acc, &mut ws);
        let (mut pacc, mut pws) = (vec![[0.0; 8]; gammas.len()], vec![[0.0; 8]; gammas.len()]);
        Portable.iduw_sums8(&p, win, &gammas, &mut pacc, &mut pws);
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
                let (a, s) = Portable.exp_weighted(&t, &d, gamma);
                assert_eq!((acc[q][l].to_bits(), ws[q][l].to_bits()), (a.to_bits(), s.to_bits()), "AVX2, centre {l}, γ {gamma}");
                assert_eq!((pacc[q][l].to_bits(), pws[q][l].to_bits()), (a.to_bits(), s.to_bits()), "portable, centre {l}, γ {gamma}");
            }
        }
    }

    #[test]
    fn avx2_and_portable_agree_bit_for_bit() {
        let Some(avx2) = Avx2::detect() else { return };
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
        assert_eq!(avx2.gram_block(&d, &c, 8, 0), Portable.gram_block(&d, &c, 8, 0));
        // The whole lower triangle (with AVX-512 where the CPU has it) against the portable
        // blocks; the blocks above the diagonal are not formed.
        let (mut lower, mut want) = ([[0.0f32; 16]; 16], [[0.0f32; 16]; 16]);
        avx2.gram_lower(&d, &c, &mut lower);
        Portable.gram_lower(&d, &c, &mut want);
        for a in 0..16 {
            let formed = if a < 8 { 8 } else { 16 };
            assert_eq!(
                lower[a][..formed].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want[a][..formed].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                "row {a} (AVX-512: {})",
                Avx512::detect().is_some()
            );
        }
        assert_eq!(avx2.dot32(d[0], d[1]).to_bits(), Portable.dot32(d[0], d[1]).to_bits());
        // Eight dot products at once: each the bits of `dot32`, in both builds.
        let (dots, wide) = (avx2.dot32x8(std::array::from_fn(|r| d[3 + r]), &y), avx2.dot32x8(std::array::from_fn(|r| e[r]), e[8]));
        for r in 0..8 {
            let one = Portable.dot32(d[3 + r], &y).to_bits();
            assert_eq!((dots[r].to_bits(), Portable.dot32x8(std::array::from_fn(|q| d[3 + q]), &y)[r].to_bits()), (one, one), "row {r}");
            let one = Portable.dot32(e[r], e[8]).to_bits();
            assert_eq!((wide[r].to_bits(), Portable.dot32x8(std::array::from_fn(|q| e[q]), e[8])[r].to_bits()), (one, one), "wide row {r}");
        }
        let want: [[f32; 8]; 8] = std::array::from_fn(|l| std::array::from_fn(|r| (8 * r + l) as f32));
        assert_eq!((avx2.transpose8(m), Portable.transpose8(m)), (want, want));
        let t: Vec<f32> = (0..229).map(|i| (u(3, i) + 0.5) as f32 * 4.0).collect();
        let dd: Vec<f32> = (0..229).map(|i| u(4, i) as f32).collect();
        let (mut tt, mut pt) = (t.clone(), t.clone());
        avx2.exp_neg_in_place(&mut tt);
        Portable.exp_neg_in_place(&mut pt);
        let (ew, pw) = (avx2.exp_weighted(&t, &dd, 0.7), Portable.exp_weighted(&t, &dd, 0.7));
        assert_eq!((ew.0.to_bits(), ew.1.to_bits()), (pw.0.to_bits(), pw.1.to_bits()));
        // Several γ at once: each the one-γ sums, in both builds, for every chunking of the list.
        let gammas: Vec<f32> = (0..10).map(|q| 0.01 + 0.27 * q as f32).collect();
        for len in [229usize, 225, 7] {
            for count in 1..=gammas.len() {
                let (mut a, mut p) = (vec![(0.0, 0.0); count], vec![(0.0, 0.0); count]);
                avx2.exp_weighted_gammas(&t[..len], &dd[..len], &gammas[..count], &mut a);
                Portable.exp_weighted_gammas(&t[..len], &dd[..len], &gammas[..count], &mut p);
                for q in 0..count {
                    let one = Portable.exp_weighted(&t[..len], &dd[..len], gammas[q]);
                    let bits = |v: (f32, f32)| (v.0.to_bits(), v.1.to_bits());
                    assert_eq!((bits(a[q]), bits(p[q])), (bits(one), bits(one)), "{len} elements, {count} γ, γ #{q}");
                }
            }
        }
        assert!(tt.iter().zip(&pt).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

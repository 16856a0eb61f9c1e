//! The fast per-channel solve: the Woodbury form of [`crate::solve`] on fixed-width rows,
//! for the three colour channels of one pixel at once.
//!
//! With `P` (8, 16, 32 or 64) a compile-time row width ≥ `B`, every loop has a fixed length
//! and runs on whole vectors (see [`crate::simd`]). Batches beyond `B` are zero columns: they
//! add an identity block to `G = I + s·Dᵀ·W⁻¹·D`, which changes nothing in β. Because `G` is
//! the identity plus a positive semi-definite matrix, its Cholesky pivots are ≥ 1 in exact
//! arithmetic; a pivot below 1/2 means the data are numerically broken and that channel is
//! retried with more ridge.
//!
//! The factorisation and the substitutions are chains of dependent square roots, divisions
//! and dot products; the three channels' chains are independent, so they are interleaved
//! step by step to keep the core busy while each waits on its latencies.
//!
//! Precision: everything runs in f32 (twice the SIMD width of f64). The deviations are f32
//! anyway, and `G`'s eigenvalues are ≥ 1, so its factorisation is well conditioned: against
//! the f64 solver β differs by < 1e-6 (measured ≤ 3.9e-7), also when `W` is a million times
//! below `V_g` (tested at every row width).
use crate::simd::Simd;
use crate::solve::{Outcome, MAX_K};

/// Per channel, the zero-padded CRN batch deviations of the `k` control variates (borrowed
/// from the batch cube: no copies) and of the centre.
pub(crate) struct Rows<'a, const P: usize> {
    pub d: [[&'a [f32; P]; MAX_K]; 3],
    pub dc: [&'a [f32; P]; 3],
}

pub(crate) struct Panel<const P: usize> {
    /// Per channel, the diagonal `W` (≥ 0).
    pub w: [[f64; MAX_K]; 3],
    /// Per channel, `‖D_j‖²` (precomputed per pixel, for the ridge scale).
    pub sq: [[f32; MAX_K]; 3],
    /// Rows of D scaled by `s/(w_j + λ)`.
    scaled: [[f32; P]; MAX_K],
    pub beta: [[f64; MAX_K]; 3],
    g: [[[f32; P]; P]; 3],
    /// 1 / L_ii, so that the substitutions multiply instead of divide.
    inv_diag: [[f32; P]; 3],
    winv: [[f64; MAX_K]; 3],
    c32: [[f32; MAX_K]; 3],
    /// Whether a solve also computes `trace_inv`.
    pub want_trace: bool,
    /// Per channel, the rows of `L⁻¹` (scratch of the trace).
    inv_rows: [[[f32; P]; P]; 3],
    /// Per channel, `tr(G⁻¹)` of the last successful solve, when `want_trace`: the hat matrix
    /// in batch space is `I − G⁻¹`, so `P − tr(G⁻¹)` is the degrees of freedom the fit spent.
    pub trace_inv: [f64; 3],
    /// Per channel, `‖z‖²` for `z = G⁻¹·d_c` of the last successful solve: the squared residual
    /// `‖d_c − Σ_j β_j D_j‖²` of the fit, because `Σ_j β_j D_j = s·Dᵀ·W⁻¹·D·z = (G − I)·z`, so
    /// the predicted variance needs no pass over the rows.
    pub resid_sq: [f64; 3],
}

impl<const P: usize> Panel<P> {
    pub fn boxed() -> Box<Self> {
        Box::new(Panel {
            w: [[0.0; MAX_K]; 3],
            sq: [[0.0; MAX_K]; 3],
            scaled: [[0.0; P]; MAX_K],
            beta: [[0.0; MAX_K]; 3],
            g: [[[0.0f32; P]; P]; 3],
            inv_diag: [[0.0f32; P]; 3],
            winv: [[0.0; MAX_K]; 3],
            c32: [[0.0; MAX_K]; 3],
            want_trace: false,
            inv_rows: [[[0.0f32; P]; P]; 3],
            trace_inv: [0.0; 3],
            resid_sq: [0.0; 3],
        })
    }

    /// `1 / (w_0 + λ)` of channel `ch` in the last successful solve (control variate 0 is the
    /// centre in `ours`).
    #[inline]
    pub fn centre_winv(&self, ch: usize) -> f64 {
        self.winv[ch][0]
    }

    /// β of each channel for `k` control variates; per channel the same contract as
    /// [`crate::solve::Workspace::solve`].
    #[inline(always)]
    pub fn solve<S: Simd>(&mut self, rows: &Rows<P>, k: usize, s: f64, ridge: f64) -> [Outcome; 3] {
        let mut out = [Outcome::Solved; 3];
        let mut pending = [false; 3];
        let mut lambda = [0.0; 3];
        let mut scale = [0.0; 3];
        for ch in 0..3 {
            let mut sc = 0.0;
            for j in 0..k {
                sc += s * self.sq[ch][j] as f64 + self.w[ch][j];
            }
            sc /= k.max(1) as f64;
            if k == 0 || !(sc > 0.0 && sc.is_finite()) {
                self.beta[ch][..k].fill(0.0);
                out[ch] = if sc.is_finite() || k == 0 { Outcome::Degenerate } else { Outcome::Failed };
            } else {
                pending[ch] = true;
                scale[ch] = sc;
                lambda[ch] = ridge * sc;
            }
        }
        for attempt in 0..8 {
            if !pending.iter().any(|p| *p) {
                break;
            }
            let ok = self.try_solve::<S>(rows, k, s, lambda, pending);
            for ch in 0..3 {
                if !pending[ch] {
                    continue;
                }
                if ok[ch] {
                    out[ch] = if attempt == 0 { Outcome::Solved } else { Outcome::Regularised };
                    pending[ch] = false;
                } else {
                    lambda[ch] = (lambda[ch] * 10.0).max(1e-7 * scale[ch]);
                }
            }
        }
        for ch in 0..3 {
            if pending[ch] {
                self.beta[ch][..k].fill(0.0);
                out[ch] = Outcome::Failed;
            }
        }
        out
    }

    #[inline(always)]
    fn try_solve<S: Simd>(&mut self, rows: &Rows<P>, k: usize, s: f64, lambda: [f64; 3], active: [bool; 3]) -> [bool; 3] {
        let mut ok = active;
        for ch in 0..3 {
            if !ok[ch] {
                continue;
            }
            for j in 0..k {
                let wi = 1.0 / (self.w[ch][j] + lambda[ch]);
                ok[ch] &= wi.is_finite();
                self.winv[ch][j] = wi;
                self.c32[ch][j] = (s * wi) as f32;
            }
            if !ok[ch] {
                continue;
            }
            // G = I + s·Σ_j D_j·D_jᵀ / w_j in 8×8 blocks, accumulators in registers while the
            // k rows of D stream past. Only blocks touching the lower triangle are formed: the
            // factorisation never reads above the diagonal.
            for j in 0..k {
                let (c, r) = (self.c32[ch][j], rows.d[ch][j]);
                self.scaled[j] = std::array::from_fn(|a| c * r[a]);
            }
            let g = &mut self.g[ch];
            for a0 in (0..P).step_by(8) {
                for b0 in (0..=a0).step_by(8) {
                    let acc = S::gram_block(&rows.d[ch][..k], &self.scaled[..k], a0, b0);
                    for q in 0..8 {
                        for l in 0..8 {
                            g[a0 + q][b0 + l] = acc[q][l];
                        }
                    }
                }
                for q in 0..8 {
                    g[a0 + q][a0 + q] += 1.0;
                }
            }
        }
        // Right-looking Cholesky on full rows, channels interleaved; L ends up in the lower
        // triangle.
        for j in 0..P {
            for ch in 0..3 {
                if !ok[ch] {
                    continue;
                }
                let g = &mut self.g[ch];
                let pivot = g[j][j];
                if !(pivot > 0.5 && pivot.is_finite()) {
                    ok[ch] = false;
                    continue;
                }
                let ljj = pivot.sqrt();
                let inv = 1.0 / ljj;
                self.inv_diag[ch][j] = inv;
                let mut col = [0.0f32; P];
                for i in j + 1..P {
                    col[i] = g[i][j] * inv;
                }
                for i in j + 1..P {
                    let lij = col[i];
                    S::axpy32(&mut g[i], -lij, &col);
                    g[i][j] = lij;
                }
                g[j][j] = ljj;
            }
        }
        for ch in 0..3 {
            if ok[ch] {
                for (i, row) in self.g[ch].iter_mut().enumerate() {
                    row[i + 1..].fill(0.0);
                }
            }
        }
        if self.want_trace {
            // tr(G⁻¹) = ‖L⁻¹‖²_F. Row i of X = L⁻¹ is (e_i − Σ_{t<i} L_it·X_t) / L_ii: whole-row
            // updates without horizontal sums, the three channels' chains interleaved.
            let mut tr = [0.0f64; 3];
            for i in 0..P {
                let mut row = [[0.0f32; P]; 3];
                for r in &mut row {
                    r[i] = 1.0;
                }
                for t in 0..i {
                    for ch in 0..3 {
                        if ok[ch] {
                            S::axpy32(&mut row[ch], -self.g[ch][i][t], &self.inv_rows[ch][t]);
                        }
                    }
                }
                for ch in 0..3 {
                    if ok[ch] {
                        let inv = self.inv_diag[ch][i];
                        row[ch].iter_mut().for_each(|v| *v *= inv);
                        tr[ch] += norm_sq(&row[ch]);
                        self.inv_rows[ch][i] = row[ch];
                    }
                }
            }
            for ch in 0..3 {
                if ok[ch] {
                    self.trace_inv[ch] = tr[ch];
                }
            }
        }
        // L·y = d_c, then Lᵀ·z = y (row-oriented, so both run over full rows).
        let mut y = [[0.0f32; P]; 3];
        for i in 0..P {
            for ch in 0..3 {
                if ok[ch] {
                    y[ch][i] = (rows.dc[ch][i] - S::dot32(&self.g[ch][i], &y[ch])) * self.inv_diag[ch][i];
                }
            }
        }
        let mut z = [[0.0f32; P]; 3];
        for i in (0..P).rev() {
            for ch in 0..3 {
                if ok[ch] {
                    let zi = y[ch][i] * self.inv_diag[ch][i];
                    z[ch][i] = zi;
                    S::axpy32(&mut y[ch], -zi, &self.g[ch][i]);
                }
            }
        }
        for ch in 0..3 {
            if ok[ch] {
                for j in 0..k {
                    self.beta[ch][j] = s * self.winv[ch][j] * S::dot32(rows.d[ch][j], &z[ch]) as f64;
                }
                self.resid_sq[ch] = norm_sq(&z[ch]);
            }
        }
        ok
    }
}

/// `‖v‖²` in f64, in four interleaved partial sums: a single running sum would be a chain of
/// `P` dependent additions.
#[inline(always)]
fn norm_sq<const P: usize>(v: &[f32; P]) -> f64 {
    let mut acc = [0.0f64; 4];
    for chunk in v.chunks_exact(4) {
        for (a, x) in acc.iter_mut().zip(chunk) {
            *a += f64::from(*x) * f64::from(*x);
        }
    }
    let tail: f64 = v.chunks_exact(4).remainder().iter().map(|x| f64::from(*x) * f64::from(*x)).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};
    use crate::simd::Portable;
    use crate::solve::{Form, Workspace};

    /// (k, B, ridge, scale of W): the default shape, the `cv` shape (W = 0), few batches, many
    /// control variates, and W a million and a billion times below V_g.
    const CASES: [(usize, usize, f64, f64); 7] = [
        (25, 16, 1e-3, 0.01),
        (24, 16, 0.1, 0.0),
        (25, 5, 1e-3, 1.0),
        (40, 30, 0.0, 0.05),
        (25, 16, 1e-3, 1e-7),
        (25, 16, 1e-5, 1e-9),
        (64, 60, 1e-3, 0.01),
    ];

    /// The random rows of one case, zero-padded to `P`, and the f64 Woodbury solve of each channel.
    struct Case<const P: usize> {
        k: usize,
        s: f64,
        ridge: f64,
        data: Vec<[[f32; P]; MAX_K]>,
        w: [[f64; MAX_K]; 3],
        want: Vec<(Outcome, Vec<f64>)>,
        /// Per channel, the f64 solver's degrees of freedom.
        df: Vec<f64>,
    }

    impl<const P: usize> Case<P> {
        fn new((k, b, ridge, wscale): (usize, usize, f64, f64)) -> Self {
            assert!(b <= P);
            let s = 1.0 / (b * (b - 1)) as f64;
            let mut data = vec![[[0.0f32; P]; MAX_K]; 3];
            let mut w = [[0.0; MAX_K]; 3];
            let mut want = vec![];
            let mut df = vec![];
            for ch in 0..3 {
                let mut ws = Workspace::boxed();
                ws.want_df = true;
                for j in 0..k {
                    for c in 0..b {
                        let v = (uniform(hash4(1 + ch as u64, j as u64, c as u64, 0)) - 0.5) as f32;
                        data[ch][j][c] = v;
                        ws.d[j * b + c] = v as f64;
                    }
                    w[ch][j] = wscale * uniform(hash4(2 + ch as u64, j as u64, 0, 0));
                    ws.w[j] = w[ch][j];
                }
                for c in 0..b {
                    ws.dc[c] = data[ch][0][c] as f64;
                }
                let o = ws.solve(k, b, s, ridge, Form::Woodbury);
                want.push((o, ws.beta[..k].to_vec()));
                df.push(ws.df);
            }
            Case { k, s, ridge, data, w, want, df }
        }

        /// A panel loaded with the case's weights and row norms.
        fn panel(&self) -> Box<Panel<P>> {
            let mut p = Panel::<P>::boxed();
            for ch in 0..3 {
                for j in 0..self.k {
                    p.w[ch][j] = self.w[ch][j];
                    p.sq[ch][j] = self.data[ch][j].iter().map(|v| v * v).sum();
                }
            }
            p
        }

        fn rows(&self) -> Rows<'_, P> {
            Rows {
                d: std::array::from_fn(|ch| std::array::from_fn(|j| &self.data[ch][j])),
                dc: std::array::from_fn(|ch| &self.data[ch][0]),
            }
        }
    }

    /// Worst |Δβ| of the f32 panel (portable build) against the f64 solver over the cases that
    /// fit in `P` columns; the outcomes must agree.
    fn worst_against_f64<const P: usize>() -> f64 {
        let mut worst: f64 = 0.0;
        for case in CASES.iter().filter(|c| c.1 <= P) {
            let c = Case::<P>::new(*case);
            let mut p = c.panel();
            p.want_trace = true;
            let got = p.solve::<Portable>(&c.rows(), c.k, c.s, c.ridge);
            for ch in 0..3 {
                assert_eq!(got[ch], c.want[ch].0, "P={P} {case:?} ch={ch}");
                if matches!(got[ch], Outcome::Solved | Outcome::Regularised) {
                    // Padded columns add 1 each to tr(G⁻¹) and nothing to df.
                    let df = P as f64 - p.trace_inv[ch];
                    assert!((df - c.df[ch]).abs() < 1e-4 * (1.0 + c.df[ch]), "P={P} {case:?} ch={ch}: df {df} against {}", c.df[ch]);
                }
                for j in 0..c.k {
                    let d = (p.beta[ch][j] - c.want[ch].1[j]).abs();
                    assert!(d < 1e-6, "P={P} {case:?} ch={ch} j={j}: |Δβ| {d:.2e}");
                    worst = worst.max(d);
                }
            }
        }
        worst
    }

    #[test]
    fn panel_matches_the_general_solver() {
        // Every row width the pass uses (8, 16, 32, 64), each case on every width it fits
        // (extra zero columns must change nothing). Bound: β within 10⁻⁶ of the f64 solve, as
        // docs/estimators.md states; the worst case measures 3.9·10⁻⁷ (f32 rounding, ε = 6·10⁻⁸,
        // through a factorisation of a matrix with eigenvalues ≥ 1).
        let worst = [worst_against_f64::<8>(), worst_against_f64::<16>(), worst_against_f64::<32>(), worst_against_f64::<64>()];
        assert!(worst.iter().all(|w| *w > 0.0), "the f32 panel should not be exact: {worst:?}");
    }

    /// Worst relative gap between the panel's `‖z‖²` and the residual `‖d_c − Σ β_j D_j‖²`
    /// computed in f64 from its own β, over the cases that fit in `P` columns.
    fn worst_residual<const P: usize>() -> f64 {
        let mut worst: f64 = 0.0;
        for case in CASES.iter().filter(|c| c.1 <= P) {
            let c = Case::<P>::new(*case);
            let mut p = c.panel();
            let got = p.solve::<Portable>(&c.rows(), c.k, c.s, c.ridge);
            for ch in 0..3 {
                if !matches!(got[ch], Outcome::Solved | Outcome::Regularised) {
                    continue;
                }
                let mut r: Vec<f64> = c.data[ch][0].iter().map(|v| f64::from(*v)).collect();
                for j in 0..c.k {
                    for (x, d) in r.iter_mut().zip(&c.data[ch][j]) {
                        *x -= p.beta[ch][j] * f64::from(*d);
                    }
                }
                let explicit: f64 = r.iter().map(|x| x * x).sum();
                // Relative to the residual, or to 10⁻⁶ of the centre's own ‖d_c‖² where the fit
                // is exact to rounding (k > B with W a billion times below V_g).
                let centre: f64 = c.data[ch][0].iter().map(|v| f64::from(*v) * f64::from(*v)).sum();
                let gap = (p.resid_sq[ch] - explicit).abs() / explicit.max(1e-6 * centre);
                assert!(gap < 1e-3, "P={P} {case:?} ch={ch}: ‖z‖² {} against {explicit}", p.resid_sq[ch]);
                worst = worst.max(gap);
            }
        }
        worst
    }

    #[test]
    fn the_residual_of_the_fit_is_the_solved_vector() {
        // The identity is exact; what is left is f32 rounding in z against f64 arithmetic on
        // the same β. Bound 10⁻³ relative (0.1% of a predicted variance's CRN part); the worst
        // case is printed so that the margin is visible.
        let worst = [worst_residual::<8>(), worst_residual::<16>(), worst_residual::<32>(), worst_residual::<64>()];
        eprintln!("worst relative residual gap per width: {worst:?}");
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn solve_avx2<const P: usize>(p: &mut Panel<P>, rows: &Rows<P>, k: usize, s: f64, ridge: f64) -> [Outcome; 3] {
        p.solve::<crate::simd::Avx2>(rows, k, s, ridge)
    }

    /// The AVX2 and portable builds of the whole 3-channel solve give the same bits at width `P`.
    #[cfg(target_arch = "x86_64")]
    fn avx2_equals_portable<const P: usize>() -> usize {
        let mut compared = 0;
        for case in CASES.iter().filter(|c| c.1 <= P) {
            let c = Case::<P>::new(*case);
            let (mut a, mut q) = (c.panel(), c.panel());
            // SAFETY: the caller checked that the CPU has AVX2.
            let oa = unsafe { solve_avx2(&mut a, &c.rows(), c.k, c.s, c.ridge) };
            let oq = q.solve::<Portable>(&c.rows(), c.k, c.s, c.ridge);
            assert_eq!(oa, oq, "P={P} {case:?}");
            for ch in 0..3 {
                for j in 0..c.k {
                    assert_eq!(a.beta[ch][j].to_bits(), q.beta[ch][j].to_bits(), "P={P} {case:?} ch={ch} j={j}");
                }
                assert_eq!(a.centre_winv(ch).to_bits(), q.centre_winv(ch).to_bits());
            }
            compared += 1;
        }
        compared
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_and_portable_panel_solves_agree_bit_for_bit_at_every_width() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let n = [avx2_equals_portable::<8>(), avx2_equals_portable::<16>(), avx2_equals_portable::<32>(), avx2_equals_portable::<64>()];
        assert!(n.iter().all(|n| *n > 0), "cases compared per width: {n:?}");
    }
}

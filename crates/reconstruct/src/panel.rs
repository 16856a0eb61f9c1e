//! The fast per-channel solve: the Woodbury form of [`crate::solve`] on fixed-width rows,
//! for up to six systems at once (the three colour channels of a pixel's joint system, and of
//! its centre-free one).
//!
//! With `P` (8, 16, 32 or 64) a compile-time row width ≥ `B`, every loop has a fixed length
//! and runs on whole vectors (see [`crate::simd`]). Batches beyond `B` are zero columns: they
//! add an identity block to `G = I + s·Dᵀ·W⁻¹·D`, which changes nothing in β. Because `G` is
//! the identity plus a positive semi-definite matrix, its Cholesky pivots are ≥ 1 in exact
//! arithmetic; a pivot below 1/2 means the data are numerically broken and that system is
//! retried with more ridge.
//!
//! Each system's `G` is formed from its own rows (vectors along the batches), then the lower
//! triangles are transposed so that element `(a, b)` of every system is one vector with
//! system `q` in lane `q`. The factorisation, the trace of `G⁻¹` and the substitutions are
//! chains of dependent square roots, divisions and sums per system; in that layout each step
//! of the chain is one vector operation for all systems, with no horizontal sums, and only the
//! elements of the lower triangle are touched. Every element sees the same IEEE operations in
//! the same order as in a solve of one system on its own (see the tests), so the layout
//! changes no bit.
//!
//! Precision: everything runs in f32 (twice the SIMD width of f64). The deviations are f32
//! anyway, and `G`'s eigenvalues are ≥ 1, so its factorisation is well conditioned: against
//! the f64 solver β differs by < 1e-6 (measured ≤ 3.9e-7), also when `W` is a million times
//! below `V_g` (tested at every row width).
use crate::simd::Simd;
use crate::solve::{Outcome, MAX_K};

/// Systems a panel solves at once.
pub(crate) const MAX_SYSTEMS: usize = 6;
/// Lanes of the vectors the systems share (the systems, then copies of system 0).
const LANES: usize = 8;
/// One element of every system, in memory.
type Lane = [f32; LANES];
const ZERO: Lane = [0.0; LANES];

/// Per system, the zero-padded CRN batch deviations of its `k` control variates (borrowed
/// from the batch cube: no copies) and of the centre.
pub(crate) struct Rows<'a, const P: usize> {
    pub d: [[&'a [f32; P]; MAX_K]; MAX_SYSTEMS],
    pub dc: [&'a [f32; P]; MAX_SYSTEMS],
}

/// What differs between the systems of one solve besides their rows and weights.
#[derive(Clone, Copy, Debug)]
pub(crate) struct System {
    /// Control variates (rows).
    pub k: usize,
    /// Ridge, relative to the mean diagonal of `V_g + W`.
    pub ridge: f64,
    /// Whether the solve also computes `trace_inv`.
    pub want_trace: bool,
    /// Whether the solve also computes `press`.
    pub want_press: bool,
}

pub(crate) struct Panel<const P: usize> {
    /// Per system, the diagonal `W` (≥ 0).
    pub w: [[f64; MAX_K]; MAX_SYSTEMS],
    /// Per system, `‖D_j‖²` (precomputed per pixel, for the ridge scale).
    pub sq: [[f32; MAX_K]; MAX_SYSTEMS],
    pub beta: [[f64; MAX_K]; MAX_SYSTEMS],
    winv: [[f64; MAX_K]; MAX_SYSTEMS],
    c32: [f32; MAX_K],
    /// Rows of D scaled by `s/(w_j + λ)`.
    scaled: [[f32; P]; MAX_K],
    /// Per system, `G` as [`Simd::gram_lower`] forms it (only the blocks of the lower triangle).
    blocks: [[[f32; P]; P]; MAX_SYSTEMS],
    /// Element `(a, b)`, `b ≤ a`, of every system's `G`, then of its Cholesky factor `L`.
    g: [[Lane; P]; P],
    /// 1 / L_ii, so that the substitutions multiply instead of divide.
    inv_diag: [Lane; P],
    /// The rows of `L⁻¹` (scratch of the trace), lower triangle.
    inv_rows: [[Lane; P]; P],
    /// Per system, `tr(G⁻¹)` of the last successful solve, when the system asks for it: the
    /// hat matrix in batch space is `I − G⁻¹`, so `P − tr(G⁻¹)` is the degrees of freedom the
    /// fit spent.
    pub trace_inv: [f64; MAX_SYSTEMS],
    /// Per system, `‖z‖²` for `z = G⁻¹·d_c` of the last successful solve: the squared residual
    /// `‖d_c − Σ_j β_j D_j‖²` of the fit, because `Σ_j β_j D_j = s·Dᵀ·W⁻¹·D·z = (G − I)·z`, so
    /// the predicted variance needs no pass over the rows.
    pub resid_sq: [f64; MAX_SYSTEMS],
    /// Per system, `Σ_b (z_b / (G⁻¹)_bb)²` of the last successful solve, when the system asks
    /// for it: the residual of each batch as a fit without that batch would leave it, because
    /// `I − H = G⁻¹` (see [`crate::solve::Workspace::press`]).
    pub press: [f64; MAX_SYSTEMS],
    /// The diagonal of `G⁻¹`, `‖column b of L⁻¹‖²` (scratch of `press`), in f64 per lane.
    inv_diag_g: [[f64; LANES]; P],
}

impl<const P: usize> Panel<P> {
    pub fn boxed() -> Box<Self> {
        Box::new(Panel {
            w: [[0.0; MAX_K]; MAX_SYSTEMS],
            sq: [[0.0; MAX_K]; MAX_SYSTEMS],
            beta: [[0.0; MAX_K]; MAX_SYSTEMS],
            winv: [[0.0; MAX_K]; MAX_SYSTEMS],
            c32: [0.0; MAX_K],
            scaled: [[0.0; P]; MAX_K],
            blocks: [[[0.0; P]; P]; MAX_SYSTEMS],
            g: [[ZERO; P]; P],
            inv_diag: [ZERO; P],
            inv_rows: [[ZERO; P]; P],
            trace_inv: [0.0; MAX_SYSTEMS],
            resid_sq: [0.0; MAX_SYSTEMS],
            press: [0.0; MAX_SYSTEMS],
            inv_diag_g: [[0.0; LANES]; P],
        })
    }

    /// `1 / (w_0 + λ)` of system `q` in the last successful solve (control variate 0 is the
    /// centre in `ours`).
    #[inline]
    pub fn centre_winv(&self, q: usize) -> f64 {
        self.winv[q][0]
    }

    /// β of each system (`systems[q]` with rows `rows.d[q]`, weights `w[q]` and norms `sq[q]`),
    /// with the vector build `simd`; per system the same contract as
    /// [`crate::solve::Workspace::solve`].
    #[inline(always)]
    pub fn solve<S: Simd>(&mut self, simd: S, rows: &Rows<P>, systems: &[System], s: f64) -> [Outcome; MAX_SYSTEMS] {
        let n = systems.len();
        assert!(n <= MAX_SYSTEMS && systems.iter().all(|q| q.k <= MAX_K), "at most {MAX_SYSTEMS} systems of {MAX_K} rows");
        let mut out = [Outcome::Solved; MAX_SYSTEMS];
        let mut pending = [false; MAX_SYSTEMS];
        let mut lambda = [0.0; MAX_SYSTEMS];
        let mut scale = [0.0; MAX_SYSTEMS];
        // The mean diagonal of each system: sums in j order, the systems' side by side.
        let mut sums = [0.0; MAX_SYSTEMS];
        for j in 0..systems.iter().map(|q| q.k).max().unwrap_or(0) {
            for (q, sys) in systems.iter().enumerate() {
                if j < sys.k {
                    sums[q] += s * self.sq[q][j] as f64 + self.w[q][j];
                }
            }
        }
        for (q, sys) in systems.iter().enumerate() {
            let k = sys.k;
            let sc = sums[q] / k.max(1) as f64;
            if k == 0 || !(sc > 0.0 && sc.is_finite()) {
                self.beta[q][..k].fill(0.0);
                out[q] = if sc.is_finite() || k == 0 { Outcome::Degenerate } else { Outcome::Failed };
            } else {
                pending[q] = true;
                scale[q] = sc;
                lambda[q] = sys.ridge * sc;
            }
        }
        // The systems whose β a factorisation writes: a system solved in an earlier attempt is
        // solved again with the same λ, which gives the same bits.
        let live = pending;
        for attempt in 0..8 {
            if !pending.iter().any(|p| *p) {
                break;
            }
            let ok = self.try_solve(simd, rows, systems, s, lambda, live);
            for q in 0..n {
                if !pending[q] {
                    continue;
                }
                if ok[q] {
                    out[q] = if attempt == 0 { Outcome::Solved } else { Outcome::Regularised };
                    pending[q] = false;
                } else {
                    lambda[q] = (lambda[q] * 10.0).max(1e-7 * scale[q]);
                }
            }
        }
        for q in 0..n {
            if pending[q] {
                self.beta[q][..systems[q].k].fill(0.0);
                out[q] = Outcome::Failed;
            }
        }
        out
    }

    /// One factorisation of all systems at the given λ; `ok[q]` tells whether system `q`'s
    /// weights and pivots were sound. β, the trace and the residual are written for the `live`
    /// systems.
    #[inline(always)]
    fn try_solve<S: Simd>(
        &mut self,
        simd: S,
        rows: &Rows<P>,
        systems: &[System],
        s: f64,
        lambda: [f64; MAX_SYSTEMS],
        live: [bool; MAX_SYSTEMS],
    ) -> [bool; MAX_SYSTEMS] {
        let n = systems.len();
        let mut ok = [false; LANES];
        for (q, sys) in systems.iter().enumerate() {
            let k = sys.k;
            let mut finite = true;
            for j in 0..k {
                let wi = 1.0 / (self.w[q][j] + lambda[q]);
                finite &= wi.is_finite();
                self.winv[q][j] = wi;
                self.c32[j] = (s * wi) as f32;
            }
            ok[q] = finite;
            // G = I + s·Σ_j D_j·D_jᵀ / w_j in 8×8 blocks, accumulators in registers while the
            // k rows of D stream past. Only blocks touching the lower triangle are formed: the
            // factorisation never reads above the diagonal.
            for j in 0..k {
                let (c, r) = (self.c32[j], rows.d[q][j]);
                self.scaled[j] = std::array::from_fn(|a| c * r[a]);
            }
            simd.gram_lower(&rows.d[q][..k], &self.scaled[..k], &mut self.blocks[q]);
        }
        // To the lane layout; the unused lanes repeat system 0, so that they stay finite.
        let from = |lane: usize| if lane < n { lane } else { 0 };
        for a in 0..P {
            for b0 in (0..=a).step_by(8) {
                let t = simd.transpose8(std::array::from_fn(|lane| block8(&self.blocks[from(lane)][a], b0)));
                for (l, v) in t.iter().enumerate().take(a + 1 - b0) {
                    self.g[a][b0 + l] = *v;
                }
            }
            let diagonal = simd.add8(simd.load8(&self.g[a][a]), simd.splat8(1.0));
            simd.store8(&mut self.g[a][a], diagonal);
        }
        let zero = simd.splat8(0.0);
        // Right-looking Cholesky; L ends up in the lower triangle. The elements left of column
        // j would only receive ±0, which changes none of them.
        for j in 0..P {
            let pivot = self.g[j][j];
            for (o, p) in ok.iter_mut().zip(pivot) {
                *o &= p > 0.5 && p.is_finite();
            }
            let ljj = simd.sqrt8(simd.load8(&pivot));
            let inv = simd.div8(simd.splat8(1.0), ljj);
            simd.store8(&mut self.inv_diag[j], inv);
            let mut col = [zero; P];
            for i in j + 1..P {
                col[i] = simd.mul8(simd.load8(&self.g[i][j]), inv);
            }
            for i in j + 1..P {
                let a = simd.neg8(col[i]);
                for m in j + 1..i + 1 {
                    let updated = simd.add8(simd.load8(&self.g[i][m]), simd.mul8(a, col[m]));
                    simd.store8(&mut self.g[i][m], updated);
                }
                simd.store8(&mut self.g[i][j], col[i]);
            }
            simd.store8(&mut self.g[j][j], ljj);
        }
        let want_press = systems.iter().any(|q| q.want_press);
        if want_press {
            self.inv_diag_g = [[0.0; LANES]; P];
        }
        if want_press || systems.iter().any(|q| q.want_trace) {
            // tr(G⁻¹) = ‖L⁻¹‖²_F. Row i of X = L⁻¹ is (e_i − Σ_{t<i} L_it·X_t) / L_ii, each
            // element summed in increasing t. X_t is zero right of t (those entries of
            // `inv_rows` are never written), and adding its ±0 products to a +0 or a 1 changes
            // nothing, so four consecutive elements run side by side over the terms from the
            // first one's on: fixed-length steps, four independent chains.
            let mut tr = [0.0f64; LANES];
            for i in 0..P {
                let inv = simd.load8(&self.inv_diag[i]);
                // ‖X_i‖² in f64, element l to partial sum l mod 4 (the zeros right of i would
                // add nothing).
                let mut acc = [[0.0f64; LANES]; 4];
                for l0 in (0..=i).step_by(4) {
                    // No closure here: it would not inherit the vector build's target features.
                    let mut r = [zero; 4];
                    if i - l0 < 4 {
                        r[i - l0] = simd.splat8(1.0);
                    }
                    for t in l0..i {
                        let a = simd.neg8(simd.load8(&self.g[i][t]));
                        for (m, r) in r.iter_mut().enumerate() {
                            *r = simd.add8(*r, simd.mul8(a, simd.load8(&self.inv_rows[t][(l0 + m).min(P - 1)])));
                        }
                    }
                    for (m, a) in acc.iter_mut().enumerate().take(i + 1 - l0) {
                        let v = simd.mul8(r[m], inv);
                        simd.store8(&mut self.inv_rows[i][l0 + m], v);
                        simd.square_add8(a, v);
                        if want_press {
                            // (G⁻¹)_ll = Σ_i X_il², summed down the rows.
                            simd.square_add8(&mut self.inv_diag_g[l0 + m], v);
                        }
                    }
                }
                for (lane, t) in tr.iter_mut().enumerate() {
                    *t += (acc[0][lane] + acc[1][lane]) + (acc[2][lane] + acc[3][lane]);
                }
            }
            self.trace_inv.copy_from_slice(&tr[..MAX_SYSTEMS]);
        }
        // L·y = d_c, then Lᵀ·z = y. Each y_i is d_c,i minus the dot product of row i of L with
        // y in eight lane sums combined pairwise, where the elements from i on are zero.
        let mut dc = [zero; P];
        for b0 in (0..P).step_by(8) {
            let t = simd.transpose8(std::array::from_fn(|lane| block8(rows.dc[from(lane)], b0)));
            for (d, v) in dc[b0..b0 + 8].iter_mut().zip(&t) {
                *d = simd.load8(v);
            }
        }
        let mut y = [zero; P];
        for i in 0..P {
            let mut acc = [zero; 8];
            for c0 in (0..P).step_by(8) {
                for (l, a) in acc.iter_mut().enumerate() {
                    let m = c0 + l;
                    *a = simd.add8(*a, if m < i { simd.mul8(simd.load8(&self.g[i][m]), y[m]) } else { zero });
                }
            }
            let dot = simd.add8(
                simd.add8(simd.add8(acc[0], acc[1]), simd.add8(acc[2], acc[3])),
                simd.add8(simd.add8(acc[4], acc[5]), simd.add8(acc[6], acc[7])),
            );
            y[i] = simd.mul8(simd.sub8(dc[i], dot), simd.load8(&self.inv_diag[i]));
        }
        let mut z = [ZERO; P];
        for i in (0..P).rev() {
            let zi = simd.mul8(y[i], simd.load8(&self.inv_diag[i]));
            simd.store8(&mut z[i], zi);
            let a = simd.neg8(zi);
            for m in 0..i {
                y[m] = simd.add8(y[m], simd.mul8(a, simd.load8(&self.g[i][m])));
            }
        }
        // ‖z‖² in f64, element m to partial sum m mod 4.
        let mut acc = [[0.0f64; LANES]; 4];
        for (m, v) in z.iter().enumerate() {
            simd.square_add8(&mut acc[m % 4], simd.load8(v));
        }
        // β_j = s·w_j⁻¹·D_jᵀz, eight rows at a time, with z back along the batches.
        let mut zs = [[0.0f32; P]; LANES];
        for b0 in (0..P).step_by(8) {
            let t = simd.transpose8(std::array::from_fn(|l| &z[b0 + l]));
            for (dst, src) in zs.iter_mut().zip(&t) {
                dst[b0..b0 + 8].copy_from_slice(src);
            }
        }
        for (q, sys) in systems.iter().enumerate() {
            if !live[q] {
                continue;
            }
            let k = sys.k;
            for j0 in (0..k).step_by(8) {
                let dots = simd.dot32x8(std::array::from_fn(|r| rows.d[q][(j0 + r).min(k - 1)]), &zs[q]);
                for (r, d) in dots.iter().enumerate().take(k - j0) {
                    self.beta[q][j0 + r] = s * self.winv[q][j0 + r] * *d as f64;
                }
            }
            self.resid_sq[q] = (acc[0][q] + acc[1][q]) + (acc[2][q] + acc[3][q]);
            if sys.want_press {
                // Padded batches have z_b = 0 and (G⁻¹)_bb = 1: they add nothing.
                self.press[q] = z.iter().zip(&self.inv_diag_g).map(|(z, g)| (f64::from(z[q]) / g[q]).powi(2)).sum();
            }
        }
        let mut out = [false; MAX_SYSTEMS];
        out.copy_from_slice(&ok[..MAX_SYSTEMS]);
        out
    }
}

/// Elements `b0 … b0 + 8` of a row.
#[inline(always)]
fn block8<const P: usize>(row: &[f32; P], b0: usize) -> &[f32; 8] {
    row[b0..b0 + 8].try_into().expect("P is a multiple of 8")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};
    use crate::simd::{Portable, Simd};
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
        /// Per channel, the f64 solver's degrees of freedom and PRESS.
        df: Vec<(f64, f64)>,
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
                ws.want_press = true;
                let o = ws.solve(k, b, s, ridge, Form::Woodbury);
                want.push((o, ws.beta[..k].to_vec()));
                df.push((ws.df, ws.press));
            }
            Case { k, s, ridge, data, w, want, df }
        }

        /// A panel loaded with the case's weights and row norms, one system per channel.
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
                d: std::array::from_fn(|q| std::array::from_fn(|j| &self.data[q % 3][j])),
                dc: std::array::from_fn(|q| &self.data[q % 3][0]),
            }
        }

        fn systems(&self) -> [System; 3] {
            [System { k: self.k, ridge: self.ridge, want_trace: true, want_press: true }; 3]
        }
    }

    /// Worst |Δβ| of the f32 panel (portable build) against the f64 solver over the cases that
    /// fit in `P` columns; the outcomes must agree.
    fn worst_against_f64<const P: usize>() -> f64 {
        let mut worst: f64 = 0.0;
        for case in CASES.iter().filter(|c| c.1 <= P) {
            let c = Case::<P>::new(*case);
            let mut p = c.panel();
            let got = p.solve(Portable, &c.rows(), &c.systems(), c.s);
            for ch in 0..3 {
                assert_eq!(got[ch], c.want[ch].0, "P={P} {case:?} ch={ch}");
                if matches!(got[ch], Outcome::Solved | Outcome::Regularised) {
                    // Padded columns add 1 each to tr(G⁻¹) and nothing to df.
                    let (want_df, want_press) = c.df[ch];
                    let df = P as f64 - p.trace_inv[ch];
                    assert!((df - want_df).abs() < 1e-4 * (1.0 + want_df), "P={P} {case:?} ch={ch}: df {df} against {want_df}");
                    let gap = (p.press[ch] - want_press).abs() / want_press.max(1e-12);
                    assert!(gap < 1e-3, "P={P} {case:?} ch={ch}: PRESS {} against {want_press}", p.press[ch]);
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
            let got = p.solve(Portable, &c.rows(), &c.systems(), c.s);
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

    /// One system solved on its own, the way the panel solves each system in its lane: the
    /// same factorisation on whole rows of `P` (a row-major `G`, full-row updates, the upper
    /// triangle zeroed afterwards, dot products over full rows), with the portable kernels.
    /// The lane layout must reproduce it bit for bit.
    struct Alone<const P: usize> {
        beta: Vec<f64>,
        winv0: f64,
        trace_inv: f64,
        resid_sq: f64,
        press: f64,
    }

    fn alone<const P: usize>(d: &[&[f32; P]], dc: &[f32; P], w: &[f64], sq: &[f32], s: f64, sys: System) -> (Outcome, Alone<P>) {
        let k = sys.k;
        let mut out = Alone { beta: vec![0.0; k], winv0: 0.0, trace_inv: 0.0, resid_sq: 0.0, press: 0.0 };
        let mut sc = 0.0;
        for j in 0..k {
            sc += s * sq[j] as f64 + w[j];
        }
        sc /= k.max(1) as f64;
        if k == 0 || !(sc > 0.0 && sc.is_finite()) {
            return (if sc.is_finite() || k == 0 { Outcome::Degenerate } else { Outcome::Failed }, out);
        }
        let mut lambda = sys.ridge * sc;
        for attempt in 0..8 {
            if let Some(r) = alone_once(d, dc, w, s, k, lambda, sys.want_trace || sys.want_press) {
                out = r;
                return (if attempt == 0 { Outcome::Solved } else { Outcome::Regularised }, out);
            }
            lambda = (lambda * 10.0).max(1e-7 * sc);
        }
        (Outcome::Failed, out)
    }

    fn alone_once<const P: usize>(
        d: &[&[f32; P]],
        dc: &[f32; P],
        w: &[f64],
        s: f64,
        k: usize,
        lambda: f64,
        want_trace: bool,
    ) -> Option<Alone<P>> {
        let axpy = |y: &mut [f32; P], a: f32, x: &[f32; P]| {
            for l in 0..P {
                y[l] += a * x[l];
            }
        };
        let winv: Vec<f64> = w[..k].iter().map(|w| 1.0 / (w + lambda)).collect();
        if !winv.iter().all(|v| v.is_finite()) {
            return None;
        }
        let scaled: Vec<[f32; P]> = (0..k).map(|j| std::array::from_fn(|a| (s * winv[j]) as f32 * d[j][a])).collect();
        let mut g = vec![[0.0f32; P]; P];
        for a0 in (0..P).step_by(8) {
            for b0 in (0..=a0).step_by(8) {
                let acc = Portable.gram_block(&d[..k], &scaled, a0, b0);
                for q in 0..8 {
                    g[a0 + q][b0..b0 + 8].copy_from_slice(&acc[q]);
                }
            }
        }
        for (a, row) in g.iter_mut().enumerate() {
            row[a] += 1.0;
        }
        let mut inv_diag = [0.0f32; P];
        for j in 0..P {
            let pivot = g[j][j];
            if !(pivot > 0.5 && pivot.is_finite()) {
                return None;
            }
            let ljj = pivot.sqrt();
            let inv = 1.0 / ljj;
            inv_diag[j] = inv;
            let mut col = [0.0f32; P];
            for i in j + 1..P {
                col[i] = g[i][j] * inv;
            }
            for i in j + 1..P {
                let lij = col[i];
                axpy(&mut g[i], -lij, &col);
                g[i][j] = lij;
            }
            g[j][j] = ljj;
        }
        for (i, row) in g.iter_mut().enumerate() {
            row[i + 1..].fill(0.0);
        }
        let norm_sq = |v: &[f32; P]| {
            let mut acc = [0.0f64; 4];
            for chunk in v.chunks_exact(4) {
                for (a, x) in acc.iter_mut().zip(chunk) {
                    *a += f64::from(*x) * f64::from(*x);
                }
            }
            (acc[0] + acc[1]) + (acc[2] + acc[3])
        };
        let mut trace_inv = 0.0;
        let mut diag_g = [0.0f64; P];
        if want_trace {
            let mut x = vec![[0.0f32; P]; P];
            for i in 0..P {
                let mut row = [0.0f32; P];
                row[i] = 1.0;
                for t in 0..i {
                    axpy(&mut row, -g[i][t], &x[t]);
                }
                row.iter_mut().for_each(|v| *v *= inv_diag[i]);
                trace_inv += norm_sq(&row);
                for (d, v) in diag_g.iter_mut().zip(&row[..=i]) {
                    *d += f64::from(*v) * f64::from(*v);
                }
                x[i] = row;
            }
        }
        let mut y = [0.0f32; P];
        for i in 0..P {
            y[i] = (dc[i] - Portable.dot32(&g[i], &y)) * inv_diag[i];
        }
        let mut z = [0.0f32; P];
        for i in (0..P).rev() {
            let zi = y[i] * inv_diag[i];
            z[i] = zi;
            axpy(&mut y, -zi, &g[i]);
        }
        let beta = (0..k).map(|j| s * winv[j] * Portable.dot32(d[j], &z) as f64).collect();
        let press = z.iter().zip(&diag_g).map(|(z, g)| (f64::from(*z) / g).powi(2)).sum();
        Some(Alone { beta, winv0: winv[0], trace_inv, resid_sq: norm_sq(&z), press })
    }

    /// Six systems of random shapes: the joint and centre-free layout of the pass (k and k − 1
    /// rows, two ridges), and in some draws a degenerate system (zero rows and weights), one that
    /// needs more ridge (a zero weight at ridge 0), one whose rows overflow f32 (fails every
    /// attempt), one with a NaN weight (fails at once) and systems that skip the trace.
    struct Systems<const P: usize> {
        data: Vec<[[f32; P]; MAX_K]>,
        centre: Vec<[f32; P]>,
        systems: Vec<System>,
        w: Vec<Vec<f64>>,
        sq: Vec<Vec<f32>>,
        s: f64,
    }

    impl<const P: usize> Systems<P> {
        fn draw(seed: u64, count: usize) -> Self {
            let u = |a: u64, b: u64, c: u64| uniform(hash4(seed, a, b, c));
            let b = (2 + (u(0, 0, 0) * (P - 1) as f64) as usize).min(P);
            let k = 1 + (u(0, 0, 1) * MAX_K as f64) as usize % MAX_K;
            let s = 1.0 / (b * (b - 1).max(1)) as f64;
            let kind = |q: usize| (u(9, q as u64, 0) * 10.0) as usize;
            let mut data = vec![[[0.0f32; P]; MAX_K]; count];
            let mut centre = vec![[0.0f32; P]; count];
            let mut systems = vec![];
            let mut w = vec![];
            let mut sq = vec![];
            for q in 0..count {
                let kq = if q < 3 { k } else { k.saturating_sub(1).max(1) };
                let ridge = if q < 3 { 1e-3 } else { 0.1 };
                let scale = if kind(q) == 7 { 1e20 } else { 1.0 };
                for j in 0..kq {
                    for c in 0..b {
                        data[q][j][c] = if kind(q) == 5 { 0.0 } else { ((u(1, q as u64, (j * P + c) as u64) - 0.5) * scale) as f32 };
                    }
                }
                for c in 0..b {
                    centre[q][c] = if kind(q) == 5 { 0.0 } else { (u(2, q as u64, c as u64) - 0.5) as f32 };
                }
                let wscale = [0.01, 1e-7, 1.0, 0.0][(u(3, q as u64, 0) * 4.0) as usize];
                let mut wq: Vec<f64> = (0..kq).map(|j| wscale * u(4, q as u64, j as u64)).collect();
                let mut ridge = ridge;
                match kind(q) {
                    5 => wq.fill(0.0),
                    6 => {
                        wq[0] = 0.0;
                        ridge = 0.0;
                    }
                    8 => wq[kq / 2] = f64::NAN,
                    _ => {}
                }
                let sqq = (0..kq).map(|j| if kind(q) == 7 { 1.0 } else { data[q][j].iter().map(|v| v * v).sum() }).collect();
                systems.push(System { k: kq, ridge, want_trace: kind(q) != 4, want_press: kind(q) % 2 == 0 });
                w.push(wq);
                sq.push(sqq);
            }
            Systems { data, centre, systems, w, sq, s }
        }

        /// Loads the draw's weights and norms into `p` (which may hold an earlier draw's
        /// state, as a pass's panel does from pixel to pixel) and returns its rows.
        fn load(&self, p: &mut Panel<P>) -> Rows<'_, P> {
            for q in 0..self.systems.len() {
                p.w[q][..self.w[q].len()].copy_from_slice(&self.w[q]);
                p.sq[q][..self.sq[q].len()].copy_from_slice(&self.sq[q]);
            }
            let n = self.systems.len();
            Rows {
                d: std::array::from_fn(|q| std::array::from_fn(|j| &self.data[q.min(n - 1)][j])),
                dc: std::array::from_fn(|q| &self.centre[q.min(n - 1)]),
            }
        }
    }

    /// The panel of `draw`, solved with the vector build `simd`, against each system alone in
    /// the portable build, bit for bit; returns the outcomes seen.
    fn lanes_equal_alone<const P: usize, S: Simd>(simd: S, p: &mut Panel<P>, draw: &Systems<P>) -> Vec<Outcome> {
        let rows = draw.load(p);
        let got = p.solve(simd, &rows, &draw.systems, draw.s);
        let mut seen = vec![];
        for (q, sys) in draw.systems.iter().enumerate() {
            let (want, one) = alone(&rows.d[q], rows.dc[q], &draw.w[q], &draw.sq[q], draw.s, *sys);
            assert_eq!(got[q], want, "P={P} system {q} {sys:?}");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&p.beta[q][..sys.k]), bits(&one.beta), "P={P} system {q} {sys:?}: β");
            if matches!(want, Outcome::Solved | Outcome::Regularised) {
                assert_eq!(p.centre_winv(q).to_bits(), one.winv0.to_bits(), "P={P} system {q}: centre weight");
                assert_eq!(p.resid_sq[q].to_bits(), one.resid_sq.to_bits(), "P={P} system {q}: ‖z‖²");
                if sys.want_trace {
                    assert_eq!(p.trace_inv[q].to_bits(), one.trace_inv.to_bits(), "P={P} system {q}: tr(G⁻¹)");
                }
                if sys.want_press {
                    assert_eq!(p.press[q].to_bits(), one.press.to_bits(), "P={P} system {q}: PRESS");
                }
            }
            seen.push(want);
        }
        seen
    }

    /// [`lanes_equal_alone`] over sixty draws of one to six systems, on one panel.
    fn every_draw<const P: usize, S: Simd>(simd: S) -> Vec<Outcome> {
        let mut seen = vec![];
        let mut p = Panel::<P>::boxed();
        for seed in 0..60 {
            let count = 1 + seed as usize % MAX_SYSTEMS;
            seen.extend(lanes_equal_alone(simd, &mut p, &Systems::<P>::draw(seed, count)));
        }
        seen
    }

    #[test]
    fn systems_side_by_side_give_the_bits_of_each_solved_alone() {
        let mut seen = every_draw::<8, _>(Portable);
        seen.extend(every_draw::<16, _>(Portable));
        seen.extend(every_draw::<32, _>(Portable));
        seen.extend(every_draw::<64, _>(Portable));
        for o in [Outcome::Solved, Outcome::Regularised, Outcome::Degenerate, Outcome::Failed] {
            assert!(seen.contains(&o), "no system came out {o:?}");
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_and_portable_panel_solves_agree_bit_for_bit_at_every_width() {
        let Some(avx2) = crate::simd::Avx2::detect() else {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        };
        // Each AVX2 solve against each system alone in the portable build: the same bits.
        let n = [
            every_draw::<8, _>(avx2).len(),
            every_draw::<16, _>(avx2).len(),
            every_draw::<32, _>(avx2).len(),
            every_draw::<64, _>(avx2).len(),
        ];
        assert!(n.iter().all(|n| *n > 0), "systems compared per width: {n:?}");
    }
}

//! The per-pixel linear solve of the control-variate coefficients.
//!
//! For `k` control variates with batch deviations `D` (`k×m`, row `i` = pixel `i`'s
//! `m` batch deviations), a diagonal `W` (PT error estimates, zero for the CV baseline) and
//! `s = 1/(B(B−1))`, the coefficients minimising Eq. 7 of the supplement solve
//!
//! `(W + s·D·Dᵀ) β = s·D·d_c`          (`V_g = s·D·Dᵀ`, `V_fg = s·D·d_c`).
//!
//! When `m < k` (fewer batches than control variates, the usual case) the Woodbury identity
//! gives the same β from an `m×m` system: `β = s·W⁻¹·D·(I + s·Dᵀ·W⁻¹·D)⁻¹·d_c`, which is
//! cheaper and always positive definite when `W > 0`. Matrices live in a fixed-size workspace
//! reused for every pixel: nothing is allocated per pixel.
//!
//! Regularisation: a ridge `λ·mean(diag(W + s·D·Dᵀ))` is added to `W` (scale-free). If a
//! Cholesky pivot is not clearly positive the solve is retried with a ten times larger ridge.

/// Largest number of control variates per pixel.
pub const MAX_K: usize = 64;
/// Largest number of batches per stream.
pub const MAX_BATCHES: usize = 64;
const MAX_COLS: usize = 3 * MAX_BATCHES;
/// The larger side of the matrices a solve factorises.
const MAX_SIDE: usize = if MAX_COLS > MAX_K { MAX_COLS } else { MAX_K };
const MAX_ATTEMPTS: usize = 8;

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Solved with the requested ridge.
    Solved,
    /// Solved after raising the ridge.
    Regularised,
    /// Every variance is zero: β = 0.
    Degenerate,
    /// No ridge made the system positive definite (only with non-finite data): β = 0.
    Failed,
}

/// Which of the two equivalent systems to solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// Woodbury when `m < k`, direct otherwise.
    Auto,
    /// The `k×k` system.
    Direct,
    /// The `m×m` system (needs `W + ridge > 0`).
    Woodbury,
}

/// Fixed-size buffers for one solve; fill `d`, `dc`, `w`, call [`Workspace::solve`], read `beta`.
pub struct Workspace {
    /// Row-major `k×m` deviations, row stride `m`.
    pub d: [f64; MAX_K * MAX_COLS],
    /// The centre's deviations (`m` values).
    pub dc: [f64; MAX_COLS],
    /// The diagonal `W` (`k` values, ≥ 0).
    pub w: [f64; MAX_K],
    /// The result (`k` values).
    pub beta: [f64; MAX_K],
    /// The absolute ridge the last successful solve used (added to every `w`).
    pub lambda: f64,
    /// Whether a solve also computes `df`.
    pub want_df: bool,
    /// The degrees of freedom `tr(H)` of the last successful solve, when `want_df`: `H` is the
    /// hat matrix in batch space, `s·Dᵀ·(s·D·Dᵀ + W + λ)⁻¹·D`.
    pub df: f64,
    /// Whether a solve also computes `rss` and `press`.
    pub want_press: bool,
    /// The in-sample squared residual `‖r‖²`, `r = d_c − Dᵀβ`, of the last successful solve,
    /// when `want_press`.
    pub rss: f64,
    /// Its leave-one-column-out counterpart `Σ_b (r_b / (1 − H_bb))²`, when `want_press`: each
    /// column's residual as a fit without that column would leave it (exact for this linear
    /// fit at a fixed λ), so a column that carries the fit by itself weighs as much as it should.
    pub press: f64,
    mat: [f64; MAX_K * MAX_K],
    vec: [f64; MAX_COLS],
    winv: [f64; MAX_K],
}

impl Workspace {
    /// A boxed workspace (about 150 KB: too large for some thread stacks).
    pub fn boxed() -> Box<Workspace> {
        Box::new(Workspace {
            d: [0.0; MAX_K * MAX_COLS],
            dc: [0.0; MAX_COLS],
            w: [0.0; MAX_K],
            beta: [0.0; MAX_K],
            lambda: 0.0,
            want_df: false,
            df: 0.0,
            want_press: false,
            rss: 0.0,
            press: 0.0,
            mat: [0.0; MAX_K * MAX_K],
            vec: [0.0; MAX_COLS],
            winv: [0.0; MAX_K],
        })
    }

    /// Solves for `k ≤ MAX_K` control variates with `m ≤ 3·MAX_BATCHES` batch columns.
    pub fn solve(&mut self, k: usize, m: usize, s: f64, ridge: f64, form: Form) -> Outcome {
        assert!(k <= MAX_K && m <= MAX_COLS, "solve size {k}x{m} exceeds the workspace");
        let form = match form {
            Form::Auto if m < k => Form::Woodbury,
            Form::Auto => Form::Direct,
            f => f,
        };
        let mut scale = 0.0;
        for j in 0..k {
            let r = &self.d[j * m..(j + 1) * m];
            scale += s * dot(r, r) + self.w[j];
        }
        scale /= k.max(1) as f64;
        if k == 0 || !(scale > 0.0 && scale.is_finite()) {
            self.beta[..k].fill(0.0);
            return if scale.is_finite() || k == 0 { Outcome::Degenerate } else { Outcome::Failed };
        }
        let mut lambda = ridge * scale;
        for attempt in 0..MAX_ATTEMPTS {
            let ok = match form {
                Form::Woodbury => self.woodbury(k, m, s, lambda),
                _ => self.direct(k, m, s, lambda),
            };
            if ok {
                self.lambda = lambda;
                if self.want_df {
                    let mut diag = [0.0; MAX_SIDE];
                    self.df = match form {
                        // tr(H) = m − tr(G⁻¹)
                        Form::Woodbury => {
                            inverse_diagonal(&self.mat[..m * m], m, &mut diag[..m]);
                            m as f64 - diag[..m].iter().sum::<f64>()
                        }
                        // tr(H) = tr(A⁻¹·(A − W − λ)) = k − Σ_j (w_j + λ)·(A⁻¹)_jj
                        _ => {
                            inverse_diagonal(&self.mat[..k * k], k, &mut diag[..k]);
                            k as f64 - (0..k).map(|j| (self.w[j] + lambda) * diag[j]).sum::<f64>()
                        }
                    };
                }
                if self.want_press {
                    (self.rss, self.press) = match form {
                        Form::Woodbury => self.woodbury_press(m),
                        _ => self.direct_press(k, m, s),
                    };
                }
                return if attempt == 0 { Outcome::Solved } else { Outcome::Regularised };
            }
            lambda = (lambda * 10.0).max(1e-7 * scale);
        }
        self.beta[..k].fill(0.0);
        Outcome::Failed
    }

    fn direct(&mut self, k: usize, m: usize, s: f64, lambda: f64) -> bool {
        let (d, a) = (&self.d, &mut self.mat);
        for j in 0..k {
            let dj = &d[j * m..(j + 1) * m];
            for l in 0..=j {
                a[j * k + l] = s * dot(dj, &d[l * m..(l + 1) * m]);
            }
            a[j * k + j] += self.w[j] + lambda;
            self.vec[j] = s * dot(dj, &self.dc[..m]);
        }
        if !cholesky(&mut a[..k * k], k) {
            return false;
        }
        cholesky_solve(&a[..k * k], k, &mut self.vec[..k]);
        self.beta[..k].copy_from_slice(&self.vec[..k]);
        true
    }

    fn woodbury(&mut self, k: usize, m: usize, s: f64, lambda: f64) -> bool {
        let g = &mut self.mat[..m * m];
        g.fill(0.0);
        for a in 0..m {
            g[a * m + a] = 1.0;
        }
        for j in 0..k {
            let wi = 1.0 / (self.w[j] + lambda);
            if !wi.is_finite() {
                return false;
            }
            self.winv[j] = wi;
            let dj = &self.d[j * m..(j + 1) * m];
            let sc = s * wi;
            for a in 0..m {
                let ra = sc * dj[a];
                for (gab, djb) in g[a * m..a * m + a + 1].iter_mut().zip(&dj[..=a]) {
                    *gab += ra * djb;
                }
            }
        }
        if !cholesky(g, m) {
            return false;
        }
        let z = &mut self.vec[..m];
        z.copy_from_slice(&self.dc[..m]);
        cholesky_solve(g, m, z);
        for j in 0..k {
            self.beta[j] = s * self.winv[j] * dot(&self.d[j * m..(j + 1) * m], z);
        }
        true
    }
}

impl Workspace {
    /// In the Woodbury form the residual is `z = G⁻¹·d_c` (the solved vector still in `vec`)
    /// and `I − H = G⁻¹`, so `1 − H_bb = (G⁻¹)_bb`.
    fn woodbury_press(&self, m: usize) -> (f64, f64) {
        let mut diag = [0.0; MAX_SIDE];
        inverse_diagonal(&self.mat[..m * m], m, &mut diag[..m]);
        let z = &self.vec[..m];
        (dot(z, z), z.iter().zip(&diag[..m]).map(|(r, g)| (r / g) * (r / g)).sum())
    }

    /// In the direct form `H_bb = s·D_bᵀ·A⁻¹·D_b = s·‖L⁻¹·D_b‖²`, `D_b` column `b` of `D` and
    /// `A = L·Lᵀ` the factorised `k×k` matrix.
    fn direct_press(&self, k: usize, m: usize, s: f64) -> (f64, f64) {
        let (l, d) = (&self.mat[..k * k], &self.d);
        let (mut rss, mut press) = (0.0, 0.0);
        let mut x = [0.0f64; MAX_K];
        for b in 0..m {
            let mut r = self.dc[b];
            for (j, beta) in self.beta[..k].iter().enumerate() {
                r -= beta * d[j * m + b];
            }
            // Forward substitution L·x = D_b.
            let mut h = 0.0;
            for i in 0..k {
                let v = (d[i * m + b] - dot(&l[i * k..i * k + i], &x[..i])) / l[i * k + i];
                x[i] = v;
                h += v * v;
            }
            let keep = 1.0 - s * h;
            rss += r * r;
            press += (r / keep) * (r / keep);
        }
        (rss, press)
    }
}

/// Dot product with four independent partial sums (vectorises; fixed summation order).
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 4];
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut tail = 0.0;
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        tail += x * y;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// In-place Cholesky `A = L·Lᵀ` of the lower triangle of a row-major `n×n` matrix.
/// Fails when a pivot is not clearly positive (relative to the original diagonal) or not finite.
pub(crate) fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let orig = a[j * n + j];
        let pivot = orig - dot(&a[j * n..j * n + j], &a[j * n..j * n + j]);
        if pivot.is_nan() || pivot <= 1e-12 * orig.abs() || !pivot.is_finite() {
            return false;
        }
        let ljj = pivot.sqrt();
        a[j * n + j] = ljj;
        for i in j + 1..n {
            let (upper, lower) = a.split_at_mut(i * n);
            let (rj, ri) = (&upper[j * n..j * n + j], &mut lower[..n]);
            ri[j] = (ri[j] - dot(&ri[..j], rj)) / ljj;
        }
    }
    true
}

/// The diagonal of `(L·Lᵀ)⁻¹`, `L` from [`cholesky`]: `‖L⁻¹·e_j‖²` per column `j`.
pub(crate) fn inverse_diagonal(l: &[f64], n: usize, out: &mut [f64]) {
    let mut x = [0.0f64; MAX_SIDE];
    for j in 0..n {
        x[j] = 1.0 / l[j * n + j];
        let mut ss = x[j] * x[j];
        for i in j + 1..n {
            let v = -dot(&l[i * n + j..i * n + i], &x[j..i]) / l[i * n + i];
            x[i] = v;
            ss += v * v;
        }
        out[j] = ss;
    }
}

/// Solves `L·Lᵀ·x = b` in place, `L` from [`cholesky`].
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let s = b[i] - dot(&l[i * n..i * n + i], &b[..i]);
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for j in i + 1..n {
            s -= l[j * n + i] * b[j];
        }
        b[i] = s / l[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{hash4, uniform};

    fn fill(ws: &mut Workspace, k: usize, m: usize, seed: u64, w_scale: f64) {
        for j in 0..k {
            for b in 0..m {
                ws.d[j * m + b] = uniform(hash4(seed, j as u64, b as u64, 1)) - 0.5 + 0.3 * (b as f64 / m as f64);
            }
            ws.w[j] = w_scale * (0.5 + uniform(hash4(seed, j as u64, 0, 2)));
        }
        for b in 0..m {
            ws.dc[b] = ws.d[b];
        }
    }

    /// Residual of (W + λ' + s·D·Dᵀ)β − s·D·d_c, computed densely and independently.
    fn residual(ws: &Workspace, k: usize, m: usize, s: f64, lambda: f64) -> f64 {
        let mut worst: f64 = 0.0;
        for j in 0..k {
            let mut lhs = (ws.w[j] + lambda) * ws.beta[j];
            for l in 0..k {
                let v: f64 = (0..m).map(|b| ws.d[j * m + b] * ws.d[l * m + b]).sum();
                lhs += s * v * ws.beta[l];
            }
            let rhs: f64 = s * (0..m).map(|b| ws.d[j * m + b] * ws.dc[b]).sum::<f64>();
            worst = worst.max((lhs - rhs).abs());
        }
        worst
    }

    #[test]
    fn direct_and_woodbury_solve_the_same_system() {
        for (k, m) in [(25, 16), (25, 48), (10, 3), (7, 7)] {
            let mut a = Workspace::boxed();
            fill(&mut a, k, m, 11, 0.01);
            let mut b = Workspace::boxed();
            fill(&mut b, k, m, 11, 0.01);
            let s = 1.0 / (m * (m - 1).max(1)) as f64;
            assert_eq!(a.solve(k, m, s, 0.0, Form::Direct), Outcome::Solved);
            assert_eq!(b.solve(k, m, s, 0.0, Form::Woodbury), Outcome::Solved);
            assert!(residual(&a, k, m, s, 0.0) < 1e-12, "direct residual k={k} m={m}");
            assert!(residual(&b, k, m, s, 0.0) < 1e-12, "woodbury residual k={k} m={m}");
            for j in 0..k {
                assert!((a.beta[j] - b.beta[j]).abs() < 1e-9 * (1.0 + a.beta[j].abs()), "k={k} m={m} j={j}");
            }
        }
    }

    #[test]
    fn df_is_the_trace_of_the_hat_matrix_in_both_forms() {
        for (k, m) in [(25, 16), (25, 48), (10, 3), (7, 7)] {
            let s = 1.0 / (m * (m - 1).max(1)) as f64;
            // Column b of H is the fit to the unit vector e_b: Σ_j β_j(e_b)·d_j.
            let mut trace = 0.0;
            for b in 0..m {
                let mut ws = Workspace::boxed();
                fill(&mut ws, k, m, 11, 0.01);
                ws.dc[..m].fill(0.0);
                ws.dc[b] = 1.0;
                assert_eq!(ws.solve(k, m, s, 0.0, Form::Direct), Outcome::Solved);
                trace += (0..k).map(|j| ws.beta[j] * ws.d[j * m + b]).sum::<f64>();
            }
            for form in [Form::Direct, Form::Woodbury] {
                let mut ws = Workspace::boxed();
                fill(&mut ws, k, m, 11, 0.01);
                ws.want_df = true;
                assert_eq!(ws.solve(k, m, s, 0.0, form), Outcome::Solved);
                assert!((ws.df - trace).abs() < 1e-9 * (1.0 + trace), "{form:?} k={k} m={m}: df {} against {trace}", ws.df);
                assert!(ws.df > 0.0 && ws.df <= k.min(m) as f64 + 1e-9, "{form:?} k={k} m={m}: df {}", ws.df);
            }
        }
    }

    #[test]
    fn press_is_the_residual_of_fits_that_leave_each_column_out() {
        for (k, m) in [(25, 16), (25, 48), (10, 3), (7, 7)] {
            let s = 1.0 / (m * (m - 1).max(1)) as f64;
            // Leaving column b out is fitting to the data with that column zeroed (it then adds
            // nothing to D·Dᵀ or D·d_c); its residual there is d_c,b − Σ_j β_j·d_j,b.
            let mut press = 0.0;
            for b in 0..m {
                let mut ws = Workspace::boxed();
                fill(&mut ws, k, m, 11, 0.01);
                let full = ws.d;
                let dcb = ws.dc[b];
                for j in 0..k {
                    ws.d[j * m + b] = 0.0;
                }
                ws.dc[b] = 0.0;
                assert_eq!(ws.solve(k, m, s, 0.0, Form::Direct), Outcome::Solved);
                let r = dcb - (0..k).map(|j| ws.beta[j] * full[j * m + b]).sum::<f64>();
                press += r * r;
            }
            for form in [Form::Direct, Form::Woodbury] {
                let mut ws = Workspace::boxed();
                fill(&mut ws, k, m, 11, 0.01);
                ws.want_press = true;
                assert_eq!(ws.solve(k, m, s, 0.0, form), Outcome::Solved);
                let rss: f64 = (0..m).map(|b| (ws.dc[b] - (0..k).map(|j| ws.beta[j] * ws.d[j * m + b]).sum::<f64>()).powi(2)).sum();
                assert!((ws.rss - rss).abs() < 1e-9 * (1.0 + rss), "{form:?} k={k} m={m}: rss {} against {rss}", ws.rss);
                assert!((ws.press - press).abs() < 1e-8 * (1.0 + press), "{form:?} k={k} m={m}: press {} against {press}", ws.press);
                assert!(ws.press > ws.rss, "{form:?} k={k} m={m}: leaving columns out must cost");
            }
        }
    }

    #[test]
    fn singular_systems_get_more_ridge_and_zero_data_gives_zero() {
        // W = 0 and m < k: D·Dᵀ is singular, so the first attempt (no ridge) must fail.
        let (k, m) = (12, 4);
        let mut ws = Workspace::boxed();
        fill(&mut ws, k, m, 5, 0.0);
        assert_eq!(ws.solve(k, m, 0.1, 0.0, Form::Direct), Outcome::Regularised);
        assert!(ws.beta[..k].iter().all(|b| b.is_finite()));
        let mut z = Workspace::boxed();
        assert_eq!(z.solve(k, m, 0.1, 0.0, Form::Auto), Outcome::Degenerate);
        assert!(z.beta[..k].iter().all(|b| *b == 0.0));
    }
}

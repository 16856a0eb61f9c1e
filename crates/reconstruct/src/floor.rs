//! The noise floor of `ours` on the CRN covariance (issue 5).
//!
//! With `B` batches of a stream whose radiance comes from rare bright paths (indirect light),
//! most pixels' CRN batches are ≈ 0 in a given render, and those pixels' batch covariance says
//! "CRN is nearly exact". The solve then trusts CRN (`β → 0`) exactly where CRN came out low:
//! the estimated covariance is correlated with the values it weights, and the output inherits
//! CRN's low values (a darkening bias; see docs/estimators.md).
//!
//! The floor raises the diagonal of `V_g` to at least `τ·ṽ_i`, with `ṽ_i` a variance estimate
//! that does not come from the pixel's CRN batches: `δ_i = max(0, τ·ṽ_i − V_g,ii)` (pixels
//! whose batches report more keep their covariance). Because the centre is in the set and
//! `f̄_c = ḡ_c`, `V_fg` gains the matching terms. Two shapes of the extra covariance:
//!
//! - `common`: `u·uᵀ`, `u_i = √δ_i`, a noise component shared by the whole set — what CRN's
//!   rare bright paths are. At a pixel whose set has all-zero batches, β spreads over the set
//!   and the output tends to the mean of the neighbours' PT values. Implemented in the batch
//!   cube (see `BatchCube::rotate_and_floor`), free per pixel.
//! - `independent`: `diag(δ)`. The neighbours cannot cancel independent noise, so at a
//!   degenerate pixel the output tends to a blend of the centre's PT and CRN values only.
//!
//! `ṽ` (`source`): `pt`, the PT error estimates `V_h` before the penalty (both streams sample
//! the same integrand, so `Var(ḡ_i) = Var(h̄_i)`, and the PT estimate is independent of the CRN
//! stream), or `crn`, the CRN batch variance smoothed by the same cross-bilateral filter.
//!
//! For `independent`, solving `(V_g + Δ + V_h' + λ) β = V_fg + δ_c·e_c` needs no second solve: with
//! `β'` the solution without the extra right-hand side (and `Δ` in the diagonal), the Woodbury
//! identity gives `β = (1 − a)·β' + a·e_c`, `a = δ_c / (w_c + λ)` with `w_c` the centre's full
//! diagonal weight. At a pixel whose batches are all zero, `β = e_c·τ/(1+τ)`: with `τ = 1` the
//! inverse-variance blend of PT and CRN, which both have variance `ṽ_c`.
use crate::named::named_enum;

named_enum! {
    /// The shape of the floor's extra covariance, `δ_i = max(0, τ·ṽ_i − V_g,ii)` on the diagonal.
    pub enum FloorMode: "floor mode" {
        /// `u·uᵀ` with `u_i = √δ_i`: noise shared by all pixels of the set (as CRN's rare bright
        /// paths are), so the neighbours can cancel it. Costs nothing per pixel: the floor is a
        /// batch column freed by a rotation of the deviations.
        Common => "common",
        /// `diag(δ)`: independent noise, which only the centre's own PT value can replace.
        Independent => "independent",
    }
}

named_enum! {
    /// Where the floor's per-pixel variance `ṽ_i` comes from.
    pub enum FloorSource: "floor source" {
        /// The PT error estimates (`--errors`), before the symmetric penalty.
        Pt => "pt",
        /// The CRN batch variance of the mean, smoothed by the cross-bilateral filter.
        Crn => "crn",
        /// The PT batch variance of the mean without each pixel's farthest batch, smoothed by
        /// the cross-bilateral filter: a PT firefly, one batch far from the rest, does not
        /// raise the floor of its neighbourhood.
        PtTrimmed => "pt-trimmed",
    }
}

/// The floor of one pass: `τ`, the mode and the per-pixel `ṽ`.
#[derive(Clone, Copy)]
pub struct Floor<'a> {
    pub tau: f64,
    pub mode: FloorMode,
    pub values: &'a [[f32; 3]],
}

impl Floor<'_> {
    /// `δ` for a pixel with floor variance `v` (already summed over channels when shared) and
    /// batch variance `s_ii`.
    #[inline(always)]
    pub fn delta(&self, v: f64, s_ii: f64) -> f64 {
        (self.tau * v - s_ii).max(0.0)
    }
}

/// Turns `β'` (the solution with `Δ` in the diagonal but without `δ_c` in `V_fg`) into the
/// solution with it: `β = (1 − a)·β' + a·e_c`, `a = δ_c·winv_c`, `winv_c = 1/(w_c + λ)`.
/// The centre must be `beta[0]`. Returns `1 − a` (1 where nothing changed): the fit's residual
/// `d_c − Σ β_j D_j` is `1 − a` times that of `β'`, because `D_c = d_c`.
#[inline]
pub(crate) fn blend_towards_centre(beta: &mut [f64], delta_c: f64, winv_c: f64) -> f64 {
    let a = delta_c * winv_c;
    if !(a > 0.0 && a.is_finite()) || beta.is_empty() {
        return 1.0;
    }
    for b in beta.iter_mut() {
        *b *= 1.0 - a;
    }
    beta[0] += a;
    1.0 - a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{Form, Workspace};

    #[test]
    fn delta_by_hand() {
        let lift = Floor { tau: 2.0, mode: FloorMode::Independent, values: &[] };
        assert_eq!(lift.delta(1.0, 0.5), 1.5);
        assert_eq!(lift.delta(1.0, 3.0), 0.0);
        assert_eq!("COMMON".parse::<FloorMode>().unwrap(), FloorMode::Common);
        assert!("max".parse::<FloorMode>().unwrap_err().to_string().contains("common, independent"));
        assert_eq!("crn".parse::<FloorSource>().unwrap(), FloorSource::Crn);
    }

    /// The closed form equals a direct solve of `(W + Δ + s·D·Dᵀ) β = s·D·d_c + δ_c·e_c`.
    #[test]
    fn blend_matches_the_system_with_the_centre_term() {
        let (k, m) = (9usize, 5usize);
        let s = 1.0 / (m * (m - 1)) as f64;
        let mut ws = Workspace::boxed();
        for j in 0..k {
            for b in 0..m {
                ws.d[j * m + b] = ((j * 7 + b * 3) % 11) as f64 / 11.0 - 0.45 + if j == 0 { 0.0 } else { 0.1 * b as f64 };
            }
            ws.w[j] = 0.02 + 0.01 * j as f64;
        }
        for b in 0..m {
            ws.dc[b] = ws.d[b];
        }
        let delta: Vec<f64> = (0..k).map(|j| 0.03 * (1 + j % 3) as f64).collect();
        for j in 0..k {
            ws.w[j] += delta[j];
        }
        // Dense reference: A = diag(w) + s·D·Dᵀ, rhs = s·D·d_c + δ_c e_0.
        let mut a = vec![0.0; k * k];
        let mut rhs = vec![0.0; k];
        for i in 0..k {
            for j in 0..k {
                a[i * k + j] = s * (0..m).map(|b| ws.d[i * m + b] * ws.d[j * m + b]).sum::<f64>();
            }
            a[i * k + i] += ws.w[i];
            rhs[i] = s * (0..m).map(|b| ws.d[i * m + b] * ws.dc[b]).sum::<f64>();
        }
        rhs[0] += delta[0];
        assert!(crate::solve::cholesky(&mut a, k));
        crate::solve::cholesky_solve(&a, k, &mut rhs);
        for form in [Form::Direct, Form::Woodbury] {
            let mut w2 = Workspace::boxed();
            w2.d = ws.d;
            w2.dc = ws.dc;
            w2.w = ws.w;
            w2.solve(k, m, s, 0.0, form);
            let mut beta = w2.beta[..k].to_vec();
            blend_towards_centre(&mut beta, delta[0], 1.0 / (w2.w[0] + w2.lambda));
            for j in 0..k {
                assert!((beta[j] - rhs[j]).abs() < 1e-10, "{form:?} j={j}: {} vs {}", beta[j], rhs[j]);
            }
        }
    }
}

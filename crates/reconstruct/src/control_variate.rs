//! The control-variate estimator of one pixel and its variance (supplement Eqs. 1–7),
//! exposed for callers that bring their own coefficients or covariances and for tests.
//!
//! `F̂_c = f̄_c − Σ_i β_i (ḡ_i − h̄_i)`, with `f̄_c` the CRN mean of the centre, `ḡ_i` the
//! CRN means and `h̄_i` the PT means of the control-variate pixels. When the centre is in the
//! set, `β = e_c` returns the PT mean `h̄_c` and `β = 0` the CRN mean `f̄_c`.
use crate::solve::{cholesky, cholesky_solve};

/// `F̂ = f̄ − Σ β_i (ḡ_i − h̄_i)`.
#[inline]
pub fn combine(f_bar: f64, g_bar: &[f64], h_bar: &[f64], beta: &[f64]) -> f64 {
    assert!(g_bar.len() == beta.len() && h_bar.len() == beta.len(), "g, h and β need one value per control variate");
    f_bar - beta.iter().zip(g_bar.iter().zip(h_bar)).map(|(b, (g, h))| b * (g - h)).sum::<f64>()
}

/// Eq. 7: the variance of `F̂` for fixed `β`, given per-sample (co)variances and `n` samples
/// per pixel: `(σ²_f + βᵀV_gβ − 2βᵀV_fg + βᵀV_hβ) / n`. `v_g` is `k×k` row-major, `v_h` the
/// diagonal of the (independent) PT per-sample variances.
pub fn predicted_variance(var_f: f64, v_g: &[f64], v_fg: &[f64], v_h: &[f64], beta: &[f64], n: f64) -> f64 {
    let k = beta.len();
    assert!(v_g.len() == k * k && v_fg.len() == k && v_h.len() == k, "V_g must be k×k, V_fg and V_h k long");
    let mut bvb = 0.0;
    for i in 0..k {
        for j in 0..k {
            bvb += beta[i] * v_g[i * k + j] * beta[j];
        }
    }
    let bfg: f64 = beta.iter().zip(v_fg).map(|(b, v)| b * v).sum();
    let bhb: f64 = beta.iter().zip(v_h).map(|(b, v)| b * b * v).sum();
    (var_f + bvb - 2.0 * bfg + bhb) / n
}

/// The minimiser of Eq. 7, `(V_g + V_h + ridge·I) β = V_fg`; `None` if the system is not
/// positive definite. Allocates: meant for analysis, not for the per-pixel path.
pub fn optimal_coefficients(v_g: &[f64], v_fg: &[f64], v_h: &[f64], ridge: f64) -> Option<Vec<f64>> {
    let k = v_fg.len();
    assert!(v_g.len() == k * k && v_h.len() == k, "V_g must be k×k and V_h k long");
    let mut a: Vec<f64> = v_g.to_vec();
    for i in 0..k {
        a[i * k + i] += v_h[i] + ridge;
    }
    if !cholesky(&mut a, k) {
        return None;
    }
    let mut beta = v_fg.to_vec();
    cholesky_solve(&a, k, &mut beta);
    Some(beta)
}

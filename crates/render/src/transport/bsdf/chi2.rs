//! χ² goodness-of-fit tests of the BSDF sampling routines against their own densities, in the
//! manner of Mitsuba 3's `chi2` test and pbrt-v4's BSDF tests: sampled directions are counted on
//! a grid of equal-area cells over the sphere, (cos θ, φ), the density is integrated over each
//! cell by quadrature for the expected counts, cells expecting fewer than five samples are
//! pooled, and the χ² statistic gives a p-value. Samples a routine rejects (it returns nothing)
//! fall in one more cell, whose expectation is the density's missing mass: a density that
//! integrates to less than the routine's acceptance rate fails as surely as a misplaced one.
//!
//! Each test case is one routine at one roughness, incident angle and index; all cases share
//! one family-wise significance level, Bonferroni-corrected over every case in this file
//! ([`ALPHA`] / [`CASES`]). Each routine also has a deliberately wrong density (a mismatched
//! roughness, index or lobe weight) that the same harness must reject, so the tests can fail.
use super::dielectric::Dielectric;
use super::ggx::Ggx;
use super::microfacet::MicrofacetReflection;
use super::pbr::Bsdf;
use crate::sampler::{StreamKind, StreamSampler};
use crate::scene::material::PbrParams;
use glam::{Vec2, Vec3A};
use std::f64::consts::PI;

/// Family-wise probability of a false alarm over all cases of this file.
const ALPHA: f64 = 0.01;
/// Cells in cos θ (an even number, so z = 0 is a cell boundary: the opaque lobes' densities
/// jump there) and in φ.
const RES_COS: usize = 16;
const RES_PHI: usize = 32;
/// Samples per case: enough that a 10% error in roughness is rejected at every case.
const SAMPLES: u32 = 1_000_000;
/// Gauss–Legendre nodes per cell and dimension: a composite rule of `SUB` sub-cells of `GL_N`
/// nodes each. The narrowest lobe below (α = 0.04 at cos θo = 0.1, cut by the horizon) needs
/// this many: with 6 sub-cells its integral came out 2·10⁻³ short, which the rejected-sample
/// cell alone turned into a failure; with 12 it is within 5·10⁻⁴.
const SUB: usize = 12;
const GL_N: usize = 5;

/// Nodes and weights of 5-point Gauss–Legendre on [−1, 1].
const GL_X: [f64; GL_N] = [-0.906_179_845_938_664, -0.538_469_310_105_683, 0.0, 0.538_469_310_105_683, 0.906_179_845_938_664];
const GL_W: [f64; GL_N] =
    [0.236_926_885_056_189, 0.478_628_670_499_366, 0.568_888_888_888_889, 0.478_628_670_499_366, 0.236_926_885_056_189];

/// The number of χ² cases in this file (the correct densities; the wrong ones are not tests of
/// the code but of the harness, and are expected to fail).
fn cases() -> usize {
    ggx_cases().len() + dielectric_cases().len() + mixture_cases().len()
}

fn significance() -> f64 {
    ALPHA / cases() as f64
}

/// The cell of a unit direction.
fn cell(w: Vec3A) -> usize {
    let z = w.z.clamp(-1.0, 1.0) as f64;
    let iz = (((z + 1.0) * 0.5 * RES_COS as f64) as usize).min(RES_COS - 1);
    let mut phi = (w.y as f64).atan2(w.x as f64);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let ip = ((phi / (2.0 * PI) * RES_PHI as f64) as usize).min(RES_PHI - 1);
    iz * RES_PHI + ip
}

/// `∫ pdf dω` over every cell: dω = d(cos θ) dφ, so the integral in (z, φ) needs no Jacobian.
fn expected_mass(pdf: &dyn Fn(Vec3A) -> f64) -> Vec<f64> {
    let (dz, dphi) = (2.0 / RES_COS as f64, 2.0 * PI / RES_PHI as f64);
    let mut mass = vec![0.0; RES_COS * RES_PHI];
    for iz in 0..RES_COS {
        for ip in 0..RES_PHI {
            let (z0, p0) = (-1.0 + iz as f64 * dz, ip as f64 * dphi);
            let (hz, hp) = (dz / SUB as f64, dphi / SUB as f64);
            let mut sum = 0.0;
            for sz in 0..SUB {
                for (xz, wz) in GL_X.iter().zip(GL_W) {
                    let z = z0 + hz * (sz as f64 + 0.5 + 0.5 * xz);
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    for sp in 0..SUB {
                        for (xp, wp) in GL_X.iter().zip(GL_W) {
                            let phi = p0 + hp * (sp as f64 + 0.5 + 0.5 * xp);
                            let w = Vec3A::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                            sum += wz * wp * pdf(w);
                        }
                    }
                }
            }
            // Each Gauss–Legendre rule spans a sub-cell of width h with weights summing to 2.
            mass[iz * RES_PHI + ip] = sum * 0.25 * hz * hp;
        }
    }
    mass
}

/// The outcome of one χ² test.
#[derive(Debug)]
struct Chi2 {
    /// `∫ pdf dω` over the sphere (by the quadrature).
    pdf_integral: f64,
    /// Fraction of samples the routine produced.
    accepted: f64,
    statistic: f64,
    dof: usize,
    p_value: f64,
    /// A sample fell where the density is zero (the test fails whatever the p-value).
    impossible: Option<String>,
}

impl Chi2 {
    fn passes(&self, alpha: f64) -> bool {
        self.impossible.is_none() && self.p_value >= alpha
    }
}

/// Counts `SAMPLES` draws of `sample` (two 1D and one 2D random numbers → a direction, or `None` if rejected) on
/// the grid and compares them with the integrated `pdf`.
fn chi2_test(seed: u64, sample: &dyn Fn([f32; 2], Vec2) -> Option<Vec3A>, pdf: &dyn Fn(Vec3A) -> f64) -> Chi2 {
    let st = StreamSampler::new(seed, StreamKind::Pt);
    let cells = RES_COS * RES_PHI;
    // The last cell counts rejected samples.
    let mut observed = vec![0.0f64; cells + 1];
    for i in 0..SAMPLES {
        let s = st.sample(0, i);
        match sample([s.get1d(0), s.get1d(3)], s.get2d(1)) {
            Some(w) => {
                assert!(w.is_finite() && (w.length() - 1.0).abs() < 1e-3, "sampled direction {w} is not a unit vector");
                observed[cell(w)] += 1.0;
            }
            None => observed[cells] += 1.0,
        }
    }
    let n = SAMPLES as f64;
    let mass = expected_mass(pdf);
    let pdf_integral: f64 = mass.iter().sum();
    let mut expected: Vec<f64> = mass.iter().map(|m| m * n).collect();
    expected.push(((1.0 - pdf_integral) * n).max(0.0));
    // Less than 10⁻⁶ expected samples: a count there is a sample where the density is zero
    // (up to the quadrature's reach), not an unlucky draw.
    let impossible = (0..=cells).find(|&c| expected[c] < 1e-6 && observed[c] > 0.0).map(|c| {
        let what = if c == cells { "rejected samples".to_string() } else { format!("cell {c}") };
        format!("{} samples in {what}, where the density integrates to {:.3e}", observed[c], expected[c] / n)
    });
    let (statistic, dof) = pooled_statistic(&observed, &expected);
    Chi2 { pdf_integral, accepted: 1.0 - observed[cells] / n, statistic, dof, p_value: chi2_survival(statistic, dof), impossible }
}

/// Pearson's statistic after pooling every cell expecting fewer than 5 samples into one (and
/// that one into the next smallest if it still expects fewer than 5); returns it with its
/// degrees of freedom (cells − 1).
fn pooled_statistic(observed: &[f64], expected: &[f64]) -> (f64, usize) {
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for &c in &order {
        if expected[c] < 5.0 {
            pool_o += observed[c];
            pool_e += expected[c];
        } else {
            cells.push((observed[c], expected[c]));
        }
    }
    if pool_e > 0.0 || pool_o > 0.0 {
        if pool_e < 5.0 && !cells.is_empty() {
            // `cells` is in ascending order of expectation.
            cells[0].0 += pool_o;
            cells[0].1 += pool_e;
        } else {
            cells.push((pool_o, pool_e));
        }
    }
    let statistic = cells.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    (statistic, cells.len().saturating_sub(1))
}

/// `P(X ≥ x)` for `X ~ χ²(dof)`: the regularised upper incomplete gamma `Q(dof/2, x/2)`.
fn chi2_survival(x: f64, dof: usize) -> f64 {
    if dof == 0 {
        return 1.0;
    }
    gamma_q(dof as f64 / 2.0, x / 2.0)
}

/// `ln Γ(a)` for `a` a positive multiple of ½ (all χ² needs), by the recurrence from Γ(1) = 1
/// and Γ(½) = √π: exact to rounding, with no approximation formula to get wrong.
fn ln_gamma_half_integer(a: f64) -> f64 {
    assert!(a > 0.0 && (2.0 * a).fract() == 0.0, "ln Γ({a}): only multiples of 1/2");
    let (mut x, mut acc) = if a.fract() == 0.0 { (1.0, 0.0) } else { (0.5, 0.5 * PI.ln()) };
    while x < a {
        acc += x.ln();
        x += 1.0;
    }
    acc
}

/// Regularised upper incomplete gamma `Q(a, x) = Γ(a, x)/Γ(a)` for `a` a multiple of ½: the
/// power series of `P = 1 − Q` below `x = a + 1`, where it converges fast, and Lentz's continued
/// fraction for `Q` above it (Numerical Recipes §6.2), each to double precision.
fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(x >= 0.0, "Q({a}, {x})");
    if x == 0.0 {
        return 1.0;
    }
    let prefactor = (-x + a * x.ln() - ln_gamma_half_integer(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * prefactor).max(0.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        prefactor * h
    }
}

fn wo_at(cos: f32) -> Vec3A {
    Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos)
}

/// GGX reflection: α (glTF roughness²) and cos θo.
fn ggx_cases() -> Vec<(f32, f32)> {
    let mut v = Vec::new();
    for alpha in [0.04f32, 0.2, 0.5, 0.9] {
        for cos in [0.95f32, 0.5, 0.1] {
            v.push((alpha, cos));
        }
    }
    v
}

/// Rough dielectric: index, α, cos θo (negative: `wo` inside).
fn dielectric_cases() -> Vec<(f32, f32, f32)> {
    let mut v = Vec::new();
    for (eta, alpha) in [(1.5f32, 0.1f32), (1.5, 0.4), (1.33, 0.25), (2.4, 0.6)] {
        for cos in [0.9f32, 0.35, -0.9, -0.6] {
            v.push((eta, alpha, cos));
        }
    }
    v
}

fn pbr(metallic: f32, roughness: f32, specular: f32, transmission: f32) -> PbrParams {
    PbrParams { base_color: Vec3A::new(0.8, 0.5, 0.3), metallic, roughness, specular, transmission, ..Default::default() }
}

/// The glTF lobe mixture: name, parameters, cos θo (negative: `wo` inside, for glass).
fn mixture_cases() -> Vec<(&'static str, PbrParams, f32)> {
    let mut v = Vec::new();
    for (name, p) in [
        ("plastic r0.5", pbr(0.0, 0.5, 1.0, 0.0)),
        ("plastic r0.25", pbr(0.0, 0.25, 1.0, 0.0)),
        ("half metal r0.4", pbr(0.5, 0.4, 1.0, 0.0)),
        ("metal r0.6", pbr(1.0, 0.6, 1.0, 0.0)),
        ("rough glass r0.5", pbr(0.0, 0.5, 1.0, 1.0)),
        ("frosted mix r0.6", pbr(0.0, 0.6, 1.0, 0.5)),
        ("water r0.4", PbrParams { ior: 1.33, ..pbr(0.0, 0.4, 1.0, 1.0) }),
    ] {
        for cos in [0.85f32, 0.3] {
            v.push((name, p, cos));
        }
    }
    v.push(("rough glass r0.5, inside", pbr(0.0, 0.5, 1.0, 1.0), -0.7));
    v.push(("frosted mix r0.6, inside", pbr(0.0, 0.6, 1.0, 0.5), -0.4));
    v
}

fn ggx_lobe(alpha: f32) -> MicrofacetReflection {
    MicrofacetReflection { ggx: Ggx::new(alpha), f0: Vec3A::splat(0.9), f90: 1.0 }
}

fn ggx_chi2(alpha: f32, cos: f32, pdf_alpha: f32) -> Chi2 {
    let (lobe, pdf_lobe, wo) = (ggx_lobe(alpha), ggx_lobe(pdf_alpha), wo_at(cos));
    chi2_test(1, &|_, u| lobe.sample(wo, u), &|wi| pdf_lobe.pdf(wo, wi) as f64)
}

fn dielectric_chi2(eta: f32, alpha: f32, cos: f32, pdf_eta: f32, pdf_alpha: f32) -> Chi2 {
    let (d, pdf_d) = (Dielectric::new(eta, alpha), Dielectric::new(pdf_eta, pdf_alpha));
    let wo = wo_at(cos.abs()) * Vec3A::new(1.0, 1.0, cos.signum());
    chi2_test(2, &|[u_choice, _], u| d.sample(wo, u_choice, u).map(|s| s.wi), &|wi| pdf_d.pdf(wo, wi) as f64)
}

/// The mixture sampled with `p` and its density taken from `pdf_params` at the same `wo`.
fn mixture_chi2(p: &PbrParams, cos: f32, pdf_params: &PbrParams) -> Chi2 {
    let wo = wo_at(cos.abs()) * Vec3A::new(1.0, 1.0, cos.signum());
    let (b, pdf_b) = (Bsdf::new(p, Vec3A::Z, Vec3A::Z, wo), Bsdf::new(pdf_params, Vec3A::Z, Vec3A::Z, wo));
    assert!(matches!(b, Bsdf::Mixture(_)), "these cases test the lobe mixture");
    let sample = |[u_lobe, u_choice]: [f32; 2], u: Vec2| b.sample(u_lobe, u, u_choice).filter(|s| !s.delta).map(|s| s.wi);
    chi2_test(3, &sample, &|wi| pdf_b.pdf(wi) as f64)
}

/// Runs every case, printing the table, and returns the descriptions of those that failed.
fn run<T>(cases: &[T], name: impl Fn(&T) -> String, test: impl Fn(&T) -> Chi2, expect_pass: bool) -> Vec<String> {
    let alpha = significance();
    let mut failures = Vec::new();
    for c in cases {
        let r = test(c);
        let line = format!(
            "{}: χ² {:.1} on {} dof, p = {:.3e} (α = {alpha:.1e}); ∫pdf {:.5}, accepted {:.5}{}",
            name(c),
            r.statistic,
            r.dof,
            r.p_value,
            r.pdf_integral,
            r.accepted,
            r.impossible.as_deref().map(|s| format!("; {s}")).unwrap_or_default()
        );
        println!("{line}");
        // The density of what is produced cannot exceed one (beyond the quadrature's error).
        if expect_pass && r.pdf_integral > 1.0 + 1e-4 {
            failures.push(format!("{line}: ∫ pdf dω > 1"));
        }
        if r.passes(alpha) != expect_pass {
            failures.push(line);
        }
    }
    failures
}

fn assert_none(failures: Vec<String>, what: &str) {
    assert!(failures.is_empty(), "{} {what}:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn upper_incomplete_gamma_matches_closed_forms_and_tables() {
    // Integer a: Q(k, x) = e^{−x} Σ_{j<k} x^j / j! (the Poisson tail), on both sides of x = a + 1.
    for k in [1usize, 2, 5, 17, 50] {
        for x in [0.01f64, 0.7, 3.0, 9.5, 40.0, 80.0] {
            let (mut term, mut sum) = (1.0f64, 0.0f64);
            for j in 0..k {
                if j > 0 {
                    term *= x / j as f64;
                }
                sum += term;
            }
            let exact = (-x).exp() * sum;
            let q = gamma_q(k as f64, x);
            assert!((q - exact).abs() <= 1e-12 + 1e-10 * exact, "Q({k}, {x}) = {q}, expected {exact}");
        }
    }
    // Upper 1% points of χ² (NIST/SEMATECH e-Handbook, table 1.3.6.7.4), with odd dof for the
    // half-integer a.
    for (dof, x) in [(1usize, 6.635), (5, 15.086), (10, 23.209), (25, 44.314), (100, 135.807)] {
        let p = chi2_survival(x, dof);
        assert!((p - 0.01).abs() < 2e-5, "P(χ²({dof}) ≥ {x}) = {p}, expected 0.01");
    }
    assert_eq!(chi2_survival(0.0, 7), 1.0);
    assert!(chi2_survival(1e4, 7) < 1e-300);
}

#[test]
fn harness_accepts_an_exact_uniform_sampler_and_rejects_a_skewed_one() {
    // Uniform on the sphere, pdf 1/4π: exact, so the test must pass; with the sampler's z
    // squashed slightly towards the pole it must not.
    let uniform = |u: Vec2, k: f32| {
        let z = 1.0 - 2.0 * u.x.powf(k);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        Some(Vec3A::new(r * phi.cos(), r * phi.sin(), z))
    };
    let pdf = |_: Vec3A| 0.25 / PI;
    let good = chi2_test(4, &|_, u| uniform(u, 1.0), &pdf);
    assert!(good.passes(significance()), "{good:?}");
    assert!((good.pdf_integral - 1.0).abs() < 1e-9, "{good:?}");
    let skewed = chi2_test(4, &|_, u| uniform(u, 1.02), &pdf);
    assert!(!skewed.passes(significance()), "{skewed:?}");
    // Rejected samples the density does not account for are caught by the extra cell.
    let lossy = chi2_test(4, &|_, u| if u.y < 0.01 { None } else { uniform(u, 1.0) }, &pdf);
    assert!(!lossy.passes(significance()), "{lossy:?}");
}

#[test]
fn ggx_reflection_sampling_follows_its_pdf() {
    let cases = ggx_cases();
    assert_none(run(&cases, |&(a, c)| format!("GGX α {a}, cos θo {c}"), |&(a, c)| ggx_chi2(a, c, a), true), "GGX cases fail");
}

#[test]
fn ggx_chi2_rejects_a_pdf_with_the_wrong_roughness() {
    let cases = ggx_cases();
    let failures = run(&cases, |&(a, c)| format!("GGX α {a}, cos θo {c}, pdf at 1.1 α"), |&(a, c)| ggx_chi2(a, c, 1.1 * a), false);
    assert_none(failures, "wrong GGX densities pass");
}

#[test]
fn ggx_sampled_weight_is_fresnel_times_g2_over_g1() {
    // Visible-normal sampling leaves the weight f cos θi / pdf = F(wo·h) G2 / G1(wo), a formula
    // independent of D and of the Jacobian: it checks eval and pdf against each other.
    let st = StreamSampler::new(5, StreamKind::Pt);
    for (alpha, cos) in ggx_cases() {
        let (lobe, wo) = (ggx_lobe(alpha), wo_at(cos));
        for i in 0..20_000 {
            let Some(wi) = lobe.sample(wo, st.sample(0, i).get2d(0)) else { continue };
            let h = (wo + wi).normalize();
            let expect = super::fresnel::schlick(lobe.f0, lobe.f90, wo.dot(h)) * (lobe.ggx.g2(wo, wi) / lobe.ggx.g1(wo));
            let weight = lobe.eval(wo, wi) * wi.z / lobe.pdf(wo, wi);
            let err = (weight - expect).abs().max_element() / expect.max_element();
            assert!(err < 1e-3, "α {alpha}, cos θo {cos}, wi {wi}: weight {weight} vs F G2/G1 {expect}");
        }
    }
}

#[test]
fn rough_dielectric_sampling_follows_its_pdf() {
    let cases = dielectric_cases();
    let failures =
        run(&cases, |&(e, a, c)| format!("dielectric η {e}, α {a}, cos θo {c}"), |&(e, a, c)| dielectric_chi2(e, a, c, e, a), true);
    assert_none(failures, "dielectric cases fail");
}

#[test]
fn dielectric_chi2_rejects_a_pdf_with_the_wrong_roughness_or_index() {
    let cases = dielectric_cases();
    let mut failures = run(
        &cases,
        |&(e, a, c)| format!("dielectric η {e}, α {a}, cos θo {c}, pdf at 1.1 α"),
        |&(e, a, c)| dielectric_chi2(e, a, c, e, 1.1 * a),
        false,
    );
    failures.extend(run(
        &cases,
        |&(e, a, c)| format!("dielectric η {e}, α {a}, cos θo {c}, pdf at η + 0.1"),
        |&(e, a, c)| dielectric_chi2(e, a, c, e + 0.1, a),
        false,
    ));
    assert_none(failures, "wrong dielectric densities pass");
}

#[test]
fn dielectric_sample_records_eval_and_pdf() {
    // The sample's f·|cos θi| and pdf are those `eval_pdf` gives for its direction, so the path
    // weight f·|cos θi|/pdf is the one MIS and light sampling assume.
    let st = StreamSampler::new(6, StreamKind::Pt);
    for (eta, alpha, cos) in dielectric_cases() {
        let d = Dielectric::new(eta, alpha);
        let wo = wo_at(cos.abs()) * Vec3A::new(1.0, 1.0, cos.signum());
        for i in 0..20_000 {
            let s = st.sample(0, i);
            let Some(r) = d.sample(wo, s.get1d(0), s.get2d(1)) else { continue };
            let (f, pdf) = d.eval_pdf(wo, r.wi);
            assert!(!r.delta && pdf > 0.0);
            assert!((r.pdf - pdf).abs() <= 1e-5 * pdf, "η {eta} α {alpha} cos {cos}: pdf {} vs {pdf}", r.pdf);
            let f_cos = f * r.wi.z.abs();
            assert!((r.f_cos - f_cos).abs() <= 1e-5 * f_cos, "η {eta} α {alpha} cos {cos}: f cos {} vs {f_cos}", r.f_cos);
            assert_eq!(r.transmitted, r.wi.z * wo.z < 0.0);
        }
    }
}

#[test]
fn lobe_mixture_sampling_follows_its_pdf() {
    let cases = mixture_cases();
    let failures = run(&cases, |(n, _, c)| format!("mixture {n}, cos θo {c}"), |(_, p, c)| mixture_chi2(p, *c, p), true);
    assert_none(failures, "mixture cases fail");
}

#[test]
fn mixture_chi2_rejects_a_pdf_with_the_wrong_roughness_or_lobe_weights() {
    let cases = mixture_cases();
    let mut failures = run(
        &cases,
        |(n, _, c)| format!("mixture {n}, cos θo {c}, pdf at 1.1 roughness"),
        |(_, p, c)| mixture_chi2(p, *c, &PbrParams { roughness: p.roughness * 1.1, ..*p }),
        false,
    );
    // Other lobe probabilities: the metallic or transmission factor shifted, which moves weight
    // between the diffuse, specular and glass lobes.
    let shifted = |p: &PbrParams| {
        if p.metallic > 0.0 {
            PbrParams { metallic: p.metallic - 0.15, ..*p }
        } else if p.transmission > 0.0 {
            PbrParams { transmission: p.transmission - 0.15, ..*p }
        } else {
            PbrParams { metallic: 0.15, ..*p }
        }
    };
    failures.extend(run(
        &cases,
        |(n, _, c)| format!("mixture {n}, cos θo {c}, pdf with shifted lobe weights"),
        |(_, p, c)| mixture_chi2(p, *c, &shifted(p)),
        false,
    ));
    assert_none(failures, "wrong mixture densities pass");
}

//! Bias of the estimators on the synthetic scene, whose reference is exact.
use cvtrace_eval::metrics::Reference;
use cvtrace_eval::stats::SeedAccumulator;
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{build, Input, Overrides};
use cvtrace_streams::{Image, StreamSet};
use std::sync::OnceLock;

const W: usize = 32;
const SEEDS: u64 = 64;

/// Squared bias of one method over seeds, with its standard deviation under zero bias.
struct Bias {
    /// `SeedAccumulator`'s relative squared bias (unbiased for the true one).
    bias2: f64,
    /// Its standard deviation if the method were unbiased.
    sd0: f64,
    /// Its delete-one-seed jackknife standard deviation (valid with a bias).
    sd_jack: f64,
    /// `SeedAccumulator`'s relative variance of one seed.
    variance: f64,
}

/// With `S` seeds, errors `e_a = x_a − r` and relMSE weights `w`, let
/// `G_ab = mean_j w_j e_a,j e_b,j` (j over pixels and channels). The bias² of
/// `SeedAccumulator` is the U-statistic `U = Σ_{a≠b} G_ab / (S(S−1))` (an identity: the
/// squared mean minus the variance of the mean over S). Seeds are independent, so without
/// bias `E[G_ab | e_a] = 0`: the pairs are uncorrelated and `Var U = 2·E[G_ab²] / (S(S−1))`,
/// estimated by the mean of `G_ab²` over the pairs. This holds however the pixels of one
/// image are correlated (CRN), since `G_ab` sums over the whole image.
fn bias(reference: &Reference, images: &[Image]) -> Bias {
    let w = reference.weights();
    let r = &reference.image.pixels;
    let e: Vec<Vec<f64>> = images
        .iter()
        .map(|im| im.pixels.iter().zip(r).flat_map(|(x, r)| (0..3).map(move |c| x[c] as f64 - r[c] as f64)).collect())
        .collect();
    let n = 3 * r.len();
    let s = images.len();
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    // Row sums of G without the diagonal, for the jackknife.
    let mut row = vec![0.0; s];
    for a in 0..s {
        for b in a + 1..s {
            let g: f64 = (0..n).map(|j| w[j / 3] * e[a][j] * e[b][j]).sum::<f64>() / n as f64;
            sum += g;
            sum_sq += g * g;
            row[a] += g;
            row[b] += g;
        }
    }
    let pairs = (s * (s - 1) / 2) as f64;
    let u = sum / pairs;
    let sd0 = (2.0 * (sum_sq / pairs) / (s * (s - 1)) as f64).sqrt();
    // Leaving seed a out: the mean of G over the pairs without a.
    let loo: Vec<f64> = row.iter().map(|r| (sum - r) / ((s - 1) * (s - 2) / 2) as f64).collect();
    let loo_mean = loo.iter().sum::<f64>() / s as f64;
    let sd_jack = ((s - 1) as f64 / s as f64 * loo.iter().map(|v| (v - loo_mean).powi(2)).sum::<f64>()).sqrt();
    let mut acc = SeedAccumulator::new(reference, "bias");
    for im in images {
        acc.add(im).unwrap();
    }
    let st = acc.finish().unwrap();
    let (bias2, variance) = (st.bias2.unwrap(), st.variance.unwrap());
    assert!((bias2 - u).abs() < 1e-9 * variance, "U-statistic {u} vs SeedAccumulator {bias2}");
    Bias { bias2, sd0, sd_jack, variance }
}

/// One estimator's images over the seeds (each seed's stream set rendered once, shared).
fn images(method: &str, options: &Overrides) -> (Reference, Vec<Image>) {
    static SETS: OnceLock<(Image, Vec<StreamSet>)> = OnceLock::new();
    let (reference, sets) = SETS.get_or_init(|| {
        let scene = SoftShadowScene::default();
        let spec = |seed| RenderSpec { width: W, height: W, spp: 32, batches: 16, seed: 7000 + seed };
        let sets = (0..SEEDS).map(|seed| scene.render(&spec(seed)).unwrap()).collect();
        (scene.reference(W, W), sets)
    });
    let est = build(method, options).unwrap();
    (Reference::new(reference.clone(), "exact").unwrap(), sets.iter().map(|s| est.run(&Input::new(s)).unwrap().image).collect())
}

#[test]
fn average_is_unbiased() {
    // PT and CRN are unbiased (synthetic.rs tests), so their mean is: |bias²| < 5·sd under
    // zero bias. Resolution here: 5·sd ≈ 1e-4, i.e. a scale error of ≈ 1% of the pixel values.
    let (reference, images) = images("average", &Overrides::default());
    let b = bias(&reference, &images);
    assert!(b.bias2.abs() < 5.0 * b.sd0, "average: bias² {:.3e}, sd under zero bias {:.3e}", b.bias2, b.sd0);
}

#[test]
fn ours_bias_is_small_against_its_variance() {
    // ours is biased by construction (β is estimated from the batches of the values it
    // weights), so what is required is that the bias be a small share of the error: bias² at
    // most 5% of the variance, so that it adds at most 5% to relMSE, the precision (about ±4%)
    // of the ablation tables that chose the defaults. The bound carries the uncertainty of the
    // estimate: bias² + 5·sd < 0.05 · variance, with sd the jackknife standard deviation over
    // seeds (conservative for this U-statistic; it is not the zero-bias sd, since the bias is
    // not zero). Measured when written: bias² 1.1% of the variance.
    let (reference, images) = images("ours", &Overrides::default());
    let b = bias(&reference, &images);
    assert!(b.bias2 + 5.0 * b.sd_jack < 0.05 * b.variance, "ours: bias² {:.3e} ± {:.3e}, variance {:.3e}", b.bias2, b.sd_jack, b.variance);
}

//! Statistics over independent seeds: relMSE mean ± standard error, and its split into
//! squared bias and variance.
//!
//! With `S` seeds, per pixel and channel `j` the sample mean `m_j` and the unbiased sample
//! variance `s²_j` of the estimates, and the relMSE weight `w_j = 1/(r̄²+ε)`:
//!
//! - variance = mean_j `w_j s²_j` — the relMSE a single seed loses to noise;
//! - bias²    = mean_j `w_j ((m_j − r_j)² − s²_j / S)` — `(m − r)²` alone overstates the
//!   squared bias by the variance of the mean, `σ²/S`; subtracting its unbiased estimate
//!   makes bias² unbiased (so it can come out slightly negative for unbiased methods).
//!
//! Then bias² + variance equals the mean of the per-seed relMSEs exactly (an identity,
//! not an approximation), which is what users expect a decomposition to do.
use crate::metrics::{Metrics, Reference};
use crate::EvalError;
use cvtrace_streams::Image;

/// Streaming per-method accumulator: add one image per seed, in seed order, and never
/// keep more than two f64 planes (Welford's running mean and sum of squared deviations).
#[derive(Clone, Debug)]
pub struct SeedAccumulator<'r> {
    reference: &'r Reference,
    method: String,
    mean: Vec<[f64; 3]>,
    m2: Vec<[f64; 3]>,
    per_seed: Vec<Metrics>,
    /// Per seed, the image mean of each channel.
    image_means: Vec<[f64; 3]>,
    /// Per seed that came with one, the relMSE-weighted mean of the estimator's own
    /// predicted per-pixel variance.
    predicted: Vec<f64>,
}

/// What [`SeedAccumulator::finish`] reports for one method.
#[derive(Clone, Debug, PartialEq)]
pub struct SeedStats {
    pub seeds: usize,
    pub relmse_mean: f64,
    /// Standard error of `relmse_mean` (sample standard deviation / √S); `None` for one seed.
    pub relmse_se: Option<f64>,
    pub relmse_per_seed: Vec<f64>,
    pub mse_mean: f64,
    pub mse_se: Option<f64>,
    /// Relative squared bias (see the module docs); `None` for one seed.
    pub bias2: Option<f64>,
    /// Relative variance of one seed's image; `None` for one seed.
    pub variance: Option<f64>,
    /// The estimator's own predicted variance, weighted like `variance` and averaged over
    /// seeds; `None` when it predicts none.
    pub predicted_variance: Option<f64>,
    /// The same per seed, in seed order (empty when it predicts none): where rare fireflies
    /// carry the error, one seed can hold most of the sum, and the ratio to `variance` then
    /// says more about that seed than about the calibration.
    pub predicted_variance_per_seed: Vec<f64>,
    /// Per channel, the image mean over seeds relative to the reference's, minus 1.
    pub image_mean_offset: [f64; 3],
    /// Standard error of `image_mean_offset` over seeds; `None` for one seed.
    pub image_mean_offset_se: Option<[f64; 3]>,
}

impl<'r> SeedAccumulator<'r> {
    /// `method` names the estimator in error messages.
    pub fn new(reference: &'r Reference, method: impl Into<String>) -> Self {
        let n = reference.image.len();
        SeedAccumulator {
            reference,
            method: method.into(),
            mean: vec![[0.0; 3]; n],
            m2: vec![[0.0; 3]; n],
            per_seed: Vec::new(),
            image_means: Vec::new(),
            predicted: Vec::new(),
        }
    }

    /// Adds the next seed's image (label defaults to "`method` seed `k`").
    pub fn add(&mut self, image: &Image) -> Result<Metrics, EvalError> {
        let label = format!("{} seed {}", self.method, self.per_seed.len());
        self.add_labelled(image, &label)
    }

    /// Adds the next seed's image; `label` (e.g. its file name) names it in errors.
    pub fn add_labelled(&mut self, image: &Image, label: &str) -> Result<Metrics, EvalError> {
        let metrics = self.reference.metrics(image, label)?;
        let k = (self.per_seed.len() + 1) as f64;
        for ((mean, m2), p) in self.mean.iter_mut().zip(&mut self.m2).zip(&image.pixels) {
            for c in 0..3 {
                let x = p[c] as f64;
                let delta = x - mean[c];
                mean[c] += delta / k;
                m2[c] += delta * (x - mean[c]);
            }
        }
        self.per_seed.push(metrics);
        self.image_means.push(channel_means(image));
        Ok(metrics)
    }

    /// Adds the estimator's predicted per-pixel variance of the seed just added.
    pub fn add_predicted_variance(&mut self, variance: &Image, label: &str) -> Result<(), EvalError> {
        if !variance.same_size(&self.reference.image) {
            return Err(EvalError::invalid(label, "its variance layer is not the size of the reference"));
        }
        let w = self.reference.weights();
        let sum: f64 = variance.pixels.iter().zip(w).map(|(v, w)| w * v.iter().map(|x| *x as f64).sum::<f64>()).sum();
        self.predicted.push(sum / (3 * variance.len()).max(1) as f64);
        Ok(())
    }

    pub fn seeds(&self) -> usize {
        self.per_seed.len()
    }

    pub fn method(&self) -> &str {
        &self.method
    }

    /// The per-pixel mean over the seeds added so far.
    pub fn mean_image(&self) -> Image {
        let r = &self.reference.image;
        Image { width: r.width, height: r.height, pixels: self.mean.iter().map(|m| m.map(|v| v as f32)).collect() }
    }

    /// Per-pixel relMSE averaged over seeds (mean over channels); its pixel mean is
    /// `relmse_mean`. A steadier false-colour map than any single seed's.
    pub fn mean_rel_mse_map(&self) -> Vec<f32> {
        let s = self.per_seed.len().max(1) as f64;
        let r = &self.reference.image.pixels;
        let w = self.reference.weights();
        (0..r.len())
            .map(|i| {
                let e: f64 = (0..3).map(|c| (self.mean[i][c] - r[i][c] as f64).powi(2) + self.m2[i][c] / s).sum();
                (e * w[i] / 3.0) as f32
            })
            .collect()
    }

    /// The statistics of the seeds added so far. Errors when none was added.
    pub fn finish(&self) -> Result<SeedStats, EvalError> {
        let s = self.per_seed.len();
        if s == 0 {
            return Err(EvalError::invalid(&self.method, "no seed was evaluated"));
        }
        let rel: Vec<f64> = self.per_seed.iter().map(|m| m.rel_mse).collect();
        let abs: Vec<f64> = self.per_seed.iter().map(|m| m.mse).collect();
        let (relmse_mean, relmse_se) = mean_and_se(&rel);
        let (mse_mean, mse_se) = mean_and_se(&abs);
        let (bias2, variance) = if s >= 2 {
            let sf = s as f64;
            let r = &self.reference.image.pixels;
            let w = self.reference.weights();
            let (mut b, mut v) = (0.0f64, 0.0f64);
            for (((mean, m2), r), w) in self.mean.iter().zip(&self.m2).zip(r).zip(w) {
                for c in 0..3 {
                    let var = m2[c] / (sf - 1.0);
                    let d = mean[c] - r[c] as f64;
                    b += w * (d * d - var / sf);
                    v += w * var;
                }
            }
            let n = (3 * r.len()).max(1) as f64;
            (Some(b / n), Some(v / n))
        } else {
            (None, None)
        };
        let predicted_variance = (!self.predicted.is_empty()).then(|| self.predicted.iter().sum::<f64>() / self.predicted.len() as f64);
        let truth = channel_means(&self.reference.image);
        let offsets: Vec<[f64; 3]> = self.image_means.iter().map(|m| std::array::from_fn(|c| m[c] / truth[c] - 1.0)).collect();
        let per_channel = |c: usize| mean_and_se(&offsets.iter().map(|o| o[c]).collect::<Vec<_>>());
        let image_mean_offset = std::array::from_fn(|c| per_channel(c).0);
        let image_mean_offset_se = (s >= 2).then(|| std::array::from_fn(|c| per_channel(c).1.unwrap_or(0.0)));
        Ok(SeedStats {
            seeds: s,
            relmse_mean,
            relmse_se,
            relmse_per_seed: rel,
            mse_mean,
            mse_se,
            bias2,
            variance,
            predicted_variance,
            predicted_variance_per_seed: self.predicted.clone(),
            image_mean_offset,
            image_mean_offset_se,
        })
    }
}

/// The mean of each channel over the pixels.
fn channel_means(image: &Image) -> [f64; 3] {
    let n = image.len().max(1) as f64;
    std::array::from_fn(|c| image.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / n)
}

/// Sample mean and its standard error (`None` with fewer than two values).
pub fn mean_and_se(values: &[f64]) -> (f64, Option<f64>) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, None);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, None);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (mean, Some((var / n as f64).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng as TestRng;

    /// A reference with varied brightness so the relMSE weights differ across pixels.
    fn truth(w: usize, h: usize) -> Image {
        Image::from_fn(w, h, |x, y| {
            let v = 0.05 + 0.9 * ((x * 7 + y * 13) % 17) as f32 / 16.0;
            [v, 0.5 * v, 0.2 + 0.3 * v]
        })
    }

    /// One seed of a synthetic estimator: truth + bias + sigma · N(0, 1), per pixel/channel.
    fn noisy(t: &Image, bias: &[[f64; 3]], sigma: &[[f64; 3]], rng: &mut TestRng) -> Image {
        let mut out = t.clone();
        for (i, p) in out.pixels.iter_mut().enumerate() {
            for c in 0..3 {
                p[c] = (p[c] as f64 + bias[i][c] + sigma[i][c] * rng.normal()) as f32;
            }
        }
        out
    }

    struct Truths {
        bias2: f64,
        variance: f64,
        /// Standard deviations of the bias² and variance estimators (Gaussian noise).
        bias2_sd: f64,
        variance_sd: f64,
    }

    fn true_values(r: &Reference, bias: &[[f64; 3]], sigma: &[[f64; 3]], s: f64) -> Truths {
        let w = r.weights();
        let n = (3 * w.len()) as f64;
        let (mut b2, mut v, mut vb, mut vv) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..w.len() {
            for c in 0..3 {
                let (b, sg2) = (bias[i][c], sigma[i][c].powi(2));
                b2 += w[i] * b * b;
                v += w[i] * sg2;
                // Var((m−r)²) + Var(s²/S); m and s² are independent for Gaussian noise.
                vb += w[i] * w[i] * (2.0 * sg2 * sg2 / (s * s) + 4.0 * b * b * sg2 / s + 2.0 * sg2 * sg2 / ((s - 1.0) * s * s));
                vv += w[i] * w[i] * 2.0 * sg2 * sg2 / (s - 1.0);
            }
        }
        Truths { bias2: b2 / n, variance: v / n, bias2_sd: vb.sqrt() / n, variance_sd: vv.sqrt() / n }
    }

    fn run(reference: &Reference, bias: &[[f64; 3]], sigma: &[[f64; 3]], seeds: usize, rng: &mut TestRng) -> (SeedStats, Vec<f32>, Image) {
        let mut acc = SeedAccumulator::new(reference, "synthetic");
        for _ in 0..seeds {
            acc.add(&noisy(&reference.image, bias, sigma, rng)).unwrap();
        }
        (acc.finish().unwrap(), acc.mean_rel_mse_map(), acc.mean_image())
    }

    #[test]
    fn decomposition_recovers_known_bias_and_variance() {
        let t = truth(64, 64);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let n = t.len();
        let mut rng = TestRng::new(1);
        // Spatially varying bias and noise so a wrong weighting would show.
        let bias: Vec<[f64; 3]> = (0..n).map(|i| [0.02 * ((i % 5) as f64 - 1.0), 0.03, -0.01]).collect();
        let sigma: Vec<[f64; 3]> = (0..n).map(|i| [0.05 + 0.1 * ((i % 3) as f64), 0.08, 0.12]).collect();
        let seeds = 6;
        let (stats, _, _) = run(&reference, &bias, &sigma, seeds, &mut rng);
        let truths = true_values(&reference, &bias, &sigma, seeds as f64);
        let (b2, v) = (stats.bias2.unwrap(), stats.variance.unwrap());
        assert!((b2 - truths.bias2).abs() < 5.0 * truths.bias2_sd, "bias² {b2} vs {} ± {}", truths.bias2, truths.bias2_sd);
        assert!((v - truths.variance).abs() < 5.0 * truths.variance_sd, "variance {v} vs {} ± {}", truths.variance, truths.variance_sd);
        // bias² + variance is the mean per-seed relMSE, exactly.
        assert!((b2 + v - stats.relmse_mean).abs() < 1e-9 * stats.relmse_mean);
    }

    #[test]
    fn unbiased_estimator_gets_bias2_near_zero_not_var_over_s() {
        let t = truth(64, 64);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let n = t.len();
        let bias = vec![[0.0; 3]; n];
        let sigma = vec![[0.1; 3]; n];
        let seeds = 4;
        let (stats, _, mean) = run(&reference, &bias, &sigma, seeds, &mut TestRng::new(2));
        let truths = true_values(&reference, &bias, &sigma, seeds as f64);
        let b2 = stats.bias2.unwrap();
        assert!(b2.abs() < 5.0 * truths.bias2_sd, "bias² {b2} should be 0 ± {}", truths.bias2_sd);
        // The naive ‖mean − ref‖² would be off by var/S: make sure that is far outside the bound.
        let naive = reference.rel_mse(&mean, "mean").unwrap();
        assert!((naive - truths.variance / seeds as f64).abs() < 5.0 * truths.bias2_sd);
        assert!(naive > 20.0 * truths.bias2_sd, "test has no power: naive {naive}");
    }

    #[test]
    fn standard_error_matches_the_spread_across_replications() {
        let t = truth(16, 16);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let n = t.len();
        let bias = vec![[0.01; 3]; n];
        let sigma: Vec<[f64; 3]> = (0..n).map(|i| [0.05 + 0.002 * (i % 50) as f64; 3]).collect();
        let mut rng = TestRng::new(3);
        let (reps, seeds) = (300, 8);
        let mut means = Vec::new();
        let mut se2 = 0.0;
        for _ in 0..reps {
            let (stats, _, _) = run(&reference, &bias, &sigma, seeds, &mut rng);
            means.push(stats.relmse_mean);
            se2 += stats.relmse_se.unwrap().powi(2) / reps as f64;
        }
        let (_, se_of_means) = mean_and_se(&means);
        let empirical_var = se_of_means.unwrap().powi(2) * reps as f64;
        // E[se²] = Var(mean); both sides are estimates with ~8% and ~4% relative spread here.
        let ratio = se2 / empirical_var;
        assert!((0.65..1.5).contains(&ratio), "mean se² {se2} vs variance of means {empirical_var}");
    }

    #[test]
    fn mean_map_averages_per_seed_maps() {
        let t = truth(9, 7);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let mut rng = TestRng::new(4);
        let n = t.len();
        let (bias, sigma) = (vec![[0.02; 3]; n], vec![[0.1; 3]; n]);
        let mut acc = SeedAccumulator::new(&reference, "m");
        let mut sum = vec![0.0f64; n];
        for _ in 0..5 {
            let img = noisy(&t, &bias, &sigma, &mut rng);
            for (s, v) in sum.iter_mut().zip(reference.rel_mse_map(&img, "x").unwrap()) {
                *s += v as f64 / 5.0;
            }
            acc.add(&img).unwrap();
        }
        for (a, b) in acc.mean_rel_mse_map().iter().zip(&sum) {
            assert!((*a as f64 - b).abs() <= 1e-5 * b.abs().max(1e-6), "{a} vs {b}");
        }
    }

    #[test]
    fn one_seed_has_no_spread_and_zero_seeds_is_an_error() {
        let t = truth(4, 4);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let acc = SeedAccumulator::new(&reference, "ours");
        assert!(acc.finish().unwrap_err().to_string().contains("ours"));
        let mut acc = SeedAccumulator::new(&reference, "ours");
        acc.add(&t).unwrap();
        let s = acc.finish().unwrap();
        assert_eq!((s.seeds, s.relmse_se, s.bias2, s.variance), (1, None, None, None));
        assert_eq!(s.relmse_mean, 0.0);
    }

    #[test]
    fn predicted_variance_is_kept_per_seed_and_averaged() {
        let t = truth(6, 5);
        let reference = Reference::new(t.clone(), "truth").unwrap();
        let mean_weight = reference.weights().iter().sum::<f64>() / t.len() as f64;
        let mut acc = SeedAccumulator::new(&reference, "ours");
        // One seed whose layer is forty times the others', as a firefly makes it.
        let layers = [0.5f32, 20.0, 0.25];
        for v in layers {
            acc.add(&t).unwrap();
            acc.add_predicted_variance(&Image::from_fn(6, 5, |_, _| [v, v, v]), "layer").unwrap();
        }
        let s = acc.finish().unwrap();
        assert_eq!(s.predicted_variance_per_seed.len(), 3);
        for (got, v) in s.predicted_variance_per_seed.iter().zip(layers) {
            assert!((got - v as f64 * mean_weight).abs() <= 1e-12 * got.abs(), "{got} against {}", v as f64 * mean_weight);
        }
        let mean = s.predicted_variance_per_seed.iter().sum::<f64>() / 3.0;
        assert!((s.predicted_variance.unwrap() - mean).abs() <= 1e-12 * mean);
        let err = acc.add_predicted_variance(&truth(5, 5), "seed-003.exr").unwrap_err().to_string();
        assert!(err.contains("seed-003.exr"), "{err}");
        let mut pt = SeedAccumulator::new(&reference, "pt");
        pt.add(&t).unwrap();
        let s = pt.finish().unwrap();
        assert!(s.predicted_variance.is_none() && s.predicted_variance_per_seed.is_empty());
    }

    #[test]
    fn wrong_size_seed_names_method_and_seed() {
        let reference = Reference::new(truth(4, 4), "ref.exr").unwrap();
        let mut acc = SeedAccumulator::new(&reference, "iduw");
        acc.add(&truth(4, 4)).unwrap();
        let err = acc.add(&truth(5, 4)).unwrap_err().to_string();
        assert!(err.contains("iduw seed 1") && err.contains("ref.exr"), "{err}");
        assert_eq!(acc.seeds(), 1, "a rejected image must not be counted");
    }
}

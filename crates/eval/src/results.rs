//! The results of a study as one JSON-able tree: what `cvtrace study` writes, what
//! `cvtrace report` reads, and what the viewer shows (as `window.CVTRACE_DATA`).
//!
//! Paths of images are relative to the folder holding the results file, use `/`, and never
//! leave it (no `..`, not absolute), so a study folder can be moved as a whole.
use crate::flip::{FlipSettings, FlipStats};
use crate::reference_noise::ReferenceNoise;
use crate::stats::SeedStats;
use crate::EvalError;
use cvtrace_streams::input_file::{regular_file, NotAFile};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::Path;

/// Bumped whenever a field changes meaning.
pub const SCHEMA_VERSION: u32 = 1;

/// Keys the study itself gives meaning to. Everything else about a method (label, short
/// label, colour, order, samples) travels with it in the results.
pub mod keys {
    /// A real PT render with `2n` spp: the equal-total-samples baseline a study renders itself
    /// (not an estimator). Ratios against it are unpaired.
    pub const PT_2N: &str = "pt2n";
    /// The PT stream alone: the paper's PT(2n) column is half of its relMSE (the Markdown
    /// summary's paper-convention column).
    pub const PT: &str = "pt";
}

/// The headline ratios of scenes whose results predate the `headline` field: the paper's
/// ours/IDUW, ours/CV and ours/PT(2n).
pub fn paper_headline() -> Vec<(String, String)> {
    [("ours", "iduw"), ("ours", "cv"), ("ours", keys::PT_2N)].iter().map(|(a, b)| (a.to_string(), b.to_string())).collect()
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StudyResults {
    pub schema_version: u32,
    /// e.g. "cvtrace 0.1.0".
    #[serde(default)]
    pub generator: String,
    pub scenes: Vec<SceneResult>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneResult {
    pub name: String,
    pub width: usize,
    pub height: usize,
    /// `n`: samples per pixel of *each* input stream; the estimators use `2n` in total.
    /// 0 when unknown (e.g. `cvtrace compare` on loose files).
    pub spp_per_stream: u32,
    /// Independent seeds evaluated.
    pub seeds: u32,
    pub reference: ReferenceInfo,
    pub methods: Vec<MethodResult>,
    /// relMSE against total spp for the convergence plot (empty without an `--spp` list).
    #[serde(default)]
    pub convergence: Vec<ConvergencePoint>,
    /// Log10 range of the false-colour relMSE maps, shared by all methods of the scene.
    #[serde(default)]
    pub error_map_scale: Option<ErrorMapScale>,
    /// The symmetric range of the signed difference maps, shared by all methods of the scene.
    #[serde(default)]
    pub difference_scale: Option<DifferenceScale>,
    /// How the methods' HDR-FLIP was computed (pixels per degree, exposures), when it was.
    #[serde(default)]
    pub flip: Option<FlipSettings>,
    /// Human-readable warnings (e.g. a reference too noisy to rank the methods).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The ratios (numerator, denominator) of method keys the tables and viewer headline.
    #[serde(default = "paper_headline")]
    pub headline: Vec<(String, String)>,
    /// What the renders were made from and with (scene hash, camera, size, depths, traversal,
    /// version), as (field, value) pairs.
    #[serde(default)]
    pub render: Vec<(String, String)>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// Where the reference EXR was read from: absolute (see [`ReferenceInfo::path_of`]), so it
    /// still names the file when the results are read from another directory.
    pub path: String,
    #[serde(default)]
    pub spp: Option<u32>,
    /// PNG preview, relative to the results folder.
    #[serde(default)]
    pub image: Option<String>,
    /// The relMSE the reference's own noise adds to every method (see `reference_noise`).
    #[serde(default)]
    pub noise: Option<ReferenceNoise>,
    /// The reference's linear RGB as the study scored against it, an EXR relative to the
    /// results folder (see `pixels`): what the viewer's pixel readout shows.
    #[serde(default)]
    pub values: Option<String>,
}

impl ReferenceInfo {
    /// The text recorded for the reference read from `path`: its absolute path with links
    /// resolved, or `path` as given if that fails.
    pub fn path_of(path: &std::path::Path) -> String {
        std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()).display().to_string()
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// Key: one of [`keys`] or a free name for ablations (e.g. "ours-no-penalty").
    pub name: String,
    /// Display label, e.g. "Ours (imperfect CV)".
    pub label: String,
    /// Short label for ratio names and narrow headers (e.g. "IDUW"); the key when empty.
    #[serde(default)]
    pub short: String,
    /// Colour in plots and the viewer, `#rrggbb`; a fallback colour when absent.
    #[serde(default)]
    pub colour: Option<String>,
    /// Every parameter the estimator ran with, as (name, value).
    #[serde(default)]
    pub settings: Vec<(String, String)>,
    /// What the estimator reported, averaged over seeds where numeric (the first seed's text
    /// otherwise), as (name, value).
    #[serde(default)]
    pub diagnostics: Vec<(String, serde_json::Value)>,
    /// Total samples per pixel the method consumed (n for PT/CRN, 2n for the rest); 0 if unknown.
    pub spp_total: u32,
    pub relmse_mean: f64,
    #[serde(default)]
    pub relmse_se: Option<f64>,
    /// Relative squared bias over seeds (unbiased estimate; may be slightly negative).
    #[serde(default)]
    pub bias2: Option<f64>,
    /// Relative variance of one seed's image.
    #[serde(default)]
    pub variance: Option<f64>,
    /// The estimator's own predicted variance, weighted like `variance`; its ratio to
    /// `variance` is the calibration of the prediction.
    #[serde(default)]
    pub predicted_variance: Option<f64>,
    /// `predicted_variance` per seed, in seed order (empty when none is predicted).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub predicted_variance_per_seed: Vec<f64>,
    /// Per channel, the image mean over seeds relative to the reference's, minus 1.
    #[serde(default)]
    pub image_mean_offset: Option<[f64; 3]>,
    /// Standard error over seeds of `image_mean_offset`.
    #[serde(default)]
    pub image_mean_offset_se: Option<[f64; 3]>,
    pub mse_mean: f64,
    #[serde(default)]
    pub relmse_per_seed: Vec<f64>,
    /// Mean seconds per seed.
    #[serde(default)]
    pub time_seconds: StageTimes,
    /// PNG preview (sRGB) of one seed's output, relative to the results folder.
    #[serde(default)]
    pub image: Option<String>,
    /// False-colour relMSE map PNG, relative to the results folder.
    #[serde(default)]
    pub error_map: Option<String>,
    /// False-colour signed difference of `image` to the reference (see `difference`), PNG,
    /// relative to the results folder.
    #[serde(default)]
    pub difference_map: Option<String>,
    /// HDR-FLIP (see `flip`): the mean over seeds of each seed's mean FLIP error, in [0, 1].
    /// Absent in results of studies that did not compute it.
    #[serde(default)]
    pub flip_mean: Option<f64>,
    /// Standard error of `flip_mean` over seeds; `None` for one seed.
    #[serde(default)]
    pub flip_se: Option<f64>,
    /// Each seed's mean FLIP error, in seed order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flip_per_seed: Vec<f64>,
    /// The per-pixel FLIP error averaged over seeds through the magma colour map (see `flip`),
    /// PNG, relative to the results folder.
    #[serde(default)]
    pub flip_map: Option<String>,
    /// Linear RGB of `image` and the per-pixel relMSE of `error_map`, an EXR relative to the
    /// results folder (see `pixels`): what the viewer's pixel readout shows.
    #[serde(default)]
    pub values: Option<String>,
    /// Part of `--ablations` (shown in a separate table).
    #[serde(default)]
    pub ablation: bool,
    /// For an ablation: the key of the method it is a variant of.
    #[serde(default)]
    pub base: Option<String>,
}

/// Mean wall-clock seconds per seed spent in each stage of one method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimes {
    /// Rendering the stream(s) the method reads.
    pub render: f64,
    /// Running the estimator (0 for plain streams).
    pub reconstruct: f64,
}

impl StageTimes {
    pub fn total(&self) -> f64 {
        self.render + self.reconstruct
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConvergencePoint {
    pub method: String,
    pub spp_total: u32,
    pub relmse: f64,
    #[serde(default)]
    pub relmse_se: Option<f64>,
    /// Mean seconds per image at this point: the render of the streams the method reads plus
    /// its reconstruction (absent in results of studies that did not record it).
    #[serde(default)]
    pub seconds: Option<f64>,
    /// Relative squared bias over the seeds at this point (as [`MethodResult::bias2`]; absent
    /// for one seed and in results of studies that did not record it).
    #[serde(default)]
    pub bias2: Option<f64>,
}

/// The colour scale of false-colour maps: log10 relMSE from `log10_min` (darkest) to
/// `log10_max` (brightest); values outside are clamped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorMapScale {
    pub log10_min: f64,
    pub log10_max: f64,
    /// Name of the colour map (see `falsecolor`).
    pub colormap: String,
}

/// The colour scale of signed difference maps: from `-max_abs` (one end of the diverging
/// map) through 0 (its dark centre) to `+max_abs`; values outside are clamped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DifferenceScale {
    pub max_abs: f64,
    /// Name of the colour map (see `difference`).
    pub colormap: String,
}

impl MethodResult {
    /// A result filled from seed statistics; times and images are left for the caller.
    pub fn from_stats(name: &str, label: &str, spp_total: u32, stats: &SeedStats) -> Self {
        MethodResult {
            name: name.to_string(),
            label: label.to_string(),
            short: String::new(),
            colour: None,
            settings: Vec::new(),
            diagnostics: Vec::new(),
            spp_total,
            relmse_mean: stats.relmse_mean,
            relmse_se: stats.relmse_se,
            bias2: stats.bias2,
            variance: stats.variance,
            predicted_variance: stats.predicted_variance,
            predicted_variance_per_seed: stats.predicted_variance_per_seed.clone(),
            image_mean_offset: Some(stats.image_mean_offset),
            image_mean_offset_se: stats.image_mean_offset_se,
            mse_mean: stats.mse_mean,
            relmse_per_seed: stats.relmse_per_seed.clone(),
            time_seconds: StageTimes::default(),
            image: None,
            error_map: None,
            difference_map: None,
            flip_mean: None,
            flip_se: None,
            flip_per_seed: Vec::new(),
            flip_map: None,
            values: None,
            ablation: false,
            base: None,
        }
    }

    /// Records the method's HDR-FLIP statistics over seeds.
    pub fn set_flip(&mut self, stats: &FlipStats) {
        self.flip_mean = Some(stats.mean);
        self.flip_se = stats.se;
        self.flip_per_seed = stats.per_seed.clone();
    }
}

/// `numerator / denominator` of two methods' mean relMSE.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ratio {
    pub numerator: String,
    pub denominator: String,
    pub value: f64,
    /// Delta-method standard error (seed noise, first order: not a confidence interval, and
    /// the ratio of means carries an O(1/S) bias where the denominator is noisy). Uses the
    /// per-seed pairing when both methods have per-seed values for the same seeds and share
    /// the input streams; PT(2n) is a render of its own, so ratios with it are unpaired.
    pub se: Option<f64>,
}

impl MethodResult {
    /// The short label, or the key.
    pub fn short_label(&self) -> &str {
        if self.short.is_empty() {
            &self.name
        } else {
            &self.short
        }
    }
}

impl SceneResult {
    pub fn method(&self, name: &str) -> Option<&MethodResult> {
        self.methods.iter().find(|m| m.name == name)
    }

    /// The short label of method `key`, or the key when the scene does not have it.
    pub fn short_label(&self, key: &str) -> String {
        self.method(key).map(|m| m.short_label().to_string()).unwrap_or_else(|| key.to_string())
    }

    /// The headline ratios among the methods present.
    pub fn ratios(&self) -> Vec<Ratio> {
        self.headline.iter().filter_map(|(a, b)| self.ratio(a, b)).collect()
    }

    pub fn ratio(&self, numerator: &str, denominator: &str) -> Option<Ratio> {
        let (a, b) = (self.method(numerator)?, self.method(denominator)?);
        if b.relmse_mean.is_nan() || b.relmse_mean <= 0.0 {
            return None;
        }
        let value = a.relmse_mean / b.relmse_mean;
        let (pa, pb) = (&a.relmse_per_seed, &b.relmse_per_seed);
        // Independent renders have no covariance; estimating one from a few seeds only adds noise.
        let shared_inputs = numerator != keys::PT_2N && denominator != keys::PT_2N;
        let se = if shared_inputs && pa.len() == pb.len() && pa.len() >= 2 {
            let n = pa.len() as f64;
            let (ma, mb) = (pa.iter().sum::<f64>() / n, pb.iter().sum::<f64>() / n);
            let cov =
                |x: &[f64], mx: f64, y: &[f64], my: f64| x.iter().zip(y).map(|(x, y)| (x - mx) * (y - my)).sum::<f64>() / (n - 1.0) / n;
            let rel_var = cov(pa, ma, pa, ma) / (ma * ma) + cov(pb, mb, pb, mb) / (mb * mb) - 2.0 * cov(pa, ma, pb, mb) / (ma * mb);
            Some(value * rel_var.max(0.0).sqrt())
        } else {
            match (a.relmse_se, b.relmse_se) {
                (Some(sa), Some(sb)) => Some(value * ((sa / a.relmse_mean).powi(2) + (sb / b.relmse_mean).powi(2)).sqrt()),
                _ => None,
            }
        };
        Some(Ratio { numerator: numerator.into(), denominator: denominator.into(), value, se })
    }

    /// The smallest mean relMSE among non-ablation methods (for the reference-noise check).
    pub fn best_relmse(&self) -> Option<f64> {
        self.methods.iter().filter(|m| !m.ablation).map(|m| m.relmse_mean).filter(|v| v.is_finite()).reduce(f64::min)
    }

    /// Methods in display order: the order of the file, which is the order of the registry
    /// that wrote it.
    pub fn ordered_methods(&self) -> Vec<&MethodResult> {
        self.methods.iter().collect()
    }
}

impl StudyResults {
    /// Every scene's headline ratios, each once, in first-seen order.
    pub fn headline(&self) -> Vec<(String, String)> {
        let mut out: Vec<(String, String)> = Vec::new();
        for pair in self.scenes.iter().flat_map(|s| s.headline.iter()) {
            if !out.contains(pair) {
                out.push(pair.clone());
            }
        }
        out
    }

    /// The short label of method `key` in the first scene that has it, or the key.
    pub fn short_label(&self, key: &str) -> String {
        self.scenes.iter().find_map(|s| s.method(key)).map(|m| m.short_label().to_string()).unwrap_or_else(|| key.to_string())
    }

    pub fn new(scenes: Vec<SceneResult>) -> Self {
        StudyResults { schema_version: SCHEMA_VERSION, generator: format!("cvtrace {}", env!("CARGO_PKG_VERSION")), scenes }
    }

    /// Geometric mean over scenes of each headline ratio (scenes lacking a method are skipped),
    /// as the paper summarises its ten scenes. Its standard error is the seed noise of the
    /// scenes' ratios carried through the logarithm (delta method, scenes fixed and
    /// independent): `G·√(Σ (seᵢ/Rᵢ)²)/K`; none unless every scene's ratio has one.
    pub fn geomean_ratios(&self) -> Vec<Ratio> {
        self.headline()
            .iter()
            .filter_map(|(a, b)| {
                let ratios: Vec<Ratio> = self.scenes.iter().filter_map(|s| s.ratio(a, b)).collect();
                let k = ratios.len() as f64;
                let value = (ratios.iter().map(|r| r.value.ln()).sum::<f64>() / k).exp();
                let rel_var: Option<f64> = ratios.iter().map(|r| r.se.map(|se| (se / r.value).powi(2))).sum();
                (!ratios.is_empty()).then(|| Ratio {
                    numerator: a.to_string(),
                    denominator: b.to_string(),
                    value,
                    se: rel_var.map(|v| value * v.sqrt() / k),
                })
            })
            .collect()
    }

    /// Checks everything the viewer and the tables rely on; errors name the scene and method.
    pub fn validate(&self) -> Result<(), EvalError> {
        if self.schema_version != SCHEMA_VERSION {
            return Err(EvalError::invalid(
                "results",
                format!("schema version {} is not supported (this cvtrace reads version {SCHEMA_VERSION})", self.schema_version),
            ));
        }
        let mut scene_names = BTreeSet::new();
        for scene in &self.scenes {
            let ctx = format!("scene `{}`", scene.name);
            if scene.name.trim().is_empty() {
                return Err(EvalError::invalid("results", "a scene has an empty name"));
            }
            if !scene_names.insert(scene.name.as_str()) {
                return Err(EvalError::invalid(&ctx, "appears twice"));
            }
            if scene.width == 0 || scene.height == 0 || scene.seeds == 0 {
                return Err(EvalError::invalid(&ctx, "width, height and seeds must be positive"));
            }
            if scene.methods.is_empty() {
                return Err(EvalError::invalid(&ctx, "has no methods"));
            }
            for (p, what) in [(&scene.reference.image, "image"), (&scene.reference.values, "values")] {
                if let Some(p) = p {
                    check_relative_path(p, &format!("{ctx}, reference {what}"))?;
                }
            }
            if let Some(scale) = &scene.difference_scale {
                if !(scale.max_abs.is_finite() && scale.max_abs > 0.0) {
                    return Err(EvalError::invalid(&ctx, "difference_scale needs a finite max_abs > 0"));
                }
            }
            if let Some(f) = &scene.flip {
                let e = (f.start_exposure, f.stop_exposure);
                if !(f.ppd.is_finite() && f.ppd > 0.0 && e.0.is_finite() && e.1.is_finite() && e.0 <= e.1 && f.num_exposures >= 2) {
                    return Err(EvalError::invalid(
                        &ctx,
                        "flip needs a finite ppd > 0, finite start_exposure <= stop_exposure and num_exposures >= 2",
                    ));
                }
            }
            if let Some(noise) = &scene.reference.noise {
                check_number(noise.relmse, true, &format!("{ctx}, reference noise"))?;
            }
            if let Some(scale) = &scene.error_map_scale {
                if !(scale.log10_min.is_finite() && scale.log10_max.is_finite() && scale.log10_min < scale.log10_max) {
                    return Err(EvalError::invalid(&ctx, "error_map_scale needs finite log10_min < log10_max"));
                }
            }
            let mut names = BTreeSet::new();
            for m in &scene.methods {
                let mctx = format!("{ctx}, method `{}`", m.name);
                if m.name.trim().is_empty() {
                    return Err(EvalError::invalid(&ctx, "a method has an empty name"));
                }
                if !names.insert(m.name.as_str()) {
                    return Err(EvalError::invalid(&mctx, "appears twice"));
                }
                check_number(m.relmse_mean, true, &format!("{mctx}, relmse_mean"))?;
                check_number(m.mse_mean, true, &format!("{mctx}, mse_mean"))?;
                for (v, what) in [(m.relmse_se, "relmse_se"), (m.variance, "variance")] {
                    if let Some(v) = v {
                        check_number(v, true, &format!("{mctx}, {what}"))?;
                    }
                }
                if let Some(b) = m.bias2 {
                    check_number(b, false, &format!("{mctx}, bias2"))?;
                }
                for v in &m.relmse_per_seed {
                    check_number(*v, true, &format!("{mctx}, relmse_per_seed"))?;
                }
                if let Some(f) = m.flip_mean {
                    check_unit(f, &format!("{mctx}, flip_mean"))?;
                }
                if let Some(se) = m.flip_se {
                    check_number(se, true, &format!("{mctx}, flip_se"))?;
                }
                for v in &m.flip_per_seed {
                    check_unit(*v, &format!("{mctx}, flip_per_seed"))?;
                }
                check_number(m.time_seconds.render, true, &format!("{mctx}, render time"))?;
                check_number(m.time_seconds.reconstruct, true, &format!("{mctx}, reconstruct time"))?;
                for (p, what) in [
                    (&m.image, "image"),
                    (&m.error_map, "error_map"),
                    (&m.difference_map, "difference_map"),
                    (&m.flip_map, "flip_map"),
                    (&m.values, "values"),
                ] {
                    if let Some(p) = p {
                        check_relative_path(p, &format!("{mctx}, {what}"))?;
                    }
                }
            }
            for c in &scene.convergence {
                let cctx = format!("{ctx}, convergence point of `{}` at {} spp", c.method, c.spp_total);
                if c.spp_total == 0 || !(c.relmse > 0.0 && c.relmse.is_finite()) {
                    return Err(EvalError::invalid(cctx, "needs spp_total > 0 and a finite relMSE > 0 (log-log plot)"));
                }
                if let Some(t) = c.seconds {
                    check_number(t, true, &format!("{cctx}, seconds"))?;
                }
            }
        }
        Ok(())
    }

    /// Reads and validates a results JSON file.
    pub fn read_json(path: &Path) -> Result<Self, EvalError> {
        match regular_file(path) {
            Err(NotAFile::Io(e)) => return Err(EvalError::io(path, e)),
            Err(e) => return Err(EvalError::invalid(path.display().to_string(), e.to_string())),
            Ok(_) => {}
        }
        let bytes = std::fs::read(path).map_err(|e| EvalError::io(path, e))?;
        let results: StudyResults =
            serde_json::from_slice(&bytes).map_err(|e| EvalError::Json { path: path.to_path_buf(), message: e.to_string() })?;
        results.validate().map_err(|e| EvalError::Json { path: path.to_path_buf(), message: e.to_string() })?;
        Ok(results)
    }

    /// Pretty JSON, the exact text of `results.json`.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("results serialise: plain data without maps keyed by non-strings")
    }

    /// Writes the results as pretty JSON, atomically.
    pub fn write_json(&self, path: &Path, overwrite: bool) -> Result<(), EvalError> {
        self.validate()?;
        let text = self.to_json();
        cvtrace_streams::atomic::write_atomically(path, overwrite, |tmp| std::fs::write(tmp, text.as_bytes()))?;
        Ok(())
    }
}

fn check_number(v: f64, non_negative: bool, ctx: &str) -> Result<(), EvalError> {
    if !v.is_finite() || (non_negative && v < 0.0) {
        let need = if non_negative { "a finite, non-negative number" } else { "a finite number" };
        return Err(EvalError::invalid(ctx, format!("is {v}, expected {need}")));
    }
    Ok(())
}

fn check_unit(v: f64, ctx: &str) -> Result<(), EvalError> {
    if !(0.0..=1.0).contains(&v) {
        return Err(EvalError::invalid(ctx, format!("is {v}, expected a number in [0, 1]")));
    }
    Ok(())
}

/// Image paths must stay inside the results folder so a report can copy them safely.
pub fn check_relative_path(p: &str, ctx: &str) -> Result<(), EvalError> {
    let path = Path::new(p);
    let bad =
        p.is_empty() || path.is_absolute() || p.contains('\\') || path.components().any(|c| !matches!(c, std::path::Component::Normal(_)));
    if bad {
        return Err(EvalError::invalid(
            ctx,
            format!("`{p}` must be a relative path inside the results folder (no `..`, `.` or `/` prefix)"),
        ));
    }
    Ok(())
}

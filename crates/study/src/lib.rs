//! The paper's protocol as a library: for every spp value `n` and seed, the paired PT/CRN
//! streams with `n` spp each and a real PT image with `2n` spp from a [`Source`], every
//! column (the registered estimators, the PT(2n) image, the declared ablation variants)
//! scored against the reference — relMSE mean ± standard error, bias² and variance over seeds,
//! HDR-FLIP mean ± standard error (at the last spp value), time per stage, diagnostics — then
//! `results.json`, `results.csv` and the PNGs of the first seed with false-colour error, signed
//! difference and FLIP maps (relMSE and FLIP averaged over seeds), and the linear values behind them
//! (`<column>.values.exr`, `reference.values.exr`) for the viewer's pixel readout.
//!
//! A source is anything that makes stream sets and PT images: the real renderer (the `cvtrace`
//! package's render session, which also reuses finished files) or [`SyntheticSource`], the
//! analytic soft-shadow scene of `cvtrace_reconstruct::synthetic`, which needs no renderer.
//! What a study asks of its source is planned from what its estimators declare they need
//! ([`Study::check_needs`] runs before the first image is made).
#![forbid(unsafe_code)]
mod columns;
mod diagnostics;
pub mod files;
mod synthetic;

pub use columns::{columns, headline, Column, ColumnKind, PT_2N_COLOUR};
pub use synthetic::SyntheticSource;

use cvtrace_eval::difference::{scale_for_differences, signed_difference, write_difference_png};
use cvtrace_eval::falsecolor::{scale_for_maps, write_false_color_png};
use cvtrace_eval::flip::{write_flip_png, FlipAccumulator, FlipReference};
use cvtrace_eval::pixels::write_values_exr;
use cvtrace_eval::reference_noise::{from_variance_image, too_noisy_warning};
use cvtrace_eval::results::{ConvergencePoint, ReferenceInfo, SceneResult, StageTimes, StudyResults};
use cvtrace_eval::{table, EvalError, Reference, SeedAccumulator};
use cvtrace_reconstruct::{Input, ReconError, Samples};
use cvtrace_streams::preview::write_png;
use cvtrace_streams::{Features, Image, Stream, StreamError, StreamMeta, StreamSet};
use diagnostics::DiagnosticsMean;
use std::path::Path;

/// Seed offset of the PT(2n) images, so that they never share random numbers with a stream.
pub const PT2N_SEED_OFFSET: u64 = 1 << 32;

/// More seeds than this is a typo, not a study: each seed writes two renders.
pub const MAX_SEEDS: u32 = 10_000;
/// Seed of a reference rendered by the study (distinct from every stream seed).
pub const REFERENCE_SEED: u64 = 0x7265_6665_7265_6e63;
/// Samples per pixel of each stream when the study is given none (nor the scene's `spp`).
pub const DEFAULT_SPP: u32 = 96;
/// Reference spp when the study is given none (nor the scene's `reference_spp`).
pub const DEFAULT_REFERENCE_SPP: u32 = 4096;

/// An error of a source, in its own words.
pub type SourceError = Box<dyn std::error::Error + Send + Sync>;

#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error(transparent)]
    Recon(#[from] ReconError),
    #[error(transparent)]
    Eval(#[from] EvalError),
    #[error(transparent)]
    Stream(#[from] StreamError),
    #[error("--spp {spp} --batches {batches}: {source}")]
    Needs { spp: u32, batches: u32, source: ReconError },
    #[error("{0}")]
    Source(SourceError),
    #[error("{0}")]
    Invalid(String),
}

/// An image or stream set a source made, the seconds it took (the render's, also when it was
/// reused from a file), and its name in messages (a file path).
pub struct Rendered<T> {
    pub value: T,
    pub seconds: f64,
    pub name: String,
}

/// Where a study's images come from.
pub trait Source {
    /// The paired streams with `n` spp each in `batches` batches, seed `seed`.
    fn streams(&mut self, n: u32, batches: u32, seed: u64) -> Result<Rendered<StreamSet>, SourceError>;
    /// A plain PT image with `spp` samples per pixel, seed `seed`.
    fn pt(&mut self, spp: u32, seed: u64) -> Result<Rendered<Image>, SourceError>;
}

/// One study of one scene.
pub struct Study<'a> {
    pub columns: &'a [Column],
    /// Samples per stream, ascending; the tables and images are of the last.
    pub spps: Vec<u32>,
    pub seeds: u32,
    /// Seed `i` renders its streams with `first_seed + i`, its PT(2n) image with that plus
    /// [`PT2N_SEED_OFFSET`].
    pub first_seed: u64,
    pub batches: u32,
    pub headline: Vec<(String, String)>,
}

/// What the results say about the scene besides the numbers.
pub struct SceneInfo {
    pub name: String,
    pub reference: ReferenceInfo,
    /// The renders' provenance, as (field, value).
    pub render: Vec<(String, String)>,
}

impl Study<'_> {
    /// Every estimator's requirements, checked on a 1×1 stand-in of the streams the study will
    /// ask for (features, a reference, `batches` batches, each spp value): a study that could
    /// not finish fails before its first render, not after the last.
    pub fn check_needs(&self) -> Result<(), StudyError> {
        let pixel = Image::new(1, 1);
        let stream = || Stream::from_batches(vec![pixel.clone(); self.batches as usize]);
        for &spp in &self.spps {
            let features = Features { albedo: pixel.clone(), normal: pixel.clone(), depth: vec![0.0] };
            let meta = StreamMeta { spp, ..Default::default() };
            let set = StreamSet { width: 1, height: 1, pt: stream(), crn: stream(), features: Some(features), meta };
            let input = Input::new(&set)
                .named("the streams this study renders", "the reference")
                .with_reference(&pixel)
                .with_pt2n(&pixel, "the study's PT(2n) image");
            for c in self.columns {
                if let ColumnKind::Estimator(est) = &c.kind {
                    input.check(est.name(), &est.needs()).map_err(|source| StudyError::Needs { spp, batches: self.batches, source })?;
                }
            }
        }
        Ok(())
    }

    /// Runs the study on `source` against `reference` and writes its results and images into
    /// `out` (which exists).
    pub fn run(&self, source: &mut dyn Source, reference: &Reference, scene: SceneInfo, out: &Path) -> Result<StudyResults, StudyError> {
        let mut convergence = Vec::new();
        let mut main = None;
        let flip_reference = FlipReference::new(&reference.image, reference.label.clone())?;
        for (si, &n) in self.spps.iter().enumerate() {
            let last = si + 1 == self.spps.len();
            let r = self.run_spp(source, reference, n, last.then_some(&flip_reference))?;
            for ((c, acc), t) in self.columns.iter().zip(&r.accs).zip(&r.times) {
                if c.base.is_some() {
                    continue;
                }
                let s = acc.finish()?;
                convergence.push(ConvergencePoint {
                    method: c.key.clone(),
                    spp_total: c.samples.total(n),
                    relmse: s.relmse_mean,
                    relmse_se: s.relmse_se,
                    seconds: Some(t.total()),
                    bias2: s.bias2,
                });
            }
            if last {
                main = Some(r);
            }
        }
        let main = main.ok_or_else(|| StudyError::Invalid("a study needs at least one spp value".into()))?;
        let n = *self.spps.last().expect("main is set, so there is an spp value");

        // Images of the first seed, false-colour maps of the mean relMSE and FLIP over seeds and
        // of the first seed's signed difference, and the linear values behind them for the viewer.
        let maps: Vec<Vec<f32>> = main.accs.iter().map(|a| a.mean_rel_mse_map()).collect();
        let scale = scale_for_maps(&maps.iter().map(|m| m.as_slice()).collect::<Vec<_>>());
        let diffs = main.first_images.iter().map(|img| signed_difference(img, &reference.image)).collect::<Result<Vec<_>, _>>()?;
        let diff_scale = scale_for_differences(&diffs.iter().map(|m| m.as_slice()).collect::<Vec<_>>());
        let mut methods = Vec::new();
        for (i, c) in self.columns.iter().enumerate() {
            let stats = main.accs[i].finish()?;
            let mut m = c.result(&stats, n);
            m.time_seconds = main.times[i];
            m.diagnostics = main.diagnostics[i].finish();
            let image = format!("{}.png", c.key);
            write_png(&out.join(&image), &main.first_images[i], 0.0, true)?;
            m.image = Some(image);
            let map = format!("{}.relmse.png", c.key);
            write_false_color_png(&out.join(&map), &maps[i], reference.width(), reference.height(), &scale, true)?;
            m.error_map = Some(map);
            let diff = format!("{}.diff.png", c.key);
            write_difference_png(&out.join(&diff), &diffs[i], reference.width(), reference.height(), &diff_scale, true)?;
            m.difference_map = Some(diff);
            let flip_map = main.flips.get(i).map(|f| f.mean_map());
            if let (Some(f), Some(map)) = (main.flips.get(i), &flip_map) {
                if let Some(stats) = f.finish() {
                    m.set_flip(&stats);
                }
                let file = format!("{}.flip.png", c.key);
                write_flip_png(&out.join(&file), map, reference.width(), reference.height(), true)?;
                m.flip_map = Some(file);
            }
            let values = format!("{}.values.exr", c.key);
            write_values_exr(&out.join(&values), &main.first_images[i], Some(&maps[i]), flip_map.as_deref(), true)?;
            m.values = Some(values);
            methods.push(m);
        }
        write_png(&out.join("reference.png"), &reference.image, 0.0, true)?;
        write_values_exr(&out.join("reference.values.exr"), &reference.image, None, None, true)?;

        // The reference's own noise, from the PT streams' batch variance scaled to its spp.
        let noise = match (scene.reference.spp, &main.pt_variance) {
            (Some(rspp), Some(var)) if rspp > 0 => {
                let scale = n as f32 / rspp as f32;
                let v = Image { width: var.width, height: var.height, pixels: var.pixels.iter().map(|p| p.map(|x| x * scale)).collect() };
                Some(from_variance_image(reference, &v, "reference noise")?)
            }
            _ => None,
        };
        let mut result = SceneResult {
            name: scene.name,
            width: reference.width(),
            height: reference.height(),
            spp_per_stream: n,
            seeds: self.seeds,
            reference: ReferenceInfo {
                image: Some("reference.png".into()),
                values: Some("reference.values.exr".into()),
                noise,
                ..scene.reference
            },
            methods,
            convergence: if self.spps.len() > 1 { convergence } else { Vec::new() },
            error_map_scale: Some(scale),
            difference_scale: Some(diff_scale),
            flip: Some(flip_reference.settings()),
            warnings: Vec::new(),
            headline: self.headline.clone(),
            render: scene.render,
        };
        let too_noisy = noise.zip(result.best_relmse()).and_then(|(noise, best)| too_noisy_warning(noise.relmse, best));
        // Not logged here: the caller shows the results, warnings included, once.
        result.warnings.extend(reference.unusable_warning().into_iter().chain(too_noisy));
        let results = StudyResults::new(vec![result]);
        results.write_json(&out.join("results.json"), true)?;
        table::write_csv(&results, &out.join("results.csv"), true)?;
        Ok(results)
    }

    /// One spp value over every seed; with `flip` (the spp the tables show), also each column's
    /// HDR-FLIP and its first seed's image.
    fn run_spp<'r>(
        &self,
        source: &mut dyn Source,
        reference: &'r Reference,
        n: u32,
        flip: Option<&'r FlipReference>,
    ) -> Result<SppRun<'r>, StudyError> {
        let cols = self.columns;
        let keep_images = flip.is_some();
        let mut accs: Vec<SeedAccumulator> = cols.iter().map(|c| SeedAccumulator::new(reference, c.key.clone())).collect();
        let mut flips: Vec<FlipAccumulator> = flip.map(|f| cols.iter().map(|_| FlipAccumulator::new(f)).collect()).unwrap_or_default();
        let mut times = vec![StageTimes::default(); cols.len()];
        let mut first_images = Vec::new();
        let mut diagnostics: Vec<DiagnosticsMean> = cols.iter().map(|_| DiagnosticsMean::default()).collect();
        let mut pt_variance: Option<Image> = None;
        let seeds = self.seeds as f64;
        for i in 0..self.seeds as u64 {
            let seed = self.first_seed + i;
            let streams = source.streams(n, self.batches, seed).map_err(StudyError::Source)?;
            let pt2n = source.pt(2 * n, seed + PT2N_SEED_OFFSET).map_err(StudyError::Source)?;
            let set = &streams.value;
            if set.meta.non_finite_samples > 0 {
                tracing::warn!("{}: {} NaN or infinite samples were replaced by zero", streams.name, set.meta.non_finite_samples);
            }
            if !set.pt.mean.same_size(&reference.image) {
                return Err(StudyError::Invalid(format!(
                    "{}: reference is {}x{} but the renders are {}x{}; render the reference at the study's size",
                    reference.label,
                    reference.width(),
                    reference.height(),
                    set.width,
                    set.height
                )));
            }
            accumulate_variance(&mut pt_variance, set, self.seeds);
            let input =
                Input::new(set).named(&streams.name, &reference.label).with_reference(&reference.image).with_pt2n(&pt2n.value, &pt2n.name);
            for (k, c) in cols.iter().enumerate() {
                let mut predicted = None;
                let (img, t) = match &c.kind {
                    ColumnKind::Estimator(est) => {
                        let mut out = est.run(&input)?;
                        diagnostics[k].add(&out.diagnostics);
                        predicted = out.aovs.iter().position(|(n, _)| n == "variance").map(|i| out.aovs.swap_remove(i).1);
                        // An estimator of one stream needs only that stream: half the pair's render
                        // time; one of the PT(2n) image, that render's.
                        let render = match c.samples {
                            Samples::Pt2n => pt2n.seconds,
                            s => s.render_share() * streams.seconds,
                        };
                        (out.image, StageTimes { render, reconstruct: out.diagnostics.seconds })
                    }
                    ColumnKind::Pt2n => (pt2n.value.clone(), StageTimes { render: pt2n.seconds, reconstruct: 0.0 }),
                };
                let label = format!("{} ({})", c.key, streams.name);
                accs[k].add_labelled(&img, &label)?;
                if let Some(f) = flips.get_mut(k) {
                    f.add(&img, &label)?;
                }
                if let Some(v) = &predicted {
                    accs[k].add_predicted_variance(v, &label)?;
                }
                times[k].render += t.render / seeds;
                times[k].reconstruct += t.reconstruct / seeds;
                if keep_images && i == 0 {
                    first_images.push(img);
                }
            }
            tracing::info!("spp {n}, seed {} of {}: done", i + 1, self.seeds);
        }
        Ok(SppRun { accs, flips, times, first_images, diagnostics, pt_variance })
    }
}

struct SppRun<'r> {
    accs: Vec<SeedAccumulator<'r>>,
    /// Per column, HDR-FLIP over the seeds (empty for the convergence points).
    flips: Vec<FlipAccumulator<'r>>,
    times: Vec<StageTimes>,
    first_images: Vec<Image>,
    diagnostics: Vec<DiagnosticsMean>,
    /// Per-pixel variance of the PT stream mean (from its batches), averaged over seeds.
    pt_variance: Option<Image>,
}

/// Adds this seed's per-pixel variance of the PT mean (batch variance / B) / seeds.
fn accumulate_variance(acc: &mut Option<Image>, set: &StreamSet, seeds: u32) {
    let b = set.pt.batches.len();
    if b < 2 {
        return;
    }
    let acc = acc.get_or_insert_with(|| Image::new(set.width, set.height));
    let norm = 1.0 / ((b - 1) as f64 * b as f64 * seeds as f64);
    for (i, out) in acc.pixels.iter_mut().enumerate() {
        let m = set.pt.mean.pixels[i];
        for c in 0..3 {
            let ss: f64 = set.pt.batches.iter().map(|im| (im.pixels[i][c] as f64 - m[c] as f64).powi(2)).sum();
            out[c] += (ss * norm) as f32;
        }
    }
}

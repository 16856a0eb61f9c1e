//! `cvtrace study`: the paper's protocol on one scene, in one command.
//!
//! For every requested spp `n` and seed, it renders the paired PT/CRN streams (`n` spp each)
//! and a real PT render with `2n` spp, reconstructs with every estimator, and scores each
//! against the reference: relMSE mean ± standard error, bias² and variance over seeds, time
//! per stage. A missing reference is rendered first. The folder is resumable: every render is
//! a file written atomically, so an interrupted study keeps its finished seeds and only
//! re-runs the (cheap) reconstructions. The protocol is `cvtrace_study`'s; the renders come
//! from `cvtrace::study_source`; this file checks the flags and prints.
use crate::cli::estimator_args::EstimatorArgs;
use crate::cli::registry;
use crate::cli::render::{open_session, progress_style_of, TerminalProgress, ViewArgs};
use anyhow::{bail, Context, Result};
use cvtrace::session::{Job, Progress, ReferenceJob};
use cvtrace::study_source::RenderSource;
use cvtrace_eval::results::ReferenceInfo;
use cvtrace_eval::{table, Reference};
use cvtrace_render::settings::MAX_SPP;
use cvtrace_streams::exr_io::{take_rgb, AttrValue, ExrChannels};
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::Provenance;
use cvtrace_study::files::Cell;
use cvtrace_study::{SceneInfo, Study, PT2N_SEED_OFFSET};
use indicatif::{ProgressBar, ProgressDrawTarget};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// More seeds than this is a typo, not a study: each seed writes two renders.
const MAX_SEEDS: u32 = 10_000;
/// Seed of a reference rendered by the study (distinct from every stream seed).
const REFERENCE_SEED: u64 = 0x7265_6665_7265_6e63;
/// Samples per pixel of each stream when neither --spp nor -D spp gives them.
const DEFAULT_SPP: u32 = 96;
/// Reference spp when neither --reference-spp nor the scene's sidecar gives one.
const DEFAULT_REFERENCE_SPP: u32 = 4096;

#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// glTF 2.0 scene.
    pub scene: PathBuf,
    /// Samples per pixel of each stream; a list (e.g. 8,16,32) also gives convergence plots.
    /// Tables and images are for the largest value [default: -D spp, else 96].
    #[arg(long, value_delimiter = ',', value_parser = crate::cli::render::spp_parser(), allow_hyphen_values = true)]
    pub spp: Vec<u32>,
    /// Independent seeds per spp value.
    #[arg(long, default_value_t = 8)]
    pub seeds: u32,
    /// First seed; seed i uses `seed + i` for its streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Batches per stream (must divide every spp value) [default: the most of 16, 8, 4, 2, 1
    /// that divides every spp value; iduw needs a multiple of 4].
    #[arg(long)]
    pub batches: Option<u32>,
    /// Reference EXR; rendered (PT, --reference-spp) when the file does not exist.
    #[arg(long)]
    pub reference: PathBuf,
    /// Samples per pixel of a reference the study renders itself [default: -D reference_spp,
    /// else the scene sidecar's reference_spp, else 4096].
    #[arg(long)]
    pub reference_spp: Option<u32>,
    /// Study folder (created; reused to resume).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also run the supplement's ablations of `ours` (penalty, oracle errors, selection).
    #[arg(long)]
    pub ablations: bool,
    /// Name of the scene in tables and the viewer (default: the scene's folder name).
    #[arg(long)]
    pub name: Option<String>,
    /// The ratios of relMSE the tables and the viewer headline, as NUMERATOR/DENOMINATOR
    /// method keys (pt2n is the study's PT render with 2n spp).
    #[arg(long, value_delimiter = ',', default_value = "ours/iduw,ours/cv,ours/pt2n")]
    pub headline: Vec<String>,
    /// Render only this cell of the study into its folder, KIND:SPP:SEED_INDEX with KIND streams
    /// or pt2n (e.g. streams:32:0): one task of `cvtrace farm study`. A later study with the same
    /// arguments reuses the file.
    #[arg(long, value_name = "KIND:SPP:SEED_INDEX")]
    pub cell: Option<Cell>,
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub options: EstimatorArgs,
}

pub fn run(args: StudyArgs) -> Result<()> {
    run_or_check(&args, false)
}

/// Every check `cvtrace study` makes of `args` before it writes anything (the scene loads, the
/// estimators' needs, a given reference matches), without writing anything: a farm's tasks then
/// fail only for reasons of their node.
pub fn check(args: &StudyArgs) -> Result<()> {
    run_or_check(args, true)
}

fn run_or_check(args: &StudyArgs, check_only: bool) -> Result<()> {
    let mut spps = args.spp.clone();
    if spps.is_empty() {
        spps.push(match args.view.define.iter().rev().find(|d| d.canonical_key() == Some("spp")) {
            Some(d) => d
                .value
                .parse()
                .ok()
                .filter(|n| (1..=MAX_SPP).contains(n))
                .with_context(|| format!("-D {d}: the study's samples per pixel must be a whole number between 1 and {MAX_SPP}"))?,
            None => DEFAULT_SPP,
        });
    }
    spps.sort_unstable();
    spps.dedup();
    if spps.is_empty() || spps[0] == 0 {
        bail!("--spp needs positive values");
    }
    if args.seeds == 0 || args.seeds > MAX_SEEDS {
        bail!("--seeds {}: must be between 1 and {MAX_SEEDS}", args.seeds);
    }
    if let Some(cell) = args.cell {
        if !spps.contains(&cell.spp) || cell.index >= args.seeds {
            bail!("--cell {cell}: not a cell of this study (--spp {:?}, seed indices 0..{})", spps, args.seeds);
        }
    }
    if let Some(b) = args.batches {
        if b == 0 {
            bail!("--batches must be at least 1");
        }
        if let Some(bad) = spps.iter().find(|&&n| n % b != 0) {
            bail!("--batches {b} does not divide --spp {bad}; every spp value must be a multiple of the batch count");
        }
    }
    // Each spp value n also takes a PT render of 2n spp.
    if let Some(&n) = spps.iter().find(|&&n| n > MAX_SPP / 2) {
        bail!("--spp {n}: the study's PT(2n) render would take {} spp, more than {MAX_SPP}", 2 * n as u64);
    }
    // Seeds seed .. seed + seeds − 1 for the streams, the same plus 2^32 for the PT(2n) renders.
    if args.seed.checked_add(args.seeds as u64 - 1).and_then(|s| s.checked_add(PT2N_SEED_OFFSET)).is_none() {
        bail!(
            "--seed {} --seeds {}: the PT(2n) renders use seeds up to seed + seeds − 1 + 2^32, which does not fit in 64 bits; give a smaller --seed",
            args.seed,
            args.seeds
        );
    }
    if !args.scene.is_file() {
        bail!("{}: scene file not found", args.scene.display());
    }
    // The results need a scene name: known now, not after the last render.
    if study_name(args).trim().is_empty() {
        match &args.name {
            Some(name) => bail!("--name {name:?}: the scene's name in tables and the viewer must not be empty"),
            None => bail!("{}: no scene name can be made from this file name; give one with --name", args.scene.display()),
        }
    }
    if crate::cli::same_output(&args.reference, &args.output) {
        bail!("{}: given as both --reference and -o; the reference is a file, the study a folder", args.output.display());
    }
    // One session renders everything (the BVH is built once, at the first render). Loading the
    // scene tells what every render of this study records about itself (so a finished one is
    // only reused if it matches), and a scene that does not load fails here, before the study
    // folder is made.
    let session = open_session(&args.scene, &args.view.session_options()?)?;
    let overall = StudyProgress::default();
    let shares = overall.clone();
    let probe = RenderSource::new(&session, args.output.clone(), args.view.view(), args.seed, Box::new(move || shares.share()));
    let plan = session.plan(&probe.stream_job(spps[0], args.batches.unwrap_or(1), args.seed, &args.output))?;
    // Each seed of n spp renders 2 streams of n and a PT image of 2n samples per pixel.
    let pixels = plan.settings.width as u64 * plan.settings.height as u64;
    overall.bar.set_length(pixels * args.seeds as u64 * spps.iter().map(|&n| 4 * n as u64).sum::<u64>());
    // Counts aside: they differ between the study's renders.
    let planned = plan.provenance.without_counts();
    let overrides = args.options.overrides()?;
    registry().check(&overrides)?;
    let columns = cvtrace_study::columns(registry(), &overrides, args.ablations)?;
    let study = Study {
        columns: &columns,
        spps: spps.clone(),
        seeds: args.seeds,
        first_seed: args.seed,
        batches: args.batches.unwrap_or_else(|| default_batches(&spps)),
        headline: cvtrace_study::headline(&args.headline, &columns)?,
    };
    if let Err(e) = study.check_needs() {
        if args.batches.is_none() {
            bail!(
                "{e}; --batches was not given, and {} is the most of 16, 8, 4, 2, 1 that divides every --spp value: give --spp values \
                 that are multiples of 4 (iduw forms 4 sub-buffers)",
                study.batches
            );
        }
        return Err(e.into());
    }
    // A given reference of another scene, view or path length is the ground truth of another
    // image. Seed, spp and rr depth may differ (the expectation does not), and so may the
    // traversal. A given reference is read and checked, and a missing one's settings, before
    // the study folder is made; one the study renders always matches.
    let existing = if args.reference.exists() {
        crate::cli::check_input_file(&args.reference)?;
        let mut mismatch = planned.differences(&Provenance::read_header(&args.reference)?);
        mismatch.retain(|d| d.field.changes_the_image());
        if !mismatch.is_empty() {
            bail!("{}: not a reference of this study's image ({})", args.reference.display(), describe_all(&mismatch, "in the file"));
        }
        Some(read_reference(args)?)
    } else {
        None
    };
    let reference_spp = match (&existing, args.reference_spp) {
        (Some(_), _) => 0,
        (None, Some(n)) => {
            if n == 0 || n > MAX_SPP {
                bail!("--reference-spp {n}: must be between 1 and {MAX_SPP}");
            }
            n
        }
        (None, None) => session.scene().render_defaults().reference_spp.unwrap_or(DEFAULT_REFERENCE_SPP),
    };
    if existing.is_none() {
        cvtrace_streams::atomic::check_extension(&args.reference, "exr")?;
    }
    if args.output.exists() && !args.output.is_dir() {
        bail!("{}: is a file; the study needs a folder (-o)", args.output.display());
    }
    if check_only {
        return Ok(());
    }
    // The folders this run makes: if it fails before anything is written in them, they go again.
    let made: Vec<PathBuf> =
        args.output.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).map(Path::to_path_buf).collect();
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create the study folder", args.output.display()))?;
    if let Some(cell) = args.cell {
        // No claim of the folder: the farm renders its cells side by side, each into its own
        // file (written atomically), and the study that follows reuses them.
        let mut source = probe;
        let path = source.render_cell(cell, study.batches).map_err(|e| anyhow::anyhow!("{e}"))?;
        crate::cli::say!("cell {cell}: {}", path.display());
        return Ok(());
    }
    // Two studies in one folder would render the same files twice and race over them: the
    // claim comes before anything else is made in it, and a study that does not get it
    // removes only what it made itself.
    let claim = cvtrace_streams::output_lock::OutputLock::acquire(&args.output.join(".cvtrace-study.lock"), &args.output);
    let (result, made_spp_dirs) = match claim {
        Ok(_claim) => {
            let mut source = probe;
            let result = study_in_folder(args, &planned, &study, &mut source, &overall, existing, reference_spp);
            (result, source.made_folders().to_vec())
        }
        Err(e) => (Err(e.into()), Vec::new()),
    };
    if result.is_err() {
        // Only empty ones: a finished render or checkpoint stays for the next run.
        for dir in made_spp_dirs.into_iter().chain(made) {
            let _ = std::fs::remove_dir(dir);
        }
    }
    result
}

/// The batch count when `--batches` is not given: the most of 16, 8, 4, 2, 1 that divides every
/// spp value. Those that are multiples of 4 come first, so iduw (4 sub-buffers) runs whenever
/// any count can serve it.
fn default_batches(spps: &[u32]) -> u32 {
    let b = [16, 8, 4, 2, 1].into_iter().find(|b| spps.iter().all(|n| n % b == 0)).unwrap_or(1);
    let list = spps.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
    tracing::info!("--batches not given: {b} batches, the most of 16, 8, 4, 2, 1 that divide --spp {list}");
    b
}

/// One progress line for all the renders of a study (streams and PT(2n) images, in pixel
/// samples), drawn on stderr when it is a terminal; a render found finished counts as done.
#[derive(Clone)]
struct StudyProgress {
    bar: ProgressBar,
}

/// The overall line: narrower than a render's, since it starts with "study".
const STUDY_PROGRESS_TEMPLATE: &str =
    "study {elapsed_precise} [{bar:16.cyan/blue}] {percent:>3}% {msamples} M, {rate} M samples/s, ETA {eta}";

impl Default for StudyProgress {
    fn default() -> Self {
        let bar = ProgressBar::hidden();
        bar.set_style(progress_style_of(STUDY_PROGRESS_TEMPLATE));
        StudyProgress { bar }
    }
}

impl StudyProgress {
    /// What one render reports to.
    fn share(&self) -> Box<dyn Progress> {
        Box::new(self.clone())
    }

    fn show(&self) {
        self.bar.set_draw_target(ProgressDrawTarget::stderr());
        self.bar.reset_eta();
    }
}

impl Progress for StudyProgress {
    fn start(&self, _total: u64, done: u64) {
        // Samples found done (a resumed or reused render) took no time now: they must not
        // enter the rate.
        if done > 0 {
            self.bar.inc(done);
            self.bar.reset_eta();
        }
    }

    fn advance(&self, samples: u64) {
        self.bar.inc(samples);
    }

    fn suspend(&self, f: &mut dyn FnMut()) {
        self.bar.suspend(f)
    }
}

/// The reference at `--reference`: its image, its sample count, and a check that its seed is
/// none of the study's.
fn read_reference(args: &StudyArgs) -> Result<(Reference, Option<u32>)> {
    let mut ref_file = ExrChannels::read(&args.reference)?;
    let reference = Reference::new(take_rgb(&mut ref_file, &args.reference, "")?, args.reference.display().to_string())?;
    let reference_spp = match ref_file.attr("cvtrace.spp") {
        Some(AttrValue::Int(v)) if *v > 0 => Some(*v as u32),
        _ => None,
    };
    if let Some(seed) = ref_file.attr("cvtrace.seed").and_then(|v| v.as_text().parse::<u64>().ok()) {
        let uses = |s: u64| (args.seed..args.seed + args.seeds as u64).any(|x| x == s || x + PT2N_SEED_OFFSET == s);
        if uses(seed) {
            bail!(
                "{}: rendered with seed {seed}, which this study also uses: its noise would correlate with the PT renders; pick another --seed",
                args.reference.display()
            );
        }
    }
    Ok((reference, reference_spp))
}

/// The study in its folder, which exists and is this run's: the reference (`existing`, or
/// rendered with `reference_spp`), then every spp value and seed, then the tables and images.
fn study_in_folder(
    args: &StudyArgs,
    planned: &Provenance,
    study: &Study,
    source: &mut RenderSource,
    overall: &StudyProgress,
    existing: Option<(Reference, Option<u32>)>,
    reference_spp: u32,
) -> Result<()> {
    // The reference: reuse the file, or render it (resumable through render's checkpoint).
    let session = source.session;
    let (reference, reference_spp) = match existing {
        Some(r) => r,
        None => {
            tracing::info!("{} does not exist: rendering a {reference_spp} spp reference first", args.reference.display());
            let job = ReferenceJob::replacing(args.reference.clone(), args.view.view(), reference_spp, REFERENCE_SEED);
            session.render(&Job::Reference(job), &TerminalProgress::default())?;
            read_reference(args)?
        }
    };
    let scene = SceneInfo {
        name: study_name(args),
        reference: ReferenceInfo {
            path: ReferenceInfo::path_of(&args.reference),
            spp: reference_spp,
            image: None,
            noise: None,
            values: None,
        },
        // The seed differs between the renders; it is in each file.
        render: planned.fields().into_iter().filter(|(k, _)| *k != "seed").map(|(k, v)| (k.to_string(), v)).collect(),
    };
    overall.show();
    let start = Instant::now();
    let results = study.run(source, &reference, scene, &args.output);
    overall.bar.finish_and_clear();
    let results = results?;
    crate::cli::say!("{}", table::terminal_report(&results).trim_end_matches('\n'));
    crate::cli::say!(
        "study written to {} in {} (make a viewer with: cvtrace report {} -o report/)",
        args.output.display(),
        wall_time(start.elapsed().as_secs_f64()),
        args.output.display()
    );
    Ok(())
}

/// Wall-clock time as "42.0 s", "3 min 05 s" or "2 h 07 min".
fn wall_time(secs: f64) -> String {
    let whole = secs.round() as u64;
    if secs < 60.0 {
        format!("{secs:.1} s")
    } else if whole < 3600 {
        format!("{} min {:02} s", whole / 60, whole % 60)
    } else {
        format!("{} h {:02} min", whole / 3600, whole % 3600 / 60)
    }
}

/// The scene's name in the results: `--name`, else from the scene's file.
fn study_name(args: &StudyArgs) -> String {
    args.name.clone().unwrap_or_else(|| scene_name(&args.scene))
}

fn scene_name(scene: &Path) -> String {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    if stem == "scene" {
        if let Some(dir) = scene.parent().and_then(|p| p.file_name()) {
            return dir.to_string_lossy().into_owned();
        }
    }
    stem
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_progress_counts_every_render_and_fits_80_columns() {
        let overall = StudyProgress::default();
        overall.bar.set_length(100);
        // A render from scratch, one resumed at 10 of 30, one found finished.
        let a = overall.share();
        a.start(40, 0);
        a.advance(25);
        a.advance(15);
        a.finish();
        let b = overall.share();
        b.start(30, 10);
        b.advance(20);
        let c = overall.share();
        c.start(30, 30);
        c.finish();
        assert_eq!(overall.bar.position(), overall.bar.length().unwrap());
        let widest = crate::cli::render::widest_progress_line(STUDY_PROGRESS_TEMPLATE);
        assert!(!widest.contains('{') && widest.starts_with("study "), "{widest}");
        assert!(widest.chars().count() <= crate::cli::render::PROGRESS_COLUMNS, "{} columns: {widest}", widest.chars().count());
    }

    #[test]
    fn wall_times_read_at_a_glance() {
        assert_eq!(wall_time(4.04), "4.0 s");
        assert_eq!(wall_time(185.2), "3 min 05 s");
        assert_eq!(wall_time(7620.0), "2 h 07 min");
    }
}

//! `cvtrace study`: the paper's protocol on one scene, in one command.
//!
//! For every requested spp `n` and seed, it renders the paired PT/CRN streams (`n` spp each)
//! and a real PT render with `2n` spp, reconstructs with every estimator, and scores each
//! against the reference: relMSE mean ± standard error, bias² and variance over seeds, time
//! per stage. A missing reference is rendered first. The folder is resumable: every render is
//! a file written atomically, so an interrupted study keeps its finished seeds and only
//! re-runs the (cheap) reconstructions.
use crate::cli::reconstruct::{read_input, EstimatorArgs};
use crate::cli::render::{open_session, TerminalProgress, ViewArgs};
use anyhow::{bail, Context, Result};
use cvtrace::session::{Job, ReferenceJob, RenderSession, StreamJob};
use cvtrace_eval::falsecolor::{scale_for_maps, write_false_color_png};
use cvtrace_eval::reference_noise::{from_variance_image, too_noisy_warning};
use cvtrace_eval::results::{keys, ConvergencePoint, MethodResult, ReferenceInfo, SceneResult, StageTimes, StudyResults};
use cvtrace_eval::{table, Reference, SeedAccumulator};
use cvtrace_render::render::MAX_SPP;
use cvtrace_render::Sidecar;
use cvtrace_reconstruct::{build, ErrorEstimate, Estimator, Input, Method, Options, Penalty, Selection};
use cvtrace_streams::exr_io::{read_rgb, take_rgb, AttrValue, ExrChannels};
use cvtrace_streams::preview::write_png;
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::{Features, Image, Provenance, Stream, StreamMeta, StreamSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// More seeds than this is a typo, not a study: each seed writes two renders.
const MAX_SEEDS: u32 = 10_000;
/// Seed offset of the PT(2n) renders, so they never share random numbers with a stream.
const PT2N_SEED_OFFSET: u64 = 1 << 32;
/// Seed of a reference rendered by the study (distinct from every stream seed).
const REFERENCE_SEED: u64 = 0x7265_6665_7265_6e63;
/// Reference spp when neither --reference-spp nor the scene's sidecar gives one.
const DEFAULT_REFERENCE_SPP: u32 = 4096;

#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// glTF 2.0 scene.
    pub scene: PathBuf,
    /// Samples per pixel of each stream; a list (e.g. 8,16,32) also gives convergence plots.
    /// Tables and images are for the largest value.
    #[arg(long, value_delimiter = ',', default_value = "96")]
    pub spp: Vec<u32>,
    /// Independent seeds per spp value.
    #[arg(long, default_value_t = 8)]
    pub seeds: u32,
    /// First seed; seed i uses `seed + i` for its streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Batches per stream (must divide every spp value).
    #[arg(long, default_value_t = 16)]
    pub batches: u32,
    /// Reference EXR; rendered (PT, --reference-spp) when the file does not exist.
    #[arg(long)]
    pub reference: PathBuf,
    /// Samples per pixel of a reference the study renders itself [default: the scene sidecar's
    /// reference_spp, else 4096].
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
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub options: EstimatorArgs,
}

/// One column of the study: a key, a label, how to make the image, and whether it is an ablation.
struct Entry {
    key: String,
    label: String,
    source: Source,
    ablation: bool,
}

enum Source {
    /// An estimator on the stream set.
    Estimator(Box<dyn Estimator>),
    /// The real PT render with 2n spp.
    Pt2n,
}

/// Every estimator's requirements, checked on a 1×1 stand-in of the streams the study will
/// render (features, a reference, `batches` batches, each spp value): a study that could not
/// finish fails before its first render, not after the last.
fn check_needs_before_rendering(list: &[Entry], spps: &[u32], batches: u32) -> Result<()> {
    let pixel = Image::new(1, 1);
    let stream = || Stream::from_batches(vec![pixel.clone(); batches as usize]);
    for &spp in spps {
        let features = Features { albedo: pixel.clone(), normal: pixel.clone(), depth: vec![0.0] };
        let meta = StreamMeta { spp, ..Default::default() };
        let set = StreamSet { width: 1, height: 1, pt: stream(), crn: stream(), features: Some(features), meta };
        let input = Input::new(&set).named("the streams this study renders", "the reference").with_reference(&pixel);
        for e in list {
            if let Source::Estimator(est) = &e.source {
                input.check(est.name(), &est.needs()).with_context(|| format!("--spp {spp} --batches {batches}"))?;
            }
        }
    }
    Ok(())
}

/// An ablation of `ours`: result key, label, and how it changes the options.
type Ablation = (&'static str, &'static str, fn(&mut Options));

fn entries(options: &Options, ablations: bool) -> Result<Vec<Entry>> {
    let mut list = Vec::new();
    let labels = [
        (Method::Pt, "PT (n)"),
        (Method::Crn, "CRN (n)"),
        (Method::Average, "Average"),
        (Method::Iduw, "IDUW"),
        (Method::Cv, "CV (baseline)"),
        (Method::Ours, "Ours"),
    ];
    for (m, label) in labels {
        list.push(Entry { key: m.name().into(), label: label.into(), source: Source::Estimator(build(m, options)?), ablation: false });
    }
    list.push(Entry { key: keys::PT_2N.into(), label: "PT (2n)".into(), source: Source::Pt2n, ablation: false });
    if ablations {
        let variants: [Ablation; 6] = [
            ("ours-no-penalty", "Ours, no penalty (CBF errors)", |o| o.ours.penalty = Penalty::None),
            ("ours-oracle", "Ours, oracle errors", |o| o.ours.errors = ErrorEstimate::Oracle),
            ("ours-oracle-no-penalty", "Ours, oracle errors, no penalty", |o| {
                o.ours.errors = ErrorEstimate::Oracle;
                o.ours.penalty = Penalty::None;
            }),
            ("ours-window", "Ours, 5×5 window selection", |o| {
                o.ours.select = Selection::Window;
                o.ours.search_window = 5;
            }),
            ("ours-random", "Ours, random selection", |o| o.ours.select = Selection::Random),
            ("ours-gbuffer", "Ours, G-buffer selection", |o| o.ours.select = Selection::Gbuffer),
        ];
        for (key, label, edit) in variants {
            let mut o = options.clone();
            edit(&mut o);
            list.push(Entry { key: key.into(), label: label.into(), source: Source::Estimator(build(Method::Ours, &o)?), ablation: true });
        }
    }
    Ok(list)
}

pub fn run(args: StudyArgs) -> Result<()> {
    let mut spps = args.spp.clone();
    spps.sort_unstable();
    spps.dedup();
    if spps.is_empty() || spps[0] == 0 {
        bail!("--spp needs positive values");
    }
    if args.seeds == 0 || args.seeds > MAX_SEEDS {
        bail!("--seeds {}: must be between 1 and {MAX_SEEDS}", args.seeds);
    }
    if args.batches == 0 {
        bail!("--batches must be at least 1");
    }
    if let Some(bad) = spps.iter().find(|&&n| n % args.batches != 0) {
        bail!("--batches {} does not divide --spp {bad}; every spp value must be a multiple of the batch count", args.batches);
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
    if study_name(&args).trim().is_empty() {
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
    // Counts aside: they differ between the study's renders.
    let planned = session.plan(&stream_job(&args, spps[0], args.seed, &args.output))?.provenance.without_counts();
    let options = args.options.to_options();
    let list = entries(&options, args.ablations)?;
    check_needs_before_rendering(&list, &spps, args.batches)?;
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
        Some(read_reference(&args)?)
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
        (None, None) => Sidecar::discover(&args.scene)?.and_then(|s| s.render.reference_spp).unwrap_or(DEFAULT_REFERENCE_SPP),
    };
    if existing.is_none() {
        cvtrace_streams::atomic::check_extension(&args.reference, "exr")?;
    }
    if args.output.exists() && !args.output.is_dir() {
        bail!("{}: is a file; the study needs a folder (-o)", args.output.display());
    }
    // The folders this run makes: if it fails before anything is written in them, they go again.
    let made: Vec<PathBuf> = args.output.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).map(Path::to_path_buf).collect();
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create the study folder", args.output.display()))?;
    let result = study_in_folder(&args, &session, &list, &spps, existing, reference_spp);
    if result.is_err() {
        // Only empty ones: a finished render or checkpoint stays for the next run.
        for dir in spps.iter().map(|&n| spp_dir(&args.output, n)).chain(made) {
            let _ = std::fs::remove_dir(dir);
        }
    }
    result
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

/// The study in its folder, which exists: the reference (`existing`, or rendered with
/// `reference_spp`), then every spp value and seed, then the tables and images.
fn study_in_folder(
    args: &StudyArgs,
    session: &RenderSession,
    list: &[Entry],
    spps: &[u32],
    existing: Option<(Reference, Option<u32>)>,
    reference_spp: u32,
) -> Result<()> {
    // Two studies in one folder would render the same files twice and race over them.
    let _claim = cvtrace_streams::output_lock::OutputLock::acquire(&args.output.join(".cvtrace-study.lock"), &args.output)?;

    // The reference: reuse the file, or render it (resumable through render's checkpoint).
    let (reference, reference_spp) = match existing {
        Some(r) => r,
        None => {
            tracing::info!("{} does not exist: rendering a {reference_spp} spp reference first", args.reference.display());
            let job = ReferenceJob::replacing(args.reference.clone(), args.view.view(), reference_spp, REFERENCE_SEED);
            session.render(&Job::Reference(job), &TerminalProgress::default())?;
            read_reference(args)?
        }
    };

    let mut convergence = Vec::new();
    let mut main = None;
    for (si, &n) in spps.iter().enumerate() {
        let last = si + 1 == spps.len();
        let r = run_spp(args, session, list, &reference, n, last)?;
        for (e, acc) in list.iter().zip(&r.accs) {
            if e.ablation {
                continue;
            }
            let s = acc.finish()?;
            convergence.push(ConvergencePoint { method: e.key.clone(), spp_total: spp_total(&e.key, n), relmse: s.relmse_mean, relmse_se: s.relmse_se });
        }
        if last {
            main = Some(r);
        }
    }
    let main = main.expect("at least one spp value");
    let n = *spps.last().unwrap();

    // Images of the first seed and false-colour maps of the mean relMSE over seeds.
    let maps: Vec<Vec<f32>> = main.accs.iter().map(|a| a.mean_rel_mse_map()).collect();
    let scale = scale_for_maps(&maps.iter().map(|m| m.as_slice()).collect::<Vec<_>>());
    let mut methods = Vec::new();
    for (i, e) in list.iter().enumerate() {
        let stats = main.accs[i].finish()?;
        let mut m = MethodResult::from_stats(&e.key, &e.label, spp_total(&e.key, n), &stats);
        m.time_seconds = main.times[i];
        m.ablation = e.ablation;
        let image = format!("{}.png", e.key);
        write_png(&args.output.join(&image), &main.first_images[i], 0.0, true)?;
        m.image = Some(image);
        let map = format!("{}.relmse.png", e.key);
        write_false_color_png(&args.output.join(&map), &maps[i], reference.width(), reference.height(), &scale, true)?;
        m.error_map = Some(map);
        methods.push(m);
    }
    write_png(&args.output.join("reference.png"), &reference.image, 0.0, true)?;

    // The reference's own noise, from the PT streams' batch variance scaled to its spp.
    let noise = match (reference_spp, &main.pt_variance) {
        (Some(rspp), Some(var)) if rspp > 0 => {
            let scale = n as f32 / rspp as f32;
            let v = Image { width: var.width, height: var.height, pixels: var.pixels.iter().map(|p| p.map(|x| x * scale)).collect() };
            Some(from_variance_image(&reference, &v, "reference noise")?)
        }
        _ => None,
    };
    let name = study_name(args);
    let mut scene = SceneResult {
        name,
        width: reference.width(),
        height: reference.height(),
        spp_per_stream: n,
        seeds: args.seeds,
        reference: ReferenceInfo {
            path: ReferenceInfo::path_of(&args.reference),
            spp: reference_spp,
            image: Some("reference.png".into()),
            noise,
        },
        methods,
        convergence: if spps.len() > 1 { convergence } else { Vec::new() },
        error_map_scale: Some(scale),
        warnings: Vec::new(),
    };
    let too_noisy = noise.zip(scene.best_relmse()).and_then(|(noise, best)| too_noisy_warning(noise.relmse, best));
    for w in reference.unusable_warning().into_iter().chain(too_noisy) {
        tracing::warn!("{w}");
        scene.warnings.push(w);
    }
    let results = StudyResults::new(vec![scene]);
    results.write_json(&args.output.join("results.json"), true)?;
    table::write_csv(&results, &args.output.join("results.csv"), true)?;
    print!("{}", table::terminal_report(&results));
    println!("study written to {} (make a viewer with: cvtrace report {} -o report/)", args.output.display(), args.output.display());
    Ok(())
}

/// The folder of the renders with `n` spp per stream.
fn spp_dir(study: &Path, n: u32) -> PathBuf {
    study.join(format!("spp{n:05}"))
}

/// PT and CRN alone use `n` samples; everything else uses `2n`.
fn spp_total(key: &str, n: u32) -> u32 {
    if key == keys::PT || key == keys::CRN {
        n
    } else {
        2 * n
    }
}

struct SppRun<'r> {
    accs: Vec<SeedAccumulator<'r>>,
    times: Vec<StageTimes>,
    first_images: Vec<Image>,
    /// Per-pixel variance of the PT stream mean (from its batches), averaged over seeds.
    pt_variance: Option<Image>,
}

fn run_spp<'r>(
    args: &StudyArgs,
    session: &RenderSession,
    list: &[Entry],
    reference: &'r Reference,
    n: u32,
    keep_images: bool,
) -> Result<SppRun<'r>> {
    let dir = spp_dir(&args.output, n);
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mut accs: Vec<SeedAccumulator> = list.iter().map(|e| SeedAccumulator::new(reference, e.key.clone())).collect();
    let mut times = vec![StageTimes::default(); list.len()];
    let mut first_images = Vec::new();
    let mut pt_variance: Option<Image> = None;
    let seeds = args.seeds as f64;
    for i in 0..args.seeds as u64 {
        let seed = args.seed + i;
        let streams_path = dir.join(format!("seed-{i:03}.streams.exr"));
        let pt2n_path = dir.join(format!("seed-{i:03}.pt2n.exr"));
        let t_streams = ensure_rendered(session, stream_job(args, n, seed, &streams_path))?;
        let pt2n = ReferenceJob::replacing(pt2n_path.clone(), args.view.view(), 2 * n, seed + PT2N_SEED_OFFSET);
        let t_pt2n = ensure_rendered(session, Job::Reference(pt2n))?;
        let set = read_input(&streams_path)?;
        if set.meta.non_finite_samples > 0 {
            tracing::warn!("{}: {} NaN or infinite samples were replaced by zero", streams_path.display(), set.meta.non_finite_samples);
        }
        if !set.pt.mean.same_size(&reference.image) {
            bail!(
                "{}: reference is {}x{} but the renders are {}x{}; render the reference at the study's size",
                reference.label, reference.width(), reference.height(), set.width, set.height
            );
        }
        accumulate_variance(&mut pt_variance, &set, args.seeds);
        let pt2n = read_rgb(&pt2n_path)?;
        let streams_name = streams_path.display().to_string();
        let input = Input::new(&set).named(&streams_name, &reference.label).with_reference(&reference.image);
        for (k, e) in list.iter().enumerate() {
            let (img, t) = match &e.source {
                Source::Estimator(est) => {
                    let out = est.reconstruct(&input)?;
                    // PT and CRN alone need only their own stream: half the pair's render time.
                    let render = if e.key == keys::PT || e.key == keys::CRN { t_streams / 2.0 } else { t_streams };
                    (out.image, StageTimes { render, reconstruct: out.diagnostics.seconds })
                }
                Source::Pt2n => (pt2n.clone(), StageTimes { render: t_pt2n, reconstruct: 0.0 }),
            };
            accs[k].add_labelled(&img, &format!("{} ({streams_name})", e.key))?;
            times[k].render += t.render / seeds;
            times[k].reconstruct += t.reconstruct / seeds;
            if keep_images && i == 0 {
                first_images.push(img);
            }
        }
        tracing::info!("spp {n}, seed {} of {}: done", i + 1, args.seeds);
    }
    Ok(SppRun { accs, times, first_images, pt_variance })
}

/// Renders `job` unless its output is already there, finished (with its timing file) and the
/// same render; returns the render's seconds (recorded in a sidecar so that resumed studies
/// still report real times). A finished file rendered with other settings is an error, not
/// silently reused.
fn ensure_rendered(session: &RenderSession, job: Job) -> Result<f64> {
    let path = job.output().to_path_buf();
    let timing = path.with_extension("seconds");
    if path.exists() {
        if let Some(t) = std::fs::read_to_string(&timing).ok().and_then(|s| s.trim().parse::<f64>().ok()) {
            let planned = session.plan(&job)?.provenance;
            let differences = planned.differences(&Provenance::read_header(&path)?);
            if !differences.is_empty() {
                bail!(
                    "{}: this finished render differs from what the study asks for ({}); use another -o or delete the folder's renders",
                    path.display(),
                    describe_all(&differences, "in the file")
                );
            }
            tracing::info!("reusing {}", path.display());
            return Ok(t);
        }
    }
    let t = Instant::now();
    session.render(&job, &TerminalProgress::default())?;
    let secs = t.elapsed().as_secs_f64();
    cvtrace_streams::atomic::write_atomically(&timing, true, |tmp| std::fs::write(tmp, format!("{secs}\n")))?;
    Ok(secs)
}

/// The stream file of seed `seed` with `spp` samples per stream, replacing `output`. Unset
/// size and path limits come from the scene's sidecar.
fn stream_job(args: &StudyArgs, spp: u32, seed: u64, output: &Path) -> Job {
    Job::Streams(StreamJob { output: output.to_path_buf(), view: args.view.view(), spp: Some(spp), batches: args.batches, seed, overwrite: true })
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


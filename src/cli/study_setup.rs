//! `cvtrace study`'s flags and every check it makes before it writes anything: the scene loads,
//! the estimators' needs, a given reference matches. `study` then runs what was prepared;
//! `farm study` prepares only, so that its tasks fail only for reasons of their node.
use crate::cli::args::{batches_parser, default_batches, parse_seed, spp_parser, ViewArgs};
use crate::cli::estimator_args::EstimatorArgs;
use crate::cli::files::{check_input_file, same_output};
use crate::cli::registry;
use anyhow::{bail, Context, Result};
use cvtrace_eval::Reference;
use cvtrace_render::settings::MAX_SPP;
use cvtrace_session::{NoProgress, RenderSession, RenderSource};
use cvtrace_streams::exr_io::{take_rgb, AttrValue, ExrChannels};
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::Provenance;
use cvtrace_study::files::Cell;
use cvtrace_study::{Column, Study, DEFAULT_REFERENCE_SPP, DEFAULT_SPP, MAX_SEEDS, PT2N_SEED_OFFSET};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// glTF 2.0 scene.
    pub scene: PathBuf,
    /// Samples per pixel of each stream; a list (e.g. 8,16,32) also gives convergence plots.
    /// Tables and images are for the largest value [default: -D spp, else 96].
    #[arg(long, value_delimiter = ',', value_parser = spp_parser(), allow_hyphen_values = true)]
    pub spp: Vec<u32>,
    /// Independent seeds per spp value.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=MAX_SEEDS as i64), allow_hyphen_values = true)]
    pub seeds: u32,
    /// First seed; seed i uses `seed + i` for its streams.
    #[arg(long, default_value_t = 1, value_parser = parse_seed, allow_hyphen_values = true)]
    pub seed: u64,
    /// Batches per stream (must divide every spp value) [default: the most of 16, 8, 4, 2, 1
    /// that divides every spp value; iduw needs a multiple of 4].
    #[arg(long, value_parser = batches_parser(), allow_hyphen_values = true)]
    pub batches: Option<u32>,
    /// Reference EXR; rendered (PT, --reference-spp) when the file does not exist.
    #[arg(long)]
    pub reference: PathBuf,
    /// Samples per pixel of a reference the study renders itself [default: -D reference_spp,
    /// else the scene sidecar's reference_spp, else 4096].
    #[arg(long, value_parser = spp_parser(), allow_hyphen_values = true)]
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

/// What [`prepare`] found: everything the study needs before its folder is made.
pub struct Prepared {
    /// The spp values, ascending and without repeats.
    pub spps: Vec<u32>,
    /// One session renders everything (the BVH is built once, at the first render).
    pub session: RenderSession,
    /// What every render of the study records about itself, counts aside.
    pub planned: Provenance,
    /// Pixels per image.
    pub pixels: u64,
    pub columns: Vec<Column>,
    pub batches: u32,
    pub headline: Vec<(String, String)>,
    /// A given reference, read: its image and sample count.
    pub existing: Option<(Reference, Option<u32>)>,
    /// The spp of a reference the study must render (0 when one is given).
    pub reference_spp: u32,
}

/// Every check of `args`, in the order a user would want to hear of them; writes nothing.
pub fn prepare(args: &StudyArgs) -> Result<Prepared> {
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
    if let Some(cell) = args.cell {
        if !spps.contains(&cell.spp) || cell.index >= args.seeds {
            bail!("--cell {cell}: not a cell of this study (--spp {:?}, seed indices 0..{})", spps, args.seeds);
        }
    }
    if let Some(b) = args.batches {
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
    if same_output(&args.reference, &args.output) {
        bail!("{}: given as both --reference and -o; the reference is a file, the study a folder", args.output.display());
    }
    // One session renders everything (the BVH is built once, at the first render). Loading the
    // scene tells what every render of this study records about itself (so a finished one is
    // only reused if it matches), and a scene that does not load fails here, before the study
    // folder is made.
    let session = args.view.open_session(&args.scene)?;
    let probe = RenderSource::new(&session, args.output.clone(), args.view.view(), args.seed, Box::new(|| Box::new(NoProgress)));
    let plan = session.plan(&probe.stream_job(spps[0], args.batches.unwrap_or(1), args.seed, &args.output))?;
    drop(probe);
    let pixels = plan.settings.width as u64 * plan.settings.height as u64;
    // Counts aside: they differ between the study's renders.
    let planned = plan.provenance.without_counts();
    let overrides = args.options.checked()?;
    let columns = cvtrace_study::columns(registry(), &overrides, args.ablations)?;
    let batches = args.batches.unwrap_or_else(|| default_batches(&spps));
    let headline = cvtrace_study::headline(&args.headline, &columns)?;
    let study =
        Study { columns: &columns, spps: spps.clone(), seeds: args.seeds, first_seed: args.seed, batches, headline: headline.clone() };
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
        check_input_file(&args.reference)?;
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
        (None, Some(n)) => n,
        (None, None) => session.scene().render_defaults().reference_spp.unwrap_or(DEFAULT_REFERENCE_SPP),
    };
    if existing.is_none() {
        cvtrace_streams::atomic::check_extension(&args.reference, "exr")?;
    }
    if args.output.exists() && !args.output.is_dir() {
        bail!("{}: is a file; the study needs a folder (-o)", args.output.display());
    }
    Ok(Prepared { spps, session, planned, pixels, columns, batches, headline, existing, reference_spp })
}

/// The reference at `--reference`: its image, its sample count, and a check that its seed is
/// none of the study's.
pub fn read_reference(args: &StudyArgs) -> Result<(Reference, Option<u32>)> {
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

/// The scene's name in the results: `--name`, else from the scene's file.
pub fn study_name(args: &StudyArgs) -> String {
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

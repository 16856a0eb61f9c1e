//! `cvtrace.study` and `cvtrace.report`: the paper's protocol on one scene, as `cvtrace study`
//! runs it (the same checks, folder, files and `results.json`), with the estimators
//! registered from Python among its columns; and the viewer of study folders.
use crate::estimators::registry;
use crate::render::{scene_name, Setup};
use crate::run::{run, Cancel, CancellingProgress};
use anyhow::{bail, Context};
use cvtrace_eval::Reference;
use cvtrace_reconstruct::{Overrides, Registry};
use cvtrace_render::settings::MAX_SPP;
use cvtrace_session::{Job, NoProgress, Progress, ReferenceJob, RenderSource};
use cvtrace_streams::output_lock::OutputLock;
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::Provenance;
use cvtrace_study::{SceneInfo, Study, DEFAULT_REFERENCE_SPP, DEFAULT_SPP, MAX_SEEDS, PT2N_SEED_OFFSET, REFERENCE_SEED};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Arc;

struct StudyArgs {
    setup: Setup,
    spps: Vec<u32>,
    seeds: u32,
    seed: u64,
    batches: Option<u32>,
    reference: PathBuf,
    reference_spp: Option<u32>,
    output: PathBuf,
    ablations: bool,
    name: Option<String>,
    headline: Vec<String>,
    methods: Option<String>,
    overrides: Overrides,
}

/// The registry's estimators, or only those `methods` names (in the registry's order).
fn lineup(methods: Option<&str>) -> anyhow::Result<Registry> {
    let all = registry();
    let Some(text) = methods else { return Ok(all) };
    let chosen = all.select(text)?;
    let mut r = Registry::new();
    for spec in all.specs() {
        if chosen.iter().any(|c| std::ptr::eq(*c, *spec)) {
            r.register(spec)?;
        }
    }
    Ok(r)
}

fn run_study(args: StudyArgs, cancel: &Arc<Cancel>) -> anyhow::Result<String> {
    let mut spps = args.spps.clone();
    spps.sort_unstable();
    spps.dedup();
    if spps.is_empty() || spps[0] == 0 {
        bail!("spp needs positive values");
    }
    if args.seeds == 0 || args.seeds > MAX_SEEDS {
        bail!("seeds={}: must be between 1 and {MAX_SEEDS}", args.seeds);
    }
    if let Some(b) = args.batches {
        if b == 0 {
            bail!("batches must be at least 1");
        }
        if let Some(bad) = spps.iter().find(|&&n| n % b != 0) {
            bail!("batches={b} does not divide spp {bad}; every spp value must be a multiple of the batch count");
        }
    }
    if let Some(&n) = spps.iter().find(|&&n| n > MAX_SPP / 2) {
        bail!("spp {n}: the study's PT(2n) render would take {} spp, more than {MAX_SPP}", 2 * n as u64);
    }
    if args.seed.checked_add(args.seeds as u64 - 1).and_then(|s| s.checked_add(PT2N_SEED_OFFSET)).is_none() {
        bail!(
            "seed={} seeds={}: the PT(2n) renders use seeds up to seed + seeds − 1 + 2^32, which does not fit in 64 bits; give a smaller seed",
            args.seed,
            args.seeds
        );
    }
    if !args.setup.scene.is_file() {
        bail!("{}: scene file not found", args.setup.scene.display());
    }
    let name = args.name.clone().unwrap_or_else(|| scene_name(&args.setup.scene));
    if name.trim().is_empty() {
        bail!("{}: no scene name can be made from this file name; give one with name=", args.setup.scene.display());
    }
    let session = args.setup.session()?;
    let view = args.setup.view;
    let probe = RenderSource::new(&session, args.output.clone(), view, args.seed, Box::new(|| Box::new(NoProgress)));
    let plan = session.plan(&probe.stream_job(spps[0], args.batches.unwrap_or(1), args.seed, &args.output))?;
    drop(probe);
    let planned = plan.provenance.without_counts();
    let registry = lineup(args.methods.as_deref())?;
    registry.check(&args.overrides)?;
    let columns = cvtrace_study::columns(&registry, &args.overrides, args.ablations)?;
    let batches = args.batches.unwrap_or_else(|| cvtrace_session::default_batches(&spps));
    let headline = cvtrace_study::headline(&args.headline, &columns)?;
    let study = Study { columns: &columns, spps: spps.clone(), seeds: args.seeds, first_seed: args.seed, batches, headline };
    if let Err(e) = study.check_needs() {
        if args.batches.is_none() {
            bail!(
                "{e}; batches was not given, and {} is the most of 16, 8, 4, 2, 1 that divides every spp value: give spp values \
                 that are multiples of 4 (iduw forms 4 sub-buffers)",
                study.batches
            );
        }
        return Err(e.into());
    }
    let existing = if args.reference.exists() {
        crate::metrics::check_input_file(&args.reference)?;
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
                bail!("reference_spp={n}: must be between 1 and {MAX_SPP}");
            }
            n
        }
        (None, None) => session.scene().render_defaults().reference_spp.unwrap_or(DEFAULT_REFERENCE_SPP),
    };
    if existing.is_none() {
        cvtrace_streams::atomic::check_extension(&args.reference, "exr")?;
    }
    if args.output.exists() && !args.output.is_dir() {
        bail!("{}: is a file; the study needs a folder (output=)", args.output.display());
    }
    let made: Vec<PathBuf> =
        args.output.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).map(Path::to_path_buf).collect();
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create the study folder", args.output.display()))?;
    let progress_cancel = cancel.clone();
    let mut source = RenderSource::new(
        &session,
        args.output.clone(),
        view,
        args.seed,
        Box::new(move || Box::new(CancellingProgress(progress_cancel.clone())) as Box<dyn Progress>),
    );
    // Declared before the claim, so that it runs after the claim's lock file is gone.
    let mut cleanup = RemoveEmptyOnFailure { dirs: made, armed: true };
    // One study per folder at a time, as the CLI's claim.
    let result = match OutputLock::acquire(&args.output.join(".cvtrace-study.lock"), &args.output) {
        Ok(_claim) => {
            let r = in_folder(&args, &name, &planned, &study, &mut source, cancel, existing, reference_spp);
            cleanup.dirs.extend(source.made_folders().iter().cloned());
            r
        }
        Err(e) => Err(e.into()),
    };
    cleanup.armed = result.is_err();
    result
}

/// Removes the (empty) folders a study made when it fails or is cancelled; a finished render
/// or checkpoint in them stays for the next run.
struct RemoveEmptyOnFailure {
    dirs: Vec<PathBuf>,
    armed: bool,
}

impl Drop for RemoveEmptyOnFailure {
    fn drop(&mut self) {
        if self.armed || std::thread::panicking() {
            // The deepest first, so that a folder emptied of its sub-folders goes too.
            self.dirs.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
            for dir in &self.dirs {
                let _ = std::fs::remove_dir(dir);
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn in_folder(
    args: &StudyArgs,
    name: &str,
    planned: &Provenance,
    study: &Study,
    source: &mut RenderSource,
    cancel: &Arc<Cancel>,
    existing: Option<(Reference, Option<u32>)>,
    reference_spp: u32,
) -> anyhow::Result<String> {
    let (reference, reference_spp) = match existing {
        Some(r) => r,
        None => {
            let job = ReferenceJob::replacing(args.reference.clone(), args.setup.view, reference_spp, REFERENCE_SEED);
            source.session.render(&Job::Reference(job), &CancellingProgress(cancel.clone()))?;
            read_reference(args)?
        }
    };
    let scene = SceneInfo::new(name.to_string(), &args.reference, reference_spp, planned);
    let results = study.run(source, &reference, scene, &args.output)?;
    Ok(results.to_json())
}

/// The reference's image and sample count, and a check that its seed is none of the study's.
fn read_reference(args: &StudyArgs) -> anyhow::Result<(Reference, Option<u32>)> {
    Ok(cvtrace_study::read_reference(&args.reference, args.seed, args.seeds)?)
}

/// The study's parameters: ``{"ours.k": 16}`` or ``{"ours": {"k": 16}}``.
fn overrides_from(params: Option<&Bound<'_, PyDict>>) -> PyResult<Overrides> {
    let mut o = Overrides::default();
    let Some(params) = params else { return Ok(o) };
    for (k, v) in params.iter() {
        let key = k.str()?.to_string();
        if let Ok(inner) = v.cast::<PyDict>() {
            for (p, value) in inner.iter() {
                o.set(&key, &p.str()?.to_string(), &crate::params::param_text(&value)?);
            }
        } else {
            let text = format!("{key}={}", crate::params::param_text(&v)?);
            o.parse_assignment(&text).map_err(|e| crate::errors::error(e.into()))?;
        }
    }
    Ok(o)
}

/// Runs the paper's protocol on ``scene``, as ``cvtrace study`` does, and returns its
/// ``results.json`` as a dict.
///
/// For every spp value ``n`` and seed it renders the PT and CRN streams (``n`` spp each) and a
/// real PT image with ``2n`` spp into ``output`` (files reused when the study runs again, so an
/// interrupted study resumes), runs every registered estimator (the built-in ones and those
/// registered from Python with ``cvtrace.register``) and scores each against the reference:
/// relMSE mean ± standard error, bias² and variance over seeds, HDR-FLIP, time per stage.
/// ``output`` then holds ``results.json``, ``results.csv`` and the images; ``cvtrace.report``
/// (or ``cvtrace report``) makes the viewer.
///
/// Args:
///     scene: the glTF scene.
///     reference: the reference EXR; rendered (``reference_spp``) when the file does not exist.
///     output: the study folder (made; reused to resume).
///     spp: samples per pixel of each stream, or a list of them (convergence plots).
///     seeds, seed: seeds ``seed .. seed + seeds - 1``.
///     batches: batches per stream (default: the most of 16, 8, 4, 2, 1 dividing every spp).
///     methods: the estimators to run, ``"ours,cv"`` or a list (default: all).
///     params: estimator parameters, ``{"ours.k": 16}`` or ``{"ours": {"k": 16}}``.
///     ablations, name, headline: as ``cvtrace study``'s flags.
///     width, height, camera, traversal, threads, **defines: as for ``render``.
#[pyfunction]
#[pyo3(signature = (scene, *, reference, output, spp = None, seeds = 8, seed = 1, batches = None, reference_spp = None, methods = None, params = None, ablations = false, name = None, headline = None, width = None, height = None, camera = None, traversal = "fast", threads = None, **defines))]
#[allow(clippy::too_many_arguments)]
pub fn study_json(
    py: Python<'_>,
    scene: PathBuf,
    reference: PathBuf,
    output: PathBuf,
    spp: Option<&Bound<'_, PyAny>>,
    seeds: u32,
    seed: u64,
    batches: Option<u32>,
    reference_spp: Option<u32>,
    methods: Option<&Bound<'_, PyAny>>,
    params: Option<&Bound<'_, PyDict>>,
    ablations: bool,
    name: Option<String>,
    headline: Option<Vec<String>>,
    width: Option<u32>,
    height: Option<u32>,
    camera: Option<&Bound<'_, PyAny>>,
    traversal: &str,
    threads: Option<usize>,
    defines: Option<&Bound<'_, PyDict>>,
) -> PyResult<String> {
    let setup = Setup::new(scene, width, height, camera, traversal, defines)?;
    let spps: Vec<u32> = match spp {
        None => vec![setup.defined::<u32>("spp").unwrap_or(DEFAULT_SPP)],
        Some(v) => match v.extract::<u32>() {
            Ok(n) => vec![n],
            Err(_) => v
                .extract::<Vec<u32>>()
                .map_err(|_| pyo3::exceptions::PyValueError::new_err("spp: expected a positive integer or a list of them"))?,
        },
    };
    let methods = match methods.filter(|m| !m.is_none()) {
        None => None,
        Some(m) => Some(match m.extract::<String>() {
            Ok(s) => s,
            Err(_) => m.extract::<Vec<String>>()?.join(","),
        }),
    };
    let args = StudyArgs {
        setup,
        spps,
        seeds,
        seed,
        batches,
        reference,
        reference_spp,
        output,
        ablations,
        name,
        headline: headline.unwrap_or_else(|| ["ours/iduw", "ours/cv", "ours/pt2n"].map(String::from).to_vec()),
        methods,
        overrides: overrides_from(params)?,
    };
    run(py, threads, move |cancel| run_study(args, cancel))
}

/// Writes the static HTML viewer of one study folder into ``output`` (an empty or new folder;
/// ``overwrite=True`` replaces an earlier report there), as ``cvtrace report`` does; returns
/// the path of its ``index.html``.
#[pyfunction]
#[pyo3(signature = (study, output, *, title = "cvtrace".to_string(), overwrite = false))]
pub fn report(py: Python<'_>, study: PathBuf, output: PathBuf, title: String, overwrite: bool) -> PyResult<PathBuf> {
    run(py, None, move |_| {
        let results_file = study.join("results.json");
        if !results_file.is_file() {
            bail!("{}: not a study folder (no results.json; run cvtrace.study first)", study.display());
        }
        let results = cvtrace_eval::StudyResults::read_json(&results_file)?;
        let options = cvtrace_eval::ReportOptions { title, overwrite };
        Ok(cvtrace_eval::write_report(&results, &study, &output, &options)?)
    })
}

//! `cvtrace render`: a glTF scene → a PT/CRN stream file, or (`--reference`) a progressive,
//! resumable PT-only reference image.
//!
//! Everything that can be checked cheaply (flags, output path, scene) is checked before the
//! render starts, so a long render never fails at the end for a reason known at the start.
//!
//! Settings not given as flags come from the scene's sidecar `<stem>.cvtrace.toml`
//! (`[render]`, docs/scene-format.md), then the glTF's `asset.extras.defaultResolution` (size
//! only), then the built-in defaults.
//! Outputs are written atomically: an error or interruption never leaves a partial file.
use anyhow::{bail, Context, Result};
use cvtrace::{set_flush_denormals, BuildOptions, Device, EmbreeScene};
use cvtrace_render::{render_reference_pass, render_streams, Camera, ReferenceAccum, RenderDefaults, RenderSettings, Scene};
use cvtrace_streams::atomic::{check_extension, check_writable};
use cvtrace_streams::output_lock::{lock_path_for, OutputLock};
use cvtrace_streams::exr_io::{take_rgb, write_rgb, AttrValue, ExrChannels};
use glam::Vec3A;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::throughput::PhaseClock;

/// Image width used when neither the flags nor the scene give a size.
const DEFAULT_WIDTH: u32 = 256;
/// Samples per pixel when neither --spp nor the sidecar gives them.
const DEFAULT_SPP: u32 = 64;
/// Path-length defaults when neither the flags nor the sidecar give them.
const DEFAULT_MAX_DEPTH: i32 = -1;
const DEFAULT_RR_DEPTH: u32 = 5;
/// Batches per stream when --batches is not given: the estimators' measured default.
const DEFAULT_BATCHES: u32 = 16;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// glTF 2.0 scene (.gltf with its buffers, or .glb).
    pub scene: PathBuf,
    /// Output: a stream file (e.g. cbox.streams.exr), or with --reference an RGB EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel of each stream (or of the reference) [default: the sidecar's `spp`, or
    /// `reference_spp` with --reference, else 64].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Batches per stream (must divide --spp; default 16, the measured default of the estimators, see docs/estimators.md). Not used with --reference.
    #[arg(long)]
    pub batches: Option<u32>,
    /// Random seed: the same seed and settings give bit-identical output.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Render a PT-only reference image, progressively, resumable from a checkpoint next to the output.
    #[arg(long)]
    pub reference: bool,
    /// With --reference: samples per pixel per pass; a checkpoint is saved after every pass.
    #[arg(long, default_value_t = 64, requires = "reference")]
    pub pass_spp: u32,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
    /// With --reference: continue the finished reference at --output (same scene, seed and
    /// settings) up to --spp samples and replace it. The samples continue its sequence, so the
    /// result equals a one-shot render of --spp to f32 rounding (the file keeps means, not sums).
    #[arg(long, requires = "reference")]
    pub extend: bool,
    /// Testing aid: with --reference, stop (keeping the checkpoint) after this many passes.
    #[arg(long, hide = true, requires = "reference")]
    pub stop_after_passes: Option<u32>,
}

/// What is rendered, shared by `render` and `study`: image size, camera, path-length limits.
/// Unset values come from the scene (see the module doc).
#[derive(clap::Args, Debug, Clone)]
pub struct ViewArgs {
    /// Image width [default: the scene's (sidecar, else the glTF's defaultResolution), else 256;
    /// with only --height given, from the camera's aspect ratio].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [default: the scene's, else from the width and the camera's aspect ratio].
    #[arg(long)]
    pub height: Option<u32>,
    /// Longest path in segments from the camera (Mitsuba convention), -1 for unlimited
    /// [default: the sidecar's max_depth, else -1].
    #[arg(long, allow_negative_numbers = true)]
    pub max_depth: Option<i32>,
    /// Path depth at which Russian roulette starts [default: the sidecar's rr_depth, else 5].
    #[arg(long)]
    pub rr_depth: Option<u32>,
    /// Override the scene camera: "ex,ey,ez:tx,ty,tz:vfov_degrees" (eye, target, vertical FOV; up stays).
    #[arg(long, value_name = "EYE:TARGET:FOV")]
    pub camera: Option<String>,
    /// Embree traversal: `robust` is watertight where triangles share an edge; `fast` (Embree's
    /// and Mitsuba 3's default) is quicker but lets rays that graze a shared edge through
    /// (docs/performance.md has both figures).
    #[arg(long, value_enum, default_value_t = Traversal::Robust)]
    pub traversal: Traversal,
}

/// How Embree intersects triangles (see [`ViewArgs::traversal`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traversal {
    Robust,
    Fast,
}

impl Traversal {
    /// The name recorded in output files (`cvtrace.traversal`).
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Robust => "robust",
            Traversal::Fast => "fast",
        }
    }
}

/// The stream-file setting and the reference's header attribute naming the traversal. Files
/// without it come from versions that only traced robustly.
const SETTING_TRAVERSAL: &str = "traversal";
const ATTR_TRAVERSAL: &str = "cvtrace.traversal";

/// The traversal a file's `cvtrace.traversal` attribute records (robust when absent).
fn recorded_traversal(attr: Option<&AttrValue>) -> String {
    attr.map_or_else(|| Traversal::Robust.name().to_string(), |v| v.as_text())
}

/// How the finished render at `path` differs from `planned` (seed included) and the asked `spp`
/// and, for stream files, `batches`: everything its header records. Values an older file did
/// not record are not compared.
pub fn recorded_differences(path: &Path, planned: &RenderIdentity, spp: u32, batches: Option<u32>) -> Result<Vec<String>> {
    Ok(differing_fields(path, planned, spp, batches)?.into_iter().map(|(_, message)| message).collect())
}

/// [`recorded_differences`] as (field, message) pairs.
fn differing_fields(path: &Path, planned: &RenderIdentity, spp: u32, batches: Option<u32>) -> Result<Vec<(&'static str, String)>> {
    let (width, height, attrs) = ExrChannels::read_header(path)?;
    let text = |k: &str| attrs.get(k).map_or_else(|| UNRECORDED.to_string(), |v| v.as_text());
    let recorded = [
        ("size", format!("{width}x{height}")),
        ("seed", text("cvtrace.seed")),
        ("max depth", text("cvtrace.maxDepth")),
        ("rr depth", text("cvtrace.rrDepth")),
        ("scene hash", text("cvtrace.sceneHash")),
        ("camera", text("cvtrace.camera")),
        ("traversal", recorded_traversal(attrs.get(ATTR_TRAVERSAL))),
        ("spp", text("cvtrace.spp")),
        ("batches", if batches.is_some() { text("cvtrace.batches") } else { UNRECORDED.into() }),
    ];
    let mut asked = planned.fields().to_vec();
    asked.push(("spp", spp.to_string()));
    asked.push(("batches", batches.map_or_else(|| UNRECORDED.into(), |b| b.to_string())));
    Ok(field_differences(&asked, &recorded, "in the file"))
}

/// How the reference at `path` is of another image than `planned` would render: scene, camera,
/// size or path length (what changes the expectation). Unrecorded values are not compared, so
/// references from other renderers pass.
pub fn reference_mismatches(path: &Path, planned: &RenderIdentity) -> Result<Vec<String>> {
    let same_image = ["size", "max depth", "scene hash", "camera"];
    let all = differing_fields(path, planned, 0, None)?;
    Ok(all.into_iter().filter(|(field, _)| same_image.contains(field)).map(|(_, message)| message).collect())
}

/// `what_saved` differs from `now` in these fields, matched by name (an unrecorded value, or a
/// field one side does not list, never differs).
fn field_differences(now: &[(&'static str, String)], saved: &[(&'static str, String)], what_saved: &str) -> Vec<(&'static str, String)> {
    now.iter()
        .filter_map(|(name, a)| Some((*name, a, &saved.iter().find(|(n, _)| n == name)?.1)))
        .filter(|(_, a, b)| a != b && *b != UNRECORDED && *a != UNRECORDED)
        .map(|(name, a, b)| (name, format!("{name} {b} ({what_saved}) vs {a} (now)")))
        .collect()
}

pub fn run(args: RenderArgs) -> Result<()> {
    // Cheap checks first: flags, then whether the output can be written at all.
    let batches = match (args.reference, args.batches) {
        (true, Some(_)) => bail!("--batches does not apply to --reference renders (they have a single PT stream)"),
        (true, None) => 1,
        (false, b) => b.unwrap_or(DEFAULT_BATCHES),
    };
    if args.reference && args.pass_spp == 0 {
        bail!("--pass-spp must be at least 1");
    }
    if args.stop_after_passes == Some(0) {
        bail!("--stop-after-passes 0: must be at least 1 (a reference stops after its last pass anyway)");
    }
    // The flags alone (scene defaults filled in after loading); a flag given is checked now.
    let flag_size = (args.view.width.unwrap_or(DEFAULT_WIDTH), args.view.height.unwrap_or(DEFAULT_WIDTH));
    let mut provisional = resolve_settings(&args, batches, &RenderDefaults::default(), flag_size);
    // Without --spp the count comes from the scene, so only --batches itself is checked here.
    provisional.spp = args.spp.unwrap_or(batches);
    provisional.validate()?;
    let camera_override = args.view.camera.as_deref().map(parse_camera).transpose()?;
    if args.extend && !args.output.is_file() {
        bail!("{}: --extend continues a finished reference, and there is none at this path", args.output.display());
    }
    check_extension(&args.output, "exr")?;
    check_writable(&args.output, args.force || args.extend)?;
    let checkpoint = checkpoint_path(&args.output);
    // A reference takes many passes and a checkpoint: a second process on the same output
    // would repeat the work and race over both files.
    let _claim = if args.reference { Some(OutputLock::acquire(&lock_path_for(&args.output), &args.output)?) } else { None };
    if args.reference {
        if checkpoint.is_dir() {
            bail!("{}: the checkpoint path is a directory", checkpoint.display());
        }
        // The checkpoint is replaced after every pass, so its location must be writable too.
        check_writable(&checkpoint, true)?;
    }

    // Denormal flushing in this thread too, for any work rayon runs on the caller.
    set_flush_denormals();

    let (scene, settings) = prepare(&args, batches, camera_override)?;

    let build = BuildOptions { robust: args.view.traversal == Traversal::Robust, ..BuildOptions::default() };
    let tracer = Device::new()
        .and_then(|device| device.build_scene(scene.positions(), scene.triangles(), &build))
        .context("building the Embree BVH")?;
    // FTZ/DAZ in every render thread (Embree's advice), whatever the thread count: a local
    // pool of the configured size (the global one follows --threads) with a start handler.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(rayon::current_num_threads())
        .thread_name(|i| format!("cvtrace-render-{i}"))
        .start_handler(|_| set_flush_denormals())
        .build()
        .map_err(|e| anyhow::anyhow!("cannot start {} render threads (ask for fewer with --threads): {e}", rayon::current_num_threads()))?;

    if args.reference {
        render_reference(&args, &scene, &tracer, &settings, &checkpoint, &pool)
    } else {
        render_stream_file(&args, &scene, &tracer, &settings, &pool)
    }
}

/// The scene as this render sees it (the `--camera` override applied) and the settings that
/// the flags and the scene's defaults resolve to.
fn prepare(args: &RenderArgs, batches: u32, camera_override: Option<CameraView>) -> Result<(Scene, RenderSettings)> {
    let t = Instant::now();
    let mut scene = Scene::load(&args.scene)?;
    tracing::info!(
        "loaded {} in {:.1} ms: {} triangles, {} materials",
        args.scene.display(),
        ms(t),
        scene.triangles().len(),
        scene.materials().len()
    );
    if let Some(view) = camera_override {
        let c = scene.camera().clone();
        let camera = Camera { eye: view.eye, target: view.target, vfov_deg: view.vfov_deg, ..c };
        camera.validate().map_err(|m| anyhow::anyhow!("--camera: {m}"))?;
        scene.set_camera(camera);
    }
    let size = image_size(&args.view, scene.render_defaults(), scene.camera());
    let settings = resolve_settings(args, batches, scene.render_defaults(), size);
    settings.validate().with_context(|| format!("{}: settings from the command line and the scene", args.scene.display()))?;
    check_memory(args, &settings)?;
    Ok((scene, settings))
}

/// Fails if the render's images cannot be held in memory here (physical memory, or the address
/// space `ulimit -v` leaves): a 16384×16384 stream file takes more than 100 GiB, and running out
/// half-way aborts the process after all the rendering.
fn check_memory(args: &RenderArgs, s: &RenderSettings) -> Result<()> {
    let (needed, what) = if args.reference {
        (s.reference_memory_estimate(args.extend || s.spp > args.pass_spp), String::new())
    } else {
        (s.stream_memory_estimate(), format!(" --batches {}", s.batches))
    };
    if !can_allocate(needed) {
        bail!(
            "--width {} --height {}{what}: the render needs about {:.1} GiB of memory, which cannot be allocated here \
             (physical memory, or the `ulimit -v` limit); render a smaller image{}",
            s.width,
            s.height,
            needed as f64 / (1u64 << 30) as f64,
            if args.reference { "" } else { " or with fewer --batches" }
        );
    }
    Ok(())
}

/// Whether `bytes` can be reserved now (the reservation is given back at once; nothing is touched).
fn can_allocate(bytes: u64) -> bool {
    usize::try_from(bytes).is_ok_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok())
}

/// What a render with `args` would record about itself (scene hash, camera, size, depths, seed,
/// traversal), found by loading the scene without rendering: `study` compares it with the
/// finished renders it is about to reuse.
pub fn planned_identity(args: &RenderArgs) -> Result<RenderIdentity> {
    let batches = if args.reference { 1 } else { args.batches.unwrap_or(DEFAULT_BATCHES) };
    let camera_override = args.view.camera.as_deref().map(parse_camera).transpose()?;
    let (scene, settings) = prepare(args, batches, camera_override)?;
    Ok(RenderIdentity::new(&scene, &settings, args.view.traversal))
}

fn render_stream_file(args: &RenderArgs, scene: &Scene, tracer: &EmbreeScene, s: &RenderSettings, pool: &rayon::ThreadPool) -> Result<()> {
    let total = s.width as u64 * s.height as u64 * s.spp as u64 * 2;
    tracing::info!(
        "rendering {}x{}, {} spp x 2 streams ({} batches), max depth {}, seed {} on {} threads",
        s.width,
        s.height,
        s.spp,
        s.batches,
        s.max_depth,
        s.seed,
        pool.current_num_threads()
    );
    let bar = progress_bar(total, 0);
    let clock = PhaseClock::start();
    let result = pool.install(|| render_streams(scene, tracer, s, &|k| bar.inc(k)));
    bar.finish_and_clear();
    let mut set = result?;
    clock.log_rate("render", total);
    set.meta.scene = args.scene.to_string_lossy().into_owned();
    // The identity a checkpoint records, so that a study can tell whether it may reuse the file.
    let identity = RenderIdentity::new(scene, s, args.view.traversal);
    for (key, value) in [
        (SETTING_TRAVERSAL, identity.traversal),
        ("rrDepth", identity.rr_depth.to_string()),
        ("sceneHash", identity.scene_hash),
        ("camera", identity.camera),
    ] {
        set.meta.settings.insert(key.into(), value);
    }
    let t = Instant::now();
    set.write(&args.output, args.force)?;
    tracing::info!("wrote {} in {:.1} ms", args.output.display(), ms(t));
    Ok(())
}

fn render_reference(
    args: &RenderArgs,
    scene: &Scene,
    tracer: &EmbreeScene,
    s: &RenderSettings,
    checkpoint: &Path,
    pool: &rayon::ThreadPool,
) -> Result<()> {
    let identity = RenderIdentity::new(scene, s, args.view.traversal);
    // An interrupted extension left a checkpoint, which is exact: it comes first.
    let mut accum = match load_checkpoint(checkpoint, &identity)? {
        Some(a) => {
            if a.samples_done > s.spp {
                bail!(
                    "{}: the checkpoint already holds {} spp, more than --spp {}; render with --spp {} or delete it to start the reference over",
                    checkpoint.display(),
                    a.samples_done,
                    s.spp,
                    a.samples_done
                );
            }
            tracing::info!("resuming from {} at {} of {} spp", checkpoint.display(), a.samples_done, s.spp);
            a
        }
        None if args.extend => {
            let a = load_finished_reference(&args.output, &identity, s)?;
            tracing::info!("extending {} from {} to {} spp", args.output.display(), a.samples_done, s.spp);
            a
        }
        None => ReferenceAccum::new(s),
    };
    let pixels = s.width as u64 * s.height as u64;
    tracing::info!(
        "rendering a reference {}x{}, {} spp in passes of {}, max depth {}, seed {} on {} threads",
        s.width,
        s.height,
        s.spp,
        args.pass_spp,
        s.max_depth,
        s.seed,
        pool.current_num_threads()
    );
    let bar = progress_bar(pixels * s.spp as u64, pixels * accum.samples_done as u64);
    let clock = PhaseClock::start();
    let start_samples = accum.samples_done;
    let mut passes = 0;
    while accum.samples_done < s.spp {
        let range = accum.samples_done..accum.samples_done.saturating_add(args.pass_spp).min(s.spp);
        let r = pool.install(|| render_reference_pass(scene, tracer, s, &mut accum, range, &|k| bar.inc(k)));
        if let Err(e) = r {
            bar.finish_and_clear();
            return Err(e.into());
        }
        passes += 1;
        let done = accum.samples_done >= s.spp;
        let stop = args.stop_after_passes.is_some_and(|n| passes >= n);
        if !done {
            bar.suspend(|| save_checkpoint(checkpoint, &accum, &identity))?;
        }
        if stop && !done {
            bar.finish_and_clear();
            tracing::info!(
                "stopped after {passes} passes as asked: {} of {} spp saved in {}",
                accum.samples_done,
                s.spp,
                checkpoint.display()
            );
            return Ok(());
        }
    }
    bar.finish_and_clear();
    clock.log_rate("render", pixels * (accum.samples_done - start_samples) as u64);

    let t = Instant::now();
    // The identity (scene hash and camera included) lets a later --extend check what it continues.
    let mut attributes = identity.attributes();
    attributes.retain(|(k, _)| *k != CKPT_KIND.0);
    attributes.extend([
        ("cvtrace.spp", AttrValue::Int(accum.samples_done as i32)),
        ("cvtrace.scene", AttrValue::Text(args.scene.to_string_lossy().into_owned())),
        ("cvtrace.nonFiniteSamples", AttrValue::Text(accum.non_finite_samples.to_string())),
    ]);
    if let Err(e) = write_rgb(&args.output, &accum.mean(), &attributes, args.force || args.extend) {
        // Keep the finished work: the next run with the same settings only has to write.
        let _ = save_checkpoint(checkpoint, &accum, &identity);
        return Err(e.into());
    }
    tracing::info!("wrote {} in {:.1} ms", args.output.display(), ms(t));
    if checkpoint.exists() {
        std::fs::remove_file(checkpoint).with_context(|| format!("{}: could not remove the finished checkpoint", checkpoint.display()))?;
    }
    Ok(())
}

/// `cbox.ref.exr` → `cbox.ref.checkpoint.exr` (other names get `.checkpoint.exr` appended).
fn checkpoint_path(output: &Path) -> PathBuf {
    let name = output.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = name.strip_suffix(".exr").unwrap_or(&name);
    output.with_file_name(format!("{stem}.checkpoint.exr"))
}

/// Everything that decides a render's samples: what a checkpoint must agree on with the current
/// run for its sums to be continued, and what every output records about itself. The sample
/// count is not part of it: passes add samples in index order, so any later target (at least
/// the samples done) continues the same sequence.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderIdentity {
    width: u32,
    height: u32,
    seed: u64,
    max_depth: i32,
    rr_depth: u32,
    /// Hash of the loaded scene (geometry, materials, textures, lights, final camera).
    scene_hash: String,
    camera: String,
    /// [`Traversal::name`]: a leak through an edge changes a sample.
    traversal: String,
}

const CKPT_KIND: (&str, &str) = ("cvtrace.checkpoint", "reference-v1");
/// Stands for a scene hash or camera that an older finished reference did not record.
const UNRECORDED: &str = "unrecorded";

impl RenderIdentity {
    fn new(scene: &Scene, s: &RenderSettings, traversal: Traversal) -> Self {
        let c = scene.camera();
        RenderIdentity {
            width: s.width,
            height: s.height,
            seed: s.seed,
            max_depth: s.max_depth,
            rr_depth: s.rr_depth,
            scene_hash: format!("{:016x}", scene_hash(scene)),
            camera: format!("eye {} target {} up {} vfov {}", c.eye, c.target, c.up, c.vfov_deg),
            traversal: traversal.name().into(),
        }
    }

    fn attributes(&self) -> Vec<(&'static str, AttrValue)> {
        vec![
            (CKPT_KIND.0, AttrValue::Text(CKPT_KIND.1.into())),
            ("cvtrace.seed", AttrValue::Text(self.seed.to_string())),
            ("cvtrace.maxDepth", AttrValue::Int(self.max_depth)),
            ("cvtrace.rrDepth", AttrValue::Int(self.rr_depth as i32)),
            ("cvtrace.sceneHash", AttrValue::Text(self.scene_hash.clone())),
            ("cvtrace.camera", AttrValue::Text(self.camera.clone())),
            (ATTR_TRAVERSAL, AttrValue::Text(self.traversal.clone())),
            ("cvtrace.version", AttrValue::Text(env!("CARGO_PKG_VERSION").into())),
        ]
    }

    /// The identity stored in a checkpoint, or (`finished`) in a finished reference, whose
    /// scene hash and camera may be missing: references written before cvtrace recorded them
    /// get `unrecorded` there.
    fn from_file(ch: &ExrChannels, path: &Path, finished: bool) -> Result<Self> {
        let what = if finished { "reference" } else { "checkpoint" };
        let text = |k: &str| -> Result<String> {
            ch.attr(k).map(|v| v.as_text()).with_context(|| format!("{}: {what} lacks the attribute {k}", path.display()))
        };
        let optional = |k: &str| -> Result<String> {
            match ch.attr(k) {
                None if finished => Ok(UNRECORDED.to_string()),
                _ => text(k),
            }
        };
        if !finished && text(CKPT_KIND.0)? != CKPT_KIND.1 {
            bail!("{}: not a cvtrace {} checkpoint", path.display(), CKPT_KIND.1);
        }
        if finished && ch.attr(CKPT_KIND.0).is_some() {
            bail!("{}: this is a checkpoint, not a finished reference", path.display());
        }
        let version = text("cvtrace.version")?;
        if version != env!("CARGO_PKG_VERSION") {
            bail!(
                "{}: {what} written by cvtrace {version}, this is {}, whose samples may differ; {}",
                path.display(),
                env!("CARGO_PKG_VERSION"),
                if finished { "render a new reference" } else { "delete it to start over" }
            );
        }
        let parse = |k: &str| -> Result<i64> {
            text(k)?.parse::<i64>().with_context(|| format!("{}: attribute {k} is not an integer", path.display()))
        };
        Ok(RenderIdentity {
            width: ch.width as u32,
            height: ch.height as u32,
            seed: text("cvtrace.seed")?.parse().with_context(|| format!("{}: bad cvtrace.seed", path.display()))?,
            max_depth: parse("cvtrace.maxDepth")? as i32,
            rr_depth: parse("cvtrace.rrDepth")? as u32,
            scene_hash: optional("cvtrace.sceneHash")?,
            camera: optional("cvtrace.camera")?,
            traversal: recorded_traversal(ch.attr(ATTR_TRAVERSAL)),
        })
    }

    /// The recorded fields, named as in error messages.
    pub fn fields(&self) -> [(&'static str, String); 7] {
        [
            ("size", format!("{}x{}", self.width, self.height)),
            ("seed", self.seed.to_string()),
            ("max depth", self.max_depth.to_string()),
            ("rr depth", self.rr_depth.to_string()),
            ("scene hash", self.scene_hash.clone()),
            ("camera", self.camera.clone()),
            ("traversal", self.traversal.clone()),
        ]
    }

    /// The same render with another seed (a study's renders differ only in seed and spp).
    pub fn with_seed(&self, seed: u64) -> Self {
        RenderIdentity { seed, ..self.clone() }
    }

    /// Human-readable differences from `saved` (a `what` file), for the mismatch error.
    /// An unrecorded value in `saved` is not a difference (see [`Self::from_file`]).
    fn differences(&self, saved: &Self, what: &str) -> Vec<String> {
        field_differences(&self.fields(), &saved.fields(), what).into_iter().map(|(_, message)| message).collect()
    }
}

/// The f64 running sums are stored exactly, as four 16-bit pieces per value in f32 channels
/// (integers below 2^24 are exact in f32); R, G, B hold the mean so far for viewing.
const SUM_PIECES: usize = 4;

fn sum_channel(c: usize, piece: usize) -> String {
    format!("sum.{}.w{piece}", ["R", "G", "B"][c])
}

fn save_checkpoint(path: &Path, accum: &ReferenceAccum, identity: &RenderIdentity) -> Result<()> {
    let t = Instant::now();
    let (w, h) = (accum.width as usize, accum.height as usize);
    let mut ch = ExrChannels::new(w, h);
    let mean = accum.mean();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        ch.insert(*name, mean.channel(c));
        for piece in 0..SUM_PIECES {
            let plane = accum.sum.iter().map(|s| ((s[c].to_bits() >> (16 * piece)) & 0xffff) as f32).collect();
            ch.insert(sum_channel(c, piece), plane);
        }
    }
    for (k, v) in identity.attributes() {
        ch.attributes.insert(k.to_string(), v);
    }
    ch.attributes.insert("cvtrace.samplesDone".into(), AttrValue::Int(accum.samples_done as i32));
    ch.attributes.insert("cvtrace.nonFiniteSamples".into(), AttrValue::Text(accum.non_finite_samples.to_string()));
    ch.write(path, true)?;
    tracing::debug!("checkpoint {} ({} spp) written in {:.1} ms", path.display(), accum.samples_done, ms(t));
    Ok(())
}

/// The accumulator saved at `path`, `None` if there is no checkpoint, or an error if it
/// belongs to a different render.
fn load_checkpoint(path: &Path, identity: &RenderIdentity) -> Result<Option<ReferenceAccum>> {
    if !path.exists() {
        return Ok(None);
    }
    // Whatever is wrong with it, the way out is the same.
    read_checkpoint(path, identity).map(Some).map_err(|e| anyhow::anyhow!("{e:#}; delete it to start the reference over"))
}

fn read_checkpoint(path: &Path, identity: &RenderIdentity) -> Result<ReferenceAccum> {
    let mut ch = ExrChannels::read(path)?;
    let saved = RenderIdentity::from_file(&ch, path, false)?;
    let diff = identity.differences(&saved, "checkpoint");
    if !diff.is_empty() {
        bail!(
            "{}: checkpoint of a different render ({}); render with its settings to resume it",
            path.display(),
            diff.join(", ")
        );
    }
    let samples_done = match ch.attr("cvtrace.samplesDone") {
        Some(AttrValue::Int(n)) if *n >= 0 => *n as u32,
        _ => bail!("{}: checkpoint lacks a valid cvtrace.samplesDone", path.display()),
    };
    let non_finite_samples = ch.attr("cvtrace.nonFiniteSamples").and_then(|v| v.as_text().parse().ok()).unwrap_or(0);
    let n = ch.width * ch.height;
    let mut bits = vec![[0u64; 3]; n];
    for c in 0..3 {
        for piece in 0..SUM_PIECES {
            let plane = ch.take(path, &sum_channel(c, piece))?;
            for (b, v) in bits.iter_mut().zip(plane) {
                if !(0.0..=65535.0).contains(&v) || v.fract() != 0.0 {
                    bail!("{}: channel {} is corrupt", path.display(), sum_channel(c, piece));
                }
                b[c] |= (v as u64) << (16 * piece);
            }
        }
    }
    let sum: Vec<[f64; 3]> = bits.iter().map(|b| b.map(f64::from_bits)).collect();
    if sum.iter().flatten().any(|v| !v.is_finite()) {
        bail!("{}: checkpoint sums are not finite", path.display());
    }
    Ok(ReferenceAccum {
        width: identity.width,
        height: identity.height,
        sum,
        samples_done,
        seed: identity.seed,
        max_depth: identity.max_depth,
        rr_depth: identity.rr_depth,
        non_finite_samples,
    })
}

/// The accumulator of the finished reference at `path`, to be extended: its identity must
/// match this render's, and it must hold fewer samples than `s.spp`.
fn load_finished_reference(path: &Path, identity: &RenderIdentity, s: &RenderSettings) -> Result<ReferenceAccum> {
    let mut ch = ExrChannels::read(path)?;
    let saved = RenderIdentity::from_file(&ch, path, true)?;
    let diff = identity.differences(&saved, "reference");
    if !diff.is_empty() {
        bail!("{}: --extend: the reference is of a different render ({})", path.display(), diff.join(", "));
    }
    if saved.scene_hash == UNRECORDED || saved.camera == UNRECORDED {
        tracing::warn!(
            "{}: written before references recorded their scene hash and camera; trusting that the scene is unchanged",
            path.display()
        );
    }
    let done = match ch.attr("cvtrace.spp") {
        Some(AttrValue::Int(n)) if *n > 0 => *n as u32,
        _ => bail!("{}: reference lacks a valid cvtrace.spp", path.display()),
    };
    if done >= s.spp {
        bail!("{}: --extend: the reference already holds {done} spp; ask for more with --spp (now {})", path.display(), s.spp);
    }
    let mean = take_rgb(&mut ch, path, "")?;
    let mut accum = ReferenceAccum::from_mean(s, &mean, done)?;
    accum.non_finite_samples = ch.attr("cvtrace.nonFiniteSamples").and_then(|v| v.as_text().parse().ok()).unwrap_or(0);
    Ok(accum)
}

/// The scene's [`Scene::fingerprint`]: geometry, materials, textures, lights and camera, not the
/// sidecar's render defaults (the resolved settings are compared on their own), so editing e.g.
/// `reference_spp` does not orphan a checkpoint.
fn scene_hash(scene: &Scene) -> u64 {
    scene.fingerprint()
}

/// Eye, target and vertical field of view from `--camera`.
struct CameraView {
    eye: Vec3A,
    target: Vec3A,
    vfov_deg: f32,
}

fn parse_camera(s: &str) -> Result<CameraView> {
    let usage = "expected --camera \"ex,ey,ez:tx,ty,tz:vfov\", e.g. \"278,273,-800:278,273,0:37\"";
    let parts: Vec<&str> = s.split(':').collect();
    if parts.len() != 3 {
        bail!("--camera {s:?}: {usage}");
    }
    let vec3 = |p: &str| -> Result<Vec3A> {
        let v: Vec<f32> =
            p.split(',').map(|x| x.trim().parse::<f32>()).collect::<Result<_, _>>().with_context(|| format!("--camera {s:?}: {usage}"))?;
        match v[..] {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3A::new(x, y, z)),
            _ => bail!("--camera {s:?}: {usage}"),
        }
    };
    let vfov_deg: f32 = parts[2].trim().parse().with_context(|| format!("--camera {s:?}: {usage}"))?;
    Ok(CameraView { eye: vec3(parts[0])?, target: vec3(parts[1])?, vfov_deg })
}

/// Flags first, then the scene's defaults, then the built-in ones; `size` is already resolved.
fn resolve_settings(args: &RenderArgs, batches: u32, d: &RenderDefaults, (width, height): (u32, u32)) -> RenderSettings {
    let scene_spp = if args.reference { d.reference_spp } else { d.spp };
    RenderSettings {
        width,
        height,
        spp: args.spp.or(scene_spp).unwrap_or(DEFAULT_SPP),
        batches,
        seed: args.seed,
        max_depth: args.view.max_depth.or(d.max_depth).unwrap_or(DEFAULT_MAX_DEPTH),
        rr_depth: args.view.rr_depth.or(d.rr_depth).unwrap_or(DEFAULT_RR_DEPTH),
    }
}

/// The render size: flags win (if either side is given, the scene's size is not used); else the
/// scene's default size; a missing side follows the camera's aspect ratio.
fn image_size(view: &ViewArgs, defaults: &RenderDefaults, camera: &Camera) -> (u32, u32) {
    let (width, height) =
        if view.width.is_some() || view.height.is_some() { (view.width, view.height) } else { (defaults.width, defaults.height) };
    let aspect = camera.width.max(1) as f64 / camera.height.max(1) as f64;
    let from_aspect = |v: f64| v.round().clamp(1.0, u32::MAX as f64) as u32;
    match (width, height) {
        (Some(w), Some(h)) => (w, h),
        (Some(w), None) => (w, from_aspect(w as f64 / aspect)),
        (None, Some(h)) => (from_aspect(h as f64 * aspect), h),
        (None, None) => (DEFAULT_WIDTH, from_aspect(DEFAULT_WIDTH as f64 / aspect)),
    }
}

/// A progress bar on stderr, drawn only when stderr is a terminal.
fn progress_bar(total: u64, done: u64) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    let style = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40.cyan/blue}] {percent:>3}% {human_pos}/{human_len} samples, {per_sec}, ETA {eta}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_position(done);
    bar.reset_eta();
    bar
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_flag_parses_and_rejects_garbage() {
        let v = parse_camera("278,273,-800:278,273,0:37").unwrap();
        assert_eq!((v.eye, v.target, v.vfov_deg), (Vec3A::new(278.0, 273.0, -800.0), Vec3A::new(278.0, 273.0, 0.0), 37.0));
        for bad in ["1,2:3,4,5:6", "1,2,3:4,5,6", "a,b,c:1,2,3:4", "1,2,3:4,5,6:x", "1,2,3,4:5,6,7:8", "nan,0,0:1,1,1:30"] {
            assert!(parse_camera(bad).is_err(), "{bad}");
        }
    }

    fn view(width: Option<u32>, height: Option<u32>) -> ViewArgs {
        ViewArgs { width, height, max_depth: None, rr_depth: None, camera: None, traversal: Traversal::Robust }
    }

    #[test]
    fn missing_side_follows_the_camera_aspect() {
        let cam = Camera { width: 640, height: 480, ..Camera::default() };
        let none = RenderDefaults::default();
        assert_eq!(image_size(&view(None, None), &none, &cam), (256, 192));
        assert_eq!(image_size(&view(Some(320), None), &none, &cam), (320, 240));
        assert_eq!(image_size(&view(None, Some(300)), &none, &cam), (400, 300));
        assert_eq!(image_size(&view(Some(7), Some(9)), &none, &cam), (7, 9));
    }

    #[test]
    fn flags_override_the_scene_size_which_overrides_the_built_in_one() {
        let cam = Camera { width: 640, height: 480, ..Camera::default() };
        let scene = RenderDefaults { width: Some(320), height: Some(180), ..Default::default() };
        assert_eq!(image_size(&view(None, None), &scene, &cam), (320, 180));
        // A flag for either side replaces the scene's size (the other side follows the aspect).
        assert_eq!(image_size(&view(Some(64), None), &scene, &cam), (64, 48));
        assert_eq!(image_size(&view(None, Some(30)), &scene, &cam), (40, 30));
        let only_width = RenderDefaults { width: Some(100), ..Default::default() };
        assert_eq!(image_size(&view(None, None), &only_width, &cam), (100, 75));
    }

    #[test]
    fn spp_and_depths_come_from_flags_then_the_sidecar_then_built_ins() {
        let args = |reference: bool, spp: Option<u32>, max_depth: Option<i32>| RenderArgs {
            scene: PathBuf::from("s.gltf"),
            output: PathBuf::from("o.exr"),
            spp,
            batches: None,
            seed: 0,
            view: ViewArgs { max_depth, ..view(None, None) },
            reference,
            pass_spp: 64,
            force: false,
            extend: false,
            stop_after_passes: None,
        };
        let d = RenderDefaults { spp: Some(96), reference_spp: Some(8192), max_depth: Some(7), rr_depth: Some(3), ..Default::default() };
        let s = resolve_settings(&args(false, None, None), 16, &d, (1, 1));
        assert_eq!((s.spp, s.max_depth, s.rr_depth), (96, 7, 3));
        assert_eq!(resolve_settings(&args(true, None, None), 1, &d, (1, 1)).spp, 8192);
        let s = resolve_settings(&args(true, Some(5), Some(-1)), 1, &d, (1, 1));
        assert_eq!((s.spp, s.max_depth), (5, -1));
        let s = resolve_settings(&args(false, None, None), 16, &RenderDefaults::default(), (1, 1));
        assert_eq!((s.spp, s.max_depth, s.rr_depth), (64, -1, 5));
    }

    #[test]
    fn scene_hash_ignores_render_defaults_but_not_lights() {
        let scene = cvtrace_render::testing::cornell_box();
        let mut with_defaults = scene.clone();
        with_defaults.set_render_defaults(RenderDefaults { reference_spp: Some(8192), width: Some(320), ..Default::default() });
        assert_eq!(scene_hash(&scene), scene_hash(&with_defaults));
        let plane = |env: Option<f32>| {
            let mut p = cvtrace_render::testing::plane_parts(0.5, 1.0);
            p.environment = env.map(|c| cvtrace_render::Environment::constant(Vec3A::splat(c)).unwrap());
            Scene::from_parts(p).unwrap()
        };
        assert_ne!(scene_hash(&plane(None)), scene_hash(&plane(Some(1.0))));
        assert_ne!(scene_hash(&plane(Some(1.0))), scene_hash(&plane(Some(2.0))));
    }

    #[test]
    fn checkpoint_sits_next_to_the_output() {
        assert_eq!(checkpoint_path(Path::new("out/cbox.ref.exr")), Path::new("out/cbox.ref.checkpoint.exr"));
        assert_eq!(checkpoint_path(Path::new("ref")), Path::new("ref.checkpoint.exr"));
    }
}

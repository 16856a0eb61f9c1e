//! A render session: one scene, loaded once, with its Embree BVH and render threads built once
//! (at the first render that needs them), and any number of renders of it: stream files (paired
//! PT and CRN), progressive references with checkpoints, and plain PT images in the reference's
//! format. Every output records its [`Provenance`], so a later run can tell whether it may reuse,
//! resume or extend it.
//!
//! Settings a job leaves unset come from the scene's sidecar `<stem>.cvtrace.toml` (`[render]`,
//! docs/scene-format.md), then the glTF's `asset.extras.defaultResolution` (size only), then
//! the built-in defaults. Every output is written atomically.
use crate::throughput::PhaseClock;
use cvtrace_embree::{set_flush_denormals, BuildOptions, Device, EmbreeScene};
use cvtrace_render::film::stream_file::{render_to_file, Written};
use cvtrace_render::{
    render_reference_pass, Camera, Define, Intersector, RenderDefaults, RenderError, RenderSettings, Scene, SceneError, StreamRender,
};
use cvtrace_streams::atomic::{check_extension, check_writable};
use cvtrace_streams::checkpoint::{self, checkpoint_path, CheckpointError};
use cvtrace_streams::output_lock::{lock_path_for, OutputLock};
use cvtrace_streams::parts::{write_reference, write_reference_part, PartError, PartSpec};
use cvtrace_streams::reference::ReferenceAccum;
use cvtrace_streams::{Provenance, StreamError};
use glam::Vec3A;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

/// Image width used when neither the job nor the scene gives a size.
pub const DEFAULT_WIDTH: u32 = 256;
/// Samples per pixel when neither the job nor the sidecar gives them.
pub const DEFAULT_SPP: u32 = 64;
/// Path-length defaults when neither the job nor the sidecar gives them.
pub const DEFAULT_MAX_DEPTH: i32 = -1;
pub const DEFAULT_RR_DEPTH: u32 = 5;
/// Batches per stream when the caller has no preference: the estimators' measured default.
pub const DEFAULT_BATCHES: u32 = 16;

/// The batch count for renders of every spp value of `spps` when none is given: the most of
/// [`DEFAULT_BATCHES`], 8, 4, 2, 1 that divides them all ([`DEFAULT_BATCHES`] for none).
pub fn default_batches(spps: &[u32]) -> u32 {
    [DEFAULT_BATCHES, 8, 4, 2, 1].into_iter().find(|b| spps.iter().all(|n| n % b == 0)).unwrap_or(1)
}
/// Samples per pass, and so between checkpoints, of [`ReferenceJob::replacing`].
pub const PLAIN_PASS_SPP: u32 = 256;

/// The version recorded in every output (`cvtrace.version`).
const VERSION: &str = env!("CARGO_PKG_VERSION");

/// How Embree intersects triangles: `robust` is watertight where triangles share an edge;
/// `fast` (Embree's and Mitsuba 3's default, and cvtrace's) is quicker but lets rays that graze
/// a shared edge through. Fast is the default because that is rare on real scenes (0.03–0.73
/// rays per million on the bundled and validation scenes) while robust traversal costs 22–27%
/// of the render's throughput on AVX2 (docs/performance.md has the figures).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Traversal {
    Robust,
    #[default]
    Fast,
}

impl Traversal {
    pub const ALL: [Traversal; 2] = [Traversal::Robust, Traversal::Fast];

    /// The name recorded in output files (`cvtrace.traversal`) and taken by [`str::parse`].
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Robust => "robust",
            Traversal::Fast => "fast",
        }
    }
}

impl std::str::FromStr for Traversal {
    type Err = String;
    fn from_str(s: &str) -> Result<Traversal, String> {
        Traversal::ALL.into_iter().find(|t| t.name() == s).ok_or_else(|| format!("{s:?}: expected robust or fast"))
    }
}

/// What builds the ray caster of a session's scene: Embree for the program, anything that
/// implements [`Intersector`] for tests and experiments (a brute-force tracer needs no library).
pub trait Backend: Sync {
    type Tracer: Intersector + Send + Sync;
    /// The name in the log and in errors ("Embree").
    fn name(&self) -> &'static str;
    /// The ray caster of `scene`, watertight at shared edges when `traversal` is robust.
    fn build(&self, scene: &Scene, traversal: Traversal) -> Result<Self::Tracer, String>;
}

/// Embree, fast or robust traversal, with the default build options.
#[derive(Clone, Copy, Debug, Default)]
pub struct Embree;

impl Backend for Embree {
    type Tracer = EmbreeScene;
    fn name(&self) -> &'static str {
        "Embree"
    }
    fn build(&self, scene: &Scene, traversal: Traversal) -> Result<EmbreeScene, String> {
        let options = BuildOptions { robust: traversal == Traversal::Robust, ..BuildOptions::default() };
        Device::new().and_then(|device| device.build_scene(scene.positions(), scene.triangles(), &options)).map_err(|e| e.to_string())
    }
}

/// A camera that replaces the scene's: eye, target and vertical field of view (its up vector
/// and aspect stay the scene's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraView {
    pub eye: Vec3A,
    pub target: Vec3A,
    pub vfov_deg: f32,
}

/// What is fixed for every render of a session: it changes the scene or its BVH.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionOptions {
    pub camera: Option<CameraView>,
    pub traversal: Traversal,
    /// `-D key=value` overrides of the scene sidecar's settings, applied in order.
    pub defines: Vec<Define>,
}

/// Image size and path-length limits of a job; `None` takes the scene's default, then the
/// built-in one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct View {
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Longest path in segments from the camera (Mitsuba convention), −1 unlimited.
    pub max_depth: Option<i32>,
    /// Path depth at which Russian roulette starts.
    pub rr_depth: Option<u32>,
}

/// A stream file: PT and CRN, `spp` samples each in `batches` batches.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamJob {
    pub output: PathBuf,
    pub view: View,
    /// `None`: the sidecar's `spp`, else [`DEFAULT_SPP`].
    pub spp: Option<u32>,
    pub batches: u32,
    pub seed: u64,
    /// Replace an existing output.
    pub overwrite: bool,
    /// Render only this part's batches into a part file (`cvtrace merge` joins the parts).
    pub part: Option<PartSpec>,
}

/// A PT-only image in the reference format (R, G, B), rendered progressively in passes of
/// `pass_spp` samples with a checkpoint next to the output after every pass but the last, and
/// resumed from that checkpoint when one is there.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceJob {
    pub output: PathBuf,
    pub view: View,
    /// `None`: the sidecar's `reference_spp`, else [`DEFAULT_SPP`].
    pub spp: Option<u32>,
    pub seed: u64,
    pub pass_spp: u32,
    pub overwrite: bool,
    /// Continue the finished reference at `output` up to `spp` samples and replace it.
    pub extend: bool,
    /// Stop (keeping the checkpoint) after this many passes.
    pub stop_after_passes: Option<u32>,
    /// Render only this part's passes into a part file (no checkpoint: a part is one job of
    /// a farm, which reruns it whole).
    pub part: Option<PartSpec>,
    /// What the render is called in the log ("a reference", "a PT(2n) image").
    pub label: &'static str,
}

impl ReferenceJob {
    /// A reference or plain PT render of `spp` samples that replaces `output`, checkpointed
    /// every [`PLAIN_PASS_SPP`] samples.
    pub fn replacing(output: PathBuf, view: View, spp: u32, seed: u64) -> ReferenceJob {
        ReferenceJob {
            output,
            view,
            spp: Some(spp),
            seed,
            pass_spp: spp.clamp(1, PLAIN_PASS_SPP),
            overwrite: true,
            extend: false,
            stop_after_passes: None,
            part: None,
            label: "a reference",
        }
    }
}

/// Any render a session runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Job {
    Streams(StreamJob),
    Reference(ReferenceJob),
}

impl Job {
    pub fn output(&self) -> &Path {
        match self {
            Job::Streams(j) => &j.output,
            Job::Reference(j) => &j.output,
        }
    }

    /// The checks of the output that need no scene: its name, that it may be written (and
    /// replaced only if the job says so), and for a reference its checkpoint's place and, to
    /// extend, that there is a reference. Rendering checks again; a caller may check first
    /// to fail before loading the scene.
    pub fn check_outputs(&self) -> Result<(), SessionError> {
        match self {
            Job::Streams(j) => {
                check_extension(&j.output, "exr")?;
                check_writable(&j.output, j.overwrite)?;
            }
            Job::Reference(j) => {
                if j.extend && !j.output.is_file() {
                    return Err(SessionError::Invalid(format!(
                        "{}: --extend continues a finished reference, and there is none at this path",
                        j.output.display()
                    )));
                }
                check_extension(&j.output, "exr")?;
                check_writable(&j.output, j.overwrite || j.extend)?;
                let checkpoint = checkpoint_path(&j.output);
                if checkpoint.is_dir() {
                    return Err(SessionError::Invalid(format!("{}: the checkpoint path is a directory", checkpoint.display())));
                }
                // The checkpoint is replaced after every pass, so its location must be writable too.
                check_writable(&checkpoint, true)?;
            }
        }
        Ok(())
    }
}

/// A job's resolved settings and what its output will record.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub settings: RenderSettings,
    pub provenance: Provenance,
}

/// How a reference job ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceOutcome {
    /// The output holds `spp` samples per pixel.
    Finished { spp: u32 },
    /// Stopped as asked after `passes` passes; the checkpoint holds `samples_done` samples.
    Stopped { passes: u32, samples_done: u32, spp: u32 },
}

/// Where a render reports its progress (a terminal progress bar, or nothing).
pub trait Progress: Sync {
    /// A render of `total` pixel-samples starts with `done` of them done.
    fn start(&self, _total: u64, _done: u64) {}
    /// `samples` more pixel-samples are done (called from the render threads).
    fn advance(&self, _samples: u64) {}
    /// Runs `f` (a checkpoint write, which may log) with the progress display out of the way.
    fn suspend(&self, f: &mut dyn FnMut()) {
        f()
    }
    /// The render ended (finished, stopped or failed).
    fn finish(&self) {}
}

/// No progress reporting.
pub struct NoProgress;
impl Progress for NoProgress {}

/// Why a session or one of its renders failed.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    File(#[from] StreamError),
    #[error("building the {backend} BVH: {message}")]
    Bvh { backend: &'static str, message: String },
    /// The camera override makes no usable camera.
    #[error("the camera override: {0}")]
    Camera(String),
    /// The cause is part of the message (not a `source`), so `{:#}` chains print it once.
    #[error("{scene}: settings from the command line and the scene: {cause}")]
    Settings { scene: PathBuf, cause: RenderError },
    #[error("cannot start {threads} render threads (ask for fewer with --threads): {message}")]
    Threads { threads: usize, message: String },
    #[error(transparent)]
    Part(#[from] PartError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("{0}")]
    Invalid(String),
}

/// The BVH and the render threads, made at the first render.
struct Engine<T> {
    tracer: T,
    pool: rayon::ThreadPool,
}

/// One scene, loaded once, and the renders of it (see the module doc). The renders run one at
/// a time, each on the session's own thread pool, with the ray caster `B` builds (Embree by
/// default).
pub struct RenderSession<B: Backend = Embree> {
    path: PathBuf,
    scene: Scene,
    traversal: Traversal,
    /// [`Scene::fingerprint`] of the scene as rendered (camera override applied), in hex.
    scene_hash: String,
    backend: B,
    engine: OnceLock<Engine<B::Tracer>>,
    bvh_builds: AtomicU32,
}

impl RenderSession {
    /// Loads the scene at `path` and applies `options`' camera. The BVH is built at the first
    /// render, so a session whose outputs all exist already never builds one.
    pub fn new(path: &Path, options: &SessionOptions) -> Result<RenderSession, SessionError> {
        RenderSession::with_backend(path, options, Embree)
    }
}

impl<B: Backend> RenderSession<B> {
    /// [`RenderSession::new`] with another ray caster.
    pub fn with_backend(path: &Path, options: &SessionOptions, backend: B) -> Result<RenderSession<B>, SessionError> {
        // Denormal flushing in this thread too, for any work rayon runs on the caller.
        set_flush_denormals();
        let t = Instant::now();
        let mut scene = Scene::load_with(path, &options.defines)?;
        tracing::info!(
            "loaded {} in {:.1} ms: {} triangles, {} materials",
            path.display(),
            ms(t),
            scene.triangles().len(),
            scene.materials().len()
        );
        if let Some(view) = options.camera {
            let c = scene.camera().clone();
            let camera = Camera { eye: view.eye, target: view.target, vfov_deg: view.vfov_deg, ..c };
            camera.validate().map_err(SessionError::Camera)?;
            scene.set_camera(camera);
        }
        // pbrt and Mitsuba users expect a view of the scene; this one may see a closed room
        // from outside, which is black: say where it is and how to give another.
        if scene.has_automatic_camera() {
            let c = scene.camera();
            tracing::warn!(
                "{}: no camera in the scene; rendering from an automatic one that frames the scene's bounds from +Z \
                 (eye {}, target {}, vertical field of view {}°; a closed room seen from outside is black); give another view \
                 with --camera \"ex,ey,ez:tx,ty,tz:fov\"",
                path.display(),
                c.eye,
                c.target,
                c.vfov_deg
            );
        }
        let scene_hash = scene_hash(&scene);
        Ok(RenderSession {
            path: path.to_path_buf(),
            scene,
            traversal: options.traversal,
            scene_hash,
            backend,
            engine: OnceLock::new(),
            bvh_builds: AtomicU32::new(0),
        })
    }

    /// The scene as rendered (camera override applied).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// How many times this session built the Embree BVH: 0 before its first render, 1 after.
    pub fn bvh_builds(&self) -> u32 {
        self.bvh_builds.load(Ordering::Relaxed)
    }

    /// The settings `job` resolves to with this scene's defaults, checked (memory included),
    /// and the provenance its output will record.
    pub fn plan(&self, job: &Job) -> Result<Plan, SessionError> {
        let (view, spp, batches, seed, reference) = match job {
            Job::Streams(j) => (&j.view, j.spp, j.batches, j.seed, false),
            Job::Reference(j) => (&j.view, j.spp, 1, j.seed, true),
        };
        let size = image_size(view, self.scene.render_defaults(), self.scene.camera());
        let settings = resolve_settings(view, spp, batches, seed, reference, self.scene.render_defaults(), size);
        settings.validate().map_err(|cause| SessionError::Settings { scene: self.path.clone(), cause })?;
        check_memory(job, &settings)?;
        let c = self.scene.camera();
        let provenance = Provenance {
            width: settings.width,
            height: settings.height,
            seed: Some(settings.seed),
            max_depth: Some(settings.max_depth),
            rr_depth: Some(settings.rr_depth),
            scene_hash: Some(self.scene_hash.clone()),
            camera: Some(format!("eye {} target {} up {} vfov {}", c.eye, c.target, c.up, c.vfov_deg)),
            traversal: Some(self.traversal.name().into()),
            spp: Some(settings.spp),
            batches: (!reference).then_some(settings.batches),
            version: Some(VERSION.into()),
        };
        Ok(Plan { settings, provenance })
    }

    /// Renders `job` (a reference job that is not told to stop always finishes).
    pub fn render(&self, job: &Job, progress: &dyn Progress) -> Result<(), SessionError> {
        match job {
            Job::Streams(j) => self.render_streams(j, progress),
            Job::Reference(j) => self.render_reference(j, progress).map(|_| ()),
        }
    }

    /// Renders the stream file of `job`.
    pub fn render_streams(&self, job: &StreamJob, progress: &dyn Progress) -> Result<(), SessionError> {
        let whole = Job::Streams(job.clone());
        whole.check_outputs()?;
        let plan = self.plan(&whole)?;
        let s = &plan.settings;
        // Claimed for the whole render: a second process on the same output fails at once
        // instead of rendering in full and then finding the file taken.
        let _claim = OutputLock::acquire(&lock_path_for(&job.output), &job.output)?;
        let engine = self.engine()?;
        let batches = match job.part {
            Some(spec) => spec.range(s.batches, "batches")?,
            None => 0..s.batches,
        };
        let total = s.width as u64 * s.height as u64 * (s.spp / s.batches * batches.len() as u32) as u64 * 2;
        tracing::info!(
            "rendering {}x{}, {} spp x 2 streams ({}), max depth {}, seed {} on {} threads",
            s.width,
            s.height,
            s.spp,
            match job.part {
                Some(spec) => format!("part {spec}: batches {}..{} of {}", batches.start, batches.end, s.batches),
                None => format!("{} batches", s.batches),
            },
            s.max_depth,
            s.seed,
            engine.pool.current_num_threads()
        );
        progress.start(total, 0);
        let clock = PhaseClock::start();
        let scene = self.path.to_string_lossy().into_owned();
        // Rendered straight into the file, band by band: the image is never held whole.
        let result = engine.pool.install(|| -> Result<Written, SessionError> {
            let render = StreamRender::new(&self.scene, &engine.tracer, s, batches)?;
            Ok(render_to_file(&render, &job.output, &plan.provenance, &scene, job.part, job.overwrite, &|k| progress.advance(k))?)
        });
        progress.finish();
        let written = result?;
        // The phase includes compressing the file, which runs alongside the rendering.
        clock.log_rate("render and write", total);
        tracing::info!("wrote {} while rendering; {:.1} ms after the last sample", job.output.display(), written.tail.as_secs_f64() * 1e3);
        Ok(())
    }

    /// Renders (or resumes, or extends) the reference of `job`. The output is claimed for the
    /// whole render: a second process on it fails at once.
    pub fn render_reference(&self, job: &ReferenceJob, progress: &dyn Progress) -> Result<ReferenceOutcome, SessionError> {
        if job.pass_spp == 0 {
            return Err(SessionError::Invalid("--pass-spp must be at least 1".into()));
        }
        let whole = Job::Reference(job.clone());
        whole.check_outputs()?;
        let plan = self.plan(&whole)?;
        let s = &plan.settings;
        // A reference takes many passes and a checkpoint: a second process on the same output
        // would repeat the work and race over both files.
        let _claim = OutputLock::acquire(&lock_path_for(&job.output), &job.output)?;
        if let Some(spec) = job.part {
            return self.render_reference_part(job, spec, &plan, progress);
        }
        let checkpoint = checkpoint_path(&job.output);
        // An interrupted extension left a checkpoint, which is exact: it comes first.
        let mut accum = match checkpoint::load(&checkpoint, &plan.provenance, &s.reference())? {
            Some(a) => {
                if a.samples_done > s.spp {
                    return Err(SessionError::Invalid(format!(
                        "{}: the checkpoint already holds {} spp, more than --spp {}; render with --spp {} or delete it to start the reference over",
                        checkpoint.display(),
                        a.samples_done,
                        s.spp,
                        a.samples_done
                    )));
                }
                tracing::info!("resuming from {} at {} of {} spp", checkpoint.display(), a.samples_done, s.spp);
                a
            }
            None if job.extend => {
                let a = checkpoint::load_finished(&job.output, &plan.provenance, &s.reference())?;
                tracing::info!("extending {} from {} to {} spp", job.output.display(), a.samples_done, s.spp);
                a
            }
            None => ReferenceAccum::new(&s.reference()),
        };
        let engine = self.engine()?;
        let pixels = s.width as u64 * s.height as u64;
        tracing::info!(
            "rendering {} {}x{}, {} spp in passes of {}, max depth {}, seed {} on {} threads",
            job.label,
            s.width,
            s.height,
            s.spp,
            job.pass_spp,
            s.max_depth,
            s.seed,
            engine.pool.current_num_threads()
        );
        progress.start(pixels * s.spp as u64, pixels * accum.samples_done as u64);
        let clock = PhaseClock::start();
        let start_samples = accum.samples_done;
        let mut passes = 0;
        while accum.samples_done < s.spp {
            let range = accum.samples_done..accum.samples_done.saturating_add(job.pass_spp).min(s.spp);
            let r =
                engine.pool.install(|| render_reference_pass(&self.scene, &engine.tracer, s, &mut accum, range, &|k| progress.advance(k)));
            if let Err(e) = r {
                progress.finish();
                return Err(e.into());
            }
            passes += 1;
            let done = accum.samples_done >= s.spp;
            if !done {
                let mut saved = Ok(());
                progress.suspend(&mut || saved = save_checkpoint(&checkpoint, &accum, &plan.provenance));
                if let Err(e) = saved {
                    progress.finish();
                    return Err(e);
                }
            }
            if !done && job.stop_after_passes.is_some_and(|n| passes >= n) {
                progress.finish();
                return Ok(ReferenceOutcome::Stopped { passes, samples_done: accum.samples_done, spp: s.spp });
            }
        }
        progress.finish();
        clock.log_rate("render", pixels * (accum.samples_done - start_samples) as u64);

        let t = Instant::now();
        // The provenance (scene hash and camera included) lets a later --extend check what it continues.
        let scene = self.path.to_string_lossy();
        if let Err(e) = write_reference(&job.output, &accum, &plan.provenance, &scene, job.overwrite || job.extend) {
            // Keep the finished work: the next run with the same settings only has to write.
            let _ = save_checkpoint(&checkpoint, &accum, &plan.provenance);
            return Err(e.into());
        }
        tracing::info!("wrote {} in {:.1} ms", job.output.display(), ms(t));
        if checkpoint.exists() {
            std::fs::remove_file(&checkpoint)
                .map_err(|e| SessionError::Invalid(format!("{}: could not remove the finished checkpoint: {e}", checkpoint.display())))?;
        }
        Ok(ReferenceOutcome::Finished { spp: accum.samples_done })
    }

    /// Renders the passes of part `spec` of the reference of `job` into a part file.
    fn render_reference_part(
        &self,
        job: &ReferenceJob,
        spec: PartSpec,
        plan: &Plan,
        progress: &dyn Progress,
    ) -> Result<ReferenceOutcome, SessionError> {
        if job.extend || job.stop_after_passes.is_some() {
            return Err(SessionError::Invalid("--part renders a range of passes in one go: no --extend or --stop-after-passes".into()));
        }
        let s = &plan.settings;
        let passes = spec.range(s.spp.div_ceil(job.pass_spp), "passes")?;
        let samples = passes.start * job.pass_spp..(passes.end * job.pass_spp).min(s.spp);
        let engine = self.engine()?;
        let pixels = s.width as u64 * s.height as u64;
        tracing::info!(
            "rendering part {spec} of a reference {}x{}: passes {}..{} of {} spp each (samples {}..{} of {}), seed {} on {} threads",
            s.width,
            s.height,
            passes.start,
            passes.end,
            job.pass_spp,
            samples.start,
            samples.end,
            s.spp,
            s.seed,
            engine.pool.current_num_threads()
        );
        let mut accum = ReferenceAccum { first: samples.start, ..ReferenceAccum::new(&s.reference()) };
        progress.start(pixels * samples.len() as u64, 0);
        let clock = PhaseClock::start();
        for pass in passes.clone() {
            let range = pass * job.pass_spp..((pass + 1) * job.pass_spp).min(s.spp);
            let r =
                engine.pool.install(|| render_reference_pass(&self.scene, &engine.tracer, s, &mut accum, range, &|k| progress.advance(k)));
            if let Err(e) = r {
                progress.finish();
                return Err(e.into());
            }
        }
        progress.finish();
        clock.log_rate("render", pixels * samples.len() as u64);
        let t = Instant::now();
        write_reference_part(&job.output, &accum, &plan.provenance, &self.path.to_string_lossy(), spec, job.overwrite)?;
        tracing::info!("wrote {} in {:.1} ms", job.output.display(), ms(t));
        Ok(ReferenceOutcome::Finished { spp: accum.samples_done })
    }

    /// The BVH and render threads, made on the first call.
    fn engine(&self) -> Result<&Engine<B::Tracer>, SessionError> {
        if let Some(engine) = self.engine.get() {
            return Ok(engine);
        }
        let t = Instant::now();
        let backend = self.backend.name();
        let tracer = self.backend.build(&self.scene, self.traversal).map_err(|message| SessionError::Bvh { backend, message })?;
        self.bvh_builds.fetch_add(1, Ordering::Relaxed);
        tracing::info!(
            "built the {backend} BVH of {} in {:.1} ms ({} triangles, {} traversal)",
            self.path.display(),
            ms(t),
            self.scene.triangles().len(),
            self.traversal.name()
        );
        // FTZ/DAZ in every render thread (Embree's advice), whatever the thread count: a local
        // pool of the configured size (the global one follows --threads) with a start handler.
        let threads = rayon::current_num_threads();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("cvtrace-render-{i}"))
            .start_handler(|_| set_flush_denormals())
            .build()
            .map_err(|e| SessionError::Threads { threads, message: e.to_string() })?;
        Ok(self.engine.get_or_init(|| Engine { tracer, pool }))
    }
}

fn save_checkpoint(path: &Path, accum: &ReferenceAccum, provenance: &Provenance) -> Result<(), SessionError> {
    let t = Instant::now();
    checkpoint::save(path, accum, provenance)?;
    tracing::debug!("checkpoint {} ({} spp) written in {:.1} ms", path.display(), accum.samples_done, ms(t));
    Ok(())
}

/// Fails if the render's images cannot be held in memory here (physical memory, or the address
/// space `ulimit -v` leaves): a 16384×16384 stream file takes more than 100 GiB, and running out
/// half-way aborts the process after all the rendering.
fn check_memory(job: &Job, s: &RenderSettings) -> Result<(), SessionError> {
    let (needed, what, advice) = match job {
        Job::Reference(j) => (s.reference_memory_estimate(j.extend || s.spp > j.pass_spp), String::new(), ""),
        Job::Streams(_) => (s.stream_memory_estimate(), format!(" --batches {}", s.batches), " or with fewer --batches"),
    };
    if !can_allocate(needed) {
        return Err(SessionError::Invalid(format!(
            "--width {} --height {}{what}: the render needs about {:.1} GiB of memory, which cannot be allocated here \
             (physical memory, or the `ulimit -v` limit); render a smaller image{advice}",
            s.width,
            s.height,
            needed as f64 / (1u64 << 30) as f64,
        )));
    }
    Ok(())
}

/// Whether `bytes` can be reserved now (the reservation is given back at once; nothing is touched).
fn can_allocate(bytes: u64) -> bool {
    usize::try_from(bytes).is_ok_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok())
}

/// The scene's [`Scene::fingerprint`]: geometry, materials, textures, lights and camera, not the
/// sidecar's render defaults (the resolved settings are recorded on their own), so editing e.g.
/// `reference_spp` does not orphan a checkpoint.
fn scene_hash(scene: &Scene) -> String {
    scene.fingerprint()
}

/// The settings of a render: the job's values first, then the scene's defaults `d`, then the
/// built-in ones (`reference`: the sidecar's `reference_spp` instead of its `spp`); `size` is
/// already resolved ([`image_size`]).
pub fn resolve_settings(
    view: &View,
    spp: Option<u32>,
    batches: u32,
    seed: u64,
    reference: bool,
    d: &RenderDefaults,
    (width, height): (u32, u32),
) -> RenderSettings {
    let scene_spp = if reference { d.reference_spp } else { d.spp };
    RenderSettings {
        width,
        height,
        spp: spp.or(scene_spp).unwrap_or(DEFAULT_SPP),
        batches,
        seed,
        max_depth: view.max_depth.or(d.max_depth).unwrap_or(DEFAULT_MAX_DEPTH),
        rr_depth: view.rr_depth.or(d.rr_depth).unwrap_or(DEFAULT_RR_DEPTH),
    }
}

/// The render size: the view's wins (if either side is given, the scene's size is not used);
/// else the scene's default size; a missing side follows the camera's aspect ratio.
pub fn image_size(view: &View, defaults: &RenderDefaults, camera: &Camera) -> (u32, u32) {
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

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(width: Option<u32>, height: Option<u32>) -> View {
        View { width, height, ..View::default() }
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
        let v = |max_depth: Option<i32>| View { max_depth, ..View::default() };
        let d = RenderDefaults { spp: Some(96), reference_spp: Some(8192), max_depth: Some(7), rr_depth: Some(3), ..Default::default() };
        let s = resolve_settings(&v(None), None, 16, 0, false, &d, (1, 1));
        assert_eq!((s.spp, s.max_depth, s.rr_depth), (96, 7, 3));
        assert_eq!(resolve_settings(&v(None), None, 1, 0, true, &d, (1, 1)).spp, 8192);
        let s = resolve_settings(&v(Some(-1)), Some(5), 1, 0, true, &d, (1, 1));
        assert_eq!((s.spp, s.max_depth), (5, -1));
        let s = resolve_settings(&v(None), None, 16, 0, false, &RenderDefaults::default(), (1, 1));
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
}

//! `cvtrace.render` and `cvtrace.render_reference`: a render session's jobs, as `cvtrace render`
//! runs them, into a file the caller names or a temporary one, read back into numpy.
use crate::errors::Error;
use crate::run::{run, CancellingProgress};
use crate::streams::Streams;
use anyhow::{bail, Context};
use cvtrace_render::{Define, RenderDefaults};
use cvtrace_session::{self as session, CameraView, Job, ReferenceJob, RenderSession, SessionOptions, StreamJob, Traversal, View};
use cvtrace_streams::{Provenance, StreamSet};
use glam::Vec3A;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::{Path, PathBuf};

/// What is rendered: the scene, its camera, traversal and `-D` overrides, and the view.
pub struct Setup {
    pub scene: PathBuf,
    pub options: SessionOptions,
    pub view: View,
}

impl Setup {
    /// The keyword arguments of a render as the CLI's flags: `defines` are `-D key=value`
    /// (`max_depth=8`, `**{"environment.color": (1, 1, 1)}`).
    pub fn new(
        scene: PathBuf,
        width: Option<u32>,
        height: Option<u32>,
        camera: Option<&Bound<'_, PyAny>>,
        traversal: &str,
        defines: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Setup> {
        let traversal: Traversal = traversal.parse().map_err(|e| PyValueError::new_err(format!("traversal={traversal:?}: {e}")))?;
        let mut list = Vec::new();
        if let Some(d) = defines {
            for (k, v) in d.iter() {
                let key: String = k.extract()?;
                list.push(Define { key, value: define_value(&v)? });
            }
        }
        cvtrace_render::scene::sidecar::check_define_keys(&list).map_err(|e| Error::new_err(e.to_string()))?;
        let max_depth = defined(&list, "max_depth");
        let rr_depth = defined(&list, "rr_depth");
        let camera = camera.map(camera_view).transpose()?;
        Ok(Setup {
            scene,
            options: SessionOptions { camera, traversal, defines: list },
            // Path limits come through `-D` (the sidecar's settings); the size may be given
            // either way, the argument winning as a flag does.
            view: View { width, height, max_depth, rr_depth },
        })
    }

    /// The render session (the scene loaded, its BVH built at the first render).
    pub fn session(&self) -> anyhow::Result<RenderSession> {
        RenderSession::new(&self.scene, &self.options).map_err(|e| match e {
            cvtrace_session::SessionError::Camera(m) => anyhow::anyhow!("camera: {m}"),
            e => e.into(),
        })
    }

    /// The value of the last define of `key`, if it parses (a bad one fails when the scene loads).
    pub fn defined<T: std::str::FromStr>(&self, key: &str) -> Option<T> {
        defined(&self.options.defines, key)
    }
}

fn defined<T: std::str::FromStr>(defines: &[Define], key: &str) -> Option<T> {
    defines.iter().rev().find(|d| d.canonical_key() == Some(key)).and_then(|d| d.value.parse().ok())
}

/// A define's value as `-D` takes it: text as it is, a sequence as `a,b,c`, a number as Python
/// writes it (which parses back to the same number).
fn define_value(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(s) = v.extract::<String>() {
        return Ok(s);
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let parts: Vec<String> = v.try_iter()?.map(|x| x.and_then(|x| Ok(x.str()?.to_string()))).collect::<PyResult<_>>()?;
        return Ok(parts.join(","));
    }
    Ok(v.str()?.to_string())
}

/// `camera=(eye, target, vfov_degrees)`, eye and target as three numbers each.
fn camera_view(v: &Bound<'_, PyAny>) -> PyResult<CameraView> {
    let usage = "camera: expected (eye, target, vfov_degrees), e.g. ((278, 273, -800), (278, 273, 0), 37)";
    let (eye, target, vfov_deg): ((f32, f32, f32), (f32, f32, f32), f32) = v.extract().map_err(|_| PyValueError::new_err(usage))?;
    let eye = Vec3A::new(eye.0, eye.1, eye.2);
    let target = Vec3A::new(target.0, target.1, target.2);
    if !(eye.is_finite() && target.is_finite() && vfov_deg.is_finite()) {
        return Err(PyValueError::new_err(usage));
    }
    Ok(CameraView { eye, target, vfov_deg })
}

/// Fails unless `bytes` can be reserved now: a stream set read into memory whole, so that a
/// render too large for it fails before it starts instead of aborting the interpreter after.
fn check_memory(bytes: u64, what: &str) -> anyhow::Result<()> {
    if !usize::try_from(bytes).is_ok_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok()) {
        bail!(
            "{what}: about {:.1} GiB in memory, which cannot be allocated here; render a smaller image, fewer batches, or into a file (output=...)",
            bytes as f64 / (1u64 << 30) as f64
        );
    }
    Ok(())
}

/// A temporary folder for a render the caller does not keep, removed when dropped.
fn scratch() -> anyhow::Result<tempfile::TempDir> {
    tempfile::Builder::new().prefix("cvtrace-").tempdir().context("cannot make a temporary folder for the render")
}

#[allow(clippy::too_many_arguments)]
pub fn render_streams(
    setup: &Setup,
    spp: Option<u32>,
    batches: Option<u32>,
    seed: u64,
    output: Option<PathBuf>,
    overwrite: bool,
    cancel: &std::sync::Arc<crate::run::Cancel>,
) -> anyhow::Result<Streams> {
    let batches = match batches {
        Some(b) => b,
        None => session::default_batches(&spp.or(setup.defined("spp")).into_iter().collect::<Vec<_>>()),
    };
    // The arguments alone first (the scene's defaults are filled in once it loads).
    let flag_size = (setup.view.width.unwrap_or(session::DEFAULT_WIDTH), setup.view.height.unwrap_or(session::DEFAULT_WIDTH));
    let mut provisional = session::resolve_settings(&setup.view, spp, batches, seed, false, &RenderDefaults::default(), flag_size);
    provisional.spp = spp.unwrap_or(batches);
    provisional.validate()?;
    let dir = if output.is_none() { Some(scratch()?) } else { None };
    let path = output.clone().unwrap_or_else(|| dir.as_ref().expect("made above").path().join("render.streams.exr"));
    let job = StreamJob { output: path.clone(), view: setup.view, spp, batches, seed, overwrite, part: None };
    let whole = Job::Streams(job.clone());
    whole.check_outputs()?;
    let session = setup.session()?;
    let plan = session.plan(&whole)?;
    let s = &plan.settings;
    let planes = 2 * (s.batches as u64 + 1) * 3 + 7;
    check_memory(s.width as u64 * s.height as u64 * planes * 4, &format!("{}x{}, {} batches", s.width, s.height, s.batches))?;
    session.render_streams(&job, &CancellingProgress(cancel.clone()))?;
    let set = StreamSet::read(&path)?;
    let provenance = Provenance::read_header(&path)?;
    let origin = match &output {
        Some(p) => p.display().to_string(),
        None => format!("cvtrace.render({})", setup.scene.display()),
    };
    Ok(Streams::new(set, Some(provenance), origin))
}

pub fn render_reference(
    setup: &Setup,
    spp: Option<u32>,
    seed: u64,
    output: Option<PathBuf>,
    overwrite: bool,
    cancel: &std::sync::Arc<crate::run::Cancel>,
) -> anyhow::Result<cvtrace_streams::Image> {
    let dir = if output.is_none() { Some(scratch()?) } else { None };
    let path = output.unwrap_or_else(|| dir.as_ref().expect("made above").path().join("render.exr"));
    let spp = spp.or(setup.defined("reference_spp"));
    let job =
        ReferenceJob { spp, overwrite, ..ReferenceJob::replacing(path.clone(), setup.view, spp.unwrap_or(session::DEFAULT_SPP), seed) };
    let job = ReferenceJob { pass_spp: job.spp.unwrap_or(session::DEFAULT_SPP).clamp(1, session::PLAIN_PASS_SPP), ..job };
    Job::Reference(job.clone()).check_outputs()?;
    let session = setup.session()?;
    session.render_reference(&job, &CancellingProgress(cancel.clone()))?;
    Ok(cvtrace_streams::exr_io::read_rgb(&path)?)
}

/// Renders the paired PT and CRN streams of ``scene`` (glTF 2.0, with its sidecar
/// ``scene.cvtrace.toml``), as ``cvtrace render`` does, and returns them as ``Streams``.
///
/// Args:
///     scene: the ``.gltf`` or ``.glb`` file.
///     spp: samples per pixel of each stream (default: the sidecar's ``spp``, else 64).
///     batches: batches per stream, dividing ``spp`` (default: the most of 16, 8, 4, 2, 1 that does).
///     seed: the same seed and settings give bit-identical streams, for any thread count.
///     width, height: the image size (default: the scene's; one side alone keeps the camera's aspect).
///     threads: worker threads (default: all cores).
///     output: also keep the stream file here (``.exr``, written atomically); by default the
///         render goes through a temporary file that is removed.
///     overwrite: replace an existing ``output``.
///     camera: ``(eye, target, vfov_degrees)`` instead of the scene's camera.
///     traversal: ``"fast"`` (Embree's default) or ``"robust"`` (watertight at shared edges).
///     **defines: ``-D`` overrides of the sidecar: ``max_depth=8``, ``rr_depth=5``,
///         ``**{"environment.color": (1, 1, 1)}``, ...
///
/// Returns:
///     Streams: ``pt``, ``crn`` (H, W, 3), ``pt_batches``, ``crn_batches`` (B, H, W, 3),
///     ``albedo``, ``normal``, ``depth``, ``provenance``.
///
/// Raises:
///     cvtrace.Error: with the message of ``cvtrace render``. Ctrl-C raises KeyboardInterrupt
///     and leaves no partial file.
#[pyfunction]
#[pyo3(signature = (scene, spp = None, batches = None, seed = 0, width = None, height = None, threads = None, *, output = None, overwrite = false, camera = None, traversal = "fast", **defines))]
#[allow(clippy::too_many_arguments)]
pub fn render(
    py: Python<'_>,
    scene: PathBuf,
    spp: Option<u32>,
    batches: Option<u32>,
    seed: u64,
    width: Option<u32>,
    height: Option<u32>,
    threads: Option<usize>,
    output: Option<PathBuf>,
    overwrite: bool,
    camera: Option<&Bound<'_, PyAny>>,
    traversal: &str,
    defines: Option<&Bound<'_, PyDict>>,
) -> PyResult<Streams> {
    let setup = Setup::new(scene, width, height, camera, traversal, defines)?;
    run(py, threads, |cancel| render_streams(&setup, spp, batches, seed, output, overwrite, cancel))
}

/// Renders a plain path-traced image of ``scene`` (PT only, ``spp`` samples per pixel), as
/// ``cvtrace render --reference`` does: a reference, or PT at the same total samples as a
/// stream pair (``2 * spp``). Returns an (H, W, 3) float32 array.
///
/// The arguments are those of ``render`` (``spp`` defaults to the sidecar's ``reference_spp``);
/// with ``output`` the image is kept as an EXR, and a render interrupted there resumes from
/// its checkpoint when called again.
#[pyfunction]
#[pyo3(name = "render_reference", signature = (scene, spp = None, seed = 0, width = None, height = None, threads = None, *, output = None, overwrite = false, camera = None, traversal = "fast", **defines))]
#[allow(clippy::too_many_arguments)]
pub fn render_reference_py(
    py: Python<'_>,
    scene: PathBuf,
    spp: Option<u32>,
    seed: u64,
    width: Option<u32>,
    height: Option<u32>,
    threads: Option<usize>,
    output: Option<PathBuf>,
    overwrite: bool,
    camera: Option<&Bound<'_, PyAny>>,
    traversal: &str,
    defines: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let setup = Setup::new(scene, width, height, camera, traversal, defines)?;
    let image = run(py, threads, |cancel| render_reference(&setup, spp, seed, output, overwrite, cancel))?;
    Ok(crate::arrays::to_numpy(py, image)?.unbind())
}

/// The scene's name from its file, as `cvtrace study` makes it: the folder of a `scene.gltf`.
pub fn scene_name(scene: &Path) -> String {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    if stem == "scene" {
        if let Some(dir) = scene.parent().and_then(|p| p.file_name()) {
            return dir.to_string_lossy().into_owned();
        }
    }
    stem
}

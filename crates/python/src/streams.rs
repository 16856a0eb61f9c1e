//! `cvtrace.Streams`: a stream set (the PT and CRN streams, their batch means, the first-hit
//! features) with its provenance, read-only from Python.
use crate::arrays;
use crate::run::run;
use cvtrace_reconstruct::stream_set_from_batches;
use cvtrace_streams::iduw_layout::{parse_iduw_name, read_iduw};
use cvtrace_streams::parts::write_stream_file;
use cvtrace_streams::{Features, Image, Provenance, StreamSet};
use numpy::{PyArray, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// The paired PT and CRN renders of one image: each stream's mean and batch means, the
/// first-hit features (albedo, shading normal, depth) when present, and where they came from.
///
/// Immutable: the arrays are read-only views of the stream set (``np.asarray(s.pt)`` copies
/// nothing; ``s.pt.copy()`` gives an array to change). Make one with ``cvtrace.render``,
/// ``Streams.read`` or ``Streams.from_arrays``.
#[pyclass(module = "cvtrace", name = "Streams", frozen)]
pub struct Streams {
    pub set: Arc<StreamSet>,
    /// What the renderer recorded about the render (cvtrace's renders and files), if known.
    pub provenance: Option<Provenance>,
    /// What the streams are called in messages: their file, or how they were made.
    pub origin: String,
    pt_batches: OnceLock<Py<PyAny>>,
    crn_batches: OnceLock<Py<PyAny>>,
}

impl Streams {
    pub fn new(set: StreamSet, provenance: Option<Provenance>, origin: String) -> Streams {
        Streams { set: Arc::new(set), provenance, origin, pt_batches: OnceLock::new(), crn_batches: OnceLock::new() }
    }

    /// Reads a stream file, or IDUW's input layout when the name follows it (as `cvtrace
    /// reconstruct` does).
    pub fn read_file(path: &Path) -> anyhow::Result<Streams> {
        let set = match parse_iduw_name(path) {
            Some((dir, scene, spp)) => read_iduw(&dir, &scene, spp)?,
            None => StreamSet::read(path)?,
        };
        let provenance = if parse_iduw_name(path).is_none() { Some(Provenance::read_header(path)?) } else { None };
        Ok(Streams::new(set, provenance, path.display().to_string()))
    }
}

fn image_view<'py>(slf: &Bound<'py, Streams>, image: &Image) -> PyResult<Bound<'py, PyAny>> {
    arrays::view(slf.clone().into_any(), (image.height, image.width, 3), image.pixels.as_flattened())
}

/// The batches of a stream as one read-only (B, H, W, 3) array (a copy: the batches are
/// separate images in the stream set), made on first use.
fn batches<'py>(slf: &Bound<'py, Streams>, cache: &OnceLock<Py<PyAny>>, list: &[Image]) -> PyResult<Bound<'py, PyAny>> {
    let py = slf.py();
    if let Some(a) = cache.get() {
        return Ok(a.bind(py).clone());
    }
    let (w, h) = (list[0].width, list[0].height);
    let flat: Vec<f32> = list.iter().flat_map(|im| im.pixels.as_flattened().iter().copied()).collect();
    let array = PyArray::from_vec(py, flat).reshape([list.len(), h, w, 3])?;
    array.getattr("flags")?.setattr("writeable", false)?;
    let array = array.into_any().unbind();
    Ok(cache.get_or_init(|| array).bind(py).clone())
}

#[pymethods]
impl Streams {
    /// The PT stream's mean, (H, W, 3) float32: independent random numbers in every pixel.
    #[getter]
    fn pt<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        image_view(slf, &slf.get().set.pt.mean)
    }

    /// The CRN stream's mean, (H, W, 3) float32: sample ``s`` of every pixel uses the same random numbers.
    #[getter]
    fn crn<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        image_view(slf, &slf.get().set.crn.mean)
    }

    /// The PT stream's batch means, (B, H, W, 3) float32 (equal sample counts per batch).
    #[getter]
    fn pt_batches<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let s = slf.get();
        batches(slf, &s.pt_batches, &s.set.pt.batches)
    }

    /// The CRN stream's batch means, (B, H, W, 3) float32.
    #[getter]
    fn crn_batches<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let s = slf.get();
        batches(slf, &s.crn_batches, &s.set.crn.batches)
    }

    /// First-hit albedo, (H, W, 3) float32, or None without features.
    #[getter]
    fn albedo<'py>(slf: &Bound<'py, Self>) -> PyResult<Option<Bound<'py, PyAny>>> {
        slf.get().set.features.as_ref().map(|f| image_view(slf, &f.albedo)).transpose()
    }

    /// First-hit shading normal, (H, W, 3) float32, or None without features.
    #[getter]
    fn normal<'py>(slf: &Bound<'py, Self>) -> PyResult<Option<Bound<'py, PyAny>>> {
        slf.get().set.features.as_ref().map(|f| image_view(slf, &f.normal)).transpose()
    }

    /// First-hit depth, (H, W) float32, or None without features.
    #[getter]
    fn depth<'py>(slf: &Bound<'py, Self>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let set = &slf.get().set;
        set.features.as_ref().map(|f| arrays::view(slf.clone().into_any(), (set.height, set.width), &f.depth)).transpose()
    }

    #[getter]
    fn width(&self) -> usize {
        self.set.width
    }

    #[getter]
    fn height(&self) -> usize {
        self.set.height
    }

    /// Batches per stream (B).
    #[getter]
    fn batches(&self) -> usize {
        self.set.batch_count()
    }

    /// Samples per pixel of each stream (0: unknown).
    #[getter]
    fn spp(&self) -> u32 {
        self.set.meta.spp
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.set.meta.seed
    }

    /// Longest path in segments from the camera (Mitsuba's convention), -1 unlimited.
    #[getter]
    fn max_depth(&self) -> i32 {
        self.set.meta.max_depth
    }

    /// The scene the streams were rendered from, as recorded.
    #[getter]
    fn scene(&self) -> &str {
        &self.set.meta.scene
    }

    /// The cvtrace version that rendered the streams, as recorded.
    #[getter]
    fn version(&self) -> &str {
        &self.set.meta.version
    }

    /// Samples that were NaN or infinite and were replaced by zero, over both streams.
    #[getter]
    fn non_finite_samples(&self) -> u64 {
        self.set.meta.non_finite_samples
    }

    /// Where the streams came from: their file, or how they were made.
    #[getter]
    fn origin(&self) -> &str {
        &self.origin
    }

    /// The renderer's other settings as recorded (``cvtrace.*`` text attributes of the file).
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in &self.set.meta.settings {
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    /// What decides the samples, as cvtrace records it (size, seed, max depth, rr depth, scene
    /// hash, camera, traversal, spp, batches): a dict of text, or None for streams from arrays.
    #[getter]
    fn provenance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(p) = &self.provenance else { return Ok(None) };
        let d = PyDict::new(py);
        for (k, v) in p.fields() {
            d.set_item(k, v)?;
        }
        if let Some(v) = &p.version {
            d.set_item("version", v)?;
        }
        Ok(Some(d))
    }

    /// Reads a stream file (docs/stream-format.md), checked as ``cvtrace reconstruct`` checks it;
    /// IDUW's input layout (``<scene>_<spp>spp_randImg.exr``) is read too.
    #[staticmethod]
    fn read(py: Python<'_>, path: PathBuf) -> PyResult<Streams> {
        run(py, None, |_| Streams::read_file(&path))
    }

    /// Writes the stream file atomically (``overwrite=False`` refuses an existing file), with the
    /// provenance the streams carry. ``Streams.read(path)`` gives the same streams back, bit for bit.
    #[pyo3(signature = (path, overwrite = false))]
    fn write(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<()> {
        let set = self.set.clone();
        let provenance = self.provenance.clone();
        run(py, None, move |_| {
            cvtrace_streams::atomic::check_extension(&path, "exr")?;
            match &provenance {
                Some(p) => write_stream_file(&path, &set, p, overwrite)?,
                None => set.write(&path, overwrite)?,
            }
            Ok(())
        })
    }

    /// Streams from any renderer's buffers: the batch means of both streams as (B, H, W, 3)
    /// arrays (equal sample counts per batch; batch ``b`` of every CRN pixel made with the same
    /// random numbers), optionally the first-hit features, ``spp`` per stream (IDUW needs it)
    /// and what else the file records. The stream means are the means of the batches unless
    /// given. Checked as a stream file is (sizes, batch counts, finite values, means).
    #[staticmethod]
    #[pyo3(signature = (pt_batches, crn_batches, *, albedo = None, normal = None, depth = None, spp = 0, seed = 0, max_depth = -1, scene = String::new(), pt = None, crn = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_arrays(
        py: Python<'_>,
        pt_batches: &Bound<'_, PyAny>,
        crn_batches: &Bound<'_, PyAny>,
        albedo: Option<&Bound<'_, PyAny>>,
        normal: Option<&Bound<'_, PyAny>>,
        depth: Option<&Bound<'_, PyAny>>,
        spp: u32,
        seed: u64,
        max_depth: i32,
        scene: String,
        pt: Option<&Bound<'_, PyAny>>,
        crn: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Streams> {
        let origin = "Streams.from_arrays".to_string();
        let pt_list = arrays::images(py, pt_batches, "pt_batches")?;
        let crn_list = arrays::images(py, crn_batches, "crn_batches")?;
        let features = match (albedo, normal, depth) {
            (None, None, None) => None,
            (Some(a), Some(n), Some(d)) => {
                let (w, h, depth) = arrays::plane(py, d, "depth")?;
                let albedo = arrays::image(py, a, "albedo")?;
                let normal = arrays::image(py, n, "normal")?;
                if (w, h) != (albedo.width, albedo.height) {
                    return Err(PyValueError::new_err(format!(
                        "depth is {w}x{h} but albedo is {}x{}: the features come as one size",
                        albedo.width, albedo.height
                    )));
                }
                Some(Features { albedo, normal, depth })
            }
            _ => return Err(PyValueError::new_err("albedo, normal and depth come together: give all three or none")),
        };
        let mut set = stream_set_from_batches(pt_list, crn_list, spp, features).map_err(|e| crate::errors::error(e.into()))?;
        if let Some(mean) = pt {
            set.pt.mean = arrays::image(py, mean, "pt")?;
        }
        if let Some(mean) = crn {
            set.crn.mean = arrays::image(py, mean, "crn")?;
        }
        set.meta.seed = seed;
        set.meta.max_depth = max_depth;
        set.meta.scene = scene;
        if !(max_depth == -1 || max_depth >= 1) {
            return Err(PyValueError::new_err(format!("max_depth={max_depth}: must be -1 (unlimited) or at least 1")));
        }
        set.validate(Path::new(&origin)).map_err(|e| crate::errors::error(e.into()))?;
        Ok(Streams::new(set, None, origin))
    }

    fn __repr__(&self) -> String {
        let s = &self.set;
        format!(
            "<cvtrace.Streams {}x{}, {} spp per stream in {} batches, seed {}{}, from {}>",
            s.width,
            s.height,
            s.meta.spp,
            s.batch_count(),
            s.meta.seed,
            if s.features.is_some() { ", with features" } else { "" },
            self.origin
        )
    }
}

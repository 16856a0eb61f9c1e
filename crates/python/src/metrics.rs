//! The metrics `cvtrace compare` reports, on arrays, and reading and writing plain images.
use crate::arrays;
use crate::run::run;
use cvtrace_eval::flip::FlipReference;
use cvtrace_eval::Reference;
use cvtrace_streams::Image;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

fn pair(py: Python<'_>, x: &Bound<'_, PyAny>, reference: &Bound<'_, PyAny>) -> PyResult<(Image, Image)> {
    Ok((arrays::image(py, x, "x")?, arrays::image(py, reference, "ref")?))
}

/// relMSE of ``x`` against ``ref``, both (H, W, 3): the mean over pixels and channels of
/// ``(x - r)^2 / (mean(r)^2 + 0.01)``, ``mean(r)`` the pixel's mean over its three channels
/// (the paper's and IDUW's definition; what ``cvtrace compare`` and ``study`` report).
#[pyfunction]
#[pyo3(name = "relmse", signature = (x, r#ref))]
pub fn relmse(py: Python<'_>, x: &Bound<'_, PyAny>, r#ref: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (x, r) = pair(py, x, r#ref)?;
    run(py, None, move |_| Ok(Reference::new(r, "ref")?.rel_mse(&x, "x")?))
}

/// Mean squared error of ``x`` against ``ref`` over pixels and channels.
#[pyfunction]
#[pyo3(signature = (x, r#ref))]
pub fn mse(py: Python<'_>, x: &Bound<'_, PyAny>, r#ref: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (x, r) = pair(py, x, r#ref)?;
    run(py, None, move |_| Ok(Reference::new(r, "ref")?.mse(&x, "x")?))
}

/// Per-pixel relMSE (the mean over the three channels), (H, W) float32: what the study's
/// false-colour maps show; its mean is ``relmse(x, ref)``.
#[pyfunction]
#[pyo3(signature = (x, r#ref))]
pub fn relmse_map(py: Python<'_>, x: &Bound<'_, PyAny>, r#ref: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
    let (x, r) = pair(py, x, r#ref)?;
    let (w, h) = (r.width, r.height);
    let map = run(py, None, move |_| Ok(Reference::new(r, "ref")?.rel_mse_map(&x, "x")?))?;
    Ok(arrays::plane_to_numpy(py, w, h, map)?.unbind())
}

/// HDR-FLIP of ``x`` against ``ref`` (NVIDIA's perceptual error, in [0, 1], with its default
/// viewing conditions and exposures from ``ref``): the mean of the error map. With
/// ``map=True``, ``(mean, map)`` with the (H, W) float32 map.
#[pyfunction]
#[pyo3(signature = (x, r#ref, *, map = false))]
pub fn flip(py: Python<'_>, x: &Bound<'_, PyAny>, r#ref: &Bound<'_, PyAny>, map: bool) -> PyResult<Py<PyAny>> {
    let (x, r) = pair(py, x, r#ref)?;
    let result = run(py, None, move |_| Ok(FlipReference::new(&r, "ref")?.evaluate(&x, "x")?))?;
    if map {
        let m = arrays::plane_to_numpy(py, result.width, result.height, result.values)?;
        Ok((result.mean, m).into_pyobject(py)?.into_any().unbind())
    } else {
        Ok(result.mean.into_pyobject(py)?.into_any().unbind())
    }
}

/// Every metric ``cvtrace compare`` reports for one image: ``relmse``, ``mse`` and ``flip``
/// (HDR-FLIP's mean), as a dict.
#[pyfunction]
#[pyo3(signature = (x, r#ref))]
pub fn metrics<'py>(py: Python<'py>, x: &Bound<'py, PyAny>, r#ref: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let (x, r) = pair(py, x, r#ref)?;
    let (m, flip) = run(py, None, move |_| {
        let m = Reference::new(r.clone(), "ref")?.metrics(&x, "x")?;
        let flip = FlipReference::new(&r, "ref")?.evaluate(&x, "x")?.mean;
        Ok((m, flip))
    })?;
    let d = PyDict::new(py);
    d.set_item("relmse", m.rel_mse)?;
    d.set_item("mse", m.mse)?;
    d.set_item("flip", flip)?;
    Ok(d)
}

/// ``cvtrace compare``: scores EXR images (their R, G, B) against a reference EXR, and returns
/// the results as JSON text in the study's schema (``results.json``).
#[pyfunction]
pub fn compare_json(py: Python<'_>, reference: PathBuf, images: Vec<PathBuf>) -> PyResult<String> {
    run(py, None, move |_| {
        for p in std::iter::once(&reference).chain(&images) {
            check_input_file(p)?;
        }
        let scene = cvtrace_eval::compare::compare_files(&reference, &images)?;
        Ok(cvtrace_eval::StudyResults::new(vec![scene]).to_json())
    })
}

/// Reads an image's R, G, B from an EXR file (a reference, a reconstruction, the picture of a
/// stream file), as an (H, W, 3) float32 array.
#[pyfunction]
pub fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Py<PyAny>> {
    let image = run(py, None, move |_| {
        check_input_file(&path)?;
        Ok(cvtrace_streams::exr_io::read_picture(&path)?)
    })?;
    Ok(arrays::to_numpy(py, image)?.unbind())
}

/// Writes an (H, W, 3) image atomically: ``.exr`` as linear float R, G, B; ``.png`` as an sRGB
/// preview (``exposure`` in stops), as ``cvtrace reconstruct --png`` writes them.
#[pyfunction]
#[pyo3(signature = (path, image, *, overwrite = false, exposure = 0.0))]
pub fn write_image(py: Python<'_>, path: PathBuf, image: &Bound<'_, PyAny>, overwrite: bool, exposure: f32) -> PyResult<()> {
    let image = arrays::image(py, image, "image")?;
    run(py, None, move |_| {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        match ext.as_str() {
            "png" => {
                if !(exposure.is_finite() && exposure.abs() <= 64.0) {
                    anyhow::bail!("exposure={exposure}: must be a number of stops between -64 and 64");
                }
                cvtrace_streams::preview::write_png(&path, &image, exposure, overwrite)?
            }
            _ => {
                cvtrace_streams::atomic::check_extension(&path, "exr")?;
                cvtrace_streams::exr_io::write_rgb(&path, &image, &[], overwrite)?
            }
        }
        Ok(())
    })
}

/// An input that is a readable regular file, with the messages of `cvtrace`'s own check.
pub fn check_input_file(path: &std::path::Path) -> anyhow::Result<()> {
    use cvtrace_streams::input_file::{regular_file, NotAFile};
    match regular_file(path) {
        Ok(_) => Ok(()),
        Err(NotAFile::Io(e)) if e.kind() == std::io::ErrorKind::NotFound => anyhow::bail!("{}: no such file", path.display()),
        Err(NotAFile::Io(e)) => anyhow::bail!("{}: cannot read: {e}", path.display()),
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    }
}

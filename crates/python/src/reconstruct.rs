//! `cvtrace.reconstruct`, `cvtrace.estimators` and `cvtrace.estimator_help`: the registry's
//! estimators on a `Streams`, as `cvtrace reconstruct` runs them.
use crate::arrays;
use crate::estimators::{is_python, registry};
use crate::run::run;
use crate::streams::Streams;
use anyhow::bail;
use cvtrace_reconstruct::{BatchNeed, DiagValue, Diagnostics, Input, Overrides, ParamKind, Params};
use cvtrace_streams::Image;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::Arc;

/// The streams argument: a `Streams`, or the path of a stream file.
pub fn streams_arg(py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<Arc<(Arc<cvtrace_streams::StreamSet>, String)>> {
    if let Ok(s) = value.cast::<Streams>() {
        let s = s.get();
        return Ok(Arc::new((s.set.clone(), s.origin.clone())));
    }
    let path: PathBuf = value
        .extract()
        .map_err(|_| pyo3::exceptions::PyTypeError::new_err("streams: expected a cvtrace.Streams or the path of a stream file"))?;
    let s = run(py, None, |_| Streams::read_file(&path))?;
    Ok(Arc::new((s.set.clone(), s.origin.clone())))
}

/// What one estimator made: the image, its other layers (`ours`: ``variance``), its
/// diagnostics and the settings it ran with.
#[pyclass(module = "cvtrace", name = "Reconstruction", frozen)]
pub struct Reconstruction {
    /// The estimator's name.
    #[pyo3(get)]
    method: String,
    /// The image, (H, W, 3) float32.
    #[pyo3(get)]
    image: Py<PyAny>,
    /// The predicted variance per pixel, (H, W, 3), for an estimator that gives one (``ours``), else None.
    #[pyo3(get)]
    variance: Option<Py<PyAny>>,
    /// Every further layer by name, (H, W, 3) each.
    #[pyo3(get)]
    aovs: Py<PyDict>,
    /// What the estimator reported (numbers or text), in its order.
    #[pyo3(get)]
    diagnostics: Py<PyDict>,
    /// Every parameter in effect, as text (what ``cvtrace reconstruct`` records in its output).
    #[pyo3(get)]
    settings: Py<PyDict>,
    /// Wall-clock seconds of the reconstruction, input checks included.
    #[pyo3(get)]
    seconds: f64,
}

#[pymethods]
impl Reconstruction {
    /// The image as an array, so a ``Reconstruction`` goes wherever an array does.
    #[pyo3(signature = (dtype = None, copy = None))]
    fn __array__<'py>(&self, py: Python<'py>, dtype: Option<Bound<'py, PyAny>>, copy: Option<bool>) -> PyResult<Bound<'py, PyAny>> {
        let image = self.image.bind(py);
        let numpy = py.import("numpy")?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("dtype", dtype)?;
        if copy == Some(true) {
            kwargs.set_item("copy", true)?;
        }
        numpy.call_method("array", (image,), Some(&kwargs))
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.image.bind(py).getattr("shape").map(|s| s.to_string()).unwrap_or_default();
        format!("<cvtrace.Reconstruction {} {shape}, {:.3} s>", self.method, self.seconds)
    }
}

pub fn diagnostics_dict<'py>(py: Python<'py>, d: &Diagnostics) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (k, v) in &d.entries {
        match v {
            DiagValue::Float(x) => out.set_item(k, x)?,
            DiagValue::Int(x) => out.set_item(k, x)?,
            DiagValue::Text(x) => out.set_item(k, x)?,
        }
    }
    Ok(out)
}

/// Reconstructs the image from ``streams`` with estimator ``method``, exactly as ``cvtrace
/// reconstruct --method METHOD`` does (the same image, bit for bit, on the same file).
///
/// Args:
///     streams: a ``cvtrace.Streams``, or the path of a stream file.
///     method: an estimator's name (``cvtrace.estimators()`` lists them): ``ours`` (default),
///         ``cv``, ``iduw``, ``pt``, ``crn``, ``average``, ``ivw``, ``oidn``..., or one
///         registered from Python.
///     reference: the ground truth, (H, W, 3), for analysis options (``errors="oracle"``).
///     pt2n: a path-traced image of the same scene with twice the streams' samples per pixel,
///         (H, W, 3), for the estimators that post-process it (``pt2n-oidn``), as ``--pt2n``.
///     details: return a ``Reconstruction`` (image, ``variance`` of ``ours``, diagnostics,
///         settings, seconds) instead of the image alone.
///     threads: worker threads (default: all cores); the image is the same for any count.
///     **params: the estimator's parameters, e.g. ``k=16, search_window=11`` for ``ours``
///         (``cvtrace.estimator_help(method)`` lists them with defaults and ranges).
///
/// Returns:
///     numpy.ndarray: the image, (H, W, 3) float32; with ``details=True`` a ``Reconstruction``.
///
/// Raises:
///     cvtrace.Error: an unknown method or parameter, a value out of range, streams the method
///     cannot take, with the message of ``cvtrace reconstruct``.
// The keyword arguments of the Python function, one parameter each.
#[allow(clippy::too_many_arguments)]
#[pyfunction]
#[pyo3(signature = (streams, method = "ours", *, reference = None, pt2n = None, details = false, threads = None, **params))]
pub fn reconstruct(
    py: Python<'_>,
    streams: &Bound<'_, PyAny>,
    method: &str,
    reference: Option<&Bound<'_, PyAny>>,
    pt2n: Option<&Bound<'_, PyAny>>,
    details: bool,
    threads: Option<usize>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let input = streams_arg(py, streams)?;
    let reference: Option<Image> = reference.map(|r| arrays::image(py, r, "reference")).transpose()?;
    let pt2n: Option<Image> = pt2n.map(|r| arrays::image(py, r, "pt2n")).transpose()?;
    let mut overrides = Overrides::default();
    if let Some(p) = params {
        for (k, v) in p.iter() {
            overrides.set(method, &k.str()?.to_string(), &crate::params::param_text(&v)?);
        }
    }
    let method_name = method.to_string();
    let (out, settings) = run(py, threads, move |_| {
        if method_name.trim().eq_ignore_ascii_case("all") || method_name.contains(',') {
            bail!("method={method_name:?}: reconstruct runs one estimator; call it once per method");
        }
        let registry = registry();
        let spec = registry.get(&method_name)?;
        registry.check(&overrides)?;
        let estimator = registry.build(spec.name, &overrides)?;
        let (set, origin) = &*input;
        let mut input = Input::new(set).named(origin, "reference");
        if let Some(r) = &reference {
            if !r.same_size(&set.pt.mean) {
                bail!("reference is {}x{} but {} is {}x{}", r.width, r.height, origin, set.width, set.height);
            }
            input = input.with_reference(r);
        }
        if let Some(image) = &pt2n {
            input = input.with_pt2n(image, "pt2n");
        }
        let out = estimator.run(&input)?;
        input.check_output(estimator.name(), &out.image)?;
        Ok((out, (estimator.name(), estimator.settings())))
    })?;
    let image = arrays::to_numpy(py, out.image)?;
    if !details {
        return Ok(image.unbind());
    }
    let aovs = PyDict::new(py);
    let mut variance = None;
    for (name, layer) in out.aovs {
        let a = arrays::to_numpy(py, layer)?;
        if name == "variance" {
            variance = Some(a.clone().unbind());
        }
        aovs.set_item(name, a)?;
    }
    let s = PyDict::new(py);
    for (k, v) in settings.1 {
        s.set_item(k, v)?;
    }
    let r = Reconstruction {
        method: settings.0.to_string(),
        image: image.unbind(),
        variance,
        aovs: aovs.unbind(),
        diagnostics: diagnostics_dict(py, &out.diagnostics)?.unbind(),
        settings: s.unbind(),
        seconds: out.diagnostics.seconds,
    };
    Ok(Py::new(py, r)?.into_any())
}

/// Every registered estimator (the lineup, then those registered from Python) with its spec:
/// ``name``, ``label``, ``short``, ``summary``, ``colour``, ``samples`` (``"n"`` or ``"2n"``),
/// ``reads`` (what it needs, in words), ``batches``, ``features``, ``python`` (registered from
/// Python), ``params`` (each with ``name``, ``kind``, ``range``, ``default``, ``doc``, ``flag``,
/// ``choices``) and ``variants`` (the ablations of ``study(ablations=True)``).
#[pyfunction]
pub fn estimators(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for spec in registry().specs() {
        let needs = (spec.needs)(&Params::defaults(spec));
        let d = PyDict::new(py);
        d.set_item("name", spec.name)?;
        d.set_item("label", spec.label)?;
        d.set_item("short", spec.short)?;
        d.set_item("summary", spec.summary)?;
        d.set_item("colour", cvtrace_eval::palette::hex(spec.colour))?;
        d.set_item("samples", spec.samples.describe().split(' ').next().unwrap_or(""))?;
        d.set_item("reads", needs.describe())?;
        d.set_item(
            "batches",
            match needs.batches {
                BatchNeed::None => None,
                BatchNeed::Range { min, max } => Some(format!("{min}..{max}")),
                BatchNeed::MultipleOf(m) => Some(format!("a multiple of {m}")),
            },
        )?;
        d.set_item("features", needs.features.is_some())?;
        d.set_item("python", is_python(spec))?;
        let params = PyList::empty(py);
        for p in spec.params {
            let pd = PyDict::new(py);
            pd.set_item("name", p.name)?;
            pd.set_item(
                "kind",
                match p.kind {
                    ParamKind::Int { .. } => "int",
                    ParamKind::Float(_) => "float",
                    ParamKind::Bool => "bool",
                    ParamKind::Choice(_) => "choice",
                    ParamKind::FloatList(_) => "floats",
                    ParamKind::AutoFloat(_) => "auto-float",
                },
            )?;
            pd.set_item("range", p.kind.to_string())?;
            pd.set_item("default", p.default)?;
            pd.set_item("doc", p.doc)?;
            pd.set_item("flag", p.alias.map(|a| format!("--{a}")))?;
            pd.set_item("choices", if let ParamKind::Choice(names) = p.kind { Some(names.to_vec()) } else { None })?;
            params.append(pd)?;
        }
        d.set_item("params", params)?;
        let variants = PyList::empty(py);
        for v in spec.variants {
            let vd = PyDict::new(py);
            vd.set_item("key", v.key)?;
            vd.set_item("label", v.label)?;
            vd.set_item("params", v.params.iter().cloned().collect::<std::collections::BTreeMap<_, _>>())?;
            variants.append(vd)?;
        }
        d.set_item("variants", variants)?;
        list.append(d)?;
    }
    Ok(list)
}

/// An estimator's spec as ``cvtrace reconstruct --help-method NAME`` prints it.
#[pyfunction]
pub fn estimator_help(name: &str) -> PyResult<String> {
    let spec = registry().get(name).map_err(|e| crate::errors::error(e.into()))?;
    Ok(spec.help().trim_end().to_string())
}

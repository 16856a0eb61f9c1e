//! The estimators Python sees: the lineup (`cvtrace_lineup::registry`) and those registered
//! from Python, which are ordinary specs to the rest of cvtrace (`cvtrace reconstruct`'s checks,
//! the study's columns, `results.json`, the viewer).
//!
//! A spec is `'static` and builds its estimator through a plain function, so a Python one is
//! made once at registration (its texts leaked: a few hundred bytes, once per registration)
//! and [`build`] finds its Python factory by the spec's address.
use crate::arrays;
use crate::run;
use crate::streams::Streams;
use cvtrace_reconstruct::{
    BatchNeed, Bounds, DiagValue, Diagnostics, Estimator, EstimatorSpec, Input, Needs, Output, ParamKind, ParamSpec, Params, ReconError,
    Registry, Samples, Value, Variant,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::collections::HashSet;
use std::sync::Mutex;

/// An estimator registered from Python: its spec, what it reads, and the factory that makes
/// one from its parameters.
struct PythonEstimator {
    spec: &'static EstimatorSpec,
    needs: Needs,
    factory: Py<PyAny>,
}

static PYTHON: Mutex<Vec<PythonEstimator>> = Mutex::new(Vec::new());

fn python_estimators() -> std::sync::MutexGuard<'static, Vec<PythonEstimator>> {
    PYTHON.lock().unwrap_or_else(|p| p.into_inner())
}

/// The lineup and then the estimators registered from Python, in registration order.
pub fn registry() -> Registry {
    let mut r = cvtrace_lineup::registry().clone();
    for e in python_estimators().iter() {
        r.register(e.spec).expect("checked at registration");
    }
    r
}

fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

/// Diagnostic names are `'static`; a Python estimator's are leaked once each.
fn interned(name: &str) -> &'static str {
    static NAMES: Mutex<Option<HashSet<&'static str>>> = Mutex::new(None);
    let mut names = NAMES.lock().unwrap_or_else(|p| p.into_inner());
    let set = names.get_or_insert_with(HashSet::new);
    if let Some(n) = set.get(name) {
        return n;
    }
    let n = leak(name.to_string());
    set.insert(n);
    n
}

fn needs_of(params: &Params) -> Needs {
    let spec = params.spec();
    python_estimators().iter().find(|e| std::ptr::eq(e.spec, spec)).map(|e| e.needs).unwrap_or(Needs::MEANS)
}

fn build(params: &Params) -> Result<Box<dyn Estimator>, ReconError> {
    let spec = params.spec();
    let failed = |message: String| ReconError::Failed { method: spec.name, message };
    let factory = Python::attach(|py| python_estimators().iter().find(|e| std::ptr::eq(e.spec, spec)).map(|e| e.factory.clone_ref(py)))
        .ok_or_else(|| failed("no longer registered".into()))?;
    Python::attach(|py| {
        let kwargs = PyDict::new(py);
        for (p, (name, _)) in spec.params.iter().zip(params.settings()) {
            kwargs.set_item(name, value_to_python(py, params.get(p.name))?)?;
        }
        let object = factory.call(py, (), Some(&kwargs))?;
        if !object.bind(py).hasattr("reconstruct")? {
            return Err(PyTypeError::new_err(format!(
                "{}: the estimator made by {} has no reconstruct(streams) method",
                spec.name,
                factory.bind(py).repr()?
            )));
        }
        Ok(object)
    })
    .map(|object| Box::new(PythonCall { name: spec.name, object }) as Box<dyn Estimator>)
    .map_err(|e| {
        let message = Python::attach(|py| format!("making the estimator: {}", describe(py, &e)));
        run::keep_python_error(e);
        failed(message)
    })
}

fn value_to_python(py: Python<'_>, v: &Value) -> PyResult<Py<PyAny>> {
    Ok(match v {
        Value::Int(i) => i.into_pyobject(py)?.into_any().unbind(),
        Value::Float(f) => f.into_pyobject(py)?.into_any().unbind(),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any().unbind(),
        Value::Choice(s) => s.into_pyobject(py)?.into_any().unbind(),
        Value::FloatList(list) => PyList::new(py, list)?.into_any().unbind(),
        Value::Auto => py.None(),
    })
}

fn describe(py: Python<'_>, e: &PyErr) -> String {
    let kind = e.get_type(py).name().map(|n| n.to_string()).unwrap_or_else(|_| "exception".into());
    format!("{kind}: {}", e.value(py))
}

/// A Python object with a `reconstruct(streams)` method, as an estimator.
struct PythonCall {
    name: &'static str,
    object: Py<PyAny>,
}

impl Estimator for PythonCall {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let cancel = run::current();
        if let Some(c) = &cancel {
            c.check();
        }
        let failed = |message: String| ReconError::Failed { method: self.name, message };
        // The estimator gets streams of its own: Python may keep them after the call.
        let streams = Streams::new(input.streams.clone(), None, input.streams_name.to_string());
        let (w, h) = (input.width(), input.height());
        let reference = input.reference.cloned();
        let result = Python::attach(|py| -> PyResult<Output> {
            let streams = Py::new(py, streams)?;
            let kwargs = PyDict::new(py);
            if let Some(r) = reference {
                let object = self.object.bind(py);
                // A reference only for an estimator that declares the keyword (oracle analyses).
                if accepts_keyword(py, object, "reference")? {
                    kwargs.set_item("reference", arrays::to_numpy(py, r)?)?;
                }
            }
            let returned = self.object.bind(py).call_method("reconstruct", (streams,), Some(&kwargs))?;
            output_from(py, &returned, self.name, w, h)
        });
        if let Some(c) = &cancel {
            c.check();
        }
        result.map_err(|e| {
            let message = Python::attach(|py| format!("reconstruct raised {}", describe(py, &e)));
            run::keep_python_error(e);
            failed(message)
        })
    }
}

fn accepts_keyword(py: Python<'_>, object: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    let inspect = py.import("inspect")?;
    let Ok(signature) = inspect.call_method1("signature", (object.getattr("reconstruct")?,)) else { return Ok(false) };
    signature.getattr("parameters")?.contains(name)
}

/// What `reconstruct` returned: an (H, W, 3) image, or `(image, diagnostics)`, or a dict with
/// `image` and optionally `variance` (its predicted variance per pixel) and `diagnostics`.
fn output_from(py: Python<'_>, value: &Bound<'_, PyAny>, name: &str, w: usize, h: usize) -> PyResult<Output> {
    let what = format!("the image {name}.reconstruct returned");
    let (image, variance, diagnostics) = if let Ok(d) = value.cast::<PyDict>() {
        let image =
            d.get_item("image")?.ok_or_else(|| PyValueError::new_err(format!("{name}.reconstruct returned a dict without \"image\"")))?;
        (image, d.get_item("variance")?, d.get_item("diagnostics")?)
    } else if let Ok(t) = value.cast::<PyTuple>() {
        if t.len() != 2 {
            return Err(PyValueError::new_err(format!(
                "{name}.reconstruct returned a tuple of {}; expected (image, diagnostics)",
                t.len()
            )));
        }
        (t.get_item(0)?, None, Some(t.get_item(1)?))
    } else {
        (value.clone(), None, None)
    };
    let image = arrays::image(py, &image, &what)?;
    if (image.width, image.height) != (w, h) {
        return Err(PyValueError::new_err(format!("{what} is {}x{}, but the streams are {w}x{h}", image.width, image.height)));
    }
    let mut out = Output::image(image);
    if let Some(v) = variance.filter(|v| !v.is_none()) {
        let v = arrays::image(py, &v, &format!("the variance {name}.reconstruct returned"))?;
        if (v.width, v.height) != (w, h) {
            return Err(PyValueError::new_err(format!(
                "the variance {name}.reconstruct returned is {}x{}, but the streams are {w}x{h}",
                v.width, v.height
            )));
        }
        out.aovs.push(("variance".into(), v));
    }
    if let Some(d) = diagnostics.filter(|d| !d.is_none()) {
        let d = d
            .cast::<PyDict>()
            .map_err(|_| PyTypeError::new_err(format!("{name}.reconstruct: diagnostics must be a dict of numbers or text")))?;
        out.diagnostics = diagnostics_from(d)?;
    }
    Ok(out)
}

fn diagnostics_from(d: &Bound<'_, PyDict>) -> PyResult<Diagnostics> {
    let mut out = Diagnostics::default();
    for (k, v) in d.iter() {
        let key = interned(&k.str()?.to_string());
        let value = if v.is_instance_of::<pyo3::types::PyBool>() {
            DiagValue::Text(v.str()?.to_string())
        } else if let Ok(i) = v.extract::<i64>() {
            DiagValue::Int(i)
        } else if let Ok(f) = v.extract::<f64>() {
            DiagValue::Float(f)
        } else {
            DiagValue::Text(v.str()?.to_string())
        };
        out.entries.push((key, value));
    }
    Ok(out)
}

/// One parameter of a Python estimator, from `cvtrace.Param` (or a dict of its fields).
fn param_spec(p: &Bound<'_, PyAny>, estimator: &str) -> PyResult<ParamSpec> {
    let get = |name: &str| -> PyResult<Option<Bound<'_, PyAny>>> {
        if let Ok(d) = p.cast::<PyDict>() {
            return d.get_item(name);
        }
        match p.getattr(name) {
            Ok(v) if !v.is_none() => Ok(Some(v)),
            Ok(_) => Ok(None),
            Err(_) => Ok(None),
        }
    };
    let text =
        |name: &str| -> PyResult<Option<String>> { get(name)?.filter(|v| !v.is_none()).map(|v| Ok(v.str()?.to_string())).transpose() };
    let number = |name: &str| -> PyResult<Option<f64>> { get(name)?.filter(|v| !v.is_none()).map(|v| v.extract::<f64>()).transpose() };
    let name = text("name")?.ok_or_else(|| PyValueError::new_err(format!("{estimator}: a parameter without a name")))?;
    let kind_name = text("kind")?.unwrap_or_else(|| "float".into());
    let bad = |why: String| PyValueError::new_err(format!("{estimator}.{name}: {why}"));
    let bounds = || -> PyResult<Bounds> {
        Ok(Bounds {
            min: number("min")?.unwrap_or(f64::NEG_INFINITY),
            above: get("above")?.map(|v| v.is_truthy()).transpose()?.unwrap_or(false),
            max: number("max")?.unwrap_or(f64::INFINITY),
        })
    };
    let kind = match kind_name.as_str() {
        "int" => ParamKind::Int {
            min: number("min")?.map(|v| v as i64).unwrap_or(i64::MIN),
            max: number("max")?.map(|v| v as i64).unwrap_or(i64::MAX),
        },
        "float" => ParamKind::Float(bounds()?),
        "bool" => ParamKind::Bool,
        "choice" => {
            let choices = get("choices")?.ok_or_else(|| bad("kind \"choice\" needs choices=[...]".into()))?;
            let names: Vec<&'static str> =
                choices.try_iter()?.map(|c| c.and_then(|c| Ok(leak(c.str()?.to_string())))).collect::<PyResult<_>>()?;
            if names.is_empty() {
                return Err(bad("choices is empty".into()));
            }
            ParamKind::Choice(Box::leak(names.into_boxed_slice()))
        }
        "floats" => ParamKind::FloatList(bounds()?),
        "auto-float" => ParamKind::AutoFloat(bounds()?),
        other => return Err(bad(format!("kind {other:?}: expected int, float, bool, choice, floats or auto-float"))),
    };
    let default = match get("default")? {
        None => return Err(bad("no default".into())),
        Some(v) => crate::params::param_text(&v)?,
    };
    Ok(ParamSpec { name: leak(name), kind, default: leak(default), doc: leak(text("doc")?.unwrap_or_default()), alias: None })
}

fn parse_colour(value: Option<&Bound<'_, PyAny>>) -> PyResult<[u8; 3]> {
    let Some(v) = value.filter(|v| !v.is_none()) else { return Ok([0x9a, 0xd0, 0x6c]) };
    if let Ok(s) = v.extract::<String>() {
        let hex = s.trim_start_matches('#');
        let bad = || PyValueError::new_err(format!("colour={s:?}: expected \"#rrggbb\" or (r, g, b) in 0..255"));
        if hex.len() != 6 {
            return Err(bad());
        }
        let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
        return Ok([byte(0)?, byte(2)?, byte(4)?]);
    }
    v.extract::<(u8, u8, u8)>()
        .map(|(r, g, b)| [r, g, b])
        .map_err(|_| PyValueError::new_err("colour: expected \"#rrggbb\" or (r, g, b) in 0..255"))
}

/// Registers an estimator written in Python, so that ``reconstruct``, ``estimators`` and
/// ``study`` (its columns, ``results.json`` and the viewer) handle it as a built-in one.
///
/// ``factory(**params)`` (usually the class) must return an object with a
/// ``reconstruct(streams)`` method that takes a ``cvtrace.Streams`` and returns the image,
/// (H, W, 3); or ``(image, diagnostics)``; or a dict with ``"image"`` and optionally
/// ``"variance"`` (its predicted variance per pixel) and ``"diagnostics"`` (a dict of numbers or
/// text). The parameters are ``cvtrace.Param``s, set as ``reconstruct(s, method, name=value)``
/// or ``study(..., params={"method.name": value})`` and checked against their kind and range.
///
/// Args:
///     name: lower-case letters, digits and ``-``; not a registered name.
///     label, short: the names in tables and the viewer (default: ``name``).
///     summary: one line: what it is.
///     colour: ``"#rrggbb"`` or ``(r, g, b)`` in the plots and viewer.
///     samples: ``"both"`` (its image stands for both streams, 2n spp) or ``"one"`` (n spp).
///     params: its parameters.
///     batches: what it needs of the batch count: None, ``(min, max)``, or ``("multiple", m)``.
///     features: whether it reads the first-hit features (albedo, normal, depth).
///     spp: whether it needs the streams' samples per pixel.
///     variants: ablations for ``study(ablations=True)``: ``[(key, label, {param: value})]``.
#[pyfunction]
#[pyo3(signature = (factory, *, name, label = None, short = None, summary = String::new(), colour = None, samples = "both", params = None, batches = None, features = false, spp = false, variants = None))]
#[allow(clippy::too_many_arguments)]
pub fn register(
    factory: Bound<'_, PyAny>,
    name: String,
    label: Option<String>,
    short: Option<String>,
    summary: String,
    colour: Option<Bound<'_, PyAny>>,
    samples: &str,
    params: Option<Bound<'_, PyAny>>,
    batches: Option<Bound<'_, PyAny>>,
    features: bool,
    spp: bool,
    variants: Option<Bound<'_, PyAny>>,
) -> PyResult<()> {
    if !factory.is_callable() {
        return Err(PyTypeError::new_err(format!("{name}: the factory must be callable (a class, or a function returning an estimator)")));
    }
    let samples = match samples {
        "both" => Samples::BothStreams,
        "one" => Samples::OneStream,
        other => return Err(PyValueError::new_err(format!("samples={other:?}: expected \"both\" (2n spp) or \"one\" (n spp)"))),
    };
    let mut list = Vec::new();
    if let Some(ps) = params.filter(|p| !p.is_none()) {
        for p in ps.try_iter()? {
            list.push(param_spec(&p?, &name)?);
        }
    }
    let batch_need = match batches.filter(|b| !b.is_none()) {
        None => BatchNeed::None,
        Some(b) => {
            if let Ok((word, m)) = b.extract::<(String, usize)>() {
                if word != "multiple" || m == 0 {
                    return Err(PyValueError::new_err("batches: expected (min, max) or (\"multiple\", m) with m ≥ 1"));
                }
                BatchNeed::MultipleOf(m)
            } else {
                let (min, max) = b
                    .extract::<(usize, usize)>()
                    .map_err(|_| PyValueError::new_err("batches: expected (min, max) or (\"multiple\", m)"))?;
                if min == 0 || min > max {
                    return Err(PyValueError::new_err(format!("batches=({min}, {max}): expected 1 ≤ min ≤ max")));
                }
                BatchNeed::Range { min, max }
            }
        }
    };
    let mut variant_list = Vec::new();
    if let Some(vs) = variants.filter(|v| !v.is_none()) {
        for v in vs.try_iter()? {
            let (key, vlabel, vparams): (String, String, Bound<'_, PyDict>) =
                v?.extract().map_err(|_| PyValueError::new_err("variants: expected [(key, label, {param: value}), ...]"))?;
            let mut pairs: Vec<(&'static str, &'static str)> = Vec::new();
            for (k, val) in vparams.iter() {
                pairs.push((leak(k.str()?.to_string()), leak(crate::params::param_text(&val)?)));
            }
            variant_list.push(Variant { key: leak(key), label: leak(vlabel), params: Box::leak(pairs.into_boxed_slice()) });
        }
    }
    let label = label.unwrap_or_else(|| name.clone());
    let spec: &'static EstimatorSpec = Box::leak(Box::new(EstimatorSpec {
        name: leak(name.clone()),
        label: leak(label),
        short: leak(short.unwrap_or_else(|| name.clone())),
        summary: leak(summary),
        colour: parse_colour(colour.as_ref())?,
        samples,
        params: Box::leak(list.into_boxed_slice()),
        needs: needs_of,
        build,
        variants: Box::leak(variant_list.into_boxed_slice()),
    }));
    let needs = Needs {
        batches: batch_need,
        features: features.then_some("(declared by the Python estimator)"),
        reference: false,
        spp,
        pt2n: false,
        bounded_values: false,
    };
    // The checks of a spec (name, parameter defaults), as for any estimator.
    let mut check = registry();
    check.register(spec).map_err(|e| crate::errors::error(e.into()))?;
    for v in spec.variants {
        let o = cvtrace_reconstruct::Overrides::default().with(spec.name, v.params);
        check.params(spec, &o).map_err(|e| crate::errors::error(anyhow::anyhow!("variant {}: {e}", v.key)))?;
    }
    python_estimators().push(PythonEstimator { spec, needs, factory: factory.unbind() });
    Ok(())
}

/// Removes an estimator registered from Python (the built-in ones stay).
#[pyfunction]
pub fn unregister(name: &str) -> PyResult<()> {
    let mut list = python_estimators();
    match list.iter().position(|e| e.spec.name.eq_ignore_ascii_case(name.trim())) {
        Some(i) => {
            list.remove(i);
            Ok(())
        }
        None => Err(PyValueError::new_err(format!("{name}: no estimator of that name was registered from Python"))),
    }
}

/// Whether `spec` was registered from Python.
pub fn is_python(spec: &'static EstimatorSpec) -> bool {
    python_estimators().iter().any(|e| std::ptr::eq(e.spec, spec))
}

//! Python values as the command line's parameter text, for every call that takes parameters.
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyList, PyTuple};

/// A parameter's value as the command line writes it: booleans as true/false, None as auto,
/// sequences comma-separated, numbers as Python writes them (which parse back to the same).
pub fn param_text(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_none() {
        return Ok("auto".into());
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(if v.is_truthy()? { "true" } else { "false" }.into());
    }
    if let Ok(s) = v.extract::<String>() {
        return Ok(s);
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let parts: Vec<String> = v.try_iter()?.map(|x| x.and_then(|x| param_text(&x))).collect::<PyResult<_>>()?;
        return Ok(parts.join(","));
    }
    if let Ok(f) = v.extract::<f64>() {
        if v.extract::<i64>().is_err() {
            return Ok(format!("{f:?}"));
        }
    }
    Ok(v.str()?.to_string())
}

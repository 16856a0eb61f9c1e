//! `cvtrace._cvtrace`, the extension module of the `cvtrace` Python package: the library crates
//! (render session, estimator registry, metrics, study protocol) behind numpy arrays. Nothing
//! here computes what the Rust side does not: each function is the glue of one CLI command,
//! with the same checks and messages, over the same library calls.
//!
//! Arrays come in as anything array-like (copied into float32 images) and go out as float32,
//! C-contiguous, (H, W, C) arrays. Work runs off the GIL on a worker thread and answers Ctrl-C
//! ([`run`]). Estimators written in Python join the registry ([`estimators`]).
#![deny(unsafe_code)]
mod arrays;
mod errors;
mod estimators;
mod metrics;
mod params;
mod reconstruct;
mod render;
mod run;
mod streams;
mod study;

use pyo3::prelude::*;

#[pymodule]
fn _cvtrace(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The library's warnings (samples replaced for being NaN, a scene without lights, ...) on
    // stderr, as the command line prints them; RUST_LOG asks for more. A subscriber the host
    // process set up first stays.
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).with_target(false).try_init();
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Error", py.get_type::<errors::Error>())?;
    m.add_class::<streams::Streams>()?;
    m.add_class::<reconstruct::Reconstruction>()?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(render::render_reference_py, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct::estimators, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct::estimator_help, m)?)?;
    m.add_function(wrap_pyfunction!(estimators::register, m)?)?;
    m.add_function(wrap_pyfunction!(estimators::unregister, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::relmse, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::mse, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::relmse_map, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::flip, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::metrics, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::compare_json, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_json, m)?)?;
    m.add_function(wrap_pyfunction!(study::report, m)?)?;
    Ok(())
}

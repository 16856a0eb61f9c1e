//! cvtrace's errors as Python exceptions, with the messages the command line prints.
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::create_exception!(
    cvtrace,
    Error,
    pyo3::exceptions::PyException,
    "An error of cvtrace: a file that cannot be read or written, a scene that does not load, input that an estimator cannot take, settings out of range. The message is the one the `cvtrace` command line prints."
);

/// An error as `cvtrace.Error`, its causes chained as `cvtrace` prints them (`error: a: b`).
pub fn error(e: anyhow::Error) -> PyErr {
    Error::new_err(format!("{e:#}"))
}

/// Most threads a call may ask for: far more than cores only costs memory.
pub const MAX_THREADS: usize = 1024;

/// A pool of `n` threads for one call (`threads=`); results are bit-identical for any count.
pub fn thread_pool(n: usize) -> PyResult<rayon::ThreadPool> {
    if n == 0 || n > MAX_THREADS {
        return Err(PyValueError::new_err(format!("threads={n}: must be between 1 and {MAX_THREADS}")));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .thread_name(|i| format!("cvtrace-{i}"))
        .build()
        .map_err(|e| Error::new_err(format!("threads={n}: cannot start {n} worker threads: {e}")))
}

//! One error type for the evaluation crate; every variant names the file or label at fault.
use cvtrace_streams::StreamError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error(transparent)]
    Stream(#[from] StreamError),
    #[error("image sizes differ: {a} is {aw}x{ah}, {b} is {bw}x{bh}")]
    SizeMismatch { a: String, aw: usize, ah: usize, b: String, bw: usize, bh: usize },
    #[error("{label}: non-finite value {value} at pixel ({x}, {y}), channel {channel}")]
    NonFinite { label: String, x: usize, y: usize, channel: usize, value: f32 },
    /// The cause is part of the message (not a `source`), so `{:#}` chains print it once.
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}: not a valid cvtrace results file: {message}")]
    Json { path: PathBuf, message: String },
    #[error("{context}: {message}")]
    Invalid { context: String, message: String },
}

impl EvalError {
    pub fn invalid(context: impl Into<String>, message: impl Into<String>) -> Self {
        EvalError::Invalid { context: context.into(), message: message.into() }
    }

    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        EvalError::Io { path: path.into(), error: source }
    }
}

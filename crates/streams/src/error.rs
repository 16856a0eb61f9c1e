//! One error type for everything that reads or writes stream and image files.
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The cause is part of the message (not a `source`), so `{:#}` chains print it once.
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}: not a readable OpenEXR file: {message}")]
    Exr { path: PathBuf, message: String },
    #[error("{path}: missing channel `{channel}`")]
    MissingChannel { path: PathBuf, channel: String },
    #[error("{path}: channel `{channel}` holds a non-finite value at pixel ({x}, {y})")]
    NonFinite { path: PathBuf, channel: String, x: usize, y: usize },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error("{path}: already exists (pass --force to replace it)")]
    AlreadyExists { path: PathBuf },
    #[error("image sizes differ: {a} is {aw}x{ah}, {b} is {bw}x{bh}")]
    SizeMismatch { a: String, aw: usize, ah: usize, b: String, bw: usize, bh: usize },
}

impl StreamError {
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        StreamError::Invalid { path: path.into(), message: message.into() }
    }
}

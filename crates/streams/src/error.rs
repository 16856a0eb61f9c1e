//! The errors of reading and writing stream and image files, and of adding up the exact sums
//! of a render's pieces.
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

/// Sums that cannot be added up: pieces of different renders, or pieces that do not follow one
/// another.
#[derive(Debug, thiserror::Error)]
pub enum SumsError {
    /// Parts of a stream render.
    #[error("invalid render settings: {0}")]
    Streams(String),
    /// A reference accumulator and the sums or image given to it.
    #[error("reference accumulator does not match: {0}")]
    Reference(String),
}

//! Why a scene could not be loaded or built.
use std::path::PathBuf;

/// Why a scene could not be loaded or built. Every variant names the file (or `<memory>`).
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The cause is part of the message (not a `source`), so `{:#}` chains print it once.
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}: not a valid glTF 2.0 file: {message}")]
    Malformed { path: PathBuf, message: String },
    #[error("{path}: requires the glTF extension `{extension}`, which cvtrace does not support")]
    UnsupportedExtension { path: PathBuf, extension: String },
    #[error("{path}: cannot read the referenced file {file}: {message}")]
    MissingFile { path: PathBuf, file: PathBuf, message: String },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    /// A `-D key=value` override that names no setting or gives it an unusable value.
    #[error("-D {define}: {message}")]
    Define { define: String, message: String },
}

impl SceneError {
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        SceneError::Invalid { path: path.into(), message: message.into() }
    }
}

//! Why a render could not run.
/// Why a render could not run: its settings, its camera, a reference's sums, or a file.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid render settings: {0}")]
    InvalidSettings(String),
    #[error("the scene's camera is unusable: {0}")]
    Camera(String),
    #[error("reference accumulator does not match: {0}")]
    ReferenceMismatch(String),
    #[error(transparent)]
    File(#[from] cvtrace_streams::StreamError),
}

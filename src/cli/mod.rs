//! What the commands share (each command is one file in `src/commands/`, and no command
//! imports another): flags, the estimators' parameters, the study's flags and checks, paths,
//! progress.

/// `println!` that never panics: with stdout closed (`| head -1`) the text is dropped and the
/// command goes on writing its files.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}
pub(crate) use say;
pub mod args;
pub mod estimator_args;
pub mod files;
pub mod progress;
pub mod study_setup;

pub use cvtrace_lineup::registry;

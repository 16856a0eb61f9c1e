//! What the commands share (each command is one file in `src/commands/`, and no command
//! imports another): flags, the estimators' parameters, the study's flags and checks, paths,
//! progress, the log's lines.

/// `println!` for what a command prints as its result (tables, listings, instructions). A
/// closed pipe (`| head -1`) is no error: the text is dropped and the command goes on writing
/// its files. Any other failure (a full disk) is kept, and [`stdout_result`] ends the command
/// with it once its work is done.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        $crate::cli::keep_stdout_error(writeln!(std::io::stdout(), $($arg)*));
    }};
}
pub(crate) use say;
pub mod args;
pub mod estimator_args;
pub mod files;
pub mod log;
pub mod progress;
pub mod study_setup;

pub use cvtrace_lineup::registry;

/// The first failure to write stdout that was not a closed pipe.
static STDOUT_ERROR: std::sync::OnceLock<std::io::Error> = std::sync::OnceLock::new();

/// Keeps the error of a write to stdout, unless it is a closed pipe.
pub fn keep_stdout_error(written: std::io::Result<()>) {
    if let Err(e) = written {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            let _ = STDOUT_ERROR.set(e);
        }
    }
}

/// Whether everything printed reached stdout (a closed pipe counts as reached): an error
/// naming the first failure otherwise.
pub fn stdout_result() -> anyhow::Result<()> {
    use std::io::Write as _;
    keep_stdout_error(std::io::stdout().flush());
    match STDOUT_ERROR.get() {
        Some(e) => anyhow::bail!("standard output: cannot write what the command prints: {e}"),
        None => Ok(()),
    }
}

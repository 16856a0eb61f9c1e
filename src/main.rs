//! The `cvtrace` command line: render, merge, reconstruct, study, compare, report (and farm),
//! one file each in `commands/`, over the library crates; `cli/` holds what they share.
#![forbid(unsafe_code)]
mod cli;
mod commands;

use clap::{Parser, Subcommand};
use std::io::{IsTerminal, Write};

#[derive(Parser)]
#[command(
    name = "cvtrace",
    version,
    about = "Embree path tracer with paired PT/CRN streams and image-space control-variate reconstruction"
)]
struct Cli {
    /// Worker threads (default: all cores). Results are bit-identical for any count.
    #[arg(short = 't', long, global = true, allow_hyphen_values = true,
          value_parser = clap::builder::RangedI64ValueParser::<usize>::new().range(1..=MAX_THREADS as i64))]
    threads: Option<usize>,
    /// Log level filter (error, warn, info, debug, trace); RUST_LOG overrides it.
    #[arg(long, global = true, default_value = "info")]
    log: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a glTF scene into a PT/CRN stream file (or a reference image with --reference).
    Render(commands::render::RenderArgs),
    /// Reconstruct an image from a stream file with one or all estimators.
    Reconstruct(commands::reconstruct::ReconstructArgs),
    /// Render in parts on a Slurm cluster: job folders, submission, status.
    Farm(commands::farm::FarmArgs),
    /// Join the parts of a render (`render --part`) into the file one render writes.
    Merge(commands::merge::MergeArgs),
    /// Render, reconstruct and score every estimator over seeds (the paper's protocol).
    Study(cli::study_setup::StudyArgs),
    /// Score finished images against a reference: a table, CSV or JSON.
    Compare(commands::compare::CompareArgs),
    /// Write the static HTML comparison viewer from study folders (images, relMSE and signed
    /// difference maps, a readout of every image's linear values under the cursor, sortable
    /// tables, relMSE against spp and against time).
    Report(commands::report::ReportArgs),
}

const MAX_THREADS: usize = 1024;

/// `--log`: a level, or comma-separated directives each naming a level (`cvtrace=debug`). A bare
/// word that is no level would parse as a target and silently log nothing.
fn log_filter(text: &str) -> Result<tracing_subscriber::EnvFilter, String> {
    let is_level = |s: &str| s.trim().parse::<tracing_subscriber::filter::LevelFilter>().is_ok();
    if text.trim().is_empty() || !text.split(',').all(|d| is_level(d) || d.split_once('=').is_some_and(|(_, l)| is_level(l))) {
        return Err("not a log level".into());
    }
    tracing_subscriber::EnvFilter::try_new(text).map_err(|e| e.to_string())
}

/// `error: …` on stderr, never failing: with stderr closed there is no one to tell.
fn say_error(message: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "error: {message}");
}

/// Address space that `threads` worker threads take: each one's stack (Rust's default of 2 MiB,
/// or RUST_MIN_STACK) with its guard page and signal stack, glibc's malloc arenas (64 MiB each,
/// up to 8 per core), and 128 MiB for the rest of the process.
fn threads_bytes(threads: u64) -> u64 {
    let stack = std::env::var("RUST_MIN_STACK").ok().and_then(|s| s.parse::<u64>().ok()).unwrap_or(2 << 20);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    threads * (stack + (64 << 10)) + threads.min(8 * cores) * (64 << 20) + (128 << 20)
}

/// Prints clap's help, version or error, and the exit code: 0 after help, 2 after an error, 1
/// when the help cannot be written (a full disk; a closed pipe is no error).
fn clap_exit(e: clap::Error) -> std::process::ExitCode {
    let printed = e.print().and_then(|()| std::io::stdout().flush());
    match printed {
        Err(io) if !e.use_stderr() && io.kind() != std::io::ErrorKind::BrokenPipe => {
            say_error(&format!("standard output: cannot write what the command prints: {io}"));
            std::process::ExitCode::FAILURE
        }
        _ => std::process::ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2)),
    }
}

fn main() -> std::process::ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return clap_exit(e),
    };
    let filter = match tracing_subscriber::EnvFilter::try_from_default_env() {
        Ok(f) => f,
        // A directive that does not parse would be dropped with a note, and the run go on silent.
        Err(_) => match log_filter(&cli.log) {
            Ok(f) => f,
            Err(e) => {
                say_error(&format!(
                    "--log {:?}: {e} (expected a level: off, error, warn, info, debug, trace; or directives such as cvtrace=debug)",
                    cli.log
                ));
                return std::process::ExitCode::from(2);
            }
        },
    };
    // Colour codes only for a terminal, where lines wrap at 100 columns; a log line that cannot
    // be written (a closed pipe) is dropped without a word, so that logging never ends the work.
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(cli::log::Stderr::default())
        .with_target(false)
        .with_ansi(std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none())
        .log_internal_errors(false)
        .init();
    // Far more threads than cores only costs memory (and at 10⁵ the pool never starts): clap
    // takes 1 to MAX_THREADS.
    if let Some(n) = cli.threads {
        // `render` and `study` start as many render threads again (the render session's pool). A thread that
        // gets its stack but not its signal stack aborts the process: so all the stacks must
        // fit in the address space (`ulimit -v`) before any thread starts.
        let threads = if matches!(cli.command, Command::Render(_) | Command::Study(_)) { 2 * n } else { n };
        let bytes = threads_bytes(threads as u64);
        if !usize::try_from(bytes).is_ok_and(|b| Vec::<u8>::new().try_reserve_exact(b).is_ok()) {
            say_error(&format!(
                "--threads {n}: cannot start {threads} worker threads: with their stacks the process needs about {:.1} GiB of address space, which cannot be reserved here (`ulimit -v`)",
                bytes as f64 / (1u64 << 30) as f64
            ));
            return std::process::ExitCode::from(2);
        }
        // Under a process limit they may still not all start.
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            say_error(&format!("--threads {n}: cannot start {n} worker threads: {e}"));
            return std::process::ExitCode::from(2);
        }
    }
    // Ctrl-C, SIGTERM, SIGHUP: remove the temporary files of the outputs being written, so an
    // interrupted run leaves no half files (finished outputs and checkpoints stay).
    if let Err(e) = ctrlc::set_handler(|| {
        cvtrace_streams::atomic::remove_pending_temporaries();
        // On a terminal the progress bar holds the current line (and stops drawing now that
        // the run is interrupted): the note replaces it instead of following it.
        let line = if std::io::stderr().is_terminal() { "\r\x1b[2K" } else { "" };
        match cli::files::interrupt_note() {
            Some(note) => {
                let _ = writeln!(std::io::stderr(), "{line}interrupted: {note}");
            }
            None => {
                let _ = writeln!(std::io::stderr(), "{line}interrupted");
            }
        }
        std::process::exit(130);
    }) {
        tracing::warn!("no signal handler: an interrupted run may leave temporary files ({e})");
    }
    let result = match cli.command {
        Command::Render(a) => commands::render::run(a),
        Command::Reconstruct(a) => commands::reconstruct::run(a),
        Command::Merge(a) => commands::merge::run(a),
        Command::Farm(a) => commands::farm::run(a),
        Command::Study(a) => commands::study::run(a),
        Command::Compare(a) => commands::compare::run(a),
        Command::Report(a) => commands::report::run(a),
    };
    // Interrupted: the signal handler is ending the process with its own code; an error that
    // came from its removing a file under a write is not this run's result.
    while cvtrace_streams::atomic::interrupted() {
        std::thread::park();
    }
    // What the command printed is part of its result.
    let result = result.and_then(|()| cli::stdout_result());
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            say_error(&format!("{e:#}"));
            std::process::ExitCode::FAILURE
        }
    }
}

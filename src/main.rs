//! The `cvtrace` command line: render, reconstruct, study, compare, report.
mod cli;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cvtrace", version, about = "Embree path tracer with paired PT/CRN streams and image-space control-variate reconstruction")]
struct Cli {
    /// Worker threads (default: all cores). Results are bit-identical for any count.
    #[arg(long, global = true)]
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
    Render(cli::render::RenderArgs),
    /// Reconstruct an image from a stream file with one or all estimators.
    Reconstruct(cli::reconstruct::ReconstructArgs),
    /// Render, reconstruct and score every estimator over seeds (the paper's protocol).
    Study(cli::study::StudyArgs),
    /// Score finished images against a reference: a table, CSV or JSON.
    Compare(cli::compare::CompareArgs),
    /// Write the static HTML comparison viewer from study folders.
    Report(cli::report::ReportArgs),
}

const MAX_THREADS: usize = 1024;

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(&cli.log));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).with_target(false).init();
    if let Some(n) = cli.threads {
        // Far more threads than cores only costs memory (and at 10⁵ the pool never starts).
        if n == 0 || n > MAX_THREADS {
            eprintln!("error: --threads {n}: must be between 1 and {MAX_THREADS}");
            return std::process::ExitCode::from(2);
        }
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().expect("thread pool is built once");
    }
    // Ctrl-C, SIGTERM, SIGHUP: remove the temporary files of the outputs being written, so an
    // interrupted run leaves no half files (finished outputs and checkpoints stay).
    if let Err(e) = ctrlc::set_handler(|| {
        cvtrace_streams::atomic::remove_pending_temporaries();
        eprintln!("interrupted");
        std::process::exit(130);
    }) {
        tracing::warn!("no signal handler: an interrupted run may leave temporary files ({e})");
    }
    let result = match cli.command {
        Command::Render(a) => cli::render::run(a),
        Command::Reconstruct(a) => cli::reconstruct::run(a),
        Command::Study(a) => cli::study::run(a),
        Command::Compare(a) => cli::compare::run(a),
        Command::Report(a) => cli::report::run(a),
    };
    // Interrupted: the signal handler is ending the process with its own code; an error that
    // came from its removing a file under a write is not this run's result.
    while cvtrace_streams::atomic::interrupted() {
        std::thread::park();
    }
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

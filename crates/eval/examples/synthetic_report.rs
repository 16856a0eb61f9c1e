//! Writes a synthetic study and its viewer, to try the viewer without rendering anything:
//!
//!     cargo run -p cvtrace-eval --example synthetic_report -- /tmp/cvtrace-synthetic
//!
//! then open /tmp/cvtrace-synthetic/report/index.html. The numbers come from toy
//! estimators on Gaussian noise and say nothing about the real ones.
use cvtrace_eval::synthetic::{write_synthetic_study, SyntheticOptions};
use cvtrace_eval::{table, write_report, ReportOptions};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "cvtrace-synthetic".into()));
    let study = out.join("study");
    let opts = SyntheticOptions { width: 160, height: 120, ..SyntheticOptions::small() };
    let results = write_synthetic_study(&study, &opts)?;
    print!("{}", table::terminal_report(&results));
    let index = write_report(&results, &study, &out.join("report"), &ReportOptions { title: "synthetic study".into(), overwrite: true })?;
    println!("\nviewer: {}", index.display());
    Ok(())
}

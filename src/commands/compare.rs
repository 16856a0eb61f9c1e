//! `cvtrace compare`: error of finished images against one reference, as a table
//! (terminal, and optionally CSV/JSON).
use anyhow::{bail, Result};
use cvtrace_eval::compare::{compare_files, compare_table};
use cvtrace_eval::{table, StudyResults};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Ground-truth EXR (channels R, G, B).
    #[arg(long)]
    pub reference: PathBuf,
    /// Images to score (EXR, channels R, G, B), e.g. the outputs of `cvtrace reconstruct --method all`.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Also write the table as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Also write the results as JSON (the study's schema).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Replace existing CSV/JSON files.
    #[arg(long)]
    pub force: bool,
}

pub fn run(args: CompareArgs) -> Result<()> {
    if let (Some(c), Some(j)) = (&args.csv, &args.json) {
        // Any two spellings of one file: the JSON would replace the CSV.
        if crate::cli::files::same_output(c, j) {
            bail!("{} and {}: --csv and --json name the same file", c.display(), j.display());
        }
    }
    let inputs: Vec<&std::path::Path> = std::iter::once(args.reference.as_path()).chain(args.images.iter().map(PathBuf::as_path)).collect();
    for p in args.csv.iter().chain(args.json.iter()) {
        crate::cli::files::refuse_overwriting_inputs(p, &inputs)?;
    }
    // Missing folders of the outputs are made, and taken back if the command fails.
    let mut made = Vec::new();
    let result = (|| {
        for p in args.csv.iter().chain(args.json.iter()) {
            made.extend(crate::cli::files::make_parent_folders(p)?);
            cvtrace_streams::atomic::check_writable(p, args.force)?;
        }
        compare(&args)
    })();
    if result.is_err() {
        made.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
        crate::cli::files::remove_empty(&made);
    }
    result
}

fn compare(args: &CompareArgs) -> Result<()> {
    // A PNG preview next to an EXR is an easy slip with `out/*`: skip it with a note.
    let (images, skipped): (Vec<PathBuf>, Vec<PathBuf>) =
        args.images.iter().cloned().partition(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")));
    for p in &skipped {
        tracing::warn!("{}: not an EXR file, skipped", p.display());
    }
    if images.is_empty() {
        bail!("no EXR images to compare among the {} paths given", args.images.len());
    }
    for p in std::iter::once(&args.reference).chain(&images) {
        crate::cli::files::check_input_file(p)?;
    }
    // `compare --reference ref.exr out/*.exr` with the reference inside `out/`: it is no estimate.
    let (references, images): (Vec<PathBuf>, Vec<PathBuf>) =
        images.into_iter().partition(|p| crate::cli::files::same_file(p, &args.reference));
    for p in &references {
        tracing::info!("{}: the reference itself, not scored", p.display());
    }
    if images.is_empty() {
        bail!("no images to compare: every EXR given is the reference {}", args.reference.display());
    }
    let scene = compare_files(&args.reference, &images)?;
    for w in &scene.warnings {
        tracing::warn!("{w}");
    }
    crate::cli::say!("{}", compare_table(&scene).trim_end_matches('\n'));
    let results = StudyResults::new(vec![scene]);
    // The CSV and the JSON are one set: if the second cannot be written, the first is taken back.
    let mut written = cvtrace_streams::atomic::OutputSet::new();
    if let Some(p) = &args.csv {
        written.write(p, || table::write_csv(&results, p, args.force))?;
    }
    if let Some(p) = &args.json {
        written.write(p, || results.write_json(p, args.force))?;
    }
    written.keep();
    Ok(())
}

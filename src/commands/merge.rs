//! `cvtrace merge`: the parts `render --part` wrote → exactly the file one render writes.
use anyhow::Result;
use cvtrace_streams::parts::{merge, STREAMS_KIND};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// The part files, in any order: every part of one render, each once.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output: the stream file (or reference) a one-shot render would have written.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
}

pub fn run(args: MergeArgs) -> Result<()> {
    for p in &args.parts {
        crate::cli::files::check_input_file(p)?;
        crate::cli::files::refuse_overwriting_inputs(&args.output, &[p])?;
    }
    let made = crate::cli::files::make_parent_folders(&args.output)?;
    let merged = match merge(&args.parts, &args.output, args.force) {
        Ok(m) => m,
        Err(e) => {
            crate::cli::files::remove_empty(&made);
            return Err(e.into());
        }
    };
    let what = if merged.kind == STREAMS_KIND { format!("{} batches", merged.units) } else { format!("{} spp", merged.units) };
    tracing::info!("merged {} parts ({what}) into {}", merged.parts, args.output.display());
    Ok(())
}

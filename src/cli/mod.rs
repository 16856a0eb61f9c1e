//! One file per subcommand.
pub mod compare;
pub mod reconstruct;
pub mod render;
pub mod report;
pub mod study;
pub mod throughput;

use anyhow::{bail, Result};
use std::path::Path;

/// Refuses an output path that names one of the command's inputs: with `--force` the input
/// would be replaced by the output (a stream file by an image, a reference by a CSV table).
pub fn refuse_overwriting_inputs(output: &Path, inputs: &[&Path]) -> Result<()> {
    let Ok(out) = output.canonicalize() else { return Ok(()) }; // not there yet: no input it can be
    for input in inputs {
        if input.canonicalize().is_ok_and(|i| i == out) {
            bail!("{}: is also an input of this command; write the output elsewhere", output.display());
        }
    }
    Ok(())
}

//! One file per subcommand.
pub mod compare;
pub mod reconstruct;
pub mod render;
pub mod report;
pub mod study;
pub mod throughput;

use anyhow::{bail, Result};
use std::path::Path;

/// True if both paths exist and are the same file: the same device and inode, so links, hard
/// links and `./` spellings all count; a path that does not exist yet is no other file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    matches!((std::fs::metadata(a), std::fs::metadata(b)), (Ok(a), Ok(b)) if a.dev() == b.dev() && a.ino() == b.ino())
}

/// Refuses an output path that names one of the command's inputs: with `--force` the input
/// would be replaced by the output (a stream file by an image, a reference by a CSV table).
pub fn refuse_overwriting_inputs(output: &Path, inputs: &[&Path]) -> Result<()> {
    for input in inputs {
        if same_file(output, input) {
            bail!("{}: is also an input of this command; write the output elsewhere", output.display());
        }
    }
    Ok(())
}

//! Paths on the command line: the folders an output needs (made, and taken back on failure),
//! outputs that would overwrite an input, two spellings of one file, inputs that are not
//! regular files, and the note an interrupt prints about the work in progress.
use anyhow::{bail, Result};
use cvtrace_streams::input_file::{regular_file, NotAFile};
use std::path::{Component, Path, PathBuf};

/// What an interrupt should tell the user about the work in progress (that a checkpoint is
/// kept, and how to resume), set by the command doing it.
static INTERRUPT_NOTE: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

pub fn set_interrupt_note(note: String) {
    *INTERRUPT_NOTE.lock().unwrap_or_else(|p| p.into_inner()) = Some(note);
}

/// The note, for the signal handler; never waits (the handler must not block on a lock).
pub fn interrupt_note() -> Option<String> {
    INTERRUPT_NOTE.try_lock().ok().and_then(|n| n.clone())
}

/// Makes the missing folders above `output`; returns them, deepest first, for [`remove_empty`].
pub fn make_parent_folders(output: &Path) -> Result<Vec<PathBuf>> {
    let Some(parent) = output.parent().filter(|p| !p.as_os_str().is_empty()) else { return Ok(Vec::new()) };
    let missing: Vec<PathBuf> =
        parent.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).map(Path::to_path_buf).collect();
    // `-o file.exr/sub.exr`: the folder to write in is a file.
    if let Some(file) = parent.ancestors().find(|p| !p.as_os_str().is_empty() && p.exists()).filter(|p| !p.is_dir()) {
        bail!("{}: {} is a file, not a folder", output.display(), file.display());
    }
    if !missing.is_empty() {
        cvtrace_streams::atomic::create_dir_all(parent)?;
    }
    Ok(missing)
}

/// Removes the folders of `dirs` that are empty (deepest first): what a failed command made.
pub fn remove_empty(dirs: &[PathBuf]) {
    for d in dirs {
        let _ = std::fs::remove_dir(d);
    }
}

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

/// `path` made absolute, `.` and `..` taken out, and the links of the part that exists resolved:
/// two spellings of one output (`t.csv`, `./t.csv`, `sub/../t.csv`, a linked folder) give the
/// same path even before the file exists.
pub fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut lexical = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                lexical.pop();
            }
            c => lexical.push(c),
        }
    }
    // The deepest existing ancestor with its links resolved, then the rest as written.
    let mut rest = Vec::new();
    let mut base = lexical.as_path();
    loop {
        if let Ok(real) = base.canonicalize() {
            return rest.iter().rev().fold(real, |p, name| p.join(name));
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                base = parent;
            }
            _ => return lexical,
        }
    }
}

/// True if `a` and `b` name the same output: the same file, or the same [`resolved`] path.
pub fn same_output(a: &Path, b: &Path) -> bool {
    same_file(a, b) || resolved(a) == resolved(b)
}

/// Fails unless `path` is a regular file (links followed): a directory or a missing file gets a
/// clear error, and a FIFO or device is not opened (reading a FIFO waits for a writer forever,
/// `/dev/zero` never ends).
pub fn check_input_file(path: &Path) -> Result<()> {
    match regular_file(path) {
        Ok(_) => Ok(()),
        Err(NotAFile::Io(e)) if e.kind() == std::io::ErrorKind::NotFound => bail!("{}: no such file", path.display()),
        Err(NotAFile::Io(e)) => bail!("{}: cannot read: {e}", path.display()),
        Err(e) => bail!("{}: {e}", path.display()),
    }
}

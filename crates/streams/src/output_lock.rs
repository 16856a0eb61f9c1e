//! Claiming an output that takes many steps to write (a reference render with its checkpoint,
//! a study folder), so that a second cvtrace process on the same output fails at once instead
//! of repeating the work and racing over the same files.
use crate::atomic::{interrupted, parent_dir, temp_name_parts, PendingTemp};
use crate::StreamError;
use std::path::{Path, PathBuf};

/// The hidden sibling `.{name}.lock` that an [`OutputLock`] on `path` uses (the name shortened
/// as for temporary files).
pub fn lock_path_for(path: &Path) -> PathBuf {
    let (prefix, _) = temp_name_parts(path);
    let name = prefix.strip_suffix(".tmp-").unwrap_or(&prefix);
    parent_dir(path).join(format!("{name}.lock"))
}

/// An exclusive claim on an output that takes many steps to write (a reference render with
/// its checkpoint, a study folder): a second cvtrace process asking for the same claim fails
/// at once instead of repeating the work and racing over the same files. The claim is an
/// advisory lock (`flock`) on a hidden lock file, which the operating system releases when the
/// process ends however it ends; the file itself is removed when the claim is dropped.
pub struct OutputLock {
    /// Holds the lock while open.
    _file: std::fs::File,
    /// The lock file's path, registered so that the signal handler removes it too.
    path: PendingTemp,
}

impl OutputLock {
    /// Claims `lock_path` for writing `what` (named in the error).
    pub fn acquire(lock_path: &Path, what: &Path) -> Result<OutputLock, StreamError> {
        let io = |e| StreamError::Io { path: lock_path.to_path_buf(), error: e };
        let not_regular = || StreamError::invalid(lock_path, "is not a regular file; remove it (it is cvtrace's lock file)");
        loop {
            // Not through a link or onto a FIFO (opening one would wait for a reader).
            if lock_path.symlink_metadata().is_ok_and(|m| !m.is_file()) {
                return Err(not_regular());
            }
            let file = std::fs::OpenOptions::new().create(true).truncate(false).write(true).open(lock_path).map_err(io)?;
            if !file.metadata().map_err(io)?.is_file() {
                return Err(not_regular());
            }
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(StreamError::invalid(
                        what,
                        format!("is being written by another cvtrace process (it holds {})", lock_path.display()),
                    ))
                }
                // A file system without locks: go on unguarded, as before locks existed.
                Err(std::fs::TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {}
                Err(std::fs::TryLockError::Error(e)) => return Err(io(e)),
            }
            // The previous holder removes the file on release: if that happened between our
            // open and our lock, we hold a lock on a file nobody else can see. Try again.
            if still_at(&file, lock_path) {
                if interrupted() {
                    // The signal handler has cleaned up already and is ending the process.
                    let _ = std::fs::remove_file(lock_path);
                    loop {
                        std::thread::park();
                    }
                }
                return Ok(OutputLock { _file: file, path: PendingTemp::new(lock_path.to_path_buf()) });
            }
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Removed while still locked, so no one can take the old file for a live claim.
        let _ = std::fs::remove_file(&self.path.0);
    }
}

#[cfg(unix)]
fn still_at(file: &std::fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    matches!((file.metadata(), std::fs::metadata(path)), (Ok(a), Ok(b)) if a.ino() == b.ino() && a.dev() == b.dev())
}

#[cfg(not(unix))]
fn still_at(_file: &std::fs::File, path: &Path) -> bool {
    path.exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_claim_on_the_same_output_fails_until_the_first_ends() {
        let dir = tempfile::tempdir().unwrap();
        let (lock, what) = (dir.path().join(".x.lock"), dir.path().join("x.exr"));
        let first = OutputLock::acquire(&lock, &what).unwrap();
        let e = OutputLock::acquire(&lock, &what).err().unwrap().to_string();
        assert!(e.contains("x.exr") && e.contains("another cvtrace process") && e.contains(".x.lock"), "{e}");
        drop(first);
        assert!(!lock.exists(), "the lock file goes with the claim");
        let again = OutputLock::acquire(&lock, &what).unwrap();
        assert!(lock.exists());
        drop(again);
        // A lock path that is a link or a FIFO is refused, not followed or waited on.
        std::os::unix::fs::symlink(dir.path().join("elsewhere"), &lock).unwrap();
        let e = OutputLock::acquire(&lock, &what).err().unwrap().to_string();
        assert!(e.contains("not a regular file") && !dir.path().join("elsewhere").exists(), "{e}");
    }
}

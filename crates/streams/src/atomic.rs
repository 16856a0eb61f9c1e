//! Atomic output: write next to the target under a temporary name, then rename.
//!
//! A crash never leaves half a file at the target path, and an existing file is only
//! replaced when the caller says so.
use crate::StreamError;
use std::path::{Path, PathBuf};

/// Fails early (before any expensive work) when `path` cannot be written as asked.
pub fn check_writable(path: &Path, overwrite: bool) -> Result<(), StreamError> {
    if path.exists() && !overwrite {
        return Err(StreamError::AlreadyExists { path: path.to_path_buf() });
    }
    if path.is_dir() {
        return Err(StreamError::invalid(path, "is a directory, expected a file path"));
    }
    let parent = parent_dir(path);
    if !parent.is_dir() {
        return Err(StreamError::invalid(path, format!("output directory {} does not exist", parent.display())));
    }
    let md = std::fs::metadata(&parent).map_err(|e| StreamError::Io { path: parent.clone(), error: e })?;
    if md.permissions().readonly() {
        return Err(StreamError::invalid(path, format!("output directory {} is not writable", parent.display())));
    }
    Ok(())
}

/// Fails unless `path` ends in `.{ext}` (any case). The writers pick the format, not the name:
/// an OpenEXR file called `out.png` would mislead every viewer and tool that trusts the name.
pub fn check_extension(path: &Path, ext: &str) -> Result<(), StreamError> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
        return Ok(());
    }
    let format = match ext {
        "exr" => "OpenEXR",
        "png" => "PNG",
        _ => ext,
    };
    Err(StreamError::invalid(path, format!("this output is written as {format}; give it a .{ext} file name")))
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The temporary sibling used while `path` is being written. It keeps the extension so
/// that format libraries which look at it behave the same.
pub fn temp_path_for(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    parent_dir(path).join(format!(".{name}.tmp-{}{ext}", std::process::id()))
}

/// Runs `write` on a temporary path and renames the result onto `path`.
/// On any error the temporary file is removed and `path` is untouched.
pub fn write_atomically<E>(
    path: &Path,
    overwrite: bool,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), StreamError>
where
    E: std::fmt::Display,
{
    check_writable(path, overwrite)?;
    let tmp = temp_path_for(path);
    if let Err(e) = write(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        return Err(StreamError::invalid(path, format!("could not write: {e}")));
    }
    // Re-check just before the rename: another process may have created the file meanwhile.
    if path.exists() && !overwrite {
        let _ = std::fs::remove_file(&tmp);
        return Err(StreamError::AlreadyExists { path: path.to_path_buf() });
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        StreamError::Io { path: path.to_path_buf(), error: e }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        let r = write_atomically(&p, false, |tmp| {
            std::fs::write(tmp, b"half").unwrap();
            Err::<(), _>("boom")
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn refuses_to_overwrite_without_permission() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        std::fs::write(&p, b"mine").unwrap();
        let r = write_atomically(&p, false, |tmp| std::fs::write(tmp, b"new").map_err(|e| e.to_string()));
        assert!(matches!(r, Err(StreamError::AlreadyExists { .. })));
        assert_eq!(std::fs::read(&p).unwrap(), b"mine");
        write_atomically(&p, true, |tmp| std::fs::write(tmp, b"new").map_err(|e| e.to_string())).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
    }

    #[test]
    fn extension_must_match_the_format() {
        assert!(check_extension(Path::new("out/a.exr"), "exr").is_ok());
        assert!(check_extension(Path::new("A.EXR"), "exr").is_ok());
        for bad in ["a.png", "a", "a.exr.tmp", "exr"] {
            let e = check_extension(Path::new(bad), "exr").unwrap_err().to_string();
            assert!(e.starts_with(bad) && e.contains("OpenEXR") && e.contains(".exr file name"), "{e}");
        }
        assert!(check_extension(Path::new("a.exr"), "png").unwrap_err().to_string().contains("PNG"));
    }

    #[test]
    fn missing_directory_is_reported() {
        let r = check_writable(Path::new("/nonexistent-dir-cvtrace/x.exr"), false);
        assert!(r.unwrap_err().to_string().contains("does not exist"));
    }
}

//! The check every input file passes before it is opened: it must be a regular file.
//!
//! Why: a FIFO blocks a read forever, a device such as /dev/zero never ends one, and a folder
//! fails later with a confusing error. Scenes, sidecars, textures, EXR inputs, results files
//! and report images all go through [`regular_file`], so they fail alike, naming the file.
use std::fmt;
use std::path::Path;

/// Why a path cannot be read as an input file.
#[derive(Debug)]
pub enum NotAFile {
    /// It does not exist or cannot be looked at.
    Io(std::io::Error),
    Directory,
    /// A device, FIFO or socket.
    Special,
}

impl fmt::Display for NotAFile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NotAFile::Io(e) => write!(f, "{e}"),
            NotAFile::Directory => write!(f, "is a directory, expected a file"),
            NotAFile::Special => write!(f, "is not a regular file (a device, FIFO or socket)"),
        }
    }
}

/// The length of `path` if it is a regular file (following links), or why it is not one.
pub fn regular_file(path: &Path) -> Result<u64, NotAFile> {
    let md = std::fs::metadata(path).map_err(NotAFile::Io)?;
    if md.is_dir() {
        Err(NotAFile::Directory)
    } else if !md.is_file() {
        Err(NotAFile::Special)
    } else {
        Ok(md.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_pass() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.txt");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(regular_file(&file).unwrap(), 5);
        assert!(matches!(regular_file(dir.path()), Err(NotAFile::Directory)));
        assert!(matches!(regular_file(Path::new("/dev/null")), Err(NotAFile::Special)));
        let missing = regular_file(&dir.path().join("none")).unwrap_err();
        assert!(matches!(&missing, NotAFile::Io(e) if e.kind() == std::io::ErrorKind::NotFound), "{missing}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("fifo");
            assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
            assert!(matches!(regular_file(&fifo), Err(NotAFile::Special)));
            assert!(regular_file(&fifo).unwrap_err().to_string().contains("not a regular file"));
        }
    }
}

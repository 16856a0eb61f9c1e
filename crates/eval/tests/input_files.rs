//! The evaluation crate's own readers (results files, report images) refuse anything but a
//! regular file at once, naming it: a FIFO would block them forever, a device never end.
use cvtrace_eval::report::png_size;
use cvtrace_eval::StudyResults;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// Runs `read` on `path` in a thread and returns its error text; a read that blocks fails the
/// test after 10 s instead of hanging it.
fn error_of(path: &Path, read: fn(&Path) -> Result<(), String>) -> String {
    let (tx, rx) = mpsc::channel();
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(read(&p));
    });
    match rx.recv_timeout(Duration::from_secs(10)) {
        Ok(r) => r.expect_err(&format!("{} was read as a file", path.display())),
        Err(_) => panic!("reading {} blocked", path.display()),
    }
}

fn special_files(dir: &Path) -> Vec<(PathBuf, &'static str)> {
    let fifo = dir.join("fifo");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    vec![(fifo, "not a regular file"), ("/dev/null".into(), "not a regular file"), (dir.to_path_buf(), "is a directory")]
}

#[test]
fn results_files_that_are_not_regular_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (path, why) in special_files(dir.path()) {
        let e = error_of(&path, |p| StudyResults::read_json(p).map(|_| ()).map_err(|e| e.to_string()));
        assert!(e.contains(&path.display().to_string()) && e.contains(why), "{e}");
    }
}

#[test]
fn report_images_that_are_not_regular_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (path, why) in special_files(dir.path()) {
        let e = error_of(&path, |p| png_size(p).map(|_| ()));
        assert!(e.contains(why), "{}: {e}", path.display());
    }
}

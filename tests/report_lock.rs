//! Two `report` runs into one folder: while the first writes, a second one is refused with or
//! without `--force` (the folder's lock), and a first run that fails half-way takes back only
//! the files it wrote, never a file someone else put into its folder.
//!
//! The testing aid `CVTRACE_TEST_PAUSE_REPORT=FILE` makes `report` create FILE once it holds the
//! folder and has made it, and wait until FILE is removed: the second run starts at that known
//! point instead of at a lucky moment.
mod common;

use common::{cvtrace, files_in, ok, scene, stderr, SMALL};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A one-seed study of the Cornell box in `dir/st`.
fn study(dir: &Path) {
    let s = scene();
    let args = [
        &["--log", "warn", "study", s.to_str().unwrap(), "--spp", "4", "--seeds", "1", "--batches", "4"][..],
        &["--reference", "ref.exr", "--reference-spp", "16", "-o", "st"],
        SMALL,
    ]
    .concat();
    ok(&cvtrace(dir, &args));
}

/// `report st -o out`, paused at the testing aid's point until `signal` is removed.
fn paused_report(dir: &Path, out: &str, signal: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(["--log", "warn", "report", "st", "-o", out])
        .env("CVTRACE_TEST_PAUSE_REPORT", signal)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits until `child` has paused (created `signal`).
fn wait_for_pause(signal: &Path, child: &mut Child) {
    for _ in 0..3000 {
        if signal.exists() {
            return;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the first report ended ({status}) without pausing at CVTRACE_TEST_PAUSE_REPORT");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("the first report never paused");
}

#[test]
fn a_second_report_into_a_folder_being_written_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    study(d);
    ok(&cvtrace(d, &["--log", "warn", "report", "st", "-o", "alone"]));
    let signal = d.join("paused");
    let mut first = paused_report(d, "rep", &signal);
    wait_for_pause(&signal, &mut first);
    // Into the first one's still empty folder, and over it with --force: both refused, and
    // neither writes a file there.
    for force in [&[][..], &["--force"]] {
        let second = cvtrace(d, &[&["--log", "warn", "report", "st", "-o", "rep"][..], force].concat());
        let e = stderr(&second);
        assert!(!second.status.success(), "a second report {force:?} ran alongside the first:\n{e}");
        assert!(e.contains("rep") && e.contains("another cvtrace process"), "{force:?}: {e}");
        assert!(files_in(&d.join("rep")).is_empty(), "{force:?} wrote into the first one's folder: {:?}", files_in(&d.join("rep")));
    }
    std::fs::remove_file(&signal).unwrap();
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "the first report failed: {}", String::from_utf8_lossy(&first.stderr));
    assert_eq!(files_in(&d.join("rep")), files_in(&d.join("alone")), "the first report is whole");
    // The claim goes with the run.
    assert!(!files_in(d).iter().any(|f| f.ends_with(".lock")), "{:?}", files_in(d));
}

#[test]
fn a_report_that_fails_half_way_takes_back_only_its_own_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    study(d);
    let signal = d.join("paused");
    let mut first = paused_report(d, "rep", &signal);
    wait_for_pause(&signal, &mut first);
    // Someone else's files in the folder, one of them where the report's plots go: the report
    // fails half-way (its images copied), in the folder it made.
    std::fs::write(d.join("rep/notes.txt"), "mine").unwrap();
    std::fs::write(d.join("rep/plots"), "mine too").unwrap();
    std::fs::remove_file(&signal).unwrap();
    let first = first.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&first.stderr);
    assert!(!first.status.success() && e.contains("plots"), "{e}");
    assert_eq!(files_in(&d.join("rep")), ["notes.txt", "plots"], "the report took back its own files, and only those");
    assert_eq!(std::fs::read_to_string(d.join("rep/notes.txt")).unwrap(), "mine");
}

//! Helpers shared by the end-to-end tests of the `cvtrace` binary.
#![allow(dead_code)]
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The shipped Cornell box.
pub fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.gltf")
}

/// Runs `cvtrace <args>` in `dir`.
pub fn cvtrace(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cvtrace")).args(args).current_dir(dir).output().expect("the cvtrace binary runs")
}

pub fn ok(out: &Output) {
    assert!(out.status.success(), "cvtrace failed ({}):\n{}", out.status, String::from_utf8_lossy(&out.stderr));
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// File names in `dir`, sorted.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// Small, quick render settings for tests.
pub const SMALL: &[&str] = &["--width", "32", "--height", "32", "--max-depth", "6"];

/// Sends `signal` to the child process, as a user's Ctrl-C or a scheduler's kill would.
pub fn interrupt(child: &std::process::Child, signal: rustix::process::Signal) {
    let pid = rustix::process::Pid::from_child(child);
    rustix::process::kill_process(pid, signal).expect("the child is alive to be signalled");
}

/// A stream file `s.streams.exr` (8 spp, 4 batches, seed 3) and a reference `ref.exr` of the
/// same small view (16 spp, seed 99), in `dir`.
pub fn stream_and_reference(dir: &Path) {
    let s = scene();
    let sp = s.to_str().unwrap();
    ok(&cvtrace(
        dir,
        &[&["--log", "warn", "render", sp, "--spp", "8", "--batches", "4", "--seed", "3", "-o", "s.streams.exr"][..], SMALL].concat(),
    ));
    ok(&cvtrace(
        dir,
        &[&["--log", "warn", "render", sp, "--reference", "--spp", "16", "--seed", "99", "-o", "ref.exr"][..], SMALL].concat(),
    ));
}

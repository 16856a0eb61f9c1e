//! What a command prints on stdout is part of its result: written to a full disk (`/dev/full`)
//! the command fails with a message that says so, instead of ending well with an empty file. A
//! closed pipe (`| head -1`) stays quiet: the reader has seen what it wanted.
mod common;

use common::{cvtrace, ok, scene, SMALL};
use std::path::Path;
use std::process::{Command, Output, Stdio};

/// Runs `cvtrace args` in `dir` with stdout on `/dev/full`, where every write fails with ENOSPC.
fn to_full_disk(dir: &Path, args: &[&str]) -> Output {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").expect("/dev/full");
    Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(full)
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

fn fails_on_stdout(dir: &Path, args: &[&str]) {
    let out = to_full_disk(dir, args);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{args:?} with stdout on /dev/full:\n{e}");
    assert!(e.contains("standard output") && e.contains("No space left on device"), "{args:?}: the error should say so:\n{e}");
    assert!(!e.contains("panicked"), "{args:?}:\n{e}");
}

#[test]
fn printed_results_on_a_full_disk_fail_the_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    // Help, version and listings, from clap and from cvtrace.
    for args in
        [&["--help"][..], &["--version"], &["render", "--help"], &["reconstruct", "--list"], &["reconstruct", "--help-method", "ours"]]
    {
        fails_on_stdout(d, args);
    }
    ok(&cvtrace(
        d,
        &[&["--log", "warn", "render", sp, "--spp", "8", "--batches", "4", "--seed", "3", "-o", "s.streams.exr"][..], SMALL].concat(),
    ));
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "--reference", "--spp", "16", "--seed", "9", "-o", "ref.exr"][..], SMALL].concat()));
    // The tables of reconstruct, compare and study, and farm's instructions.
    fails_on_stdout(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "pt", "--reference", "ref.exr", "-o", "pt.exr"]);
    fails_on_stdout(d, &["--log", "warn", "compare", "--reference", "ref.exr", "pt.exr"]);
    let study =
        [&["--log", "warn", "study", sp, "--spp", "4", "--seeds", "1", "--batches", "4", "--reference", "ref.exr", "-o", "st"][..], SMALL]
            .concat();
    fails_on_stdout(d, &study);
    fails_on_stdout(
        d,
        &[&["--log", "warn", "farm", "render", sp, "--spp", "8", "--batches", "4", "--parts", "2", "-o", "f.streams.exr"][..], SMALL]
            .concat(),
    );
}

//! A closed pipe never costs the work: `cvtrace render ... 2>&1 | head -1` and `reconstruct ...
//! | head -0` write their outputs and succeed although nothing can be printed, and log lines go
//! without colour codes to anything that is not a terminal.
mod common;

use common::{scene, SMALL};
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};

/// Runs `cvtrace args` in `dir` with stdout and stderr on a pipe whose reading end is closed
/// before the process starts, so that every write it makes fails with EPIPE.
fn with_closed_pipes(dir: &Path, args: &[&str]) -> ExitStatus {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(writer.try_clone().unwrap())
        .stderr(writer)
        .status()
        .unwrap()
}

#[test]
fn renders_and_reconstructions_finish_with_their_output_closed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let render =
        [&["--log", "info", "render", s.to_str().unwrap(), "--spp", "8", "--batches", "4", "-o", "s.streams.exr"][..], SMALL].concat();
    let status = with_closed_pipes(d, &render);
    assert!(status.success(), "render: {status}");
    assert!(d.join("s.streams.exr").is_file());
    let status = with_closed_pipes(d, &["--log", "info", "reconstruct", "s.streams.exr", "--method", "all", "-o", "out"]);
    assert!(status.success(), "reconstruct: {status}");
    assert!(d.join("out/ours.exr").is_file() && d.join("out/pt.png").is_file());
    // An error still ends the command with its code, told to no one.
    let status = with_closed_pipes(d, &["reconstruct", "missing.exr", "-o", "x.exr"]);
    assert_eq!(status.code(), Some(1));
}

#[test]
fn log_lines_to_a_file_carry_no_colour_codes_and_unknown_levels_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let out = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args([&["--log", "info", "render", s.to_str().unwrap(), "--spp", "4", "--batches", "4", "-o", "x.exr"][..], SMALL].concat())
        .current_dir(d)
        .env_remove("RUST_LOG")
        .env_remove("NO_COLOR")
        .output()
        .unwrap();
    assert!(out.status.success());
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(log.contains("INFO") && !log.contains('\u{1b}'), "{log}");
    for bad in ["bogus", "cvtrace=loud", ""] {
        let out = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
            .args(["--log", bad, "reconstruct", "--list"])
            .env_remove("RUST_LOG")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "--log {bad:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--log"), "--log {bad:?}");
    }
    for good in ["warn", "cvtrace=debug,info", "OFF"] {
        let out = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
            .args(["--log", good, "reconstruct", "--list"])
            .env_remove("RUST_LOG")
            .output()
            .unwrap();
        assert!(out.status.success(), "--log {good:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

#[test]
fn help_and_listings_into_a_closed_pipe_end_well() {
    let dir = tempfile::tempdir().unwrap();
    for args in
        [&["--help"][..], &["--version"], &["render", "--help"], &["reconstruct", "--list"], &["reconstruct", "--help-method", "ours"]]
    {
        let status = with_closed_pipes(dir.path(), args);
        assert!(status.success(), "{args:?}: {status}");
    }
}

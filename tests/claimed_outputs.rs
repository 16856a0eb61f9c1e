//! An output that cannot be written, or that another process is writing, is an error before
//! any rendering, not after it: the folder is probed by making a file in it, and a stream
//! render claims its output for the whole render.
mod common;

use common::{cvtrace, ok, scene, stderr, SMALL};
use std::os::unix::fs::PermissionsExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn render_args<'a>(scene: &'a str, spp: &'a str, output: &'a str) -> Vec<&'a str> {
    [&["--log", "info", "render", scene, "--spp", spp, "--batches", "4", "-o", output][..], SMALL].concat()
}

#[test]
fn writability_is_probed_not_read_from_permission_bits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    std::fs::create_dir(d.join("locked")).unwrap();
    std::fs::set_permissions(d.join("locked"), std::fs::Permissions::from_mode(0o555)).unwrap();
    let is_root = rustix::process::geteuid().is_root();
    if is_root {
        // Root writes into a mode-555 folder: refusing it because of the bits was wrong.
        ok(&cvtrace(d, &render_args(sp, "4", "locked/x.streams.exr")));
        assert!(d.join("locked/x.streams.exr").is_file());
        // Another user cannot: told before the render starts, naming the folder. That user
        // must reach the binary, its libraries and the scene first, which a checkout in a
        // private folder (a `mktemp -d` clone) does not let it.
        let as_nobody = || {
            let mut c = Command::new("setpriv");
            c.args(["--reuid=65534", "--regid=65534", "--clear-groups", env!("CARGO_BIN_EXE_cvtrace")]).current_dir(d);
            c
        };
        let probe = as_nobody().arg("--version").output().unwrap();
        if probe.status.success() {
            let out = as_nobody().args(render_args(sp, "4", "locked/y.streams.exr")).output().unwrap();
            let e = stderr(&out);
            assert!(!out.status.success() && e.contains("locked") && e.contains("not writable"), "{e}");
            assert!(!e.contains("rendering"), "the render started before the output was found unwritable:\n{e}");
        } else {
            eprintln!("not checked as another user, who cannot run this build from where it is: {}", stderr(&probe));
        }
    } else {
        let out = cvtrace(d, &render_args(sp, "4", "locked/y.streams.exr"));
        let e = stderr(&out);
        assert!(!out.status.success() && e.contains("not writable") && !e.contains("rendering"), "{e}");
    }
    // The probe leaves nothing behind.
    let names: Vec<_> = std::fs::read_dir(d.join("locked")).unwrap().flatten().map(|e| e.file_name()).collect();
    assert!(names.len() <= 1, "{names:?}");
}

#[test]
fn a_second_render_to_the_same_output_fails_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let long = [
        &["--log", "info", "render", sp, "--spp", "256", "--batches", "4", "-o", "same.streams.exr"][..],
        &["--width", "96", "--height", "96", "--max-depth", "6"],
    ]
    .concat();
    let first = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(&long)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lock = d.join(".same.streams.exr.lock");
    let start = Instant::now();
    while !lock.exists() && start.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(lock.exists(), "the first render never claimed its output");
    let t = Instant::now();
    let second = cvtrace(d, &long);
    let took = t.elapsed();
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    let e = stderr(&second);
    assert!(!second.status.success() && e.contains("another cvtrace process"), "{e}");
    assert!(!e.contains("rendering"), "the second render started: {e}");
    assert!(took < Duration::from_secs(5), "refused only after {took:?}");
    assert!(!lock.exists(), "the lock file is removed with the claim");
}

//! Ctrl-C during `report` into a new folder leaves either no folder or the complete report,
//! never half of one that the next `report` refuses as "not empty".
mod common;

use common::{cvtrace, interrupt, ok, scene, SMALL};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn an_interrupted_report_leaves_nothing_or_everything() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let study = [
        &["--log", "warn", "study", s.to_str().unwrap(), "--spp", "4", "--seeds", "1", "--batches", "4"][..],
        &["--reference", "ref.exr", "--reference-spp", "16", "-o", "st"],
        SMALL,
    ]
    .concat();
    ok(&cvtrace(d, &study));
    let started = std::time::Instant::now();
    ok(&cvtrace(d, &["--log", "warn", "report", "st", "-o", "whole"]));
    // Interrupts spread over the time a report takes, from its start to past its end.
    let took = started.elapsed().max(Duration::from_millis(20));
    let mut interrupted = 0;
    for i in 0..24u32 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
            .args(["--log", "warn", "report", "st", "-o", "rep"])
            .current_dir(d)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(took * i / 20);
        // SAFETY: kill(2) on the child's own PID, which has not been waited for yet.
        interrupt(&child, rustix::process::Signal::INT);
        let status = child.wait().unwrap();
        interrupted += usize::from(status.code() == Some(130));
        let rep = d.join("rep");
        if rep.exists() {
            for f in ["index.html", "data.js", "viewer.js", "results.json"] {
                assert!(rep.join(f).is_file(), "interrupt {i} ({status}): a partial report without {f}");
            }
            std::fs::remove_dir_all(&rep).unwrap();
        }
        // No temporaries left next to it either.
        let litter: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains("tmp"))
            .collect();
        assert!(litter.is_empty(), "interrupt {i}: {litter:?}");
    }
    assert!(interrupted >= 4, "only {interrupted} of 24 runs were interrupted; the test did not test");
}

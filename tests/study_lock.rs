//! Two studies started into one new folder: the second is refused by the folder's lock and,
//! on its way out, takes back nothing the first one made, so the first finishes.
mod common;

use common::{scene, stderr};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn a_second_study_into_the_same_new_folder_leaves_the_first_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    // Large enough that the first study is still rendering into its first spp folder (empty
    // until that render is written) when the second one gives up.
    let args = [
        &["--log", "warn", "study", s.to_str().unwrap(), "--spp", "32,64", "--seeds", "2", "--batches", "4"][..],
        &["--reference", "ref.exr", "--reference-spp", "16", "-o", "st"],
        &["--width", "96", "--height", "96", "--max-depth", "6"],
    ]
    .concat();
    let first = Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(&args)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The second starts while the first renders into its first spp folder.
    let busy = d.join("st/spp00032");
    for _ in 0..2000 {
        if busy.exists() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(busy.exists(), "the first study never started its renders");
    let second = Command::new(env!("CARGO_BIN_EXE_cvtrace")).args(&args).current_dir(d).output().unwrap();
    assert!(!second.status.success(), "the second study ran alongside the first");
    assert!(stderr(&second).contains("st"), "{}", stderr(&second));
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "the first study failed: {}", String::from_utf8_lossy(&first.stderr));
    assert!(d.join("st/results.json").is_file() && d.join("st/spp00064/seed-001.streams.exr").is_file());
}

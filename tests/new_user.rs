//! Habits a new user brings from Mitsuba and pbrt: `-t N`, `render --spp 8` without thinking
//! of batches, and outputs into folders that do not exist yet.
mod common;

use common::{cvtrace, ok, scene, stderr, SMALL};
use cvtrace_streams::exr_io::{AttrValue, ExrChannels};

#[test]
fn batches_default_to_what_divides_spp_and_outputs_make_their_folders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    for (spp, batches) in [("8", 8), ("12", 4), ("48", 16), ("7", 1)] {
        let out = format!("new/{spp}/x.streams.exr");
        let run = cvtrace(d, &[&["--log", "info", "-t", "1", "render", sp, "--spp", spp, "-o", &out][..], SMALL].concat());
        ok(&run);
        let file = ExrChannels::read(&d.join(&out)).unwrap();
        assert_eq!(file.attr("cvtrace.batches"), Some(&AttrValue::Int(batches)), "--spp {spp}");
        if batches != 16 {
            assert!(stderr(&run).contains(&format!("{batches} batches")), "the choice is logged:\n{}", stderr(&run));
        }
    }
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "new/8/x.streams.exr", "--method", "ours", "-o", "deeper/still/ours.exr"]));
    assert!(d.join("deeper/still/ours.exr").is_file());
    // A value given that does not divide stays an error, and the folders it would have made go.
    let bad = cvtrace(d, &[&["render", sp, "--spp", "8", "--batches", "3", "-o", "gone/x.streams.exr"][..], SMALL].concat());
    assert!(!bad.status.success() && stderr(&bad).contains("multiple of batches (3)"), "{}", stderr(&bad));
    assert!(!d.join("gone").exists());
}

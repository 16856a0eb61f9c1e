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

#[test]
fn a_stream_file_opens_as_its_picture_and_render_writes_a_preview() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "--spp", "8", "-o", "s.streams.exr", "--preview", "s.png"][..], SMALL].concat()));
    // The top-level layer is the mean of both streams: what `average` reconstructs.
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "average", "-o", "avg.exr"]));
    let picture = cvtrace_streams::exr_io::read_picture(&d.join("s.streams.exr")).unwrap();
    // As an image to score it is refused: the picture is no reconstruction.
    assert!(cvtrace_streams::exr_io::read_rgb(&d.join("s.streams.exr")).unwrap_err().to_string().contains("is a PT/CRN stream file"));
    assert_eq!(picture, cvtrace_streams::exr_io::read_rgb(&d.join("avg.exr")).unwrap());
    let png = std::fs::read(d.join("s.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "the preview is a PNG");
    // OpenImageIO's tools show the picture by default: an opaque RGBA export of the top layer.
    let have = std::process::Command::new("oiiotool").arg("--version").output().is_ok();
    assert!(have || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "oiiotool is missing and CVTRACE_REQUIRE_TOOLS is set");
    if have {
        let out = std::process::Command::new("oiiotool").args(["s.streams.exr", "-o", "o.png"]).current_dir(d).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let stats = std::process::Command::new("oiiotool").args(["--stats", "o.png"]).current_dir(d).output().unwrap();
        let text = String::from_utf8_lossy(&stats.stdout);
        let min = text.lines().find(|l| l.contains("Stats Min")).unwrap_or_default();
        assert!(min.trim_end().ends_with("255 (of 255)"), "alpha is opaque: {text}");
    }
}

#[test]
fn ctrl_c_on_a_reference_render_says_how_to_resume() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let args = [
        &["--log", "warn", "render", s.to_str().unwrap(), "--reference", "--spp", "100000", "--pass-spp", "1", "-o", "r.ref.exr"][..],
        SMALL,
    ]
    .concat();
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_cvtrace"))
        .args(&args)
        .current_dir(d)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !d.join("r.ref.checkpoint.exr").exists() {
        assert!(start.elapsed().as_secs() < 60, "no checkpoint after 60 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // SAFETY: kill(2) on our own child's pid, not yet waited for.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130));
    let e = stderr(&out);
    assert!(e.contains("r.ref.checkpoint.exr") && e.contains("run the same command again to resume"), "{e}");
}

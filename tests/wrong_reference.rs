//! A reference is the ground truth of one image: `reconstruct --reference` (and `--pt2n`) and
//! `compare --reference` refuse one whose recorded scene, camera, size or path length differs from what
//! it scores (as `study` does), and warn, naming it, when it holds negative pixels.
mod common;

use common::{cvtrace, ok, scene, stderr, SMALL};
use cvtrace_streams::exr_io::ExrChannels;
use std::path::{Path, PathBuf};

fn other_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/door-ajar/scene.gltf")
}

#[test]
fn a_reference_of_another_scene_is_refused_and_negative_pixels_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (s, o) = (scene(), other_scene());
    let (sp, op) = (s.to_str().unwrap(), o.to_str().unwrap());
    ok(&cvtrace(
        d,
        &[&["--log", "warn", "render", sp, "--spp", "8", "--batches", "4", "--seed", "3", "-o", "s.streams.exr"][..], SMALL].concat(),
    ));
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "--reference", "--spp", "16", "--seed", "9", "-o", "ref.exr"][..], SMALL].concat()));
    // The same size and depth, another scene.
    ok(&cvtrace(d, &[&["--log", "warn", "render", op, "--reference", "--spp", "4", "--seed", "9", "-o", "other.exr"][..], SMALL].concat()));

    let out = cvtrace(d, &["reconstruct", "s.streams.exr", "--method", "pt", "--reference", "other.exr", "-o", "pt.exr"]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("other.exr") && e.contains("scene hash"), "{e}");
    assert!(!d.join("pt.exr").exists());
    // A PT(2n) render of another scene is refused the same way.
    let out = cvtrace(d, &["reconstruct", "s.streams.exr", "--method", "pt2n-oidn", "--pt2n", "other.exr", "-o", "pt2n.exr"]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("other.exr") && e.contains("PT(2n) render") && e.contains("scene hash"), "{e}");
    assert!(!d.join("pt2n.exr").exists());
    let out = cvtrace(d, &["compare", "--reference", "other.exr", "ref.exr"]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("other.exr") && e.contains("ref.exr") && e.contains("scene hash"), "{e}");

    // The right reference scores; with a negative pixel the user hears of it on stderr.
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "pt", "--reference", "ref.exr", "-o", "pt.exr"]));
    let mut negative = ExrChannels::read(&d.join("ref.exr")).unwrap();
    negative.channels.get_mut("G").unwrap()[5] = -0.25;
    negative.write(&d.join("negative.exr"), false).unwrap();
    let out =
        cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "pt", "--reference", "negative.exr", "-o", "pt2.exr"]);
    ok(&out);
    assert!(stderr(&out).contains("negative.exr") && stderr(&out).contains("negative"), "{}", stderr(&out));
    let out = cvtrace(d, &["--log", "warn", "compare", "--reference", "negative.exr", "pt.exr"]);
    ok(&out);
    assert!(stderr(&out).contains("negative.exr: 1 reference pixels are negative"), "{}", stderr(&out));
}

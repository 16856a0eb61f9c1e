//! The scene sidecar `<stem>.cvtrace.toml` end to end: `cvtrace render` takes its size, spp and
//! path limits from it unless flags say otherwise, `--reference` takes `reference_spp`, an
//! environment light in it renders, and a bad sidecar fails before anything is written.
use cvtrace_streams::exr_io::{write_rgb, AttrValue, ExrChannels};
use cvtrace_streams::{Image, StreamSet};
mod common;

use common::{cvtrace, files_in, ok, scene, stderr};
use std::path::Path;

/// A copy of the shipped Cornell box in `dir` (scene.gltf + scene.bin), with `sidecar` as its
/// `scene.cvtrace.toml`.
fn scene_folder(dir: &Path, sidecar: &str) {
    let src = scene();
    let from = src.parent().unwrap();
    for f in ["scene.gltf", "scene.bin"] {
        std::fs::copy(from.join(f), dir.join(f)).unwrap();
    }
    std::fs::write(dir.join("scene.cvtrace.toml"), sidecar).unwrap();
}

const SIDECAR: &str = "[render]\nwidth = 24\nheight = 16\nspp = 4\nmax_depth = 3\nrr_depth = 2\nreference_spp = 6\n";

#[test]
fn renders_at_the_sidecar_settings_and_flags_override_them() {
    let dir = tempfile::tempdir().unwrap();
    scene_folder(dir.path(), SIDECAR);
    let out = cvtrace(dir.path(), &["render", "scene.gltf", "--batches", "2", "-o", "a.streams.exr"]);
    ok(&out);
    assert!(stderr(&out).contains("using sidecar"), "the sidecar is announced: {}", stderr(&out));
    let set = StreamSet::read(&dir.path().join("a.streams.exr")).unwrap();
    assert_eq!((set.width, set.height, set.meta.spp, set.meta.max_depth), (24, 16, 4, 3));

    // --width replaces the sidecar's size (the height follows the camera's square aspect),
    // --spp and --max-depth its values.
    ok(&cvtrace(
        dir.path(),
        &["render", "scene.gltf", "--width", "10", "--spp", "2", "--max-depth", "-1", "--batches", "2", "-o", "b.streams.exr"],
    ));
    let set = StreamSet::read(&dir.path().join("b.streams.exr")).unwrap();
    assert_eq!((set.width, set.height, set.meta.spp, set.meta.max_depth), (10, 10, 2, -1));

    // A reference without --spp renders reference_spp samples, and its header says so.
    ok(&cvtrace(dir.path(), &["render", "scene.gltf", "--reference", "-o", "ref.exr"]));
    let ch = ExrChannels::read(&dir.path().join("ref.exr")).unwrap();
    assert_eq!((ch.width, ch.height), (24, 16));
    assert_eq!(ch.attr("cvtrace.spp"), Some(&AttrValue::Int(6)));
    assert_eq!(ch.attr("cvtrace.maxDepth"), Some(&AttrValue::Int(3)));
    assert_eq!(ch.attr("cvtrace.rrDepth"), Some(&AttrValue::Int(2)));
}

#[test]
fn study_takes_the_reference_spp_and_view_from_the_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    scene_folder(dir.path(), SIDECAR);
    let out = cvtrace(
        dir.path(),
        &["--log", "warn", "study", "scene.gltf", "--spp", "4", "--seeds", "1", "--batches", "4", "--reference", "ref.exr", "-o", "study"],
    );
    ok(&out);
    // The reference it rendered has reference_spp samples and the sidecar's view.
    let ch = ExrChannels::read(&dir.path().join("ref.exr")).unwrap();
    assert_eq!((ch.width, ch.height), (24, 16));
    assert_eq!(ch.attr("cvtrace.spp"), Some(&AttrValue::Int(6)));
    assert_eq!(ch.attr("cvtrace.maxDepth"), Some(&AttrValue::Int(3)));
    let set = StreamSet::read(&dir.path().join("study/spp00004/seed-000.streams.exr")).unwrap();
    assert_eq!((set.width, set.height, set.meta.spp, set.meta.max_depth), (24, 16, 4, 3));
}

#[test]
fn an_environment_map_lights_the_open_box() {
    let dir = tempfile::tempdir().unwrap();
    // The Cornell box is open towards the camera: a bright sky behind the camera adds light.
    let sky = Image::from_fn(16, 8, |_, _| [2.0, 2.0, 2.0]);
    write_rgb(&dir.path().join("sky.exr"), &sky, &[], false).unwrap();
    let render = |sidecar: &str, out: &str| {
        scene_folder(dir.path(), sidecar);
        ok(&cvtrace(dir.path(), &["render", "scene.gltf", "--spp", "8", "--batches", "2", "-o", out]));
        let set = StreamSet::read(&dir.path().join(out)).unwrap();
        set.pt.mean.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / set.pt.mean.len() as f64
    };
    let dark = render("[render]\nwidth = 16\nheight = 16\n", "dark.streams.exr");
    let lit = render("[render]\nwidth = 16\nheight = 16\n[environment]\nmap = \"sky.exr\"\nrotation = 90\n", "lit.streams.exr");
    eprintln!("mean green without the environment {dark}, with it {lit}");
    assert!(lit > dark * 1.2, "the environment adds light: {lit} vs {dark}");
}

#[test]
fn a_bad_sidecar_fails_naming_the_file_and_writes_nothing() {
    for (text, needles) in [
        ("[render]\nwidth = 24\nheight 16\n", &["scene.cvtrace.toml", "line 3"][..]),
        ("[render]\nwidht = 24\n", &["scene.cvtrace.toml", "widht"][..]),
        ("[environment]\nmap = \"missing.exr\"\n", &["scene.cvtrace.toml", "missing.exr"][..]),
        ("[environment]\ncolor = [1, 1, 1]\nmap = \"sky.exr\"\n", &["scene.cvtrace.toml", "both"][..]),
        ("[render]\nspp = 0\n", &["scene.cvtrace.toml", "spp = 0"][..]),
    ] {
        let dir = tempfile::tempdir().unwrap();
        scene_folder(dir.path(), text);
        let before = files_in(dir.path());
        let out = cvtrace(dir.path(), &["render", "scene.gltf", "-o", "x.streams.exr"]);
        assert!(!out.status.success(), "{text:?} was accepted");
        let err = stderr(&out);
        for n in needles {
            assert!(err.contains(n), "error for {text:?} lacks {n:?}: {err}");
        }
        assert_eq!(files_in(dir.path()), before, "a failed render left files behind");
    }
}

#[test]
fn a_sidecar_that_is_not_a_regular_file_fails_at_once() {
    // Found by fuzzing the scene input: a FIFO sidecar blocked `render` forever, and one linked
    // to /dev/zero was read until 2 GiB of memory were used. Both must fail at once, naming
    // the sidecar, without a panic and without writing anything.
    for kind in ["fifo", "/dev/zero"] {
        let dir = tempfile::tempdir().unwrap();
        scene_folder(dir.path(), "");
        let sidecar = dir.path().join("scene.cvtrace.toml");
        std::fs::remove_file(&sidecar).unwrap();
        if kind == "fifo" {
            assert!(std::process::Command::new("mkfifo").arg(&sidecar).status().unwrap().success());
        } else {
            std::os::unix::fs::symlink(kind, &sidecar).unwrap();
        }
        let before = files_in(dir.path());
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cvtrace"))
            .args(["render", "scene.gltf", "--spp", "1", "--batches", "1", "-o", "x.streams.exr"])
            .current_dir(dir.path())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if start.elapsed() > std::time::Duration::from_secs(30) {
                child.kill().unwrap();
                panic!("{kind}: cvtrace render did not finish in 30 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert_eq!(status.code(), Some(1), "{kind}: {err}");
        assert!(err.contains("scene.cvtrace.toml") && err.contains("not a regular file") && !err.contains("panicked"), "{kind}: {err}");
        assert_eq!(files_in(dir.path()), before, "{kind}: a failed render left files behind");
    }
}

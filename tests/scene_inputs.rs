//! Scenes that load but would not render what their author meant: a glTF without a camera gets
//! one that frames the scene, with a warning that says where it is and how to give another; an
//! emitter too bright for a render's exact sums is an error that names the glTF and the material.
mod common;

use common::{cvtrace, ok, scene, stderr, SMALL};
use std::path::Path;

/// The Cornell box's glTF, changed by `edit`, written with its buffer into `dir` as `name`.
fn cornell_box_with(dir: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) {
    let s = scene();
    let mut gltf: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&s).unwrap()).unwrap();
    edit(&mut gltf);
    std::fs::write(dir.join(name), serde_json::to_string(&gltf).unwrap()).unwrap();
    std::fs::copy(s.with_file_name("scene.bin"), dir.join("scene.bin")).unwrap();
}

#[test]
fn a_gltf_without_a_camera_is_framed_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    cornell_box_with(d, "camless.gltf", |g| {
        g.as_object_mut().unwrap().remove("cameras");
        for node in g["nodes"].as_array_mut().unwrap() {
            node.as_object_mut().unwrap().remove("camera");
        }
    });
    let render = [&["--log", "warn", "render", "camless.gltf", "--spp", "4", "--batches", "4"][..], SMALL].concat();
    let out = cvtrace(d, &[&render[..], &["-o", "x.streams.exr"]].concat());
    ok(&out);
    let e = stderr(&out);
    assert!(e.contains("camless.gltf") && e.contains("no camera") && e.contains("--camera"), "a silent automatic camera:\n{e}");
    // Where it looks from, so that a black image is explained.
    assert!(e.contains("eye") && e.contains("bounds"), "{e}");
    // A camera given on the command line is no reason to warn.
    let given = [&render[..], &["--camera", "278,273,-800:278,273,0:37", "-o", "y.streams.exr"]].concat();
    let out = cvtrace(d, &given);
    ok(&out);
    assert!(stderr(&out).trim().is_empty(), "{}", stderr(&out));
}

#[test]
fn an_emitter_too_bright_for_the_exact_sums_names_the_scene_not_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    cornell_box_with(d, "hot.gltf", |g| {
        g["materials"][1]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = serde_json::json!(1e15);
    });
    for kind in [&["--spp", "4", "--batches", "4", "-o", "hot.streams.exr"][..], &["--reference", "--spp", "4", "-o", "hot.ref.exr"]] {
        let out = cvtrace(d, &[&["--log", "warn", "render", "hot.gltf"][..], kind, SMALL].concat());
        let e = stderr(&out);
        assert!(!out.status.success(), "{kind:?} rendered:\n{e}");
        assert!(
            e.contains("hot.gltf") && e.contains("\"light\"") && e.contains("emissi"),
            "{kind:?}: the error should blame the emitter:\n{e}"
        );
        assert!(!e.contains("batches are not") && !e.contains("hot.streams.exr"), "{kind:?}:\n{e}");
        assert!(!d.join("hot.streams.exr").exists() && !d.join("hot.ref.exr").exists());
    }
}

//! The bodies of the fuzz targets in `fuzz/` (cargo-fuzz, libFuzzer), one function per input
//! format. They live in a normal crate so that the stable test suite can replay every committed
//! corpus file through every target (`tests/corpus_replay.rs`, `make fuzz-smoke`) without a
//! nightly toolchain or cargo-fuzz.
//!
//! Each function takes arbitrary bytes, writes them where the reader expects a file (the readers
//! take paths: they check for regular files and resolve relative references), and runs the
//! reader. Errors are the expected outcome for most inputs and are discarded; a panic, an abort
//! or an unbounded allocation is a bug.
#![forbid(unsafe_code)]

use cvtrace_render::{Scene, Sidecar};
use cvtrace_streams::checkpoint;
use cvtrace_streams::exr_io::ExrChannels;
use cvtrace_streams::reference::ReferenceSettings;
use cvtrace_streams::{iduw_layout, Provenance, StreamSet};
use std::path::{Path, PathBuf};

/// Separates the parts of a multi-file input: the glTF and its sidecar, or the files of an
/// IDUW set. A line of its own, so that a text corpus stays readable.
pub const SEPARATOR: &[u8] = b"\n#--cvtrace-fuzz-part--\n";

/// A target's body: arbitrary bytes in, nothing out (errors are discarded, panics are bugs).
pub type Target = fn(&[u8]);

/// The targets by name, as `fuzz/fuzz_targets/<name>.rs` and `fuzz/corpus/<name>/` call them.
pub const TARGETS: &[(&str, Target)] = &[
    ("gltf_scene", gltf_scene),
    ("stream_file", stream_file),
    ("checkpoint", checkpoint_file),
    ("iduw_layout", iduw_set),
    ("sidecar", sidecar),
];

/// `data` split at every [`SEPARATOR`].
pub fn parts(data: &[u8]) -> Vec<&[u8]> {
    let mut out = Vec::new();
    let mut rest = data;
    while let Some(i) = rest.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
        out.push(&rest[..i]);
        rest = &rest[i + SEPARATOR.len()..];
    }
    out.push(rest);
    out
}

fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary folder for the fuzz input")
}

fn write(path: &Path, data: &[u8]) {
    std::fs::write(path, data).expect("writing the fuzz input to a temporary file");
}

/// glTF or GLB import with an optional sidecar: the scene file's bytes, then (after a
/// [`SEPARATOR`]) the sidecar's `scene.cvtrace.toml`. `.glb` if the bytes start with GLB's
/// magic, else `.gltf`. External buffers and images resolve into an otherwise empty folder.
pub fn gltf_scene(data: &[u8]) {
    let dir = scratch();
    let parts = parts(data);
    let scene = parts[0];
    let name = if scene.starts_with(b"glTF") { "scene.glb" } else { "scene.gltf" };
    let path = dir.path().join(name);
    write(&path, scene);
    if let Some(sidecar) = parts.get(1) {
        write(&dir.path().join("scene.cvtrace.toml"), sidecar);
    }
    if let Ok(scene) = Scene::load(&path) {
        // What a render asks of a loaded scene before it builds the BVH.
        let _ = scene.fingerprint();
        let _ = scene.bounds();
    }
}

/// The sidecar TOML on its own: parsed, checked, and its environment built (an environment map
/// path resolves into an empty folder).
pub fn sidecar(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let dir = scratch();
    let path = dir.path().join("scene.cvtrace.toml");
    if let Ok(s) = Sidecar::parse(text, &path) {
        let _ = s.environment();
    }
}

/// A stream file (`*.streams.exr`).
pub fn stream_file(data: &[u8]) {
    let dir = scratch();
    let path = dir.path().join("input.streams.exr");
    write(&path, data);
    if let Ok(set) = StreamSet::read(&path) {
        let _ = set.validate(&path);
    }
}

/// A reference checkpoint, and the same file as a finished reference to extend. The planned
/// render is the one the file records, so that a well-formed file gets past the provenance
/// comparison to the sums; a file whose record does not read is checked against a default plan.
pub fn checkpoint_file(data: &[u8]) {
    let dir = scratch();
    let path = dir.path().join("input.ref.checkpoint.exr");
    write(&path, data);
    let saved = ExrChannels::read(&path).ok().and_then(|ch| Provenance::from_exr(&ch, &path).ok());
    let (planned, settings) = match saved {
        Some(p) => {
            let s = ReferenceSettings {
                width: p.width,
                height: p.height,
                spp: p.spp.unwrap_or(1).saturating_add(1),
                seed: p.seed.unwrap_or(0),
                max_depth: p.max_depth.unwrap_or(-1),
                rr_depth: p.rr_depth.unwrap_or(5),
            };
            (p, s)
        }
        None => {
            let s = ReferenceSettings { width: 8, height: 8, spp: 16, seed: 0, max_depth: -1, rr_depth: 5 };
            (Provenance { width: 8, height: 8, ..Default::default() }, s)
        }
    };
    let _ = checkpoint::load(&path, &planned, &settings);
    let _ = checkpoint::load_finished(&path, &planned, &settings);
}

/// IDUW's input layout: up to ten files split at [`SEPARATOR`] — the PT mean, its four
/// sub-buffers, the CRN mean and its four — where a missing part repeats the last one given
/// (so one small RGB EXR makes a whole, consistent set).
pub fn iduw_set(data: &[u8]) {
    let dir = scratch();
    let parts = parts(data);
    let [(pt, pt_subs), (crn, crn_subs)] = iduw_layout::iduw_paths(dir.path(), "fuzz", 4);
    let files: Vec<PathBuf> = std::iter::once(pt).chain(pt_subs).chain(std::iter::once(crn)).chain(crn_subs).collect();
    for (i, file) in files.iter().enumerate() {
        write(file, parts[i.min(parts.len() - 1)]);
    }
    let _ = iduw_layout::read_iduw(dir.path(), "fuzz", 4);
}

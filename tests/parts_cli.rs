//! `render --part` and `merge` end to end: parts of the shipped Cornell box merge into the very
//! bytes a one-shot render writes, and every way the parts can fail to fit is an error that
//! names the file and writes nothing.
mod common;

use common::{cvtrace, files_in, ok, scene, stderr, SMALL};
use std::path::Path;

fn render(dir: &Path, extra: &[&str], out: &str) -> std::process::Output {
    let s = scene();
    let base = ["--log", "warn", "render", s.to_str().unwrap(), "-o", out];
    cvtrace(dir, &[&base[..], SMALL, extra].concat())
}

fn same_bytes(a: &Path, b: &Path) {
    assert!(std::fs::read(a).unwrap() == std::fs::read(b).unwrap(), "{} and {} differ", a.display(), b.display());
}

/// Failed with a message containing every one of `needles`, without a panic.
fn refused(out: &std::process::Output, needles: &[&str]) {
    let e = stderr(out);
    assert!(!out.status.success(), "succeeded, expected an error with {needles:?}");
    for n in needles {
        assert!(e.contains(n), "error lacks {n:?}: {e}");
    }
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn stream_parts_merge_into_the_one_shot_file_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["--spp", "12", "--batches", "6", "--seed", "5"];
    ok(&render(d, &args, "one.streams.exr"));
    // Uneven parts (2, 2 and 2 of 6; then 1 and 5 of 6 with 2 parts of 5 batches each below).
    for i in 0..3 {
        ok(&render(d, &[&args[..], &["--part", &format!("{i}/3")]].concat(), &format!("p{i}.exr")));
    }
    // Given in any order, with one thread or two: the same bytes.
    ok(&cvtrace(d, &["--log", "warn", "merge", "p2.exr", "p0.exr", "p1.exr", "-o", "merged.streams.exr"]));
    same_bytes(&d.join("one.streams.exr"), &d.join("merged.streams.exr"));

    // Four parts of six batches (1, 2, 1, 2), rendered with another thread count.
    for i in 0..4 {
        ok(&render(d, &[&args[..], &["-t", "1", "--part", &format!("{i}/4")]].concat(), &format!("q{i}.exr")));
    }
    ok(&cvtrace(d, &["--log", "warn", "merge", "q0.exr", "q1.exr", "q2.exr", "q3.exr", "-o", "merged4.streams.exr"]));
    same_bytes(&d.join("one.streams.exr"), &d.join("merged4.streams.exr"));
    // A part is not a stream file: the readers of stream files refuse it.
    let out = cvtrace(d, &["--log", "warn", "reconstruct", "p0.exr", "--method", "pt", "-o", "x.exr"]);
    assert!(!out.status.success());
}

/// Sponza (textures, sun and sky, many grazing rays). Camera rays are traced in groups of one
/// sample index over neighbouring pixels so that a part traces the same groups as the one-shot
/// render: grouped by pixel, the groups depend on the part's samples, and Embree's coherent
/// traversal made one pixel in 57 600 differ here at 320x180 and 16 spp.
#[test]
fn parts_of_a_large_scene_merge_into_the_one_shot_file_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sponza/scene.gltf");
    let args = ["--log", "warn", "render", s.to_str().unwrap(), "--width", "160", "--height", "90", "--spp", "16", "--batches", "8"];
    ok(&cvtrace(d, &[&args[..], &["-o", "one.streams.exr"]].concat()));
    for i in 0..4 {
        ok(&cvtrace(d, &[&args[..], &["--part", &format!("{i}/4"), "-o", &format!("p{i}.exr")]].concat()));
    }
    ok(&cvtrace(d, &["--log", "warn", "merge", "p0.exr", "p1.exr", "p2.exr", "p3.exr", "-o", "merged.streams.exr"]));
    same_bytes(&d.join("one.streams.exr"), &d.join("merged.streams.exr"));
}

#[test]
fn reference_parts_merge_into_the_one_shot_reference_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["--reference", "--spp", "22", "--pass-spp", "4", "--seed", "2"];
    // The one-shot reference in other passes than the parts: the sums are exact either way.
    ok(&render(d, &["--reference", "--spp", "22", "--pass-spp", "7", "--seed", "2"], "one.ref.exr"));
    // 6 passes (the last of 2 samples) in 4 parts.
    for i in 0..4 {
        ok(&render(d, &[&args[..], &["--part", &format!("{i}/4")]].concat(), &format!("r{i}.exr")));
    }
    ok(&cvtrace(d, &["--log", "warn", "merge", "r3.exr", "r1.exr", "r0.exr", "r2.exr", "-o", "merged.ref.exr"]));
    same_bytes(&d.join("one.ref.exr"), &d.join("merged.ref.exr"));
    assert!(!d.join("r0.checkpoint.exr").exists(), "a part keeps no checkpoint");
}

#[test]
fn bad_parts_and_bad_part_flags_are_clear_errors_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["--spp", "8", "--batches", "4", "--seed", "1"];
    for i in 0..2 {
        ok(&render(d, &[&args[..], &["--part", &format!("{i}/2")]].concat(), &format!("a{i}.exr")));
    }
    // The same settings but another seed: a part of another render.
    ok(&render(d, &["--spp", "8", "--batches", "4", "--seed", "2", "--part", "1/2"], "other1.exr"));
    ok(&render(d, &["--reference", "--spp", "8", "--pass-spp", "4", "--part", "1/2"], "ref1.exr"));
    ok(&render(d, &args, "whole.streams.exr"));
    let before = files_in(d);
    let merge = |parts: &[&str]| cvtrace(d, &[&["--log", "warn", "merge"][..], parts, &["-o", "out.streams.exr"]].concat());

    refused(&merge(&["a0.exr"]), &["batches 2..4 of 4 are in none of the parts", "a0.exr (batches 0..2)"]);
    refused(&merge(&["a1.exr"]), &["batches 0..2 of 4 are in none of the parts", "a1.exr (batches 2..4)"]);
    refused(&merge(&["a0.exr", "a1.exr", "a1.exr"]), &["a1.exr (batches 2..4) is the same part as a1.exr (batches 2..4)"]);
    refused(&merge(&["a0.exr", "other1.exr"]), &["other1.exr (batches 2..4) is not a part of the same render as a0.exr", "seed 2"]);
    refused(&merge(&["a0.exr", "ref1.exr"]), &["ref1.exr", "reference render"]);
    refused(&merge(&["a0.exr", "whole.streams.exr"]), &["whole.streams.exr: not a part of a render"]);
    // A part cut short: its header still reads, its pixels do not.
    let bytes = std::fs::read(d.join("a1.exr")).unwrap();
    std::fs::write(d.join("cut1.exr"), &bytes[..bytes.len() / 2]).unwrap();
    refused(&merge(&["a0.exr", "cut1.exr"]), &["cut1.exr (batches 2..4)"]);
    refused(&merge(&["a0.exr", "missing.exr"]), &["missing.exr: no such file"]);
    std::fs::remove_file(d.join("cut1.exr")).unwrap();
    assert_eq!(files_in(d), before, "a refused merge writes nothing");

    // --part out of range, no parts, more parts than batches (or passes), garbage.
    for (flag, needle) in [
        ("9/8", "9/8: parts are numbered 0 to 7 of 8"),
        ("8/8", "parts are numbered 0 to 7 of 8"),
        ("0/0", "0/0: there must be at least one part"),
        ("0/5", "--part 0/5: 5 parts but only 4 batches"),
        ("three", "expected I/N"),
    ] {
        refused(&render(d, &[&args[..], &["--part", flag]].concat(), "x.exr"), &[needle]);
    }
    refused(&render(d, &["--reference", "--spp", "8", "--pass-spp", "4", "--part", "0/3"], "x.exr"), &["3 parts but only 2 passes"]);
    assert_eq!(files_in(d), before, "a refused render writes nothing");
}

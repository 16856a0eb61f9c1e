//! OpenImageIO's own tools must read what cvtrace writes: the stream file is a contract
//! with other renderers and tools, not a private format.
use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
use std::process::Command;

/// Whether `tool` runs. `make test` sets `CVTRACE_REQUIRE_TOOLS` (its setup installs the tools),
/// so there a missing tool fails the test instead of skipping it.
fn have(tool: &str) -> bool {
    let found = Command::new(tool).arg("--help").output().is_ok();
    assert!(found || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "{tool} is not installed and CVTRACE_REQUIRE_TOOLS is set");
    found
}

fn sample_set() -> StreamSet {
    let (w, h) = (8, 6);
    let batches = |o: f32| (0..4).map(|b| Image::from_fn(w, h, |x, y| [o + x as f32, y as f32, b as f32])).collect();
    StreamSet {
        width: w,
        height: h,
        pt: Stream::from_batches(batches(0.0)),
        crn: Stream::from_batches(batches(0.25)),
        features: Some(Features {
            albedo: Image::from_fn(w, h, |_, _| [0.7, 0.6, 0.5]),
            normal: Image::from_fn(w, h, |_, _| [0.0, 1.0, 0.0]),
            depth: vec![3.5; w * h],
        }),
        meta: StreamMeta {
            spp: 16,
            seed: 7,
            max_depth: 8,
            scene: "x.gltf".into(),
            version: "t".into(),
            non_finite_samples: 0,
            ..Default::default()
        },
    }
}

#[test]
fn oiiotool_lists_every_channel_and_attribute() {
    if !have("oiiotool") {
        eprintln!("SKIPPED: oiiotool not installed (scripts/setup.sh installs openimageio-tools)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.streams.exr");
    sample_set().write(&p, false).unwrap();
    let out = Command::new("oiiotool").args(["--info", "-v"]).arg(&p).output().unwrap();
    assert!(out.status.success(), "oiiotool failed: {}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    for ch in ["pt.R", "crn.B", "pt.b00.R", "crn.b03.G", "albedo.G", "normal.Z", "depth.Z"] {
        assert!(text.contains(ch), "oiiotool does not list {ch}:\n{text}");
    }
    // 37 stream and feature channels and the R, G, B, A picture.
    assert!(text.contains("41 channel") && text.contains("channel list: R, G, B, A,") && text.contains("float openexr"), "{text}");
    assert!(text.contains("cvtrace.spp: 16"), "{text}");
    assert!(text.to_lowercase().contains("zip"), "expected ZIP compression:\n{text}");
}

#[test]
fn idiff_sees_identical_files_as_identical_and_different_ones_as_different() {
    if !have("idiff") {
        eprintln!("SKIPPED: idiff not installed (scripts/setup.sh installs openimageio-tools)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (dir.path().join("a.exr"), dir.path().join("b.exr"), dir.path().join("c.exr"));
    let s = sample_set();
    s.write(&a, false).unwrap();
    s.write(&b, false).unwrap();
    let mut t = s.clone();
    t.crn.batches[1].pixels[5][0] += 1.0;
    t.crn.mean = Image::mean_of(&t.crn.batches);
    t.write(&c, false).unwrap();
    let same = Command::new("idiff").arg(&a).arg(&b).status().unwrap();
    assert!(same.success(), "idiff reports a difference between identical files");
    let diff = Command::new("idiff").arg(&a).arg(&c).status().unwrap();
    assert!(!diff.success(), "idiff missed a changed pixel");
}

//! `cvtrace render` end to end: runs the built binary on small renders of the shipped
//! Cornell box and checks files, determinism, resumable references and error handling.
use cvtrace_streams::exr_io::{AttrValue, ExrChannels};
use cvtrace_streams::StreamSet;
mod common;

use common::{cvtrace, files_in, interrupt, ok, scene, stderr, SMALL};
use std::path::Path;
use std::process::Command;

/// Channels compared bit for bit and attributes, then the whole files byte for byte (the
/// writer sorts header attributes, so equal images give equal files).
fn assert_same_content(a: &Path, b: &Path) {
    let (x, y) = (ExrChannels::read(a).unwrap(), ExrChannels::read(b).unwrap());
    assert_eq!((x.width, x.height), (y.width, y.height));
    assert_eq!(x.channels.keys().collect::<Vec<_>>(), y.channels.keys().collect::<Vec<_>>());
    for (name, pa) in &x.channels {
        let pb = &y.channels[name];
        let first = pa.iter().zip(pb).position(|(u, v)| u.to_bits() != v.to_bits());
        assert!(first.is_none(), "{name} differs at pixel {}: {} vs {}", first.unwrap(), pa[first.unwrap()], pb[first.unwrap()]);
    }
    assert_eq!(x.attributes, y.attributes);
    assert!(std::fs::read(a).unwrap() == std::fs::read(b).unwrap(), "{} and {} differ in bytes", a.display(), b.display());
}

/// Whether `name` runs. `make test` sets `CVTRACE_REQUIRE_TOOLS` (its setup installs the tools),
/// so there a missing tool fails the test instead of skipping it.
fn tool_available(name: &str) -> bool {
    let found = Command::new(name).arg("--help").output().is_ok();
    assert!(found || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "{name} is not installed and CVTRACE_REQUIRE_TOOLS is set");
    found
}

#[test]
fn stream_file_has_every_channel_and_openimageio_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    let args = |out: &'static str| {
        [&["--log", "warn", "render", sp, "--spp", "8", "--batches", "4", "--seed", "7", "-o", out][..], SMALL].concat()
    };
    ok(&cvtrace(dir.path(), &args("a.streams.exr")));

    let ch = ExrChannels::read(&dir.path().join("a.streams.exr")).unwrap();
    assert_eq!((ch.width, ch.height), (32, 32));
    let mut expected: Vec<String> = Vec::new();
    for stream in ["pt", "crn"] {
        for prefix in std::iter::once(format!("{stream}.")).chain((0..4).map(|b| format!("{stream}.b{b:02}."))) {
            expected.extend(["R", "G", "B"].map(|c| format!("{prefix}{c}")));
        }
    }
    expected.extend(["albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "depth.Z"].map(String::from));
    // The picture: what viewers show of the file.
    expected.extend(["R", "G", "B", "A"].map(String::from));
    for name in &expected {
        assert!(ch.channels.contains_key(name), "missing channel {name}; have {:?}", ch.channels.keys());
    }
    assert_eq!(ch.channels.len(), expected.len(), "unexpected extra channels: {:?}", ch.channels.keys());

    let set = StreamSet::read(&dir.path().join("a.streams.exr")).unwrap();
    assert_eq!((set.meta.spp, set.meta.seed, set.meta.max_depth), (8, 7, 6));
    assert_eq!(set.meta.scene, sp, "meta.scene records the scene path");
    assert_eq!(set.batch_count(), 4);
    // The box is lit: the image is not black, and PT and CRN render the same scene.
    let mean = |im: &cvtrace_streams::Image| im.pixels.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>() / im.len() as f64;
    let (pt, crn) = (mean(&set.pt.mean), mean(&set.crn.mean));
    assert!(pt > 0.05 && crn > 0.05, "image means pt {pt}, crn {crn}");

    if !tool_available("oiiotool") {
        eprintln!("SKIPPED the OpenImageIO part: oiiotool is not installed (scripts/setup.sh installs it)");
        return;
    }
    let info = Command::new("oiiotool").args(["--info", "-v", "a.streams.exr"]).current_dir(dir.path()).output().unwrap();
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success(), "oiiotool: {}", String::from_utf8_lossy(&info.stderr));
    assert!(text.contains("32 x   32") && text.contains("41 channel") && text.contains("channel list: R, G, B, A,"), "{text}");
    assert!(text.contains("crn.b03.B") && text.contains("cvtrace.spp: 8"), "{text}");

    ok(&cvtrace(dir.path(), &args("b.streams.exr")));
    let idiff = Command::new("idiff").args(["a.streams.exr", "b.streams.exr"]).current_dir(dir.path()).output().unwrap();
    let text = String::from_utf8_lossy(&idiff.stdout);
    assert!(idiff.status.success() && text.contains("PASS"), "idiff of two identical renders: {text}");
}

#[test]
fn one_and_two_threads_give_identical_output() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    let run = |threads: &str, seed: &str, out: &str| {
        let base = ["--threads", threads, "--log", "warn", "render", sp, "--spp", "6", "--batches", "3", "--seed", seed, "-o", out];
        ok(&cvtrace(dir.path(), &[&base[..], SMALL].concat()));
    };
    run("1", "11", "t1.streams.exr");
    run("2", "11", "t2.streams.exr");
    assert_same_content(&dir.path().join("t1.streams.exr"), &dir.path().join("t2.streams.exr"));
    // The comparison can fail: another seed changes the pixels.
    run("2", "12", "t3.streams.exr");
    let (a, c) =
        (ExrChannels::read(&dir.path().join("t1.streams.exr")).unwrap(), ExrChannels::read(&dir.path().join("t3.streams.exr")).unwrap());
    assert_ne!(a.channels["pt.R"], c.channels["pt.R"]);
}

/// SIGTERM (and Ctrl-C) end a run through cvtrace's handler: exit code 130 and no temporary or
/// lock file left, even when the signal arrives while a file is being written (here a
/// checkpoint after every 1-spp pass, so writes are frequent); the last checkpoint stays
/// readable. Meanwhile a second render of the same reference is refused.
#[test]
fn a_terminated_render_leaves_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene();
    let args = [
        &["--log", "warn", "render", s.to_str().unwrap(), "--reference", "--spp", "100000", "--pass-spp", "1", "-o", "t.ref.exr"][..],
        SMALL,
    ]
    .concat();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cvtrace")).args(&args).current_dir(dir.path()).spawn().unwrap();
    let ckpt = dir.path().join("t.ref.checkpoint.exr");
    let start = std::time::Instant::now();
    while !ckpt.exists() {
        assert!(start.elapsed().as_secs() < 60, "no checkpoint after 60 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // A second process on the same reference is refused at once (it would redo the work and
    // race over the checkpoint).
    let second = cvtrace(dir.path(), &args);
    let e = stderr(&second);
    assert!(!second.status.success() && e.contains("t.ref.exr") && e.contains("another cvtrace process"), "{e}");
    std::thread::sleep(std::time::Duration::from_millis(300));
    // SAFETY: kill(2) on our own child's pid.
    interrupt(&child, rustix::process::Signal::TERM);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status}");
    let names: Vec<String> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["t.ref.checkpoint.exr"], "only the checkpoint stays");
    ExrChannels::read(&ckpt).unwrap();
}

#[test]
fn interrupted_reference_resumes_to_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    let base = |pass: &'static str, out: &'static str| {
        [&["--log", "warn", "render", sp, "--reference", "--spp", "12", "--seed", "3", "--pass-spp", pass, "-o", out][..], SMALL].concat()
    };
    ok(&cvtrace(dir.path(), &base("4", "full.ref.exr")));

    // Stop after one pass of 4 spp: only the checkpoint exists.
    ok(&cvtrace(dir.path(), &[base("4", "part.ref.exr"), vec!["--stop-after-passes", "1"]].concat()));
    assert!(!dir.path().join("part.ref.exr").exists());
    let ckpt = dir.path().join("part.ref.checkpoint.exr");
    let saved = ExrChannels::read(&ckpt).unwrap();
    assert_eq!(saved.attr("cvtrace.samplesDone"), Some(&AttrValue::Int(4)));

    // A different render must not silently continue it.
    let out =
        cvtrace(dir.path(), &[&["render", sp, "--reference", "--spp", "12", "--seed", "4", "-o", "part.ref.exr"][..], SMALL].concat());
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("part.ref.checkpoint.exr") && e.contains("seed") && e.contains("delete it to start the reference over"), "{e}");
    assert!(ckpt.exists(), "a mismatched checkpoint is kept");

    // A checkpoint that is not one: the same way out, and nothing is written.
    std::fs::write(dir.path().join("junk.ref.checkpoint.exr"), "not an EXR").unwrap();
    let out = cvtrace(dir.path(), &[&["render", sp, "--reference", "--spp", "12", "-o", "junk.ref.exr"][..], SMALL].concat());
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("junk.ref.checkpoint.exr") && e.contains("delete it to start the reference over"), "{e}");
    assert!(!dir.path().join("junk.ref.exr").exists());

    // Resume with a different pass size: the samples are still added in the same order.
    ok(&cvtrace(dir.path(), &base("5", "part.ref.exr")));
    assert!(!ckpt.exists(), "the checkpoint is removed once the reference is written");
    assert_same_content(&dir.path().join("full.ref.exr"), &dir.path().join("part.ref.exr"));
    let full = ExrChannels::read(&dir.path().join("full.ref.exr")).unwrap();
    assert_eq!(full.channels.keys().collect::<Vec<_>>(), ["B", "G", "R"]);
    assert_eq!(full.attr("cvtrace.spp"), Some(&AttrValue::Int(12)));
    assert_eq!(full.attr("cvtrace.seed").map(|v| v.as_text()), Some("3".to_string()));

    // The reference is the PT stream of a stream render with the same seed and settings.
    ok(&cvtrace(
        dir.path(),
        &[&["--log", "warn", "render", sp, "--spp", "12", "--batches", "2", "--seed", "3", "-o", "s.streams.exr"][..], SMALL].concat(),
    ));
    let streams = ExrChannels::read(&dir.path().join("s.streams.exr")).unwrap();
    for c in ["R", "G", "B"] {
        assert_eq!(full.channels[c], streams.channels[&format!("pt.{c}")], "channel {c}");
    }
}

/// Pixel values of `a` and `b` agree to f32 rounding (a few ulps), attributes exactly.
fn assert_equal_to_rounding(a: &Path, b: &Path) {
    let (x, y) = (ExrChannels::read(a).unwrap(), ExrChannels::read(b).unwrap());
    assert_eq!(x.attributes, y.attributes);
    for c in ["R", "G", "B"] {
        for (i, (u, v)) in x.channels[c].iter().zip(&y.channels[c]).enumerate() {
            assert!((u - v).abs() <= 4.0 * f32::EPSILON * u.abs().max(v.abs()), "{c} pixel {i}: {u} vs {v}");
        }
    }
}

#[test]
fn finished_reference_extends_to_a_one_shot_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let run = |spp: &'static str, seed: &'static str, out: &'static str, extra: &[&'static str]| {
        cvtrace(d, &[&["--log", "warn", "render", sp, "--reference", "--spp", spp, "--seed", seed, "-o", out][..], SMALL, extra].concat())
    };
    ok(&run("12", "3", "once.ref.exr", &[]));
    ok(&run("8", "3", "grown.ref.exr", &[]));
    let before = std::fs::read(d.join("grown.ref.exr")).unwrap();

    // Nothing to extend, a different render, or no new samples: clear errors, file untouched.
    let e = run("12", "3", "absent.ref.exr", &["--extend"]);
    assert!(!e.status.success() && stderr(&e).contains("absent.ref.exr") && stderr(&e).contains("none"), "{}", stderr(&e));
    let e = run("12", "4", "grown.ref.exr", &["--extend"]);
    assert!(!e.status.success() && stderr(&e).contains("grown.ref.exr") && stderr(&e).contains("seed 3"), "{}", stderr(&e));
    let e = run("8", "3", "grown.ref.exr", &["--extend"]);
    assert!(!e.status.success() && stderr(&e).contains("already holds 8 spp"), "{}", stderr(&e));
    let e = cvtrace(d, &[&["render", sp, "--spp", "8", "--batches", "2", "-o", "grown.ref.exr", "--extend"][..], SMALL].concat());
    assert!(!e.status.success() && stderr(&e).contains("--reference"), "{}", stderr(&e));
    assert_eq!(std::fs::read(d.join("grown.ref.exr")).unwrap(), before);

    // Interrupted half-way, the extension keeps its exact checkpoint and the old file.
    ok(&run("12", "3", "grown.ref.exr", &["--extend", "--pass-spp", "2", "--stop-after-passes", "1"]));
    assert_eq!(std::fs::read(d.join("grown.ref.exr")).unwrap(), before);
    let ckpt = ExrChannels::read(&d.join("grown.ref.checkpoint.exr")).unwrap();
    assert_eq!(ckpt.attr("cvtrace.samplesDone"), Some(&AttrValue::Int(10)), "the 8 finished samples are continued, not redone");
    ok(&run("12", "3", "grown.ref.exr", &["--extend"]));
    assert!(!d.join("grown.ref.checkpoint.exr").exists());
    assert_equal_to_rounding(&d.join("once.ref.exr"), &d.join("grown.ref.exr"));
    assert_eq!(files_in(d), ["grown.ref.exr", "once.ref.exr"], "no temporary file is left");

    // A reference from before scene hashes were recorded still extends, with a warning.
    let mut old = ExrChannels::read(&d.join("grown.ref.exr")).unwrap();
    old.attributes.retain(|k, _| k != "cvtrace.sceneHash" && k != "cvtrace.camera");
    old.write(&d.join("old.ref.exr"), false).unwrap();
    let out =
        cvtrace(d, &[&["render", sp, "--reference", "--spp", "16", "--seed", "3", "-o", "old.ref.exr", "--extend"][..], SMALL].concat());
    ok(&out);
    assert!(stderr(&out).contains("scene hash"), "{}", stderr(&out));
    let grown = ExrChannels::read(&d.join("old.ref.exr")).unwrap();
    assert_eq!(grown.attr("cvtrace.spp"), Some(&AttrValue::Int(16)));
    assert!(grown.attr("cvtrace.sceneHash").is_some(), "the extended file records its scene hash");
}

#[test]
fn bad_input_fails_clearly_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("broken.gltf"), "{ this is not json").unwrap();
    std::fs::write(
        d.join("draco.gltf"),
        r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]}"#,
    )
    .unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    let inputs = files_in(d);
    let cases: &[(&[&str], &[&str])] = &[
        (&["render", "missing.gltf", "-o", "x.streams.exr"], &["missing.gltf"]),
        (&["render", "broken.gltf", "-o", "x.streams.exr"], &["broken.gltf", "not a valid glTF"]),
        (&["render", "draco.gltf", "-o", "x.streams.exr"], &["draco.gltf", "KHR_draco_mesh_compression"]),
        (&["render", sp, "--spp", "0", "-o", "x.streams.exr"], &["spp"]),
        (&["render", sp, "--spp", "10", "--batches", "4", "-o", "x.streams.exr"], &["multiple of batches"]),
        (&["render", sp, "--width", "1000000", "-o", "x.streams.exr"], &["1000000"]),
        (&["render", sp, "--height", "0", "-o", "x.streams.exr"], &["--height", "1..=16384"]),
        (&["render", sp, "--max-depth", "0", "-o", "x.streams.exr"], &["max_depth"]),
        (&["render", sp, "--camera", "1,2,3", "-o", "x.streams.exr"], &["--camera"]),
        (&["render", sp, "--reference", "--batches", "2", "-o", "x.ref.exr"], &["--batches"]),
        (&["render", sp, "--reference", "--pass-spp", "0", "-o", "x.ref.exr"], &["--pass-spp"]),
        // The writer picks OpenEXR whatever the name says: a name that says otherwise is refused.
        (&["render", sp, "-o", "x.png"], &["x.png", ".exr file name"]),
        (&["render", sp, "--reference", "-o", "reference"], &["reference", ".exr file name"]),
    ];
    for (args, needles) in cases {
        let out = cvtrace(d, args);
        let e = stderr(&out);
        assert!(!out.status.success(), "{args:?} should fail");
        for n in *needles {
            assert!(e.contains(n), "{args:?}: error should mention {n:?}:\n{e}");
        }
        assert!(!e.contains("panicked"), "{args:?} panicked:\n{e}");
        assert_eq!(files_in(d), inputs, "{args:?} left files behind");
    }
}

#[test]
fn existing_output_is_kept_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("mine.streams.exr"), b"precious").unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    let args = [&["--log", "warn", "render", sp, "--spp", "2", "--batches", "2", "-o", "mine.streams.exr"][..], SMALL].concat();
    let out = cvtrace(d, &args);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("mine.streams.exr") && stderr(&out).contains("--force"), "{}", stderr(&out));
    assert_eq!(std::fs::read(d.join("mine.streams.exr")).unwrap(), b"precious");

    ok(&cvtrace(d, &[args, vec!["--force"]].concat()));
    assert!(StreamSet::read(&d.join("mine.streams.exr")).is_ok());
    assert_eq!(files_in(d), ["mine.streams.exr"], "no temporary file is left");
}

#[test]
fn traversal_is_recorded_and_guards_extension() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let stream = |out: &str, extra: &[&str]| {
        cvtrace(d, &[&["--log", "warn", "render", sp, "--spp", "4", "--batches", "2", "--seed", "5", "-o", out][..], SMALL, extra].concat())
    };
    ok(&stream("robust.streams.exr", &["--traversal", "robust"]));
    ok(&stream("fast.streams.exr", &[]));
    let traversal = |f: &str| StreamSet::read(&d.join(f)).unwrap().meta.settings.get("traversal").cloned();
    assert_eq!(traversal("robust.streams.exr").as_deref(), Some("robust"));
    assert_eq!(traversal("fast.streams.exr").as_deref(), Some("fast"), "fast is the default");
    // Both trace the same scene: the images agree to Monte Carlo noise (same seed).
    let (a, b) = (StreamSet::read(&d.join("robust.streams.exr")).unwrap(), StreamSet::read(&d.join("fast.streams.exr")).unwrap());
    let mean = |im: &cvtrace_streams::Image| im.pixels.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>() / im.len() as f64;
    let (ma, mb) = (mean(&a.pt.mean), mean(&b.pt.mean));
    assert!((ma - mb).abs() < 0.02 * ma, "image means {ma} (robust) vs {mb} (fast)");

    let e = stream("x.streams.exr", &["--traversal", "sloppy"]);
    assert!(!e.status.success() && stderr(&e).contains("sloppy") && stderr(&e).contains("robust"), "{}", stderr(&e));

    // A reference keeps its traversal, and --extend refuses to continue it with the other one.
    let reference = |spp: &str, extra: &[&str]| {
        cvtrace(
            d,
            &[&["--log", "warn", "render", sp, "--reference", "--spp", spp, "--seed", "5", "-o", "r.ref.exr"][..], SMALL, extra].concat(),
        )
    };
    ok(&reference("4", &[]));
    assert_eq!(ExrChannels::read(&d.join("r.ref.exr")).unwrap().attr("cvtrace.traversal"), Some(&AttrValue::Text("fast".into())));
    let e = reference("8", &["--extend", "--traversal", "robust"]);
    assert!(!e.status.success() && stderr(&e).contains("traversal fast"), "{}", stderr(&e));
    // A reference from before the traversal was recorded was traced robustly: the default
    // (fast) does not continue it, robust does.
    let mut old = ExrChannels::read(&d.join("r.ref.exr")).unwrap();
    old.attributes.remove("cvtrace.traversal");
    old.write(&d.join("r.ref.exr"), true).unwrap();
    let e = reference("8", &["--extend"]);
    assert!(!e.status.success() && stderr(&e).contains("traversal robust"), "{}", stderr(&e));
    ok(&reference("8", &["--extend", "--traversal", "robust"]));
    let e = reference("12", &["--extend", "--traversal", "fast"]);
    assert!(!e.status.success() && stderr(&e).contains("traversal"), "{}", stderr(&e));
}

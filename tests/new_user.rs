//! Habits a new user brings from Mitsuba and pbrt: `-t N`, `render --spp 8` without thinking
//! of batches, and outputs into folders that do not exist yet.
mod common;

use common::{cvtrace, interrupt, ok, scene, stderr, SMALL};
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
    interrupt(&child, rustix::process::Signal::INT);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130));
    let e = stderr(&out);
    assert!(e.contains("r.ref.checkpoint.exr") && e.contains("run the same command again to resume"), "{e}");
}

#[test]
fn defines_override_scene_settings_and_flags_win_over_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let stream = |args: &[&str], out: &str| {
        ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "-o", out][..], args].concat()));
        cvtrace_streams::StreamSet::read(&d.join(out)).unwrap()
    };
    // No --batches: the count follows -D spp as it follows --spp.
    let set =
        stream(&["-D", "width=24", "-D", "height=16", "-D", "spp=4", "-D", "max_depth=3", "-D", "render.rr_depth=2"], "a.streams.exr");
    assert_eq!((set.width, set.height, set.meta.spp, set.meta.max_depth, set.pt.batches.len()), (24, 16, 4, 3, 4));
    // A flag wins over -D of the same setting; one side alone keeps the camera's square aspect.
    let set = stream(&["-D", "width=24", "-D", "spp=4", "--width", "10", "--spp", "2"], "b.streams.exr");
    assert_eq!((set.width, set.height, set.meta.spp), (10, 10, 2));
    let set = stream(&["-D", "width=12", "-D", "spp=2"], "c.streams.exr");
    assert_eq!((set.width, set.height), (12, 12));
    // The Cornell box is open towards the camera: a sky behind it adds light, and its strength scales it.
    let green = |set: &cvtrace_streams::StreamSet| set.pt.mean.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / set.pt.mean.len() as f64;
    let small = ["-D", "width=16", "-D", "spp=8"];
    let dark = green(&stream(&small, "dark.streams.exr"));
    let lit = green(&stream(&[&small[..], &["-D", "environment.color=1,1,1"]].concat(), "lit.streams.exr"));
    let brighter =
        green(&stream(&[&small[..], &["-D", "environment.color=1,1,1", "-D", "environment.strength=3"]].concat(), "lit3.streams.exr"));
    assert!(lit > dark * 1.2 && brighter > lit * 1.5, "the environment adds light: {dark} < {lit} < {brighter}");
    // The study takes them too: -D spp for --spp, -D reference_spp for the reference it renders.
    let out = cvtrace(
        d,
        &[
            "--log",
            "warn",
            "study",
            sp,
            "-D",
            "spp=4",
            "-D",
            "reference_spp=6",
            "-D",
            "width=16",
            "-D",
            "height=8",
            "--seeds",
            "1",
            "--batches",
            "4",
            "--reference",
            "ref.exr",
            "-o",
            "study",
        ],
    );
    ok(&out);
    let ch = ExrChannels::read(&d.join("ref.exr")).unwrap();
    assert_eq!((ch.width, ch.height, ch.attr("cvtrace.spp")), (16, 8, Some(&AttrValue::Int(6))));
    let set = cvtrace_streams::StreamSet::read(&d.join("study/spp00004/seed-000.streams.exr")).unwrap();
    assert_eq!((set.width, set.height, set.meta.spp), (16, 8, 4));
}

#[test]
fn a_bad_define_fails_naming_the_key_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    for (define, needles) in [
        ("widht=24", &["-D widht=24", "no such setting", "max_depth"][..]),
        ("max_depth=deep", &["-D max_depth=deep", "not a whole number"][..]),
        ("width=0", &["-D width=0", "between 1"][..]),
        ("environment.strength=-2", &["-D environment.strength=-2", "non-negative"][..]),
        ("environment.strength=2", &["-D environment.strength=2", "no environment light"][..]),
        ("environment.map=nowhere.exr", &["-D environment.map=nowhere.exr", "nowhere.exr"][..]),
        ("novalue", &["novalue", "KEY=VALUE"][..]),
    ] {
        for command in ["render", "study"] {
            let extra: &[&str] = if command == "study" { &["--reference", "r.exr", "-o", "out/x"] } else { &["-o", "out/x.streams.exr"] };
            let out = cvtrace(d, &[&[command, sp, "-D", define, "--spp", "4"][..], extra].concat());
            assert!(!out.status.success(), "{command} -D {define} was accepted");
            let err = stderr(&out);
            assert!(!err.contains("panicked"), "{err}");
            for n in needles {
                assert!(err.contains(n), "{command} -D {define}: the error lacks {n:?}: {err}");
            }
            assert!(!d.join("out").exists() && !d.join("r.exr").exists(), "{command} -D {define} left files behind");
        }
    }
}

#[test]
fn help_lists_the_defines() {
    let dir = tempfile::tempdir().unwrap();
    for command in ["render", "study"] {
        let out = cvtrace(dir.path(), &[command, "--help"]);
        ok(&out);
        let help = common::stdout(&out);
        for needle in ["-D <KEY=VALUE>", "width, height, spp, max_depth, rr_depth, reference_spp", "environment.strength", "flag wins"] {
            assert!(help.contains(needle), "{command} --help lacks {needle:?}:\n{help}");
        }
    }
}

#[test]
fn study_batches_default_to_what_divides_every_spp_and_suits_iduw() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let small = ["--width", "8", "--height", "8", "--max-depth", "3", "--seeds", "1", "--reference-spp", "4", "--reference", "ref.exr"];
    for (spp, batches) in [("8", 8), ("12,24", 4)] {
        let folder = format!("study-{batches}");
        let run = cvtrace(d, &[&["--log", "info", "study", sp, "--spp", spp, "-o", &folder][..], &small].concat());
        ok(&run);
        assert!(stderr(&run).contains(&format!("--batches not given: {batches} batches")), "the choice is logged:\n{}", stderr(&run));
        let first = spp.split(',').next().unwrap();
        let file = ExrChannels::read(&d.join(format!("{folder}/spp{:05}/seed-000.streams.exr", first.parse::<u32>().unwrap()))).unwrap();
        assert_eq!(file.attr("cvtrace.batches"), Some(&AttrValue::Int(batches)), "--spp {spp}");
    }
    // 6 spp divides into 2 batches at most, and iduw needs a multiple of 4: an error that says why.
    let run = cvtrace(d, &[&["study", sp, "--spp", "6", "-o", "study-6"][..], &small].concat());
    assert!(!run.status.success(), "--spp 6 without --batches was accepted");
    let err = stderr(&run);
    assert!(err.contains("--batches was not given") && err.contains("multiples of 4") && err.contains("iduw"), "{err}");
    assert!(!d.join("study-6").exists());
}

#[test]
fn study_names_its_pt2n_renders_warns_once_and_reports_its_wall_time() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    // A 4-spp reference is far too noisy for 8+8 spp streams: the warning is due.
    let run = cvtrace(
        d,
        &[
            "--log",
            "info",
            "study",
            sp,
            "--spp",
            "4,8",
            "--seeds",
            "2",
            "--width",
            "8",
            "--height",
            "8",
            "--max-depth",
            "3",
            "--reference-spp",
            "4",
            "--reference",
            "ref.exr",
            "-o",
            "study",
        ],
    );
    ok(&run);
    let (out, err) = (common::stdout(&run), stderr(&run));
    let both = format!("{out}{err}");
    assert_eq!(err.matches("rendering a reference").count(), 1, "only the reference is called one:\n{err}");
    assert_eq!(err.matches("rendering a PT(2n) image").count(), 4, "2 seeds × 2 spp values:\n{err}");
    assert_eq!(both.matches("reference too noisy to rank the methods").count(), 1, "the warning once:\n{both}");
    let line = out.lines().find(|l| l.starts_with("study written to")).unwrap_or_else(|| panic!("no last line:\n{out}"));
    assert!(line.contains(" in ") && line.contains(" s "), "the wall time: {line}");
}

#[test]
fn farm_render_hands_the_defines_to_every_part() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let out = cvtrace(
        d,
        &["farm", "render", sp, "--spp", "4", "--parts", "2", "-D", "width=8", "-D", "environment.color=1,1,1", "-o", "x.streams.exr"],
    );
    ok(&out);
    let manifest = std::fs::read_to_string(d.join("x.streams.farm/manifest.json")).unwrap();
    assert!(manifest.contains("\"-D\"") && manifest.contains("width=8") && manifest.contains("environment.color=1,1,1"), "{manifest}");
    // A key no part could use fails before the job folder is written.
    let bad = cvtrace(d, &["farm", "render", sp, "--spp", "4", "--parts", "2", "-D", "widht=8", "-o", "y.streams.exr"]);
    assert!(!bad.status.success() && stderr(&bad).contains("-D widht=8"), "{}", stderr(&bad));
    assert!(!d.join("y.streams.farm").exists());
}

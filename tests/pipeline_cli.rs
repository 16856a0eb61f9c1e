//! The rest of the command line end to end on tiny renders of the shipped Cornell box:
//! reconstruct (one and all methods), compare, study (with resume) and report.
mod common;

use common::{cvtrace, files_in, ok, scene, stderr, stdout, SMALL};
use cvtrace_eval::StudyResults;
use cvtrace_streams::exr_io::{read_rgb, AttrValue, ExrChannels};
use std::path::Path;

/// Renders a stream file and a reference into `dir`.
fn render_inputs(dir: &Path) {
    let s = scene();
    let sp = s.to_str().unwrap();
    let streams = [&["--log", "warn", "render", sp, "--spp", "16", "--batches", "8", "--seed", "3", "-o", "s.streams.exr"][..], SMALL];
    ok(&cvtrace(dir, &streams.concat()));
    let reference = [&["--log", "warn", "render", sp, "--reference", "--spp", "256", "--seed", "99", "-o", "ref.exr"][..], SMALL];
    ok(&cvtrace(dir, &reference.concat()));
}

#[test]
fn reconstruct_all_then_compare_ranks_against_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_inputs(d);
    let out = cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "all", "--reference", "ref.exr", "-o", "out"]);
    ok(&out);
    let names = files_in(&d.join("out"));
    for m in ["pt", "crn", "average", "iduw", "cv", "ours"] {
        assert!(names.contains(&format!("{m}.exr")) && names.contains(&format!("{m}.png")), "{m} missing in {names:?}");
        let ch = ExrChannels::read(&d.join(format!("out/{m}.exr"))).unwrap();
        assert_eq!(ch.attr("cvtrace.method"), Some(&AttrValue::Text(m.into())));
    }
    // The table printed by reconstruct lists relMSE for every method.
    let table = stdout(&out);
    assert!(table.lines().filter(|l| matches!(l.split_whitespace().next(), Some("ours" | "iduw"))).count() == 2, "{table}");

    // Samples the renderer replaced are counted into every output, and a count above zero is
    // warned about.
    assert_eq!(ExrChannels::read(&d.join("out/ours.exr")).unwrap().attr("cvtrace.nonFiniteSamples"), Some(&AttrValue::Text("0".into())));
    let mut replaced = ExrChannels::read(&d.join("s.streams.exr")).unwrap();
    replaced.attributes.insert("cvtrace.nonFiniteSamples".into(), AttrValue::Text("7".into()));
    replaced.write(&d.join("nf.streams.exr"), false).unwrap();
    let nf = cvtrace(d, &["reconstruct", "nf.streams.exr", "--method", "ours", "-o", "nf.exr"]);
    ok(&nf);
    assert!(stderr(&nf).contains("nf.streams.exr") && stderr(&nf).contains("replaced 7 NaN or infinite samples"), "{}", stderr(&nf));
    assert_eq!(ExrChannels::read(&d.join("nf.exr")).unwrap().attr("cvtrace.nonFiniteSamples"), Some(&AttrValue::Text("7".into())));

    // `pt` is the PT stream mean, bit for bit.
    let pt = read_rgb(&d.join("out/pt.exr")).unwrap();
    let set = cvtrace_streams::StreamSet::read(&d.join("s.streams.exr")).unwrap();
    assert_eq!(pt, set.pt.mean);

    // compare: one row per image (the reference, given again under another spelling, is no
    // image to score), the JSON it writes is a valid results file naming the reference absolutely.
    let mut images: Vec<String> = ["pt", "average", "ours"].iter().map(|m| format!("out/{m}.exr")).collect();
    images.push("./out/../ref.exr".into());
    std::fs::hard_link(d.join("ref.exr"), d.join("hard-link.exr")).unwrap();
    images.push("hard-link.exr".into());
    let mut args = vec!["--log", "warn", "compare", "--reference", "ref.exr", "--json", "cmp.json", "--csv", "cmp.csv"];
    args.extend(images.iter().map(String::as_str));
    ok(&cvtrace(d, &args));
    let r = StudyResults::read_json(&d.join("cmp.json")).unwrap();
    let scene = &r.scenes[0];
    assert_eq!(scene.methods.len(), 3);
    // Reconstructions carry the samples they stand for (16 per stream here).
    assert_eq!((scene.method("pt").unwrap().spp_total, scene.method("ours").unwrap().spp_total), (16, 32));
    assert_eq!(Path::new(&scene.reference.path), d.join("ref.exr").canonicalize().unwrap());
    let rel = |k: &str| scene.method(k).unwrap().relmse_mean;
    // Averaging two independent-enough estimates beats one of them, even at 32×32.
    assert!(rel("average") < rel("pt"), "average {} vs pt {}", rel("average"), rel("pt"));
    assert!(std::fs::read_to_string(d.join("cmp.csv")).unwrap().lines().count() >= 4);

    // The PT error filter's options reach the estimator: leaving the centre out changes `ours`.
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "ours", "--cbf-exclude-centre", "-o", "excl.exr"]));
    assert_ne!(read_rgb(&d.join("excl.exr")).unwrap(), read_rgb(&d.join("out/ours.exr")).unwrap());

    // Outputs are not overwritten without --force.
    let again = cvtrace(d, &["reconstruct", "s.streams.exr", "--method", "ours", "-o", "out/ours.exr"]);
    assert!(!again.status.success() && stderr(&again).contains("--force"), "{}", stderr(&again));
}

#[test]
fn reconstruct_rejects_bad_inputs_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_inputs(d);
    // A reference of another size.
    let s = scene();
    let small =
        ["--log", "warn", "render", s.to_str().unwrap(), "--reference", "--spp", "4", "--width", "16", "--height", "16", "-o", "small.exr"];
    ok(&cvtrace(d, &small));
    let cases: [(&[&str], &str); 13] = [
        (&["reconstruct", "missing.streams.exr", "-o", "x.exr"], "missing.streams.exr"),
        (&["reconstruct", "s.streams.exr", "--method", "ours", "--cbf-radius", "99", "-o", "x.exr"], "cbf-radius"),
        (&["reconstruct", "s.streams.exr", "--method", "ours", "--cbf-sigma-colour", "0", "-o", "x.exr"], "cbf-sigma-colour"),
        (&["reconstruct", "s.streams.exr", "--reference", "small.exr", "-o", "x.exr"], "small.exr"),
        (&["reconstruct", "s.streams.exr", "--method", "ours", "--errors", "oracle", "-o", "x.exr"], "reference"),
        (&["reconstruct", "s.streams.exr", "--method", "bilateral", "-o", "x.exr"], "bilateral"),
        (&["reconstruct", "ref.exr", "-o", "x.exr"], "ref.exr: is an RGB image"),
        (&["reconstruct", "s.streams.exr", "--reference", "s.streams.exr", "-o", "x.exr"], "s.streams.exr: is a PT/CRN stream file"),
        (&["reconstruct", "s.streams.exr", "--method", "ours", "-o", "x.png"], "x.png: this output is written as OpenEXR"),
        (&["reconstruct", "s.streams.exr", "--method", "pt", "--force", "-o", "s.streams.exr"], "s.streams.exr: is also an input"),
        (&["reconstruct", "s.streams.exr", "--method", "pt", "--exposure=nan", "-o", "x.exr"], "--exposure NaN"),
        (
            &["reconstruct", "s.streams.exr", "--method", "cv", "--k", "1", "-o", "x.exr"],
            "--k 1 (sets cv.k and ours.k): cv.k must be between 2",
        ),
        // A failed `--method all` does not leave its new directory behind.
        (&["reconstruct", "missing.streams.exr", "--method", "all", "-o", "new-dir"], "missing.streams.exr"),
    ];
    for (args, needle) in cases {
        let out = cvtrace(d, args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let e = stderr(&out);
        assert!(e.contains(needle), "{args:?}: error does not name {needle}:\n{e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!d.join("x.exr").exists() && !d.join("x.png").exists() && !d.join("new-dir").exists());
    }
}

#[test]
fn absurd_arguments_fail_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_inputs(d);
    let s = scene();
    let sp = s.to_str().unwrap();
    let before = files_in(d);
    let study = |extra: &[&'static str]| -> Vec<String> {
        let mut a: Vec<String> = ["study", sp, "--reference", "ref.exr", "--spp", "8", "-o", "st"].map(String::from).to_vec();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (study(&["--batches", "0", "--seeds", "1"]), "'0' for '--batches <BATCHES>': 0 is not in 1..=100"),
        (study(&["--seeds", "4000000000"]), "'4000000000' for '--seeds <SEEDS>': 4000000000 is not in 1..=10000"),
        // iduw needs a multiple of 4 batches: known before the first render.
        (study(&["--batches", "2", "--seeds", "1"]), "`iduw` needs a positive multiple of 4 batches"),
        (
            ["study", "ref.exr", "--reference", "ref.exr", "--spp", "8", "--batches", "4", "--seeds", "1", "-o", "st"]
                .map(String::from)
                .to_vec(),
            "ref.exr: not a valid glTF",
        ),
        (
            ["--threads", "100000", "reconstruct", "s.streams.exr", "-o", "x.exr"].map(String::from).to_vec(),
            "'100000' for '--threads <THREADS>': 100000 is not in 1..=1024",
        ),
        (["compare", "--reference", "ref.exr", "s.streams.exr"].map(String::from).to_vec(), "s.streams.exr: is a PT/CRN stream file"),
        (
            ["compare", "--reference", "ref.exr", "ref.exr", "--csv", "ref.exr", "--force"].map(String::from).to_vec(),
            "ref.exr: is also an input",
        ),
        (
            ["compare", "--reference", "ref.exr", "ref.exr", "--csv", "/dev/null", "--force"].map(String::from).to_vec(),
            "/dev/null: is not a regular file",
        ),
        (
            [
                "study",
                sp,
                "--reference",
                "ref.exr",
                "--spp",
                "8",
                "--batches",
                "4",
                "--seeds",
                "1",
                "--width",
                "32",
                "--height",
                "32",
                "--max-depth",
                "6",
                "-o",
                "s.streams.exr",
            ]
            .map(String::from)
            .to_vec(),
            "s.streams.exr: is a file; the study needs a folder",
        ),
    ];
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = cvtrace(d, &args);
        let e = stderr(&out);
        assert!(!out.status.success() && e.contains(needle), "{args:?}: error should mention {needle:?}:\n{e}");
        assert!(!e.contains("panicked"), "{e}");
        assert_eq!(files_in(d), before, "{args:?} left files behind");
    }
}

#[test]
fn study_resumes_and_report_builds_the_viewer() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let study = [
        &["--log", "warn", "study", sp, "--spp", "4,8", "--seeds", "2", "--batches", "4", "--reference", "ref.exr"][..],
        &["--reference-spp", "128", "-o", "study/cbox", "--ablations"],
        SMALL,
    ]
    .concat();
    ok(&cvtrace(d, &study));
    let results = StudyResults::read_json(&d.join("study/cbox/results.json")).unwrap();
    let scene = &results.scenes[0];
    assert_eq!((scene.name.as_str(), scene.seeds, scene.spp_per_stream), ("cornell-box", 2, 8));
    for k in ["pt", "crn", "average", "iduw", "cv", "ours", "pt2n", "ours-oracle", "ours-window"] {
        let m = scene.method(k).unwrap_or_else(|| panic!("{k} missing"));
        assert_eq!(m.relmse_per_seed.len(), 2);
        assert!(m.relmse_mean.is_finite() && m.relmse_mean > 0.0);
        assert!(d.join("study/cbox").join(m.image.as_ref().unwrap()).is_file());
    }
    // Two spp values: a convergence point per method and spp.
    assert!(scene.convergence.iter().filter(|p| p.method == "ours").count() == 2);
    assert!(scene.reference.noise.is_some());

    // Resume: a second run reuses every render (the files are not rewritten).
    let stamp = |p: &str| std::fs::metadata(d.join(p)).unwrap().modified().unwrap();
    let before = stamp("study/cbox/spp00008/seed-001.streams.exr");
    let out = cvtrace(d, &[&["--log", "info"][..], &study[2..]].concat());
    ok(&out);
    assert_eq!(stamp("study/cbox/spp00008/seed-001.streams.exr"), before);
    assert!(stderr(&out).contains("reusing"), "{}", stderr(&out));
    let again = StudyResults::read_json(&d.join("study/cbox/results.json")).unwrap();
    let rel = |r: &StudyResults| r.scenes[0].methods.iter().map(|m| m.relmse_mean).collect::<Vec<_>>();
    assert_eq!(rel(&again), rel(&results), "a resumed study gives the same numbers");
    // Other settings into the same folder: an error naming the file and the difference, not a
    // silent reuse of renders made otherwise.
    let deeper: Vec<&str> =
        study.iter().zip(std::iter::once(&"").chain(&study)).map(|(a, prev)| if *prev == "--max-depth" { "3" } else { a }).collect();
    // Settings that change the image itself make the reference another image's: that comes first.
    let cases: [(Vec<&str>, [&str; 2]); 4] = [
        ([&study[..], &["--traversal", "robust"]].concat(), ["seed-000", "traversal fast (in the file) vs robust (now)"]),
        ([&study[..], &["--rr-depth", "3"]].concat(), ["seed-000", "rr depth 5 (in the file) vs 3 (now)"]),
        (deeper, ["ref.exr: not a reference of this study's image", "max depth 6 (in the file) vs 3 (now)"]),
        ([&study[..], &["--camera", "278,273,-700:278,273,0:37"]].concat(), ["ref.exr: not a reference of this study's image", "camera"]),
    ];
    for (args, needles) in cases {
        let out = cvtrace(d, &args);
        assert!(!out.status.success(), "{needles:?}: the old renders were reused");
        assert!(needles.iter().all(|n| stderr(&out).contains(n)), "{needles:?}: {}", stderr(&out));
    }
    assert_eq!(stamp("study/cbox/spp00008/seed-001.streams.exr"), before);

    ok(&cvtrace(d, &["--log", "warn", "report", "study", "-o", "report", "--markdown", "summary.md"]));
    let md = std::fs::read_to_string(d.join("summary.md")).unwrap();
    assert!(md.contains("| cornell-box (8+8) |") && md.contains("Ours, 5×5 window selection"), "{md}");
    // The summary is not overwritten without --force.
    let again = cvtrace(d, &["--log", "warn", "report", "study", "-o", "report2", "--markdown", "summary.md"]);
    assert!(!again.status.success() && stderr(&again).contains("summary.md"), "{}", stderr(&again));
    assert!(!d.join("report2").exists(), "nothing written when the summary cannot be");
    let index = std::fs::read_to_string(d.join("report/index.html")).unwrap();
    assert!(index.contains("data.js"));
    let data = std::fs::read_to_string(d.join("report/data.js")).unwrap();
    assert!(data.contains("cornell-box") && data.contains("\"ours\""));
    let pngs = |dir: &str| -> Vec<String> {
        walk(&d.join(dir)).into_iter().filter(|p| p.ends_with(".png")).map(|p| p.rsplit('/').next().unwrap().to_string()).collect()
    };
    assert!(pngs("report").contains(&"ours-window.png".to_string()));

    // A lighter viewer: the ablations keep their numbers but lose their pictures.
    ok(&cvtrace(d, &["--log", "warn", "report", "study", "-o", "light", "--no-ablation-images"]));
    let light = pngs("light");
    assert!(light.contains(&"ours.png".to_string()) && !light.iter().any(|p| p.starts_with("ours-")), "{light:?}");
    assert!(std::fs::read_to_string(d.join("light/data.js")).unwrap().contains("ours-window"));
    // The pixel readout's values follow the images: all of them in the full viewer, none of the
    // ablations' in the light one (the study's files are found through the nested study folder).
    let pixels = |dir: &str| std::fs::read_to_string(d.join(dir).join("images/cornell-box/pixels.js")).unwrap();
    assert!(pixels("report").contains("\"ours\":") && pixels("report").contains("\"ours-window\":"));
    assert!(pixels("light").contains("\"ours\":") && !pixels("light").contains("\"ours-window\":"));

    // A viewer written among the studies is not taken for a study when the report is redone.
    ok(&cvtrace(d, &["--log", "warn", "report", "study", "-o", "study/viewer"]));
    ok(&cvtrace(d, &["--log", "warn", "report", "study", "-o", "study/viewer", "--force"]));
}

/// Every file under `dir`, as paths.
fn walk(dir: &std::path::Path) -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p.to_string_lossy().into_owned());
        }
    }
    out
}

//! Estimators as plug-ins, end to end: every parameter of every registered estimator is
//! recorded in its output, and an estimator of another crate (`cvtrace-ivw`) is reconstructed,
//! studied, reported and shown in the viewer like the built-in ones.
mod common;

use common::{cvtrace, ok, scene, stdout, SMALL};
use cvtrace_eval::StudyResults;
use cvtrace_streams::exr_io::{AttrValue, ExrChannels};
use std::path::Path;
use std::process::Command;

fn render_streams(dir: &Path) {
    let s = scene();
    let args = [
        &["--log", "warn", "render", s.to_str().unwrap(), "--spp", "16", "--batches", "8", "--seed", "3", "-o", "s.streams.exr"][..],
        SMALL,
    ];
    ok(&cvtrace(dir, &args.concat()));
}

/// Non-default values the estimators still run with: among them the settings that outputs
/// once failed to record (the filter's tolerances and centre, the seed of `cv`).
const CHANGED: [&str; 7] = [
    "ours.cbf_sigma_colour=0.5",
    "ours.cbf_sigma_normal=0.3",
    "ours.cbf_exclude_centre=true",
    "cv.seed=7",
    "iduw.selection_stride=2",
    "ivw.radius=2",
    "ours.crn_floor_mode=independent",
];

#[test]
fn every_parameter_of_every_estimator_is_recorded_in_its_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_streams(d);
    // A plain PT render of twice the streams' samples, for the estimators that post-process one.
    let s = scene();
    ok(&cvtrace(
        d,
        &[&["--log", "warn", "render", s.to_str().unwrap(), "--reference", "--spp", "32", "-o", "pt2n.exr"][..], SMALL].concat(),
    ));
    let mut args = vec!["--log", "warn", "reconstruct", "s.streams.exr", "--method", "all", "--pt2n", "pt2n.exr", "-o", "out"];
    for a in CHANGED {
        args.extend(["--param", a]);
    }
    ok(&cvtrace(d, &args));
    let registry = cvtrace_lineup::registry();
    assert!(registry.specs().iter().any(|s| s.name == "ivw"), "the example estimator is registered");
    for spec in registry.specs() {
        let file = ExrChannels::read(&d.join(format!("out/{}.exr", spec.name))).unwrap();
        assert_eq!(file.attr("cvtrace.method"), Some(&AttrValue::Text(spec.name.into())));
        for p in spec.params {
            let given = CHANGED.iter().find_map(|a| a.strip_prefix(&format!("{}.{}=", spec.name, p.name)));
            let want = given.unwrap_or(p.default);
            let key = format!("cvtrace.option.{}", p.name);
            assert_eq!(file.attr(&key), Some(&AttrValue::Text(want.into())), "{}: {key}", spec.name);
        }
        let recorded = file.attributes.keys().filter(|k| k.starts_with("cvtrace.option.")).count();
        assert_eq!(recorded, spec.params.len(), "{}: only declared parameters are recorded", spec.name);
    }
    // --list names every registered estimator; --help-method prints one spec.
    let list = stdout(&cvtrace(d, &["reconstruct", "--list"]));
    assert!(registry.specs().iter().all(|s| list.lines().any(|l| l.starts_with(s.name))), "{list}");
    let help = stdout(&cvtrace(d, &["reconstruct", "--help-method", "ivw"]));
    assert!(help.contains("ivw.max_weight = 1") && help.contains("Inverse-variance blend"), "{help}");
}

#[test]
fn an_estimator_of_another_crate_is_studied_reported_and_shown() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let study = [
        &["--log", "warn", "study", s.to_str().unwrap(), "--spp", "8", "--seeds", "2", "--batches", "4", "--reference", "ref.exr"][..],
        &["--reference-spp", "64", "-o", "study/cbox", "--param", "ivw.max_weight=0.9", "--headline", "ivw/pt,ours/pt2n"],
        SMALL,
    ]
    .concat();
    ok(&cvtrace(d, &study));
    let results = StudyResults::read_json(&d.join("study/cbox/results.json")).unwrap();
    let scene = &results.scenes[0];
    let ivw = scene.method("ivw").expect("ivw is a column of the study");
    assert_eq!((ivw.label.as_str(), ivw.short.as_str(), ivw.colour.as_deref()), ("Inverse-variance blend", "IVW", Some("#ff9da7")));
    assert_eq!(ivw.spp_total, 16);
    assert!(ivw.settings.contains(&("max_weight".into(), "0.9".into())), "{:?}", ivw.settings);
    assert!(ivw.diagnostics.iter().any(|(k, v)| k == "crn_weight_mean" && v.as_f64().is_some_and(|w| w > 0.0 && w <= 0.9)));
    assert_eq!(ivw.relmse_per_seed.len(), 2);
    assert!(scene.ratios().iter().any(|r| r.numerator == "ivw" && r.denominator == "pt"));
    // Settings and provenance of every method, not only the new one.
    let ours = scene.method("ours").unwrap();
    assert!(ours.settings.iter().any(|(k, _)| k == "cbf_sigma_albedo") && !ours.diagnostics.is_empty());
    assert!(scene.render.iter().any(|(k, _)| k == "scene hash"));

    ok(&cvtrace(d, &["--log", "warn", "report", "study", "-o", "report", "--markdown", "summary.md"]));
    let md = std::fs::read_to_string(d.join("summary.md")).unwrap();
    assert!(md.contains("IVW/PT(n)"), "{md}");
    let chromium = Path::new("/usr/bin/chromium");
    if !chromium.exists() {
        assert!(std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "chromium is missing and CVTRACE_REQUIRE_TOOLS is set");
        eprintln!("no chromium: the viewer's DOM is not checked");
        return;
    }
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(chromium)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking"])
        .args(["--disable-component-update", "--disable-sync", "--allow-file-access-from-files", "--virtual-time-budget=5000"])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", d.join("report/index.html").display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&out.stdout);
    // The results table, the legend and the provenance block show the new estimator.
    assert!(dom.matches("Inverse-variance blend").count() >= 2, "{dom}");
    assert!(dom.contains("max_weight = 0.9") && dom.contains("crn_weight_mean"), "settings and diagnostics are shown");
    assert!(dom.contains("IVW / PT(n)"), "the headline ratio uses the short labels");
    // Equal-time efficiency beside equal-sample error, and no local absolute path in the page.
    assert!(dom.contains("relMSE × s") && dom.contains("÷ PT(2n), equal time") && dom.contains("/efficiency_over_pt2n"), "{dom}");
    let root = d.canonicalize().unwrap().display().to_string();
    let data = std::fs::read_to_string(d.join("report/data.js")).unwrap();
    assert!(!dom.contains(&root) && !data.contains(&root), "the page names {root}");
}

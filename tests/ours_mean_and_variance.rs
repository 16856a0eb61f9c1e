//! Two statistical promises of `ours` on a real render, checked over independent seeds of the
//! Cornell box at 32 + 32 spp against its committed 16 384-spp reference:
//!
//! - **mean-preserving**: per channel, the image mean over seeds is within 0.2% of the
//!   reference's, or within 3 standard errors of its own seed noise where that is larger
//!   (the reference's own noise in the image mean is ≈ 0.01%, far below either);
//! - **calibrated**: the estimator's predicted variance (its `variance` layer, Eq. 7 at the
//!   chosen β) averaged over pixels like relMSE, divided by the variance measured over the
//!   seeds, lies in 0.8–1.25. With 4 seeds the measured variance of the pixel average has a
//!   relative standard error of about 2% here, so the band is wide against seed noise and
//!   narrow against a prediction that misses a term.
mod common;
use common::{cvtrace, ok, scene};
use cvtrace_eval::StudyResults;

#[test]
fn ours_keeps_the_image_mean_and_predicts_its_variance_at_32_spp() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = scene().parent().unwrap().join("scene.ref.exr");
    let out = tmp.path().join("study");
    let run = cvtrace(
        tmp.path(),
        &[
            "--log",
            "warn",
            "study",
            scene().to_str().unwrap(),
            "--spp",
            "32",
            "--batches",
            "16",
            "--seeds",
            "4",
            "--reference",
            reference.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
    );
    ok(&run);
    let results = StudyResults::read_json(&out.join("results.json")).unwrap();
    let ours = results.scenes[0].method("ours").unwrap();
    let offset = ours.image_mean_offset.expect("image mean offset recorded");
    let se = ours.image_mean_offset_se.expect("4 seeds give a standard error");
    for ch in 0..3 {
        let allowed = 0.002f64.max(3.0 * se[ch]);
        assert!(
            offset[ch].abs() <= allowed,
            "channel {ch}: image mean off by {:+.3}% (allowed ±{:.3}%)",
            100.0 * offset[ch],
            100.0 * allowed
        );
    }
    let calibration = ours.predicted_variance.expect("ours predicts its variance") / ours.variance.unwrap();
    assert!((0.8..=1.25).contains(&calibration), "predicted ÷ measured variance {calibration:.3}");
    // The per-seed figures are in results.json too, and average to the reported one.
    let per_seed = &ours.predicted_variance_per_seed;
    assert_eq!(per_seed.len(), ours.relmse_per_seed.len());
    let mean = per_seed.iter().sum::<f64>() / per_seed.len() as f64;
    assert!((mean - ours.predicted_variance.unwrap()).abs() <= 1e-9 * mean);
    // Methods without a variance layer record none.
    let pt = results.scenes[0].method("pt").unwrap();
    assert!(pt.predicted_variance.is_none() && pt.predicted_variance_per_seed.is_empty());
}

#[test]
fn reconstruct_writes_the_variance_layer_beside_the_picture() {
    let tmp = tempfile::tempdir().unwrap();
    let streams = tmp.path().join("s.exr");
    let scene = scene();
    let mut args =
        vec!["--log", "warn", "render", scene.to_str().unwrap(), "--spp", "8", "--batches", "4", "-o", streams.to_str().unwrap()];
    args.extend_from_slice(common::SMALL);
    ok(&cvtrace(tmp.path(), &args));
    let out = tmp.path().join("ours.exr");
    ok(&cvtrace(tmp.path(), &["--log", "warn", "reconstruct", streams.to_str().unwrap(), "-o", out.to_str().unwrap()]));
    let ch = cvtrace_streams::exr_io::ExrChannels::read(&out).unwrap();
    let names: Vec<&str> = ch.channels.keys().map(String::as_str).collect();
    assert_eq!(names, ["B", "G", "R", "variance.B", "variance.G", "variance.R"]);
    assert!(ch.channels["variance.R"].iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(ch.channels["variance.G"].iter().any(|v| *v > 0.0));
}

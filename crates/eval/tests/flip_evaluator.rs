//! HDR-FLIP against NVIDIA's own implementation: the `flip-evaluator` package (PyPI), run by the
//! project's virtual environment (`.venv` at the repository root, made by scripts/setup.sh)
//! on the same EXR files. The exposures must be the same, the means agree to 1e-3 (the
//! project's requirement; in practice far closer) and every pixel of the error maps closely.
//!
//! Skipped, with a message, when `.venv/bin/python` or the package is missing, unless
//! `CVTRACE_REQUIRE_TOOLS` is set (as `make test` does), in which case it fails.
use cvtrace_eval::flip::FlipReference;
use cvtrace_streams::exr_io::{read_rgb, write_rgb};
use cvtrace_streams::Image;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The tolerance the project asks for on the mean.
const MEAN_TOLERANCE: f64 = 1e-3;
/// Per pixel: the implementations do the same f32 operations in the same order, so only
/// rounding separates them (amplified near edges by the powers; 3.2e-5 at most here).
const PIXEL_TOLERANCE: f32 = 1e-4;

fn venv_python() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/bin/python")
}

/// Whether the venv's Python imports flip_evaluator and numpy; with `CVTRACE_REQUIRE_TOOLS`
/// set, a missing one fails the test instead.
fn have_flip_evaluator() -> bool {
    let python = venv_python();
    let found =
        python.exists() && Command::new(&python).args(["-c", "import flip_evaluator, numpy"]).output().is_ok_and(|o| o.status.success());
    assert!(
        found || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(),
        "{} cannot import flip_evaluator and CVTRACE_REQUIRE_TOOLS is set: run scripts/setup.sh",
        python.display()
    );
    found
}

/// A small deterministic generator (xorshift), uniform in [0, 1) and roughly normal.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn normal(&mut self) -> f32 {
        (0..4).map(|_| self.uniform()).sum::<f32>() - 2.0
    }
}

fn blur(img: &Image, r: usize) -> Image {
    Image::from_fn(img.width, img.height, |x, y| {
        let mut s = [0.0f32; 3];
        let mut n = 0.0;
        for yy in y.saturating_sub(r)..(y + r + 1).min(img.height) {
            for xx in x.saturating_sub(r)..(x + r + 1).min(img.width) {
                let p = img.get(xx, yy);
                (0..3).for_each(|c| s[c] += p[c]);
                n += 1.0;
            }
        }
        s.map(|v| v / n)
    })
}

/// (name, reference, test) pairs that exercise the exposure range, noise, highlights and edges.
fn cases() -> Vec<(&'static str, Image, Image)> {
    let (w, h) = (160, 120);
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);

    // A rendered-like HDR gradient (a lit wall falling off into shadow), with path-tracing-like
    // multiplicative noise in the test image.
    let gradient = Image::from_fn(w, h, |x, y| {
        let u = x as f32 / w as f32;
        let v = y as f32 / h as f32;
        let light = 4.0 * (-3.0 * ((u - 0.3).powi(2) + (v - 0.2).powi(2))).exp() + 0.02;
        [light * 0.9, light * 0.8 * (0.6 + 0.4 * u), light * (0.5 + 0.5 * v)]
    });
    let noisy = Image {
        pixels: gradient.pixels.iter().map(|p| p.map(|c| (c * (1.0 + 0.35 * rng.normal())).max(0.0))).collect(),
        ..gradient.clone()
    };

    // Values well above 1 (an emitter of 50 and its glow) against a denoiser-like blurred,
    // slightly darkened estimate.
    let bright = Image::from_fn(w, h, |x, y| {
        let (dx, dy) = (x as f32 - 100.0, y as f32 - 40.0);
        let d2 = dx * dx + dy * dy;
        let base = [0.3 + 0.2 * (x as f32 / w as f32), 0.25, 0.2];
        if d2 < 64.0 {
            [50.0, 45.0, 30.0]
        } else {
            base.map(|b| b + 8.0 * (-d2 / 400.0).exp())
        }
    });
    let mut blurred = blur(&bright, 2);
    blurred.pixels.iter_mut().for_each(|p| *p = p.map(|c| c * 0.93));

    // Hard edges: boxes and stripes, against the same shifted by a pixel with a little noise.
    let edges = Image::from_fn(w, h, |x, y| {
        let stripe = if (x / 6) % 2 == 0 { 0.8 } else { 0.05 };
        let in_box = (40..90).contains(&x) && (30..80).contains(&y);
        if in_box {
            [2.5, 0.1, 0.1]
        } else if y > 90 {
            [stripe, stripe, stripe]
        } else {
            [0.1, 0.3 * (x as f32 / w as f32), 0.6]
        }
    });
    let shifted = Image::from_fn(w, h, |x, y| {
        let p = edges.get((x + 1).min(w - 1), y);
        let n = 1.0 + 0.1 * rng.normal();
        p.map(|c| (c * n).max(0.0))
    });

    // A dark interior lit by small bright lights: a wide range, so many exposures.
    let dark = Image::from_fn(w, h, |x, y| {
        let v = 0.002 + 0.03 * (x as f32 / w as f32) * (y as f32 / h as f32);
        if (x % 53 < 3) && (y % 41 < 3) {
            [200.0, 180.0, 150.0]
        } else {
            [v, v * 1.1, v * 0.9]
        }
    });
    let dark_noisy =
        Image { pixels: dark.pixels.iter().map(|p| p.map(|c| (c * (1.0 + 0.5 * rng.normal())).max(0.0))).collect(), ..dark.clone() };
    vec![
        ("gradient-noise", gradient, noisy),
        ("above-one-blurred", bright, blurred),
        ("edges", edges, shifted),
        ("dark-lights", dark, dark_noisy),
    ]
}

/// Runs flip-evaluator on every (reference, test) EXR pair; per pair, its error map (f32,
/// row-major, written next to the files) and a line of JSON: the mean, the parameters and the
/// sum of the reference it read (to show it read the same pixels).
const SCRIPT: &str = r#"
import json, sys
import numpy as np
import flip_evaluator as flip
for ref, test, out in zip(*[iter(sys.argv[1:])] * 3):
    r = flip.load(ref)
    t = flip.load(test)
    err, mean, params = flip.evaluate(r, t, "HDR", applyMagma=False)
    np.asarray(err, dtype="<f4").reshape(-1).tofile(out)
    print(json.dumps({"mean": float(mean), "params": params, "ref_sum": float(np.asarray(r, dtype=np.float64).sum())}))
"#;

#[test]
fn hdr_flip_matches_nvidias_flip_evaluator() {
    if !have_flip_evaluator() {
        eprintln!(
            "SKIPPED flip_evaluator: {} cannot import flip_evaluator. Run scripts/setup.sh (it makes .venv with flip-evaluator) to compare against NVIDIA's implementation.",
            venv_python().display()
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cases = cases();
    let mut args = Vec::new();
    for (name, r, t) in &cases {
        let (rp, tp) = (dir.path().join(format!("{name}.ref.exr")), dir.path().join(format!("{name}.test.exr")));
        write_rgb(&rp, r, &[], false).unwrap();
        write_rgb(&tp, t, &[], false).unwrap();
        args.extend([rp, tp, dir.path().join(format!("{name}.flip.f32"))]);
    }
    let out = Command::new(venv_python()).arg("-c").arg(SCRIPT).args(&args).output().unwrap();
    assert!(out.status.success(), "flip-evaluator failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).expect("one JSON line per pair")).collect();
    assert_eq!(lines.len(), cases.len());

    let (mut worst_mean, mut worst_pixel) = (0.0f64, 0.0f32);
    for (((name, _, _), theirs), files) in cases.iter().zip(&lines).zip(args.chunks(3)) {
        // Both sides score exactly what the files hold.
        let (r, t) = (read_rgb(&files[0]).unwrap(), read_rgb(&files[1]).unwrap());
        let ref_sum: f64 = r.pixels.iter().flatten().map(|v| *v as f64).sum();
        assert!((ref_sum - theirs["ref_sum"].as_f64().unwrap()).abs() <= 1e-9 * ref_sum.abs(), "{name}: flip-evaluator read other pixels");

        let fr = FlipReference::new(&r, files[0].display().to_string()).unwrap();
        let e = fr.exposures();
        let p = &theirs["params"];
        assert_eq!(p["ppd"].as_f64().unwrap() as f32, fr.ppd(), "{name}: ppd");
        assert_eq!(p["startExposure"].as_f64().unwrap() as f32, e.start, "{name}: start exposure");
        assert_eq!(p["stopExposure"].as_f64().unwrap() as f32, e.stop, "{name}: stop exposure");
        assert_eq!(p["numExposures"].as_u64().unwrap() as u32, e.count, "{name}: number of exposures");

        let ours = fr.evaluate(&t, &files[1].display().to_string()).unwrap();
        let map: Vec<f32> = std::fs::read(&files[2]).unwrap().chunks(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        assert_eq!(map.len(), ours.values.len(), "{name}: map size");
        let mean_diff = (ours.mean - theirs["mean"].as_f64().unwrap()).abs();
        let (mut max_diff, mut at, mut differing) = (0.0f32, 0, 0);
        for (i, (a, b)) in ours.values.iter().zip(&map).enumerate() {
            let d = (a - b).abs();
            differing += usize::from(d > 0.0);
            if d > max_diff {
                (max_diff, at) = (d, i);
            }
        }
        eprintln!(
            "{name}: {} exposures from {:.4} to {:.4}; mean FLIP {:.6} (flip-evaluator {:.6}, |Δ| {mean_diff:.2e}); pixels: max |Δ| {max_diff:.2e}, {differing} of {} differ",
            e.count,
            e.start,
            e.stop,
            ours.mean,
            theirs["mean"].as_f64().unwrap(),
            map.len()
        );
        assert!(mean_diff <= MEAN_TOLERANCE, "{name}: mean FLIP {} vs flip-evaluator's {}", ours.mean, theirs["mean"]);
        assert!(
            max_diff <= PIXEL_TOLERANCE,
            "{name}: pixel ({}, {}) is {} here, {} in flip-evaluator",
            at % r.width,
            at / r.width,
            ours.values[at],
            map[at]
        );
        assert!(ours.mean > 0.01, "{name}: the test image should differ visibly, or the check proves little");
        worst_mean = worst_mean.max(mean_diff);
        worst_pixel = worst_pixel.max(max_diff);
    }
    eprintln!("all cases: max |Δ mean| {worst_mean:.2e}, max |Δ pixel| {worst_pixel:.2e}");
}

//! A synthetic study: a procedural box-like image, Gaussian "PT" and "CRN" noise, and toy
//! combinations standing in for the estimators — no renderer involved.
//!
//! It exercises the whole evaluation pipeline (seed statistics, reference noise, previews,
//! false-colour maps, convergence, results.json) exactly as a real study would, for tests,
//! docs and trying the viewer. Its numbers say nothing about the real estimators, and its
//! labels say "synthetic" so nobody mistakes them.
use crate::difference::{scale_for_differences, signed_difference, write_difference_png};
use crate::falsecolor::{scale_for_maps, write_false_color_png};
use crate::flip::{write_flip_png, FlipAccumulator, FlipReference};
use crate::metrics::Reference;
use crate::pixels::write_values_exr;
use crate::reference_noise::{from_half_references, too_noisy_warning};
use crate::results::{keys, ConvergencePoint, MethodResult, ReferenceInfo, SceneResult, StageTimes, StudyResults};
use crate::rng::Rng;
use crate::stats::SeedAccumulator;
use crate::EvalError;
use cvtrace_streams::Image;
use std::f32::consts::TAU;
use std::path::Path;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SyntheticOptions {
    pub scene_name: String,
    pub width: usize,
    pub height: usize,
    pub spp_per_stream: u32,
    pub seeds: u32,
    /// Per-stream spp values of the convergence plot (empty: no plot).
    pub convergence_spp: Vec<u32>,
    /// Add one ablation method.
    pub ablations: bool,
}

impl SyntheticOptions {
    /// Small enough for unit tests (well under a second).
    pub fn small() -> Self {
        SyntheticOptions {
            scene_name: "synthetic box".into(),
            width: 64,
            height: 48,
            spp_per_stream: 16,
            seeds: 4,
            convergence_spp: vec![4, 8, 16, 32],
            ablations: true,
        }
    }
}

/// The noise-free image: back wall, red and green side walls, floor, a ceiling light that
/// clips, a shaded sphere with a soft shadow and a box.
pub fn synthetic_truth(width: usize, height: usize) -> Image {
    Image::from_fn(width, height, |x, y| {
        let u = (x as f32 + 0.5) / width as f32;
        let v = (y as f32 + 0.5) / height as f32;
        let light_falloff = 0.35 + 0.65 * (1.0 - v).powf(0.7);
        let mut c = [0.55 * light_falloff, 0.52 * light_falloff, 0.48 * light_falloff];
        if u < 0.14 {
            c = [0.55 * light_falloff, 0.06, 0.05];
        } else if u > 0.86 {
            c = [0.08, 0.42 * light_falloff, 0.09];
        } else if v > 0.8 {
            let d = 0.25 + 0.75 * (1.0 - (u - 0.5).abs());
            c = [0.45 * d, 0.43 * d, 0.4 * d];
        } else if v < 0.07 {
            c = if (0.38..0.62).contains(&u) { [9.0, 8.0, 6.5] } else { [0.3, 0.29, 0.27] };
        }
        // Soft shadow under the sphere.
        let (sx, sy) = (0.36f32, 0.66f32);
        let shadow = ((u - sx).powi(2) / 0.02 + (v - 0.86).powi(2) / 0.002).min(1.0);
        if v > 0.8 {
            c = c.map(|k| k * (0.45 + 0.55 * shadow));
        }
        // Sphere.
        let (dx, dy) = ((u - sx) / 0.14, (v - sy) / (0.14 * width as f32 / height as f32));
        let r2 = dx * dx + dy * dy;
        if r2 < 1.0 {
            let nz = (1.0 - r2).sqrt();
            let l = [0.0f32, -0.8, 0.6];
            let ndotl = (dx * l[0] + dy * l[1] + nz * l[2]).max(0.0);
            let s = 0.06 + 0.9 * ndotl;
            c = [0.8 * s, 0.78 * s, 0.72 * s];
        }
        // Box.
        if (0.56..0.8).contains(&u) && (0.42..0.84).contains(&v) {
            let top = v < 0.5;
            let s = if top { 0.75 } else { 0.38 + 0.1 * (u - 0.56) / 0.24 };
            c = [0.7 * s, 0.68 * s, 0.65 * s];
        }
        c
    })
}

/// Per-pixel noise standard deviation at 1 spp (brighter pixels are noisier).
fn sigma1(p: [f32; 3]) -> f32 {
    let lum = (p[0] + p[1] + p[2]) / 3.0;
    0.9 * (lum + 0.02).sqrt()
}

fn pt_image(t: &Image, spp: u32, rng: &mut Rng) -> Image {
    let s = 1.0 / (spp as f32).sqrt();
    let mut out = t.clone();
    for p in out.pixels.iter_mut() {
        let sg = sigma1(*p) * s;
        for v in p.iter_mut() {
            *v += sg * rng.normal() as f32;
        }
    }
    out
}

/// CRN-like noise: a smooth field shared by all pixels (the common random numbers) plus a
/// weaker independent part.
fn crn_image(t: &Image, spp: u32, rng: &mut Rng) -> Image {
    let s = 1.0 / (spp as f32).sqrt();
    let (a, b, ph1, ph2) = (rng.normal() as f32, rng.normal() as f32, rng.uniform() as f32 * TAU, rng.uniform() as f32 * TAU);
    let (w, h) = (t.width as f32, t.height as f32);
    let mut out = t.clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let (x, y) = ((i % t.width) as f32 / w, (i / t.width) as f32 / h);
        let field = 0.9 * (a * (3.0 * x + ph1).sin() + b * (2.0 * y + ph2).cos());
        let sg = sigma1(*p) * s;
        for v in p.iter_mut() {
            *v += sg * (field + 0.35 * rng.normal() as f32);
        }
    }
    out
}

/// Separable box blur of radius `r` with mirrored borders.
fn box_blur(img: &Image, r: usize) -> Image {
    let (w, h) = (img.width as isize, img.height as isize);
    let mirror = |i: isize, n: isize| -> usize {
        let i = if i < 0 { -i } else { i };
        (if i >= n { 2 * n - 2 - i } else { i }).clamp(0, n - 1) as usize
    };
    let pass = |src: &Image, horizontal: bool| -> Image {
        Image::from_fn(src.width, src.height, |x, y| {
            let mut acc = [0.0f32; 3];
            for k in -(r as isize)..=(r as isize) {
                let (sx, sy) = if horizontal { (mirror(x as isize + k, w), y) } else { (x, mirror(y as isize + k, h)) };
                let p = src.get(sx, sy);
                for c in 0..3 {
                    acc[c] += p[c];
                }
            }
            acc.map(|v| v / (2 * r + 1) as f32)
        })
    };
    pass(&pass(img, true), false)
}

fn zip(a: &Image, b: &Image, f: impl Fn(f32, f32) -> f32) -> Image {
    Image {
        width: a.width,
        height: a.height,
        pixels: a.pixels.iter().zip(&b.pixels).map(|(p, q)| [0, 1, 2].map(|c| f(p[c], q[c]))).collect(),
    }
}

/// The toys that use one stream's samples.
fn one_stream(key: &str) -> bool {
    key == "pt" || key == "crn"
}

/// One colour per toy, in `methods` order.
const TOY_COLOURS: [[u8; 3]; 8] = [
    [0xe1, 0x57, 0x59],
    [0xf2, 0x8e, 0x2b],
    [0xed, 0xc9, 0x48],
    [0x76, 0xb7, 0xf2],
    [0xb0, 0x7a, 0xe1],
    [0x59, 0xd9, 0x8e],
    [0xc8, 0xc0, 0xbc],
    [0x86, 0xbc, 0xb6],
];

/// `crn + blur_r(pt − crn)`: unbiased where the CRN error is smooth.
fn toy_cv(pt: &Image, crn: &Image, r: usize) -> Image {
    let diff = zip(pt, crn, |a, b| a - b);
    zip(crn, &box_blur(&diff, r), |a, b| a + b)
}

/// (key, label, ablation) of the synthetic methods, in display order: toys named after the
/// estimators they stand in for, so that the viewer's tests see a study's shape.
fn methods(ablations: bool) -> Vec<(&'static str, &'static str, bool)> {
    let mut m = vec![
        ("pt", "PT (synthetic)", false),
        ("crn", "CRN (synthetic)", false),
        ("average", "Average (synthetic)", false),
        ("iduw", "IDUW (synthetic toy)", false),
        ("cv", "CV (synthetic toy)", false),
        ("ours", "Ours (synthetic toy)", false),
        (keys::PT_2N, "PT 2n (synthetic)", false),
    ];
    if ablations {
        m.push(("ours-unsmoothed", "Ours, no smoothing (synthetic toy)", true));
    }
    m
}

/// One seed of every method at `spp` per stream, with the seconds each took.
fn run_seed(t: &Image, spp: u32, seed: u64, ablations: bool) -> Vec<(Image, StageTimes)> {
    let mut rng = Rng::new(seed);
    let t0 = Instant::now();
    let pt = pt_image(t, spp, &mut rng);
    let t_pt = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let crn = crn_image(t, spp, &mut rng);
    let t_crn = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let pt2n = pt_image(t, 2 * spp, &mut rng);
    let t_pt2n = t2.elapsed().as_secs_f64();
    let render = StageTimes { render: t_pt + t_crn, reconstruct: 0.0 };
    let timed = |f: &dyn Fn() -> Image| {
        let s = Instant::now();
        let img = f();
        (img, StageTimes { render: render.render, reconstruct: s.elapsed().as_secs_f64() })
    };
    let mut out = vec![
        (pt.clone(), StageTimes { render: t_pt, reconstruct: 0.0 }),
        (crn.clone(), StageTimes { render: t_crn, reconstruct: 0.0 }),
        timed(&|| zip(&pt, &crn, |a, b| 0.5 * (a + b))),
        timed(&|| toy_cv(&pt, &crn, 1)),
        timed(&|| toy_cv(&pt, &crn, 2)),
        timed(&|| {
            let x = toy_cv(&pt, &crn, 3);
            zip(&x, &box_blur(&x, 1), |a, b| 0.6 * a + 0.4 * b)
        }),
        (pt2n, StageTimes { render: t_pt2n, reconstruct: 0.0 }),
    ];
    if ablations {
        out.push(timed(&|| toy_cv(&pt, &crn, 3)));
    }
    out
}

/// Runs the synthetic study into `dir` (created if needed): previews, relMSE, difference and
/// FLIP maps and results.json (overwritten). Returns the results, with paths relative to `dir`.
pub fn write_synthetic_study(dir: &Path, opts: &SyntheticOptions) -> Result<StudyResults, EvalError> {
    if opts.width < 8 || opts.height < 8 || opts.spp_per_stream == 0 || opts.seeds == 0 {
        return Err(EvalError::invalid("synthetic study", "needs at least 8x8 pixels, 1 spp and 1 seed"));
    }
    std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    let truth = synthetic_truth(opts.width, opts.height);
    let list = methods(opts.ablations);

    // The reference: the average of two independent, nearly noise-free halves.
    let mut rng = Rng::new(0x5eed);
    let ref_spp = 4096;
    let half_a = pt_image(&truth, ref_spp / 2, &mut rng);
    let half_b = pt_image(&truth, ref_spp / 2, &mut rng);
    let reference = Reference::new(Image::mean_of(&[half_a.clone(), half_b.clone()]), "synthetic reference")?;
    let noise = from_half_references(&reference, &half_a, "reference half A", &half_b, "reference half B")?;
    cvtrace_streams::preview::write_png(&dir.join("reference.png"), &reference.image, 0.0, true)?;

    let n = opts.spp_per_stream;
    let mut accs: Vec<SeedAccumulator> = list.iter().map(|(k, _, _)| SeedAccumulator::new(&reference, *k)).collect();
    let flip_reference = FlipReference::new(&reference.image, reference.label.clone())?;
    let mut flips: Vec<FlipAccumulator> = list.iter().map(|_| FlipAccumulator::new(&flip_reference)).collect();
    let mut times = vec![StageTimes::default(); list.len()];
    let mut first_images = Vec::new();
    for seed in 0..opts.seeds {
        for (i, (img, t)) in run_seed(&truth, n, 1000 + seed as u64, opts.ablations).into_iter().enumerate() {
            accs[i].add(&img)?;
            flips[i].add(&img, &format!("{} seed {seed}", list[i].0))?;
            times[i].render += t.render / opts.seeds as f64;
            times[i].reconstruct += t.reconstruct / opts.seeds as f64;
            if seed == 0 {
                cvtrace_streams::preview::write_png(&dir.join(format!("{}.png", list[i].0)), &img, 0.0, true)?;
                first_images.push(img);
            }
        }
    }
    let maps: Vec<Vec<f32>> = accs.iter().map(|a| a.mean_rel_mse_map()).collect();
    let scale = scale_for_maps(&maps.iter().map(|m| m.as_slice()).collect::<Vec<_>>());
    let diffs = first_images.iter().map(|img| signed_difference(img, &reference.image)).collect::<Result<Vec<_>, _>>()?;
    let diff_scale = scale_for_differences(&diffs.iter().map(|m| m.as_slice()).collect::<Vec<_>>());
    write_values_exr(&dir.join("reference.values.exr"), &reference.image, None, None, true)?;
    let mut results = Vec::new();
    for (i, (key, label, ablation)) in list.iter().enumerate() {
        let stats = accs[i].finish()?;
        let spp_total = if one_stream(key) { n } else { 2 * n };
        let mut m = MethodResult::from_stats(key, label, spp_total, &stats);
        m.colour = Some(crate::palette::hex(TOY_COLOURS[i % TOY_COLOURS.len()]));
        m.time_seconds = times[i];
        m.ablation = *ablation;
        m.image = Some(format!("{key}.png"));
        let map_file = format!("{key}.relmse.png");
        write_false_color_png(&dir.join(&map_file), &maps[i], opts.width, opts.height, &scale, true)?;
        m.error_map = Some(map_file);
        let diff_file = format!("{key}.diff.png");
        write_difference_png(&dir.join(&diff_file), &diffs[i], opts.width, opts.height, &diff_scale, true)?;
        m.difference_map = Some(diff_file);
        if let Some(f) = flips[i].finish() {
            m.set_flip(&f);
        }
        let flip_map = flips[i].mean_map();
        let flip_file = format!("{key}.flip.png");
        write_flip_png(&dir.join(&flip_file), &flip_map, opts.width, opts.height, true)?;
        m.flip_map = Some(flip_file);
        let values_file = format!("{key}.values.exr");
        write_values_exr(&dir.join(&values_file), &first_images[i], Some(&maps[i]), Some(&flip_map), true)?;
        m.values = Some(values_file);
        results.push(m);
    }

    // Convergence: two seeds per spp value.
    let mut convergence = Vec::new();
    for &spp in &opts.convergence_spp {
        let mut accs: Vec<SeedAccumulator> = list.iter().map(|(k, _, _)| SeedAccumulator::new(&reference, *k)).collect();
        let mut seconds = vec![0.0; list.len()];
        for seed in 0..2u64 {
            for (i, (img, t)) in run_seed(&truth, spp, 50_000 + 100 * spp as u64 + seed, false).into_iter().enumerate() {
                accs[i].add(&img)?;
                seconds[i] += t.total() / 2.0;
            }
        }
        for ((acc, (key, _, _)), t) in accs.iter().zip(&list).zip(&seconds).filter(|((_, (_, _, abl)), _)| !abl) {
            let s = acc.finish()?;
            let spp_total = if one_stream(key) { spp } else { 2 * spp };
            convergence.push(ConvergencePoint {
                method: key.to_string(),
                spp_total,
                relmse: s.relmse_mean,
                relmse_se: s.relmse_se,
                // A time of 0 (a clock too coarse for a tiny image) has no place on a log axis.
                seconds: (*t > 0.0).then_some(*t),
                bias2: s.bias2,
            });
        }
    }

    let mut scene = SceneResult {
        name: opts.scene_name.clone(),
        width: opts.width,
        height: opts.height,
        spp_per_stream: n,
        seeds: opts.seeds,
        reference: ReferenceInfo {
            path: "synthetic (no file)".into(),
            spp: Some(ref_spp),
            image: Some("reference.png".into()),
            noise: Some(noise),
            values: Some("reference.values.exr".into()),
        },
        methods: results,
        convergence,
        error_map_scale: Some(scale),
        difference_scale: Some(diff_scale),
        flip: Some(flip_reference.settings()),
        warnings: Vec::new(),
        headline: crate::results::paper_headline(),
        render: Vec::new(),
    };
    if let Some(w) = scene.best_relmse().and_then(|best| too_noisy_warning(noise.relmse, best)) {
        scene.warnings.push(w);
    }
    let study = StudyResults::new(vec![scene]);
    study.write_json(&dir.join("results.json"), true)?;
    Ok(study)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_study_is_deterministic_and_ranks_as_designed() {
        let dir = tempfile::tempdir().unwrap();
        let a = write_synthetic_study(&dir.path().join("a"), &SyntheticOptions::small()).unwrap();
        let b = write_synthetic_study(&dir.path().join("b"), &SyntheticOptions::small()).unwrap();
        let strip = |r: &StudyResults| {
            let mut r = r.clone();
            for s in r.scenes.iter_mut() {
                s.methods.iter_mut().for_each(|m| m.time_seconds = StageTimes::default());
                s.convergence.iter_mut().for_each(|p| p.seconds = None);
            }
            r
        };
        assert_eq!(strip(&a), strip(&b), "same seeds, same numbers (times aside)");
        let s = &a.scenes[0];
        let rel = |k: &str| s.method(k).unwrap().relmse_mean;
        // PT(2n) halves PT(n)'s variance: its relMSE ratio should be near 1/2.
        let r = rel(keys::PT_2N) / rel(keys::PT);
        assert!((0.4..0.6).contains(&r), "PT(2n)/PT(n) = {r}");
        assert!(rel("ours") < rel(keys::PT_2N));
        // HDR-FLIP ranks the noisy methods the same way, and every method has a map.
        let flip = |k: &str| s.method(k).unwrap().flip_mean.unwrap();
        assert!(
            flip(keys::PT_2N) < flip(keys::PT) && flip("ours") < flip(keys::PT),
            "{} {} {}",
            flip("ours"),
            flip(keys::PT_2N),
            flip(keys::PT)
        );
        assert!(s.methods.iter().all(|m| m.flip_se.is_some() && m.flip_per_seed.len() == 4 && m.flip_map.is_some()));
        assert!(s.flip.is_some());
        // The reference is far cleaner than any method, so no warning.
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(StudyResults::read_json(&dir.path().join("a/results.json")).unwrap(), a);
    }
}

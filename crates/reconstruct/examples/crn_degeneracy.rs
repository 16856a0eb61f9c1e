#![allow(clippy::needless_range_loop)]
//! Diagnosis of issue 5's "ours is darker than the reference" on real stream files: the error of
//! each method split by how degenerate the CRN batches of the pixel are.
//!
//! ρ_c = (CRN batch variance of the pixel mean) / (PT batch variance of the mean averaged over
//! the 7×7 neighbours, centre left out). Both streams sample the same integrand, so in
//! expectation ρ ≈ 1; ρ ≪ 1 means the pixel's 16 CRN batches happened to miss the rare bright
//! paths. Per ρ bin: pixel share, mean signed relative error `(x − r)/√(r̄² + 0.01)` (bias),
//! and the bin's contribution to relMSE.
//!
//! ```text
//! cargo run --release -p cvtrace-reconstruct --example crn_degeneracy -- REF.exr S0.streams.exr S1.streams.exr ...
//! ```
//! Extra `ours` variants: `FLOORS=0.5,1` (lift floor from the PT errors), `CROSSFIT=1`.
use cvtrace_reconstruct::*;
use std::path::Path;

const EDGES: [f64; 7] = [0.01, 0.03, 0.1, 0.3, 1.0, 3.0, f64::INFINITY];

fn variants() -> Vec<(String, Box<dyn Estimator>)> {
    let mut v: Vec<(String, Box<dyn Estimator>)> = vec![];
    for name in ["pt", "crn", "iduw", "ours"] {
        v.push((name.to_string(), Box::new(build(name, &Overrides::default()).unwrap())));
    }
    for (name, f) in extra_variants() {
        let mut o = ImperfectCvOptions::default();
        f(&mut o);
        v.push((name, Box::new(estimators::ImperfectCv::new(o).unwrap())));
    }
    v
}

type Tweak = Box<dyn Fn(&mut ImperfectCvOptions)>;

fn extra_variants() -> Vec<(String, Tweak)> {
    let mut v: Vec<(String, Tweak)> = vec![];
    if let Ok(spec) = std::env::var("FLOORS") {
        for t in spec.split(',').filter(|s| !s.is_empty()) {
            let tau: f64 = t.parse().unwrap();
            v.push((format!("ours common floor {t}"), Box::new(move |o: &mut ImperfectCvOptions| o.crn_floor = tau)));
            v.push((
                format!("ours independent floor {t}"),
                Box::new(move |o: &mut ImperfectCvOptions| {
                    o.crn_floor = tau;
                    o.crn_floor_mode = FloorMode::Independent;
                }),
            ));
        }
    }
    if std::env::var("CROSSFIT").is_ok() {
        v.push(("ours cross-fit".into(), Box::new(|o: &mut ImperfectCvOptions| o.folds = Folds::Halves)));
        v.push((
            "ours cross-fit common floor 1".into(),
            Box::new(|o: &mut ImperfectCvOptions| {
                o.folds = Folds::Halves;
                o.crn_floor = 1.0;
            }),
        ));
    }
    v
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let reference = cvtrace_streams::exr_io::read_rgb(Path::new(&args[0])).unwrap();
    let weights: Vec<f64> =
        reference.pixels.iter().map(|p| 1.0 / ((p.iter().map(|v| *v as f64).sum::<f64>() / 3.0).powi(2) + 0.01)).collect();
    let est = variants();
    let nb = EDGES.len();
    // [method][bin] → (count of pixel-channels, Σ signed error, Σ squared error, Σx, Σr)
    let mut acc = vec![vec![(0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64); nb]; est.len()];
    let mut corr = vec![(0.0f64, 0.0f64, 0.0f64); est.len()];
    let mut total = 0.0f64;
    for path in &args[1..] {
        let set = StreamSet::read(Path::new(path)).unwrap();
        let (w, h) = (set.width, set.height);
        let vc = variance_of_mean(&set.crn);
        let vp = variance_of_mean(&set.pt);
        let lum = |v: &[f32; 3]| (v[0] as f64 + v[1] as f64 + v[2] as f64) / 3.0;
        let mut bin = vec![0usize; w * h];
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut n) = (0.0, 0.0);
                for yy in y.saturating_sub(3)..(y + 4).min(h) {
                    for xx in x.saturating_sub(3)..(x + 4).min(w) {
                        if (xx, yy) != (x, y) {
                            s += lum(&vp[yy * w + xx]);
                            n += 1.0;
                        }
                    }
                }
                let c = y * w + x;
                let rho = lum(&vc[c]) / (s / n).max(1e-20);
                bin[c] = EDGES.iter().position(|e| rho < *e).unwrap();
            }
        }
        let input = Input::new(&set);
        let crn = &set.crn.mean.pixels;
        for (m, (_, e)) in est.iter().enumerate() {
            let out = e.reconstruct(&input).unwrap();
            for c in 0..w * h {
                let wt = weights[c].sqrt();
                for ch in 0..3 {
                    let (x, r) = (out.image.pixels[c][ch] as f64, reference.pixels[c][ch] as f64);
                    let err = (x - r) * wt;
                    let a = &mut acc[m][bin[c]];
                    a.0 += 1.0;
                    a.1 += err;
                    a.2 += err * err;
                    a.3 += x;
                    a.4 += r;
                    let ecrn = (crn[c][ch] as f64 - r) * wt;
                    corr[m].0 += err * ecrn;
                    corr[m].1 += err * err;
                    corr[m].2 += ecrn * ecrn;
                }
            }
        }
        total += (3 * w * h) as f64;
    }
    println!(
        "{} seeds; ρ = CRN var / neighbours' PT var; per bin: share | mean signed rel. error | relMSE contribution | Σx/Σr",
        args.len() - 1
    );
    print!("| method |");
    let mut lo = 0.0;
    for e in EDGES {
        print!(" ρ {lo}–{e} |");
        lo = e;
    }
    println!(" all | corr(err, CRN err) |");
    print!("|---|");
    for _ in 0..=nb + 1 {
        print!("---|");
    }
    println!();
    print!("| share |");
    for b in 0..nb {
        print!(" {:.3} |", acc[0][b].0 / total);
    }
    println!(" 1 | |");
    for (m, (name, _)) in est.iter().enumerate() {
        print!("| {name} |");
        let mut all = (0.0, 0.0, 0.0, 0.0);
        for b in 0..nb {
            let a = acc[m][b];
            print!(" {:+.3} / {:.4} / {:.2} |", a.1 / a.0.max(1.0), a.2 / total, a.3 / a.4.max(1e-20));
            all.0 += a.1;
            all.1 += a.2;
            all.2 += a.3;
            all.3 += a.4;
        }
        let c = corr[m];
        println!(" {:+.3} / {:.4} / {:.3} | {:.3} |", all.0 / total, all.1 / total, all.2 / all.3, c.0 / (c.1 * c.2).sqrt());
    }
}

//! The measurements behind the defaults in docs/estimators.md.
//!
//! Renders the synthetic soft-shadow scene (`cvtrace_reconstruct::synthetic`) over several
//! seeds, reconstructs it with every method and option variant, and prints Markdown tables of
//! relMSE (mean over seeds ± standard error, and the ratio to PT at 2n, i.e. the same total
//! sample count spent on independent samples).
//!
//! ```text
//! cargo run --release -p cvtrace-reconstruct --example ablation            # full (a few minutes)
//! cargo run --release -p cvtrace-reconstruct --example ablation -- --quick # 3 seeds, 1 spp level
//! ```
use cvtrace_eval::{Reference, SeedAccumulator};
use cvtrace_reconstruct::estimators::{ClassicCv, Iduw, ImperfectCv};
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::*;
use cvtrace_streams::Image;
use std::collections::BTreeMap;

type Make = Box<dyn Fn() -> Box<dyn Estimator>>;

/// The options the tables in docs/estimators.md were measured with: the defaults of that time,
/// before the real scenes added the CRN floor and kept the centre of the PT error filter.
fn table_options() -> Overrides {
    Overrides::parse(["ours.crn_floor=0", "ours.cbf_exclude_centre=true"]).unwrap()
}

fn table_ours_options() -> ImperfectCvOptions {
    let registry = Registry::builtin();
    ImperfectCvOptions::from_params(&registry.params(registry.get("ours").unwrap(), &table_options()).unwrap())
}

struct Variant {
    table: &'static str,
    label: String,
    batches: usize,
    make: Make,
}

fn ours(f: impl Fn(&mut ImperfectCvOptions) + 'static) -> Make {
    Box::new(move || {
        let mut o = table_ours_options();
        f(&mut o);
        Box::new(ImperfectCv::new(o).unwrap())
    })
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let size = 128;
    let seeds: u64 = if quick { 3 } else { 8 };
    let spps: &[u32] = if quick { &[32] } else { &[32, 128] };
    let scene = SoftShadowScene::default();
    let reference = scene.reference(size, size);

    let mut v: Vec<Variant> = vec![];
    let mut add = |table: &'static str, label: String, batches: usize, make: Make| v.push(Variant { table, label, batches, make });
    for spec in estimators::BUILTIN {
        let name = spec.name;
        add("methods", name.to_string(), 16, Box::new(move || Box::new(build(name, &table_options()).unwrap())));
    }
    for b in [4usize, 8, 16, 32] {
        add("batches", format!("ours, B = {b}"), b, ours(|_| {}));
        add("batches", format!("ours, variance errors, B = {b}"), b, ours(|o| o.errors = ErrorEstimate::Variance));
    }
    for e in ErrorEstimate::ALL {
        for p in Penalty::ALL {
            let (e, p) = (*e, *p);
            add(
                "errors",
                format!("{e} / {p}"),
                16,
                ours(move |o| {
                    o.errors = e;
                    o.penalty = p;
                }),
            );
        }
    }
    for s in Selection::ALL {
        let s = *s;
        add("selection", format!("{s}"), 16, ours(move |o| o.select = s));
    }
    for k in [9usize, 16, 25, 36] {
        add("k", format!("knn, k = {k}"), 16, ours(move |o| o.k = k));
        add(
            "k",
            format!("window, k = {k}"),
            16,
            ours(move |o| {
                o.k = k;
                o.select = Selection::Window;
            }),
        );
    }
    for sw in [7usize, 11, 15] {
        add("search", format!("knn, search window {sw}"), 16, ours(move |o| o.search_window = sw));
    }
    add("coefficients", "per channel".into(), 16, ours(|_| {}));
    add("coefficients", "shared".into(), 16, ours(|o| o.shared_coefficients = true));
    for r in [1e-5, 1e-3, 1e-2, 1e-1] {
        add("ridge", format!("ours, ridge {r}"), 16, ours(move |o| o.ridge = r));
    }
    for r in [1e-2, 1e-1, 0.3, 1.0, 3.0] {
        add(
            "ridge",
            format!("cv, ridge {r}"),
            16,
            Box::new(move || Box::new(ClassicCv::new(ClassicCvOptions { ridge: r, ..Default::default() }).unwrap())),
        );
    }
    for radius in [2usize, 3, 5, 8] {
        add("cbf", format!("radius {radius}"), 16, ours(move |o| o.cbf.radius = radius));
    }
    for sc in [0.1f32, 0.25, 0.5, 1.0] {
        add("cbf", format!("σ_colour {sc}"), 16, ours(move |o| o.cbf.sigma_colour = sc));
    }
    add("cbf", "centre included".into(), 16, ours(|o| o.cbf.exclude_centre = false));
    for w in [7usize, 11, 15, 21] {
        add(
            "iduw",
            format!("window {w}"),
            16,
            Box::new(move || Box::new(Iduw::new(IduwOptions { window: w, ..Default::default() }).unwrap())),
        );
    }
    add(
        "iduw",
        "window 15, grid extended to γ = 100".into(),
        16,
        Box::new(|| {
            let mut gammas = GAMMA_GRID.to_vec();
            gammas.extend([5.0, 10.0, 25.0, 50.0, 100.0]);
            Box::new(Iduw::new(IduwOptions { gammas, ..Default::default() }).unwrap())
        }),
    );

    for &spp in spps {
        // results[variant] = relMSE per seed; outputs kept for the bias/variance split.
        let mut results: Vec<Vec<f64>> = vec![vec![]; v.len()];
        let mut pt2n = vec![];
        let mut bv_outputs: BTreeMap<String, Vec<Image>> = BTreeMap::new();
        let mut gammas: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        let mut scaled: BTreeMap<(String, u32), Vec<f64>> = BTreeMap::new();
        for seed in 0..seeds {
            let mut sets = BTreeMap::new();
            for var in &v {
                sets.entry(var.batches).or_insert_with(|| {
                    scene.render(&RenderSpec { width: size, height: size, spp, batches: var.batches, seed: 7000 + seed }).unwrap()
                });
            }
            // Radiance scale: relMSE is (nearly) scale-free, so only a scale-dependent method moves.
            for scale in [0.1f32, 1.0, 10.0] {
                let mut set = sets[&16].clone();
                for im in std::iter::once(&mut set.pt.mean)
                    .chain(set.pt.batches.iter_mut())
                    .chain(std::iter::once(&mut set.crn.mean))
                    .chain(set.crn.batches.iter_mut())
                {
                    im.pixels.iter_mut().for_each(|p| p.iter_mut().for_each(|v| *v *= scale));
                }
                let mut r = reference.clone();
                r.pixels.iter_mut().for_each(|p| p.iter_mut().for_each(|v| *v *= scale));
                for m in ["iduw", "ours"] {
                    let out = build(m, &table_options()).unwrap().run(&Input::new(&set)).unwrap();
                    scaled
                        .entry((m.to_string(), (scale * 10.0) as u32))
                        .or_default()
                        .push(rel_mse(&out.image, &r) / rel_mse(&set.pt.mean, &r));
                }
            }
            let spec16 = RenderSpec { width: size, height: size, spp, batches: 16, seed: 7000 + seed };
            let second = scene.render_pt(&spec16, 1).unwrap();
            pt2n.push(rel_mse(&Image::mean_of(&[sets[&16].pt.mean.clone(), second.mean]), &reference));
            for (vi, var) in v.iter().enumerate() {
                let set = &sets[&var.batches];
                let out = (var.make)().reconstruct(&Input::new(set).with_reference(&reference)).unwrap();
                results[vi].push(rel_mse(&out.image, &reference));
                if let Some(g) = out.diagnostics.get("gamma").and_then(DiagValue::as_f64) {
                    gammas.entry(var.label.clone()).or_default().push(g);
                }
                if var.table == "selection" {
                    bv_outputs.entry(var.label.clone()).or_default().push(out.image);
                }
            }
        }
        let (m2n, _) = mean_se(&pt2n);
        println!("\n## {size}×{size}, {spp} spp per stream, {seeds} seeds\n");
        println!("PT at 2n ({} spp): relMSE {m2n:.3e}\n", 2 * spp);
        let mut current = "";
        for (vi, var) in v.iter().enumerate() {
            if var.table != current {
                current = var.table;
                println!("\n### {current}\n\n| variant | relMSE | ± se | / PT@2n |\n|---|---|---|---|");
            }
            let (m, se) = mean_se(&results[vi]);
            println!("| {} | {m:.3e} | {se:.1e} | {:.3} |", var.label, m / m2n);
        }
        println!("\n### γ chosen by IDUW (mean over seeds)\n\n| variant | γ |\n|---|---|");
        for (label, g) in &gammas {
            println!("| {label} | {:.3} |", g.iter().sum::<f64>() / g.len() as f64);
        }
        println!("\n### radiance scale (relMSE relative to PT alone at the same scale)\n\n| method | ×0.1 | ×1 | ×10 |\n|---|---|---|---|");
        for m in ["iduw", "ours"] {
            let cell = |s: u32| mean_se(&scaled[&(m.to_string(), s)]).0;
            println!("| {m} | {:.3} | {:.3} | {:.3} |", cell(1), cell(10), cell(100));
        }
        println!(
            "\n### bias / variance of the selections (relative, over seeds)\n\n| selection | squared bias | variance |\n|---|---|---|"
        );
        for (label, outs) in &bv_outputs {
            let reference = Reference::new(reference.clone(), "synthetic truth").unwrap();
            let mut acc = SeedAccumulator::new(&reference, label.to_string());
            for o in outs {
                acc.add(o).unwrap();
            }
            let stats = acc.finish().unwrap();
            let (b, var) = (stats.bias2.unwrap_or(f64::NAN), stats.variance.unwrap_or(f64::NAN));
            println!("| {label} | {b:.3e} | {var:.3e} |");
        }
    }
}

fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (m, (var / n).sqrt())
}

/// relMSE as the evaluation layer defines it (one definition for the whole project).
fn rel_mse(x: &Image, reference: &Image) -> f64 {
    cvtrace_eval::metrics::rel_mse(x, reference).expect("images of one size")
}

//! Renders a scene with the brute-force test intersector and writes PNG previews of the PT and
//! CRN means and the albedo feature: a quick visual check without Embree.
//!
//!     cargo run --release -p cvtrace-render --example preview -- <scene.gltf|cornell|materials> <out-dir> [spp] [max_depth] [size]
use cvtrace_render::testing::{cornell_box, materials_box, BruteForce};
use cvtrace_render::{render_streams, RenderSettings, Scene};
use cvtrace_streams::preview::write_png;
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = match args.get(1).map(String::as_str) {
        Some("cornell") | None => cornell_box(),
        Some("materials") => materials_box(),
        Some(p) => Scene::load(Path::new(p)).unwrap_or_else(|e| panic!("{e}")),
    };
    let out = Path::new(args.get(2).map(String::as_str).unwrap_or("."));
    let spp: u32 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(16);
    let max_depth: i32 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(-1);
    let size: u32 = args.get(5).map(|s| s.parse().unwrap()).unwrap_or(256);
    let tracer = BruteForce::new(&scene);
    let settings = RenderSettings { width: size, height: size, spp, batches: 1, seed: 1, max_depth, rr_depth: 5 };
    let set = render_streams(&scene, &tracer, &settings, &|_| {}).unwrap();
    write_png(&out.join("pt.png"), &set.pt.mean, 0.0, true).unwrap();
    write_png(&out.join("crn.png"), &set.crn.mean, 0.0, true).unwrap();
    write_png(&out.join("albedo.png"), &set.features.as_ref().unwrap().albedo, 0.0, true).unwrap();
    let mean: f64 = set.pt.mean.pixels.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / set.pt.mean.len() as f64;
    println!("mean PT radiance {mean:.4}, non-finite samples {}", set.meta.non_finite_samples);
}

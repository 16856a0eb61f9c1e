//! One render of the bundled Cornell box on one thread, with the wavefront's rays traced as
//! Embree packets or one at a time, for timing the two as whole processes, in turn:
//!
//!     cargo run --release -p cvtrace-embree --example packets -- packets|single [spp] [side] [robust]
//!
//! Prints the samples per second of the render alone (the scene load and BVH build excluded).
use cvtrace_embree::{set_flush_denormals, BuildOptions, Device};
use cvtrace_render::{render_streams, RenderSettings, Scene};
use std::path::Path;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let packets = match args.get(1).map(String::as_str) {
        Some("packets") => true,
        Some("single") => false,
        _ => panic!("usage: packets packets|single [spp] [side] [robust]"),
    };
    let spp: u32 = args.get(2).map_or(16, |s| s.parse().expect("spp"));
    let side: u32 = args.get(3).map_or(256, |s| s.parse().expect("side"));
    let robust = args.get(4).is_some_and(|s| s == "robust");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = Scene::load(&path).expect("the bundled Cornell box loads");
    let options = BuildOptions { robust, packets, ..BuildOptions::default() };
    let tracer = Device::new().and_then(|d| d.build_scene(scene.positions(), scene.triangles(), &options)).expect("Embree builds it");
    let settings = RenderSettings { width: side, height: side, spp, batches: 1, seed: 1, max_depth: 8, rr_depth: 5 };
    // One worker with FTZ/DAZ, as the CLI sets up its workers.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).start_handler(|_| set_flush_denormals()).build().expect("thread pool");
    let t0 = Instant::now();
    let set = pool.install(|| render_streams(&scene, &tracer, &settings, &|_| {})).expect("renders");
    let secs = t0.elapsed().as_secs_f64();
    // Both streams, PT and CRN.
    let samples = f64::from(side * side * spp) * 2.0;
    let mean: f64 = set.pt.mean.pixels.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>() / set.pt.mean.pixels.len() as f64;
    println!("{}: {:.3} M samples/s ({secs:.3} s), mean {mean:.6}", if packets { "packets" } else { "single" }, samples / secs / 1e6);
}

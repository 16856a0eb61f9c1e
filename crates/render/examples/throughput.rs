//! Measures render throughput with the brute-force test intersector and splits the time into
//! ray casting and everything else, to estimate throughput with a fast (Embree) intersector.
//!
//!     cargo run --release -p cvtrace-render --example throughput -- [scene.gltf] [spp] [max_depth]
use cvtrace_render::intersect::{Hit, Intersector, Ray};
use cvtrace_render::testing::{cornell_box, BruteForce};
use cvtrace_render::{render_streams, RenderSettings, Scene};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Counts rays (only used in a separate, untimed run).
struct Counting<'a>(&'a BruteForce, AtomicU64, AtomicU64);
impl Intersector for Counting<'_> {
    fn intersect(&self, r: &Ray) -> Option<Hit> {
        self.1.fetch_add(1, Ordering::Relaxed);
        self.0.intersect(r)
    }
    fn occluded(&self, r: &Ray) -> bool {
        self.2.fetch_add(1, Ordering::Relaxed);
        self.0.occluded(r)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = match args.get(1) {
        Some(p) if p != "-" => Scene::load(std::path::Path::new(p)).expect("scene loads"),
        _ => cornell_box(),
    };
    let spp: u32 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(8);
    let max_depth: i32 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(8);
    let tracer = BruteForce::new(&scene);
    let settings = RenderSettings { width: 256, height: 256, spp, batches: 1, seed: 7, max_depth, rr_depth: 5 };
    let samples = 256.0 * 256.0 * spp as f64 * 2.0;

    // CVTRACE_NO_COUNT=1 skips the counting run (for profiling the timed run alone).
    let (ni, no) = if std::env::var_os("CVTRACE_NO_COUNT").is_some() {
        (0, 0)
    } else {
        let counting = Counting(&tracer, AtomicU64::new(0), AtomicU64::new(0));
        render_streams(&scene, &counting, &settings, &|_| {}).unwrap();
        (counting.1.load(Ordering::Relaxed), counting.2.load(Ordering::Relaxed))
    };

    let threads = rayon::current_num_threads() as f64;
    let t0 = Instant::now();
    render_streams(&scene, &tracer, &settings, &|_| {}).unwrap();
    let wall = t0.elapsed().as_secs_f64();

    // Cost of the same number of brute-force rays alone (primary-like rays, single thread).
    let cam = scene.camera().frame(256, 256);
    let n_probe = 200_000u32;
    let t1 = Instant::now();
    let mut hits = 0u32;
    for i in 0..n_probe {
        let r = cam.ray(i % 256, (i / 256) % 256, glam::Vec2::splat(0.5));
        hits += tracer.intersect(&r).is_some() as u32;
        hits += tracer.occluded(&Ray { tmax: 1.0, ..r }) as u32;
    }
    let per_pair = t1.elapsed().as_secs_f64() / n_probe as f64;
    std::hint::black_box(hits);
    let cpu = wall * threads;
    let cast = (ni.max(no)) as f64 * per_pair;
    println!(
        "scene: {} triangles, {} lights; 256x256, {spp} spp per stream, max_depth {max_depth}",
        scene.triangles().len(),
        scene.lights().len()
    );
    println!("rays: {ni} intersect + {no} occluded = {:.2} per sample", (ni + no) as f64 / samples);
    println!("wall {wall:.3} s on {threads} threads → {:.3} M samples per CPU-second (brute force)", samples / cpu / 1e6);
    println!("approx. brute-force ray time {cast:.3} CPU-s of {cpu:.3}; the rest ({:.3} CPU-s) is the integrator", cpu - cast);
    println!("→ integrator alone: {:.2} M samples per CPU-second", samples / (cpu - cast).max(1e-9) / 1e6);
}

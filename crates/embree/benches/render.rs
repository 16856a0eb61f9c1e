//! Render throughput on the shipped Cornell box (256×256, max depth 8) and bare Embree ray
//! rates against its BVH. Run with `cargo bench -p cvtrace-embree --bench render`.
//!
//! Target: ≥ 1.5 M path samples per CPU-second (so ≥ 3 M/s wall on 2 cores).
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use cvtrace_embree::{set_flush_denormals, BuildOptions, BuildQuality, Device, EmbreeScene};
use cvtrace_render::{render_reference_pass, render_streams, Intersector, Ray, RenderSettings, Scene};
use cvtrace_streams::reference::ReferenceAccum;
use glam::{Vec2, Vec3A};
use std::hint::black_box;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

const SIDE: u32 = 256;
const SPP: u32 = 4;

fn cornell() -> (Scene, EmbreeScene) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = Scene::load(&path).expect("the shipped Cornell box loads");
    let robust = BuildOptions { robust: true, ..BuildOptions::default() };
    let tracer = Device::new().and_then(|d| d.build_scene(scene.positions(), scene.triangles(), &robust)).expect("Embree builds it");
    (scene, tracer)
}

/// The render pool as the CLI sets it up: `threads` workers (0: all cores), FTZ/DAZ in each.
fn render_pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).start_handler(|_| set_flush_denormals()).build().expect("thread pool")
}

fn settings() -> RenderSettings {
    RenderSettings { width: SIDE, height: SIDE, spp: SPP, batches: 1, seed: 1, max_depth: 8, rr_depth: 5 }
}

/// Counts the rays a render casts, to put samples/s and rays/s side by side.
struct Counting<'a> {
    inner: &'a EmbreeScene,
    intersect: AtomicU64,
    occluded: AtomicU64,
}

impl Intersector for Counting<'_> {
    fn intersect(&self, ray: &Ray) -> Option<cvtrace_render::Hit> {
        self.intersect.fetch_add(1, Ordering::Relaxed);
        self.inner.intersect(ray)
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.occluded.fetch_add(1, Ordering::Relaxed);
        self.inner.occluded(ray)
    }
}

fn path_tracer(c: &mut Criterion) {
    let (scene, tracer) = cornell();
    let pool = render_pool(0);
    let s = settings();
    {
        let counting = Counting { inner: &tracer, intersect: AtomicU64::new(0), occluded: AtomicU64::new(0) };
        let mut acc = ReferenceAccum::new(&s.reference());
        pool.install(|| render_reference_pass(&scene, &counting, &s, &mut acc, 0..SPP, &|_| {})).unwrap();
        let n = (SIDE * SIDE * SPP) as f64;
        eprintln!(
            "rays per PT sample at max depth {}: {:.2} nearest-hit + {:.2} shadow",
            s.max_depth,
            counting.intersect.load(Ordering::Relaxed) as f64 / n,
            counting.occluded.load(Ordering::Relaxed) as f64 / n
        );
    }
    let pixels = SIDE as u64 * SIDE as u64;
    let mut g = c.benchmark_group("path_tracer");
    g.sample_size(10).measurement_time(Duration::from_secs(8)).warm_up_time(Duration::from_secs(1));

    // PT only: the progressive reference pass, samples of one stream.
    g.throughput(Throughput::Elements(pixels * SPP as u64));
    g.bench_function("cornell_256_depth8_pt_4spp", |b| {
        b.iter_batched_ref(
            || ReferenceAccum::new(&s.reference()),
            |acc| pool.install(|| render_reference_pass(&scene, &tracer, &s, acc, 0..SPP, &|_| {})).unwrap(),
            BatchSize::LargeInput,
        )
    });

    // The same on one thread: its rate is samples per CPU-second, the unit of issue 2's target
    // (the calling thread only waits).
    let one_thread = render_pool(1);
    g.bench_function("cornell_256_depth8_pt_4spp_1thread", |b| {
        b.iter_batched_ref(
            || ReferenceAccum::new(&s.reference()),
            |acc| one_thread.install(|| render_reference_pass(&scene, &tracer, &s, acc, 0..SPP, &|_| {})).unwrap(),
            BatchSize::LargeInput,
        )
    });

    // The same with `--traversal fast` (Embree's non-robust triangle test).
    let fast = Device::new()
        .unwrap()
        .build_scene(scene.positions(), scene.triangles(), &BuildOptions { robust: false, ..BuildOptions::default() })
        .unwrap();
    g.bench_function("cornell_256_depth8_pt_4spp_fast_traversal", |b| {
        b.iter_batched_ref(
            || ReferenceAccum::new(&s.reference()),
            |acc| pool.install(|| render_reference_pass(&scene, &fast, &s, acc, 0..SPP, &|_| {})).unwrap(),
            BatchSize::LargeInput,
        )
    });
    g.bench_function("cornell_256_depth8_pt_4spp_fast_traversal_1thread", |b| {
        b.iter_batched_ref(
            || ReferenceAccum::new(&s.reference()),
            |acc| one_thread.install(|| render_reference_pass(&scene, &fast, &s, acc, 0..SPP, &|_| {})).unwrap(),
            BatchSize::LargeInput,
        )
    });

    // The same with plain triangles instead of triangle pairs as Embree quads.
    let triangles = device_triangles(&scene);
    g.bench_function("cornell_256_depth8_pt_4spp_triangles", |b| {
        b.iter_batched_ref(
            || ReferenceAccum::new(&s.reference()),
            |acc| pool.install(|| render_reference_pass(&scene, &triangles, &s, acc, 0..SPP, &|_| {})).unwrap(),
            BatchSize::LargeInput,
        )
    });

    // Paired PT + CRN streams with first-hit features: what `cvtrace render` does.
    g.throughput(Throughput::Elements(pixels * SPP as u64 * 2));
    g.bench_function("cornell_256_depth8_streams_2x4spp", |b| {
        b.iter(|| black_box(pool.install(|| render_streams(&scene, &tracer, &s, &|_| {})).unwrap()))
    });
    g.finish();
}

/// SplitMix64 for reproducible random rays.
fn splitmix(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

fn embree_rays(c: &mut Criterion) {
    set_flush_denormals();
    let (scene, tracer) = cornell();
    let frame = scene.camera().frame(SIDE, SIDE);
    let coherent: Vec<Ray> = (0..SIDE * SIDE).map(|i| frame.ray(i % SIDE, i / SIDE, Vec2::splat(0.5))).collect();
    // Incoherent: random points inside the box towards random directions (like bounce rays).
    let (lo, hi) = scene.bounds();
    let mut st = 42u64;
    let incoherent: Vec<Ray> = (0..SIDE * SIDE)
        .map(|_| {
            let origin = lo + (hi - lo) * Vec3A::new(splitmix(&mut st), splitmix(&mut st), splitmix(&mut st)) * 0.98 + (hi - lo) * 0.01;
            let z = 2.0 * splitmix(&mut st) - 1.0;
            let phi = std::f32::consts::TAU * splitmix(&mut st);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray { origin, dir: Vec3A::new(r * phi.cos(), r * phi.sin(), z), tmin: 0.0, tmax: f32::INFINITY }
        })
        .collect();

    let mut g = c.benchmark_group("embree_single_thread");
    g.sample_size(20).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_millis(500));
    g.throughput(Throughput::Elements(coherent.len() as u64));
    g.bench_function("intersect_primary_coherent", |b| b.iter(|| coherent.iter().filter(|r| tracer.intersect(r).is_some()).count()));
    // The renderer's camera-ray batches: 16 jittered samples per pixel, 64 rays per call.
    let mut st = 7u64;
    let jittered: Vec<Ray> = (0..SIDE * SIDE)
        .map(|i| {
            let p = i / 16;
            frame.ray(p % SIDE, p / SIDE, Vec2::new(splitmix(&mut st), splitmix(&mut st)))
        })
        .collect();
    let mut hits = vec![None; 64];
    g.bench_function("intersect_camera_16spp_one_by_one", |b| b.iter(|| jittered.iter().filter(|r| tracer.intersect(r).is_some()).count()));
    g.bench_function("intersect_camera_16spp_batches_of_64", |b| b.iter(|| hits_in_batches(&tracer, &jittered, &mut hits)));
    g.bench_function("intersect_random_incoherent", |b| b.iter(|| incoherent.iter().filter(|r| tracer.intersect(r).is_some()).count()));
    g.bench_function("occluded_random_incoherent", |b| b.iter(|| incoherent.iter().filter(|r| tracer.occluded(r)).count()));
    let triangles = device_triangles(&scene);
    g.bench_function("occluded_random_incoherent_triangles", |b| b.iter(|| incoherent.iter().filter(|r| triangles.occluded(r)).count()));
    // What the build options cost on incoherent rays (default: high quality, robust, quads).
    let device = Device::new().unwrap();
    for (name, quality, robust, quads) in [
        ("triangles", BuildQuality::High, true, false),
        ("high_fast", BuildQuality::High, false, true),
        ("triangles_high_fast", BuildQuality::High, false, false),
        ("medium_fast", BuildQuality::Medium, false, true),
    ] {
        let t = device
            .build_scene(scene.positions(), scene.triangles(), &BuildOptions { quality, robust, compact: false, quads, packets: true })
            .unwrap();
        g.bench_function(format!("intersect_random_incoherent_{name}"), |b| {
            b.iter(|| incoherent.iter().filter(|r| t.intersect(r).is_some()).count())
        });
        if name == "high_fast" {
            // The rest of what a `--traversal fast` (the default) render traces, for its ceiling.
            g.bench_function("occluded_random_incoherent_high_fast", |b| b.iter(|| incoherent.iter().filter(|r| t.occluded(r)).count()));
            g.bench_function("intersect_camera_16spp_batches_of_64_high_fast", |b| b.iter(|| hits_in_batches(&t, &jittered, &mut hits)));
        }
    }
    g.finish();
}

/// Hits of `rays` traced in coherent batches of `hits.len()`, as the renderer traces camera rays.
fn hits_in_batches(tracer: &EmbreeScene, rays: &[Ray], hits: &mut [Option<cvtrace_render::Hit>]) -> usize {
    rays.chunks(hits.len())
        .map(|c| {
            tracer.intersect_coherent(c, &mut hits[..c.len()]);
            hits[..c.len()].iter().filter(|h| h.is_some()).count()
        })
        .sum()
}

/// The Cornell box as plain Embree triangles (robust), to compare with the default quads.
fn device_triangles(scene: &Scene) -> EmbreeScene {
    Device::new()
        .unwrap()
        .build_scene(scene.positions(), scene.triangles(), &BuildOptions { quads: false, ..BuildOptions::default() })
        .unwrap()
}

criterion_group!(benches, path_tracer, embree_rays);
criterion_main!(benches);

//! Throughput of the estimators on synthetic stream sets with B = 16 batches (16 spp per
//! stream), generated in memory. Criterion reports elements/s = pixels/s.
//!
//! - `reconstruct_256x256_b16_one_thread`: every registered estimator on one thread.
//! - `reconstruct_1920x1080_b16_one_thread`: `ours`, `iduw`, `cv` and `pt` on one thread at
//!   the size the one-core throughput targets are set at (docs/performance.md). One run of
//!   `ours` takes seconds there, so this group takes criterion's minimum of ten samples, flat.
//! - `pass_640x360_b16_one_thread`: the control-variate pass of `ours` and `cv` alone
//!   (time per pixel = 1 / throughput).
//!
//! `cargo bench -p cvtrace-reconstruct --bench estimators` (a few minutes on a quiet machine;
//! append `-- 256x256` to run one group).
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{Input, Overrides, Registry};
use std::time::Duration;

fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("thread pool")
}

fn streams(w: usize, h: usize) -> cvtrace_streams::StreamSet {
    SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 16, batches: 16, seed: 1 }).expect("synthetic streams")
}

fn small(c: &mut Criterion) {
    let (w, h) = (256, 256);
    let set = streams(w, h);
    let input = Input::new(&set);
    let pool = one_thread();
    let mut group = c.benchmark_group("reconstruct_256x256_b16_one_thread");
    group.throughput(Throughput::Elements((w * h) as u64));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    let registry = Registry::builtin();
    for spec in registry.specs() {
        let est = registry.build(spec.name, &Overrides::default()).expect("default options");
        group.bench_function(spec.name, |b| b.iter(|| pool.install(|| est.run(&input).expect("reconstruct"))));
    }
    group.finish();
}

fn full_hd(c: &mut Criterion) {
    let (w, h) = (1920, 1080);
    let set = streams(w, h);
    let input = Input::new(&set);
    let pool = one_thread();
    let mut group = c.benchmark_group("reconstruct_1920x1080_b16_one_thread");
    group.throughput(Throughput::Elements((w * h) as u64));
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    group.warm_up_time(Duration::from_millis(1));
    group.measurement_time(Duration::from_secs(20));
    let registry = Registry::builtin();
    for name in ["ours", "iduw", "cv", "pt"] {
        let est = registry.build(name, &Overrides::default()).expect("default options");
        group.bench_function(name, |b| b.iter(|| pool.install(|| est.run(&input).expect("reconstruct"))));
    }
    group.finish();
}

/// One thread, 640×360, B = 16: the per-pixel cost of selection, gathering and the three
/// channels' solves. `ours` with the raw batch variance as errors and no floor, so that almost
/// all of the time is the pass itself.
fn pass_one_thread(c: &mut Criterion) {
    let (w, h) = (640, 360);
    let set = streams(w, h);
    let input = Input::new(&set);
    let pool = one_thread();
    let options = Overrides::parse(["ours.errors=variance", "ours.crn_floor=0"]).expect("assignments");
    let registry = Registry::builtin();
    let mut group = c.benchmark_group("pass_640x360_b16_one_thread");
    group.throughput(Throughput::Elements((w * h) as u64));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(2));
    group.measurement_time(Duration::from_secs(10));
    for name in ["ours", "cv"] {
        let est = registry.build(name, &options).expect("options");
        group.bench_function(name, |b| b.iter(|| pool.install(|| est.run(&input).expect("reconstruct"))));
    }
    group.finish();
}

criterion_group!(benches, small, full_hd, pass_one_thread);
criterion_main!(benches);

//! Throughput of every estimator on a synthetic 1280×720 stream set with B = 16 batches
//! (16 spp per stream), generated in memory. Criterion reports elements/s = pixels/s.
//! A second group times the control-variate pass of `ours` and `cv` on one thread at 640×360
//! (time per pixel = 1 / throughput; it replaces the ignored `pass_cost` and
//! `panel_solve_cost` micro-benchmarks that used to live in the unit tests).
//!
//! `cargo bench -p cvtrace-reconstruct --bench estimators`
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{Input, Overrides, Registry};
use std::time::Duration;

fn estimators(c: &mut Criterion) {
    let (w, h) = (1280, 720);
    let set =
        SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 16, batches: 16, seed: 1 }).expect("synthetic streams");
    let input = Input::new(&set);
    let mut group = c.benchmark_group("reconstruct_1280x720_b16");
    group.throughput(Throughput::Elements((w * h) as u64));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(2));
    group.measurement_time(Duration::from_secs(15));
    let registry = Registry::builtin();
    for spec in registry.specs() {
        let est = registry.build(spec.name, &Overrides::default()).expect("default options");
        group.bench_function(spec.name, |b| b.iter(|| est.run(&input).expect("reconstruct")));
    }
    group.finish();
}

/// One thread, 640×360, B = 16: the per-pixel cost of selection, gathering and the three
/// channels' solves. `ours` with the raw batch variance as errors and no floor, so that almost
/// all of the time is the pass itself.
fn pass_one_thread(c: &mut Criterion) {
    let (w, h) = (640, 360);
    let set =
        SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 16, batches: 16, seed: 1 }).expect("synthetic streams");
    let input = Input::new(&set);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("thread pool");
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

criterion_group!(benches, estimators, pass_one_thread);
criterion_main!(benches);

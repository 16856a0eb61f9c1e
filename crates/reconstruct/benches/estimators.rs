//! Throughput of every estimator on a synthetic 1280×720 stream set with B = 16 batches
//! (16 spp per stream), generated in memory. Criterion reports elements/s = pixels/s.
//!
//! `cargo bench -p cvtrace-reconstruct --bench estimators`
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{build, Input, Method, Options};
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
    for m in Method::ALL {
        let est = build(*m, &Options::default()).expect("default options");
        group.bench_function(m.name(), |b| b.iter(|| est.reconstruct(&input).expect("reconstruct")));
    }
    group.finish();
}

criterion_group!(benches, estimators);
criterion_main!(benches);

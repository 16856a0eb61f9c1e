//! The stream render's contract: determinism across thread counts, batch/mean consistency,
//! the CRN/PT correlation structure, progressive references, and non-finite handling.
use cvtrace_render::testing::{cornell_box, furnace_box, BruteForce};
use cvtrace_render::{render_reference_pass, render_streams, RenderSettings};
use cvtrace_streams::reference::ReferenceAccum;
use cvtrace_streams::{Image, StreamSet};
use std::sync::atomic::{AtomicU64, Ordering};

fn settings(width: u32, height: u32, spp: u32, batches: u32) -> RenderSettings {
    RenderSettings { width, height, spp, batches, seed: 99, max_depth: -1, rr_depth: 5 }
}

fn render_with_threads(threads: usize, s: &RenderSettings) -> StreamSet {
    let scene = cornell_box();
    let tracer = BruteForce::new(&scene);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| render_streams(&scene, &tracer, s, &|_| {}).unwrap())
}

#[test]
fn one_and_two_threads_give_bit_identical_streams() {
    // 37x21 leaves partial tiles on both edges.
    let s = settings(37, 21, 8, 4);
    let a = render_with_threads(1, &s);
    let b = render_with_threads(2, &s);
    assert!(a == b, "stream sets differ between 1 and 2 threads");
    // ...and the render is not trivially black.
    assert!(a.pt.mean.pixels.iter().filter(|p| p[0] > 0.0).count() > 37 * 21 / 2);
    // A different seed changes the noise.
    let c = render_with_threads(2, &RenderSettings { seed: 100, ..s });
    assert!(a.pt.mean != c.pt.mean && a.crn.mean != c.crn.mean);
}

#[test]
fn batches_average_to_the_stream_mean_and_meta_is_filled() {
    let s = settings(20, 20, 12, 3);
    let done = AtomicU64::new(0);
    let scene = cornell_box();
    let tracer = BruteForce::new(&scene);
    let set = render_streams(&scene, &tracer, &s, &|k| {
        done.fetch_add(k, Ordering::Relaxed);
    })
    .unwrap();
    assert_eq!(done.load(Ordering::Relaxed), 20 * 20 * 12 * 2, "progress must count every pixel-sample of both streams");
    assert_eq!(set.batch_count(), 3);
    set.validate(std::path::Path::new("mem")).unwrap();
    for stream in [&set.pt, &set.crn] {
        let avg = Image::mean_of(&stream.batches);
        for (a, m) in avg.pixels.iter().zip(&stream.mean.pixels) {
            for c in 0..3 {
                assert!((a[c] - m[c]).abs() <= 1e-5 * (1.0 + m[c].abs()), "batch average {a:?} vs mean {m:?}");
            }
        }
    }
    assert_eq!((set.meta.spp, set.meta.seed, set.meta.max_depth), (12, 99, -1));
    assert_eq!(set.meta.version, env!("CARGO_PKG_VERSION"));
    assert!(set.pt.mean != set.crn.mean, "PT and CRN must use different random numbers");
}

/// Pooled correlation between horizontally neighbouring pixels across batches, each pixel
/// centred on its own batch average (so only the sample noise is compared).
fn neighbour_correlation(batches: &[Image], pairs: &[(usize, usize)]) -> (f64, usize) {
    let b = batches.len() as f64;
    let lum = |p: [f32; 3]| (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) as f64;
    let (mut sxy, mut sxx, mut syy, mut n) = (0.0, 0.0, 0.0, 0);
    for &(i, j) in pairs {
        let xs: Vec<f64> = batches.iter().map(|im| lum(im.pixels[i])).collect();
        let ys: Vec<f64> = batches.iter().map(|im| lum(im.pixels[j])).collect();
        let (mx, my) = (xs.iter().sum::<f64>() / b, ys.iter().sum::<f64>() / b);
        for (x, y) in xs.iter().zip(&ys) {
            sxy += (x - mx) * (y - my);
            sxx += (x - mx) * (x - mx);
            syy += (y - my) * (y - my);
            n += 1;
        }
    }
    (sxy / (sxx * syy).sqrt(), n)
}

#[test]
fn crn_neighbours_are_correlated_and_pt_neighbours_are_not() {
    // At 64x64 neighbouring back-wall pixels are ~0.05 (2.5% of the room) apart.
    let (w, h) = (64u32, 64u32);
    let scene = cornell_box();
    let tracer = BruteForce::new(&scene);
    let set = render_streams(&scene, &tracer, &settings(w, h, 32, 16), &|_| {}).unwrap();
    let f = set.features.as_ref().unwrap();
    // Flat region: both pixels see the back wall (normal +z) at nearly the same depth.
    let flat = |i: usize| f.normal.pixels[i][2] > 0.999 && (f.depth[i] - 4.9).abs() < 0.2;
    let mut pairs = Vec::new();
    for y in 0..h as usize {
        for x in 0..w as usize - 1 {
            let (i, j) = (y * w as usize + x, y * w as usize + x + 1);
            if flat(i) && flat(j) {
                pairs.push((i, j));
            }
        }
    }
    assert!(pairs.len() >= 40, "only {} flat pairs found", pairs.len());
    let (crn, _) = neighbour_correlation(&set.crn.batches, &pairs);
    let (pt, n) = neighbour_correlation(&set.pt.batches, &pairs);
    eprintln!("neighbour correlation over {} pairs: CRN {crn}, PT {pt} (n = {n})", pairs.len());
    assert!(crn > 0.8, "CRN neighbour correlation {crn}");
    // Pooled deviations have ~n(1 - 1/B) degrees of freedom; under independence sd ≈ 1/sqrt(n).
    assert!(pt.abs() < 5.0 / (n as f64).sqrt(), "PT neighbour correlation {pt} over {n} values");
}

#[test]
fn reference_passes_are_split_invariant_and_match_the_pt_stream() {
    let s = settings(19, 17, 8, 2);
    let scene = cornell_box();
    let tracer = BruteForce::new(&scene);
    let mut split = ReferenceAccum::new(&s.reference());
    render_reference_pass(&scene, &tracer, &s, &mut split, 0..3, &|_| {}).unwrap();
    render_reference_pass(&scene, &tracer, &s, &mut split, 3..8, &|_| {}).unwrap();
    let mut whole = ReferenceAccum::new(&s.reference());
    render_reference_pass(&scene, &tracer, &s, &mut whole, 0..8, &|_| {}).unwrap();
    assert_eq!(split, whole);
    assert_eq!(split.samples_done, 8);
    let streams = render_streams(&scene, &tracer, &s, &|_| {}).unwrap();
    assert!(whole.mean() == streams.pt.mean, "reference at 8 spp must equal the 8 spp PT stream mean");
    // A pass that does not continue where the last one stopped is refused.
    let e = render_reference_pass(&scene, &tracer, &s, &mut whole, 4..9, &|_| {}).unwrap_err().to_string();
    assert!(e.contains("starts at sample 4"), "{e}");
    let other_seed = RenderSettings { seed: 5, ..s.clone() };
    assert!(render_reference_pass(&scene, &tracer, &other_seed, &mut whole, 8..9, &|_| {}).is_err());
}

#[test]
fn non_finite_samples_are_zeroed_and_counted() {
    // Emission is bounded (a scene may not emit beyond what the exact sums hold, 2^47), but an
    // albedo of 1e30 overflows the light a second segment brings to infinity.
    let scene = furnace_box(2f32.powi(46), 1e30);
    let tracer = BruteForce::new(&scene);
    let s = RenderSettings { max_depth: 3, ..settings(4, 4, 4, 2) };
    let set = render_streams(&scene, &tracer, &s, &|_| {}).unwrap();
    assert_eq!(set.meta.non_finite_samples, 4 * 4 * 4 * 2);
    assert!(set.pt.mean.pixels.iter().chain(&set.crn.mean.pixels).all(|p| *p == [0.0; 3]));
    set.validate(std::path::Path::new("mem")).unwrap();
    // With one segment the same scene is finite: nothing is counted.
    let one = render_streams(&scene, &tracer, &RenderSettings { max_depth: 1, ..s }, &|_| {}).unwrap();
    assert_eq!(one.meta.non_finite_samples, 0);
}

#[test]
fn invalid_settings_are_rejected_with_a_reason() {
    let scene = cornell_box();
    let tracer = BruteForce::new(&scene);
    for (bad, needle) in [
        (settings(8, 8, 0, 1), "spp"),
        (settings(8, 8, 8, 0), "batches"),
        (settings(8, 8, 10, 4), "multiple"),
        (settings(0, 8, 8, 1), "size"),
        (settings(20000, 8, 8, 1), "size"),
        (RenderSettings { max_depth: 0, ..settings(8, 8, 8, 1) }, "max_depth"),
        (RenderSettings { max_depth: -2, ..settings(8, 8, 8, 1) }, "max_depth"),
    ] {
        let e = render_streams(&scene, &tracer, &bad, &|_| {}).unwrap_err().to_string();
        assert!(e.contains(needle), "{bad:?}: {e}");
    }
}

//! Whole-integrator checks against analytic answers: furnace enclosures (unlimited and
//! depth-limited, with and without a glass object) and direct lighting of a plane.
//! Bounds come from the renders' own variance: PT pixels are independent, so the spread of
//! pixel means gives the standard error of the image mean.
use cvtrace_render::testing::{add_box, add_quad, furnace_box, BruteForce};
use cvtrace_render::{render_streams, Camera, Material, RenderSettings, Scene, SceneParts};
use cvtrace_streams::Image;
use glam::Vec3A;

/// Mean and standard error of the per-pixel values of channel `c` (independent PT pixels).
fn pixel_stats(im: &Image, c: usize) -> (f64, f64) {
    let v: Vec<f64> = im.pixels.iter().map(|p| p[c] as f64).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Mean and standard error over the image means of the batches (batches are independent
/// sample ranges, so this is valid for CRN too, whose pixels are correlated).
fn batch_stats(batches: &[Image], c: usize) -> (f64, f64) {
    let means: Vec<f64> = batches.iter().map(|b| b.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / b.len() as f64).collect();
    let n = means.len() as f64;
    let mean = means.iter().sum::<f64>() / n;
    let var = means.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

fn settings(w: u32, spp: u32, batches: u32, max_depth: i32) -> RenderSettings {
    RenderSettings { width: w, height: w, spp, batches, seed: 1234, max_depth, rr_depth: 5 }
}

#[test]
fn furnace_converges_to_le_over_one_minus_albedo() {
    let (le, rho) = (1.0f32, 0.6f32);
    let scene = furnace_box(le, rho);
    let tracer = BruteForce::new(&scene);
    let set = render_streams(&scene, &tracer, &settings(32, 64, 16, -1), &|_| {}).unwrap();
    let expect = (le / (1.0 - rho)) as f64;
    for c in 0..3 {
        let (m, se) = pixel_stats(&set.pt.mean, c);
        eprintln!("furnace PT channel {c}: {m} ± {se} (expected {expect})");
        assert!((m - expect).abs() < 5.0 * se, "PT channel {c}: {m} ± {se}, expected {expect}");
        assert!(se < 0.02 * expect, "suspiciously noisy: se {se}");
        let (m, se) = batch_stats(&set.crn.batches, c);
        assert!((m - expect).abs() < 5.0 * se, "CRN channel {c}: {m} ± {se}, expected {expect}");
    }
    assert_eq!(set.meta.non_finite_samples, 0);
}

#[test]
fn depth_limited_furnace_gives_the_geometric_partial_sum() {
    let (le, rho) = (0.5f32, 0.7f32);
    let scene = furnace_box(le, rho);
    let tracer = BruteForce::new(&scene);
    for max_depth in [1, 2, 3, 6] {
        let set = render_streams(&scene, &tracer, &settings(12, 32, 4, max_depth), &|_| {}).unwrap();
        let expect: f64 = (0..max_depth).map(|k| (le * rho.powi(k)) as f64).sum();
        let (m, se) = pixel_stats(&set.pt.mean, 1);
        if max_depth == 1 {
            // Only the directly visible emitter: every sample is exactly Le.
            assert!(set.pt.mean.pixels.iter().chain(&set.crn.mean.pixels).all(|p| (p[1] - le).abs() < 1e-6), "max_depth 1");
        } else {
            assert!((m - expect).abs() < 5.0 * se + 1e-6, "max_depth {max_depth}: {m} ± {se}, expected {expect}");
        }
    }
}

#[test]
fn smooth_glass_is_invisible_in_a_furnace() {
    // Non-absorbing glass inside a uniform radiance field leaves it uniform: this exercises delta
    // lobes, refraction's radiance scaling and its compensation in Russian roulette.
    let (le, rho) = (1.0f32, 0.5f32);
    let mut parts = SceneParts {
        materials: vec![Material::emissive(Vec3A::splat(rho), Vec3A::splat(le)), Material::glass(1.5, 0.0)],
        ..Default::default()
    };
    add_box(&mut parts, Vec3A::splat(-2.0), Vec3A::splat(2.0), 0);
    for t in &mut parts.triangles {
        t.swap(1, 2);
    }
    add_box(&mut parts, Vec3A::splat(-0.6), Vec3A::splat(0.6), 1);
    parts.camera =
        Some(Camera { eye: Vec3A::new(0.3, 0.4, 1.9), target: Vec3A::ZERO, up: Vec3A::Y, vfov_deg: 30.0, width: 16, height: 16 });
    let scene = Scene::from_parts(parts).unwrap();
    let tracer = BruteForce::new(&scene);
    let set = render_streams(&scene, &tracer, &settings(16, 64, 8, -1), &|_| {}).unwrap();
    let expect = (le / (1.0 - rho)) as f64;
    let (m, se) = pixel_stats(&set.pt.mean, 0);
    eprintln!("glass furnace: {m} ± {se} (expected {expect})");
    assert!((m - expect).abs() < 5.0 * se, "{m} ± {se}, expected {expect}");
    // The glass must actually be in view (first-hit depth shorter than the walls').
    let depth = &set.features.as_ref().unwrap().depth;
    assert!(depth.iter().filter(|d| **d < 1.8).count() > depth.len() / 2);
}

/// Form factor from a point to a parallel square of half-size `a` centred `h` above it.
fn square_form_factor(a: f64, h: f64) -> f64 {
    let x = a / h;
    let s = (1.0 + x * x).sqrt();
    4.0 * (2.0 * x / s * (x / s).atan()) / (2.0 * std::f64::consts::PI)
}

#[test]
fn max_depth_two_is_direct_lighting_and_one_shows_only_emitters() {
    let (le, rho, a, h) = (3.0f32, 0.5f32, 1.0f32, 1.0f32);
    let mut parts = SceneParts {
        materials: vec![Material::diffuse(Vec3A::splat(rho)), Material::emissive(Vec3A::ZERO, Vec3A::splat(le))],
        ..Default::default()
    };
    let v = Vec3A::new;
    add_quad(&mut parts, [v(-10., 0., 10.), v(10., 0., 10.), v(10., 0., -10.), v(-10., 0., -10.)], 0);
    add_quad(&mut parts, [v(-a, h, -a), v(a, h, -a), v(a, h, a), v(-a, h, a)], 1);
    parts.camera = Some(Camera { eye: v(0.0, 0.5, 2.0), target: Vec3A::ZERO, up: Vec3A::Y, vfov_deg: 0.5, width: 8, height: 8 });
    let scene = Scene::from_parts(parts).unwrap();
    let tracer = BruteForce::new(&scene);

    let direct = render_streams(&scene, &tracer, &settings(8, 256, 4, 2), &|_| {}).unwrap();
    let expect = (rho * le) as f64 * square_form_factor(a as f64, h as f64);
    let (m, se) = pixel_stats(&direct.pt.mean, 0);
    eprintln!("direct lighting: {m} ± {se} (expected {expect})");
    // The pixels see points within ~0.04 of the centre, where the form factor is flat to <0.5%.
    assert!((m - expect).abs() < 5.0 * se + 0.005 * expect, "direct: {m} ± {se}, expected {expect}");

    let emitters_only = render_streams(&scene, &tracer, &settings(8, 4, 1, 1), &|_| {}).unwrap();
    assert!(emitters_only.pt.mean.pixels.iter().all(|p| *p == [0.0; 3]), "max_depth 1 must not light the plane");
}

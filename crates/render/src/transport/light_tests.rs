//! Whole-estimator checks of every light kind against analytic answers, on a Lambertian plane
//! (`testing::plane_parts`) with the brute-force intersector. Delta lights give deterministic
//! estimates (checked to float precision); environment estimates are checked within 5
//! standard errors of their own samples (fixed seeds), with the error bar also bounded so a
//! broken estimator cannot hide behind huge variance.
use crate::film::driver::render_streams;
use crate::sampler::{dims, StreamKind, StreamSampler};
use crate::scene::camera::Camera;
use crate::scene::lights::{Environment, Punctual};
use crate::scene::material::Material;
use crate::scene::world::{Scene, SceneParts};
use crate::settings::RenderSettings;
use crate::testing::{add_box, add_quad, estimate_radiance, plane_parts, ray_through, BruteForce};
use crate::transport::bsdf::Bsdf;
use cvtrace_streams::Image;
use glam::Vec3A;
use std::f32::consts::PI;

const RHO: f32 = 0.6;
/// Camera position for looking at the plane.
const EYE: Vec3A = Vec3A::new(0.2, 4.0, 1.0);

fn scene_with(parts: SceneParts) -> (Scene, BruteForce) {
    let scene = Scene::from_parts(parts).unwrap();
    let bf = BruteForce::new(&scene);
    (scene, bf)
}

fn close(a: Vec3A, b: Vec3A, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * b.abs().max_element().max(1e-6)
}

#[test]
fn point_light_over_a_plane_gives_rho_over_pi_i_cos_over_d2() {
    let mut parts = plane_parts(RHO, 10.0);
    let light = Vec3A::new(0.5, 1.5, -0.3);
    let intensity = Vec3A::new(4.0, 2.0, 1.0);
    parts.lights.push(Punctual::Point { position: light, intensity });
    let (scene, bf) = scene_with(parts);
    for p in [Vec3A::new(1.0, 0.0, 0.5), Vec3A::new(-2.0, 0.0, 1.0), Vec3A::new(0.5, 0.0, -0.3)] {
        let d = light - p;
        let expect = intensity * (RHO / PI) * (d.y / d.length()) / d.length_squared();
        for max_depth in [2, -1] {
            let (m, se) = estimate_radiance(&scene, &bf, ray_through(EYE, p), max_depth, 16, 1);
            assert!(close(m, expect, 1e-4), "at {p}: {m} vs {expect}");
            assert!(se.max_element() < 1e-5 * expect.max_element(), "a delta light needs no samples: se {se}");
        }
    }
    // Below the horizon of the surface (light under the plane): nothing.
    let mut parts = plane_parts(RHO, 10.0);
    parts.lights.push(Punctual::Point { position: Vec3A::new(0.0, -1.0, 0.0), intensity });
    let (scene, bf) = scene_with(parts);
    assert_eq!(estimate_radiance(&scene, &bf, ray_through(EYE, Vec3A::ZERO), -1, 4, 1).0, Vec3A::ZERO);
}

#[test]
fn directional_light_gives_rho_over_pi_e_cos_and_an_occluder_casts_a_shadow() {
    let dir = Vec3A::new(0.3, -1.0, 0.5).normalize();
    let e = Vec3A::new(2.0, 3.0, 1.5);
    let mut parts = plane_parts(RHO, 10.0);
    parts.lights.push(Punctual::Directional { direction: dir, irradiance: e });
    // A small box hovering over (−3, 0, −3), shadowing the point along the sun direction.
    let shadowed = Vec3A::new(-3.0, 0.0, -3.0);
    let above = shadowed - dir * 1.0;
    add_box(&mut parts, above - Vec3A::splat(0.2), above + Vec3A::splat(0.2), 0);
    let (scene, bf) = scene_with(parts);
    let expect = e * (RHO / PI) * (-dir.y);
    for p in [Vec3A::new(1.0, 0.0, 0.5), Vec3A::new(4.0, 0.0, -2.0)] {
        let (m, _) = estimate_radiance(&scene, &bf, ray_through(EYE, p), 2, 8, 2);
        assert!(close(m, expect, 1e-4), "at {p}: {m} vs {expect}");
    }
    let (m, _) = estimate_radiance(&scene, &bf, ray_through(Vec3A::new(-3.0, 8.0, -2.0), shadowed), 2, 8, 2);
    assert_eq!(m, Vec3A::ZERO, "the occluded point is lit");
}

#[test]
fn spot_light_follows_the_gltf_cone_on_the_plane() {
    let (inner, outer) = (0.3f32, 0.6f32);
    let h = 2.0f32;
    let intensity = Vec3A::splat(5.0);
    let mut parts = plane_parts(RHO, 20.0);
    parts.lights.push(Punctual::spot(Vec3A::new(0.0, h, 0.0), Vec3A::NEG_Y, intensity, inner, outer).unwrap());
    let (scene, bf) = scene_with(parts);
    let mut last = f32::INFINITY;
    for k in 0..=40 {
        let a = 0.8 * k as f32 / 40.0;
        let p = Vec3A::new(h * a.tan(), 0.0, 0.0);
        let (m, _) = estimate_radiance(&scene, &bf, ray_through(EYE, p), 2, 4, 3);
        let d2 = h * h + p.x * p.x;
        let falloff = if a <= inner {
            1.0
        } else if a >= outer {
            0.0
        } else {
            let t = (a.cos() - outer.cos()) / (inner.cos() - outer.cos());
            t * t
        };
        let expect = intensity * (RHO / PI) * falloff * a.cos() / d2;
        assert!(close(m, expect, 2e-3) || (expect.max_element() < 1e-6 && m.max_element() < 1e-6), "angle {a}: {m} vs {expect}");
        // The falloff alone (radiance × d² / cos) is 1 inside, 0 outside, monotone between.
        let f = m.x / (intensity.x * RHO / PI) * d2 / a.cos();
        assert!(f <= last + 1e-4, "not monotone at {a}: {f} after {last}");
        if a < inner {
            assert!((f - 1.0).abs() < 1e-3, "inside the inner cone at {a}: {f}");
        }
        if a > outer {
            assert_eq!(f, 0.0, "outside the outer cone at {a}");
        }
        last = f;
    }
}

/// Mean ± se of `f(i)` over `n` samples.
fn mean_se(n: u32, mut f: impl FnMut(u32) -> Vec3A) -> (Vec3A, Vec3A) {
    let (mut s, mut q) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for i in 0..n {
        let v = f(i).as_dvec3();
        s += v;
        q += v * v;
    }
    let m = s / n as f64;
    let var = (q / n as f64 - m * m).max(glam::DVec3::ZERO) * (n as f64 / (n as f64 - 1.0));
    (m.as_vec3a(), (var / n as f64).map(f64::sqrt).as_vec3a())
}

fn within(m: Vec3A, se: Vec3A, expect: Vec3A, what: &str) {
    eprintln!("{what}: {m} ± {se} (expected {expect})");
    assert!(((m - expect).abs() - 5.0 * se).max_element() <= 1e-6, "{what}: {m} ± {se}, expected {expect}");
    assert!(se.max_element() < 0.05 * expect.max_element(), "{what}: suspiciously noisy, se {se}");
}

/// NEE alone, BSDF sampling alone and the full MIS estimator at the plane's centre: each must
/// give `expect`.
fn check_estimators(scene: &Scene, bf: &BruteForce, expect: Vec3A, n: u32, what: &str) {
    let p = Vec3A::ZERO;
    let wo = (EYE - p).normalize();
    let mat: &Material = &scene.materials()[0];
    let bsdf = Bsdf::new(&mat.params_at(scene.textures(), glam::Vec2::ZERO), Vec3A::Y, Vec3A::Y, wo);
    let lights = scene.lights();
    let st = StreamSampler::new(11, StreamKind::Pt);
    let (m, se) = mean_se(n, |i| {
        let smp = st.sample(0, i);
        let Some(ls) = lights.sample(scene, p, smp.get1d(dims::at(0, dims::LIGHT_SELECT)), smp.get2d(dims::at(0, dims::LIGHT_POS))) else {
            return Vec3A::ZERO;
        };
        // Nothing but the plane itself, which never occludes the upper hemisphere.
        bsdf.eval(ls.wi) * ls.li / ls.pdf
    });
    within(m, se, expect, &format!("{what}, light sampling only"));
    let env = lights.environment().unwrap();
    let (m, se) = mean_se(n, |i| {
        let smp = st.sample(1, i);
        match bsdf.sample(smp.get1d(dims::at(0, dims::LOBE)), smp.get2d(dims::at(0, dims::BSDF_DIR)), 0.0) {
            Some(bs) if bs.wi.y > 0.0 => bs.weight * env.eval(bs.wi),
            _ => Vec3A::ZERO,
        }
    });
    within(m, se, expect, &format!("{what}, BSDF sampling only"));
    let (m, se) = estimate_radiance(scene, bf, ray_through(EYE, p), -1, n, 5);
    within(m, se, expect, &format!("{what}, MIS (full estimator)"));
}

#[test]
fn constant_environment_over_a_plane_gives_rho_times_l() {
    let l_env = Vec3A::new(0.6, 0.7, 1.0);
    let mut parts = plane_parts(RHO, 1000.0);
    parts.environment = Some(Environment::constant(l_env).unwrap());
    let (scene, bf) = scene_with(parts);
    check_estimators(&scene, &bf, l_env * RHO, 20_000, "constant environment");
    // A camera ray that misses sees the environment, and records it as the first-hit albedo.
    let mut fh = crate::transport::integrator::FirstHit::default();
    let st = StreamSampler::new(1, StreamKind::Pt);
    let up = ray_through(EYE, EYE + Vec3A::Y);
    let limits = crate::settings::PathLimits { max_depth: -1, rr_depth: 5 };
    let v = crate::transport::integrator::radiance(&scene, &bf, limits, up, &st.sample(0, 0), Some(&mut fh));
    assert_eq!(v, l_env);
    assert_eq!((fh.albedo, fh.normal, fh.depth), (l_env, Vec3A::ZERO, 0.0));
}

/// A sky-like lat-long map: a bright small sun, a gradient, a dark lower half.
fn sky() -> Image {
    Image::from_fn(64, 32, |x, y| {
        let g = 0.3 + 0.4 * (y as f32 / 32.0) + 0.1 * (x as f32 / 64.0);
        let sun = if (40..43).contains(&x) && (6..8).contains(&y) { 60.0 } else { 0.0 };
        let dim = if y >= 16 { 0.1 } else { 1.0 };
        [(g + sun) * dim, (0.9 * g + sun) * dim, (0.7 * g + 0.8 * sun) * dim]
    })
}

#[test]
fn lat_long_environment_over_a_plane_matches_the_irradiance_integral() {
    let strength = 0.5;
    let env = Environment::from_image(&sky(), strength).unwrap().rotated(25.0).unwrap();
    // ρ/π ∫_{y>0} L(ω) cos θ dω, exactly: a rotation about +Y maps the upper hemisphere and
    // cos θ onto themselves, and the upper half of the map's rows is exactly the hemisphere;
    // a texel spanning [θ0, θ1] × 2π/W contributes L · 2π/W · (sin²θ1 − sin²θ0)/2.
    let img = sky();
    let (w, h) = (img.width, img.height);
    let mut e = glam::DVec3::ZERO;
    for row in 0..h / 2 {
        let (t0, t1) = (std::f64::consts::PI * row as f64 / h as f64, std::f64::consts::PI * (row + 1) as f64 / h as f64);
        let band = (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0 * 2.0 * std::f64::consts::PI / w as f64;
        for col in 0..w {
            e += Vec3A::from_array(img.pixels[row * w + col]).as_dvec3() * (strength as f64 * band);
        }
    }
    let expect = (e * (RHO as f64 / std::f64::consts::PI)).as_vec3a();
    let mut parts = plane_parts(RHO, 1000.0);
    parts.environment = Some(env);
    let (scene, bf) = scene_with(parts);
    check_estimators(&scene, &bf, expect, 40_000, "lat-long environment");
}

#[test]
fn a_constant_map_renders_like_the_constant_colour() {
    let c = Vec3A::new(0.6, 0.7, 1.0);
    let map = Image::from_fn(16, 8, |_, _| [0.3, 0.35, 0.5]);
    let mut means = Vec::new();
    for env in [Environment::constant(c).unwrap(), Environment::from_image(&map, 2.0).unwrap()] {
        let mut parts = plane_parts(RHO, 3.0);
        // A box on the plane, so there are shadows and interreflections, plus a point light.
        add_box(&mut parts, Vec3A::new(-0.5, 0.0, -0.5), Vec3A::new(0.5, 1.0, 0.5), 0);
        parts.lights.push(Punctual::Point { position: Vec3A::new(1.0, 2.0, 1.0), intensity: Vec3A::splat(2.0) });
        parts.environment = Some(env);
        let (scene, bf) = scene_with(parts);
        let (m, se) = estimate_radiance(&scene, &bf, ray_through(EYE, Vec3A::new(0.8, 0.0, 0.2)), -1, 20_000, 8);
        means.push((m, se));
    }
    let ((a, sa), (b, sb)) = (means[0], means[1]);
    eprintln!("constant colour {a} ± {sa}, constant map {b} ± {sb}");
    let se = (sa * sa + sb * sb).map(f32::sqrt);
    assert!(((a - b).abs() - 5.0 * se).max_element() <= 0.0, "{a} ± {sa} vs {b} ± {sb}");
    assert!(se.max_element() < 0.02 * a.max_element());
}

/// An open box (Cornell-style geometry, front open) of white Lambertian walls with blocks,
/// under a constant environment: a white furnace, so every pixel converges to the environment's
/// radiance however many bounces a path needs.
fn white_furnace(l_env: f32, sun: bool) -> Scene {
    let mut parts = SceneParts { materials: vec![Material::diffuse(Vec3A::ONE)], ..Default::default() };
    let v = Vec3A::new;
    add_quad(&mut parts, [v(-1., -1., 1.), v(1., -1., 1.), v(1., -1., -1.), v(-1., -1., -1.)], 0);
    add_quad(&mut parts, [v(-1., 1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(-1., 1., 1.)], 0);
    add_quad(&mut parts, [v(-1., -1., -1.), v(1., -1., -1.), v(1., 1., -1.), v(-1., 1., -1.)], 0);
    add_quad(&mut parts, [v(-1., -1., 1.), v(-1., -1., -1.), v(-1., 1., -1.), v(-1., 1., 1.)], 0);
    add_quad(&mut parts, [v(1., -1., -1.), v(1., -1., 1.), v(1., 1., 1.), v(1., 1., -1.)], 0);
    add_box(&mut parts, v(-0.65, -1.0, -0.6), v(-0.05, 0.2, -0.05), 0);
    parts.camera = Some(Camera { eye: v(0.0, 0.0, 3.9), target: Vec3A::ZERO, up: Vec3A::Y, vfov_deg: 45.0, width: 16, height: 16 });
    parts.environment = Some(Environment::constant(Vec3A::splat(l_env)).unwrap());
    if sun {
        parts.lights.push(Punctual::Directional { direction: v(-0.3, -0.5, -1.0).normalize(), irradiance: Vec3A::splat(2.0) });
    }
    Scene::from_parts(parts).unwrap()
}

#[test]
fn white_furnace_under_a_constant_environment() {
    let l_env = 0.5;
    let scene = white_furnace(l_env, false);
    let bf = BruteForce::new(&scene);
    let s = RenderSettings { width: 16, height: 16, spp: 64, batches: 8, seed: 3, max_depth: -1, rr_depth: 5 };
    let set = render_streams(&scene, &bf, &s, &|_| {}).unwrap();
    let v: Vec<f64> = set.pt.mean.pixels.iter().map(|p| p[1] as f64).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    eprintln!("white furnace: {mean} ± {se} (expected {l_env})");
    assert!((mean - l_env as f64).abs() < 5.0 * se && se < 0.01, "{mean} ± {se}");
    assert_eq!(set.meta.non_finite_samples, 0);
}

#[test]
fn environment_and_sun_renders_are_identical_for_any_thread_count() {
    let scene = white_furnace(0.3, true);
    let bf = BruteForce::new(&scene);
    let s = RenderSettings { width: 12, height: 10, spp: 8, batches: 2, seed: 9, max_depth: 6, rr_depth: 3 };
    let render = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render_streams(&scene, &bf, &s, &|_| {}).unwrap())
    };
    let (a, b) = (render(1), render(2));
    assert!(a == b, "1 and 2 threads differ");
    assert!(a.pt.mean.pixels.iter().any(|p| p[0] > 0.0));
}

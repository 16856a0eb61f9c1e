//! Unidirectional path tracing with next-event estimation, multiple importance sampling (power
//! heuristic) between BSDF and light sampling, and Russian roulette.
//!
//! **Lights.** Each non-specular vertex samples one emitter from [`crate::lights::LightSet`]
//! (emissive triangles, punctual lights, the environment, chosen by power). Area lights and the
//! environment are also found by BSDF sampling (a hit on an emitter's front, or a ray that
//! escapes the scene), so both estimates are MIS-weighted; punctual lights are deltas reached
//! only by light sampling (weight 1). Shadow rays towards the environment or a sun go to
//! infinity.
//!
//! **Path length (Mitsuba 3's convention).** `max_depth = N` keeps paths of at most `N`
//! segments counted from the camera: `1` shows only directly visible emitters, `2` adds direct
//! lighting, `3` one indirect bounce, and so on; `-1` is unlimited. A vertex reached by segment
//! `k` only spawns light-sampling and continuation segments if `k < N`.
//!
//! **Russian roulette** starts at vertices reached by segment `k ≥ rr_depth` (default 5): the path
//! survives with probability `q = min(max(throughput) · η², 0.95)` and is reweighted by `1/q`,
//! where `η²` undoes the radiance scaling of refraction so glass interiors are not culled early.
//!
//! Random numbers come from [`crate::sampler`] with a fixed block of dimensions per vertex, so
//! CRN paths of neighbouring pixels make the same decisions at the same depths.
use crate::bsdf::{Bsdf, SampleDraw};
use crate::intersect::{Hit, Intersector, Ray};
use crate::lights::ShadowEnd;
use crate::sampler::{dims, SampleSampler};
use crate::scene::Scene;
use glam::Vec3A;

/// First-hit features of one sample (for denoising-style estimators).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstHit {
    /// Base colour at the first hit; emission for emitters seen from the front; the
    /// environment's radiance for a miss (0 without an environment).
    pub albedo: Vec3A,
    /// Shading normal facing the camera (world space); 0 for a miss.
    pub normal: Vec3A,
    /// Distance from the camera; 0 for a miss.
    pub depth: f32,
}

/// Path-length limits (see the module doc).
#[derive(Clone, Copy, Debug)]
pub struct PathLimits {
    pub max_depth: i32,
    pub rr_depth: u32,
}

/// Balance of two densities by the power heuristic (β = 2), for the first one.
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2.is_infinite() {
        return 1.0;
    }
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Starts a ray at `p` off the surface with geometric normal `ng`, on the side of `dir`.
#[inline]
fn spawn_origin(p: Vec3A, ng: Vec3A, dir: Vec3A, eps: f32) -> Vec3A {
    if dir.dot(ng) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}

/// The radiance carried by the camera ray `ray` for one sample. `ray.dir` must be a unit vector
/// (hit distances are used as lengths).
/// `first` receives the first-hit features if asked for.
pub fn radiance<T: Intersector>(
    scene: &Scene,
    tracer: &T,
    limits: PathLimits,
    ray: Ray,
    sampler: &SampleSampler,
    first: Option<&mut FirstHit>,
) -> Vec3A {
    let hit = tracer.intersect(&ray);
    radiance_from_hit(scene, tracer, limits, ray, hit, sampler, first)
}

/// [`radiance`] for a camera ray whose nearest hit `camera_hit` was already traced (the render
/// driver traces camera rays in coherent batches).
pub fn radiance_from_hit<T: Intersector>(
    scene: &Scene,
    tracer: &T,
    limits: PathLimits,
    mut ray: Ray,
    camera_hit: Option<Hit>,
    sampler: &SampleSampler,
    mut first: Option<&mut FirstHit>,
) -> Vec3A {
    let eps = scene.ray_epsilon();
    let textures = scene.textures();
    let lights = scene.lights();
    let max_depth = if limits.max_depth < 0 { u32::MAX } else { limits.max_depth as u32 };
    let mut l = Vec3A::ZERO;
    let mut beta = Vec3A::ONE;
    let mut eta_scale = 1.0f32;
    // Density of the BSDF sample that produced `ray`, and whether it was a delta lobe.
    let mut prev_pdf = 0.0f32;
    let mut prev_delta = true;
    // Segments so far, including `ray`.
    let mut depth = 1u32;
    // The nearest hit of `ray`.
    let mut next_hit = camera_hit;
    loop {
        let Some(hit) = next_hit else {
            // Escaped: the environment, MIS-weighted against its light sampling.
            if let Some(env) = lights.environment() {
                let (le, pdf_light) = if prev_delta { (env.eval(ray.dir), 0.0) } else { lights.environment_radiance(ray.dir) };
                let w = if prev_delta { 1.0 } else { power_heuristic(prev_pdf, pdf_light) };
                l += beta * le * w;
                if let Some(f) = first.take() {
                    *f = FirstHit { albedo: le, normal: Vec3A::ZERO, depth: 0.0 };
                }
            }
            break;
        };
        let sp = scene.surface(hit.prim, hit.u, hit.v);
        let material = &scene.materials()[sp.material as usize];
        let front = ray.dir.dot(sp.ng) < 0.0;

        // Emission, MIS-weighted against light sampling unless the previous bounce was specular.
        let mut le = Vec3A::ZERO;
        if front && material.is_emissive() {
            le = material.emission_at(textures, sp.uv);
            let w = if prev_delta {
                1.0
            } else {
                let cos_l = -ray.dir.dot(sp.ng);
                let pdf_light = lights.pdf_area(hit.prim) * hit.t * hit.t / cos_l;
                power_heuristic(prev_pdf, pdf_light)
            };
            l += beta * le * w;
        }
        if let Some(f) = first.take() {
            let ns = if sp.ns.dot(ray.dir) > 0.0 { -sp.ns } else { sp.ns };
            *f =
                FirstHit { albedo: if le != Vec3A::ZERO { le } else { material.base_color_at(textures, sp.uv) }, normal: ns, depth: hit.t };
        }
        if depth >= max_depth {
            break;
        }

        let wo = -ray.dir;
        let bsdf = material.bsdf_at(textures, sp.uv, sp.ns, sp.ng, wo);
        let vertex = depth - 1;
        // The continuation's random numbers, drawn before the shadow ray (see `SampleDraw`).
        let u_choice = if bsdf.has_glass() { sampler.get1d(dims::at(vertex, dims::DIELECTRIC_CHOICE)) } else { 0.0 };
        let u_lobe = if matches!(bsdf, Bsdf::Mixture(_)) { sampler.get1d(dims::at(vertex, dims::LOBE)) } else { 0.0 };
        let draw = SampleDraw::new(u_lobe, sampler.get2d(dims::at(vertex, dims::BSDF_DIR)), u_choice);

        // Next-event estimation: one point or direction on one emitter.
        if bsdf.has_non_delta() && !lights.is_empty() {
            let u_sel = sampler.get1d(dims::at(vertex, dims::LIGHT_SELECT));
            let u_pos = sampler.get2d(dims::at(vertex, dims::LIGHT_POS));
            if let Some(ls) = lights.sample(scene, sp.p, u_sel, u_pos) {
                let (f, pdf_bsdf) = bsdf.eval_pdf(ls.wi);
                if f != Vec3A::ZERO {
                    let origin = spawn_origin(sp.p, sp.ng, ls.wi, eps);
                    let shadow = match ls.end {
                        ShadowEnd::Point(target) => Ray { origin, dir: target - origin, tmin: 0.0, tmax: 1.0 },
                        ShadowEnd::Infinite => Ray { origin, dir: ls.wi, tmin: 0.0, tmax: f32::INFINITY },
                    };
                    if !tracer.occluded(&shadow) {
                        let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf_bsdf) };
                        l += beta * f * ls.li * (w / ls.pdf);
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let Some(bs) = bsdf.sample_drawn(&draw) else { break };
        beta *= bs.weight;
        if beta == Vec3A::ZERO || !beta.is_finite() {
            break;
        }
        eta_scale *= bs.eta * bs.eta;
        prev_pdf = bs.pdf;
        prev_delta = bs.delta;
        if depth >= limits.rr_depth {
            let q = (beta.max_element() * eta_scale).min(0.95);
            // q may be NaN only if beta is; beta was checked finite above.
            if sampler.get1d(dims::at(vertex, dims::RUSSIAN_ROULETTE)) >= q {
                break;
            }
            beta /= q;
        }
        ray = Ray { origin: spawn_origin(sp.p, sp.ng, bs.wi, eps), dir: bs.wi, tmin: 0.0, tmax: f32::INFINITY };
        next_hit = tracer.intersect(&ray);
        depth += 1;
    }
    l
}

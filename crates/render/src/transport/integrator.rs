//! Unidirectional path tracing with next-event estimation, multiple importance sampling (power
//! heuristic) between BSDF and light sampling, and Russian roulette.
//!
//! **Lights.** Each non-specular vertex samples one emitter from [`crate::scene::lights::LightSet`]
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
use crate::intersect::{Hit, Intersector, Ray};
use crate::sampler::{dims, SampleSampler};
use crate::scene::world::Scene;
use crate::settings::PathLimits;
use crate::transport::bsdf::{Bsdf, SampleDraw};
use crate::transport::light_sample::ShadowEnd;
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

/// Balance of two densities by the power heuristic (β = 2), for the first one.
#[inline]
pub(crate) fn power_heuristic(a: f32, b: f32) -> f32 {
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
pub(crate) fn spawn_origin(p: Vec3A, ng: Vec3A, dir: Vec3A, eps: f32) -> Vec3A {
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
    ray: Ray,
    camera_hit: Option<Hit>,
    sampler: &SampleSampler,
    mut first: Option<&mut FirstHit>,
) -> Vec3A {
    let ctx = PathContext::new(scene, limits);
    let mut path = Path::new(ray);
    let mut hit = camera_hit;
    loop {
        let step = ctx.vertex(&mut path, hit, sampler, first.take());
        if let Some((shadow, light)) = step.shadow {
            if !tracer.occluded(&shadow) {
                path.l += light;
            }
        }
        if !step.next {
            return path.l;
        }
        hit = tracer.intersect(&path.ray);
    }
}

/// One path between two vertices: the ray that left the last one and what the path carries.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Path {
    /// The ray whose nearest hit is the next vertex (the camera ray at first).
    pub ray: Ray,
    /// Throughput from the camera to the next vertex.
    pub beta: Vec3A,
    /// Radiance gathered so far.
    pub l: Vec3A,
    /// Product of the squared relative indices crossed (Russian roulette undoes them).
    pub eta_scale: f32,
    /// Density of the BSDF sample that produced `ray`, and whether it was a delta lobe.
    pub prev_pdf: f32,
    pub prev_delta: bool,
    /// Segments so far, including `ray`.
    pub depth: u32,
}

impl Path {
    pub fn new(ray: Ray) -> Path {
        Path { ray, beta: Vec3A::ONE, l: Vec3A::ZERO, eta_scale: 1.0, prev_pdf: 0.0, prev_delta: true, depth: 1 }
    }
}

/// What one vertex leaves for the ray caster.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step {
    /// A shadow ray towards a light sample, and the radiance it adds to `l` if nothing
    /// occludes it.
    pub shadow: Option<(Ray, Vec3A)>,
    /// Whether the path goes on: the nearest hit of its new `ray` is the next vertex.
    pub next: bool,
}

/// What every vertex of a render reads.
#[derive(Clone, Copy)]
pub(crate) struct PathContext<'a> {
    pub scene: &'a Scene,
    pub limits: PathLimits,
    /// `limits.max_depth` as a count of segments (`u32::MAX` for unlimited).
    pub max_depth: u32,
    pub eps: f32,
}

impl<'a> PathContext<'a> {
    pub fn new(scene: &'a Scene, limits: PathLimits) -> PathContext<'a> {
        let max_depth = if limits.max_depth < 0 { u32::MAX } else { limits.max_depth as u32 };
        PathContext { scene, limits, max_depth, eps: scene.ray_epsilon() }
    }

    /// The vertex at `hit`, the nearest hit of `path.ray` (`None`: the ray escaped): adds its
    /// emission to `path.l`, samples a light and the continuation, and leaves the path ready
    /// for its next ray. `first` receives the first-hit features if asked for.
    #[inline]
    pub fn vertex(&self, path: &mut Path, hit: Option<Hit>, sampler: &SampleSampler, first: Option<&mut FirstHit>) -> Step {
        let (scene, lights, textures) = (self.scene, self.scene.lights(), self.scene.textures());
        let done = Step { shadow: None, next: false };
        let ray = path.ray;
        let Some(hit) = hit else {
            // Escaped: the environment, MIS-weighted against its light sampling.
            if let Some(env) = lights.environment() {
                let (le, pdf_light) = if path.prev_delta { (env.eval(ray.dir), 0.0) } else { lights.environment_radiance(ray.dir) };
                let w = if path.prev_delta { 1.0 } else { power_heuristic(path.prev_pdf, pdf_light) };
                path.l += path.beta * le * w;
                if let Some(f) = first {
                    *f = FirstHit { albedo: le, normal: Vec3A::ZERO, depth: 0.0 };
                }
            }
            return done;
        };
        let sp = scene.surface(hit.prim, hit.u, hit.v);
        let material = &scene.materials()[sp.material as usize];
        let front = ray.dir.dot(sp.ng) < 0.0;

        // Emission, MIS-weighted against light sampling unless the previous bounce was specular.
        let mut le = Vec3A::ZERO;
        if front && material.is_emissive() {
            le = material.emission_at(textures, sp.uv);
            let w = if path.prev_delta {
                1.0
            } else {
                let cos_l = -ray.dir.dot(sp.ng);
                let pdf_light = lights.pdf_area(hit.prim) * hit.t * hit.t / cos_l;
                power_heuristic(path.prev_pdf, pdf_light)
            };
            path.l += path.beta * le * w;
        }
        if let Some(f) = first {
            let ns = if sp.ns.dot(ray.dir) > 0.0 { -sp.ns } else { sp.ns };
            *f =
                FirstHit { albedo: if le != Vec3A::ZERO { le } else { material.base_color_at(textures, sp.uv) }, normal: ns, depth: hit.t };
        }
        if path.depth >= self.max_depth {
            return done;
        }

        let wo = -ray.dir;
        let bsdf = Bsdf::at(material, textures, sp.uv, sp.ns, sp.ng, wo);
        let vertex = path.depth - 1;
        // The continuation's random numbers, drawn before the shadow ray (see `SampleDraw`).
        let u_choice = if bsdf.has_glass() { sampler.get1d(dims::at(vertex, dims::DIELECTRIC_CHOICE)) } else { 0.0 };
        let u_lobe = if matches!(bsdf, Bsdf::Mixture(_)) { sampler.get1d(dims::at(vertex, dims::LOBE)) } else { 0.0 };
        let draw = SampleDraw::new(u_lobe, sampler.get2d(dims::at(vertex, dims::BSDF_DIR)), u_choice);

        // Next-event estimation: one point or direction on one emitter.
        let mut shadow = None;
        if bsdf.has_non_delta() && !lights.is_empty() {
            let u_sel = sampler.get1d(dims::at(vertex, dims::LIGHT_SELECT));
            let u_pos = sampler.get2d(dims::at(vertex, dims::LIGHT_POS));
            if let Some(ls) = lights.sample(scene, sp.p, u_sel, u_pos) {
                let (f, pdf_bsdf) = bsdf.eval_pdf(ls.wi);
                if f != Vec3A::ZERO {
                    let origin = spawn_origin(sp.p, sp.ng, ls.wi, self.eps);
                    let ray = match ls.end {
                        ShadowEnd::Point(target) => Ray { origin, dir: target - origin, tmin: 0.0, tmax: 1.0 },
                        ShadowEnd::Infinite => Ray { origin, dir: ls.wi, tmin: 0.0, tmax: f32::INFINITY },
                    };
                    let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf_bsdf) };
                    shadow = Some((ray, path.beta * f * ls.li * (w / ls.pdf)));
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let Some(bs) = bsdf.sample_drawn(&draw) else { return Step { shadow, next: false } };
        let mut beta = path.beta * bs.weight;
        if beta == Vec3A::ZERO || !beta.is_finite() {
            return Step { shadow, next: false };
        }
        path.eta_scale *= bs.eta * bs.eta;
        path.prev_pdf = bs.pdf;
        path.prev_delta = bs.delta;
        if path.depth >= self.limits.rr_depth {
            let q = (beta.max_element() * path.eta_scale).min(0.95);
            // q may be NaN only if beta is; beta was checked finite above.
            if sampler.get1d(dims::at(vertex, dims::RUSSIAN_ROULETTE)) >= q {
                return Step { shadow, next: false };
            }
            beta /= q;
        }
        path.beta = beta;
        path.ray = Ray { origin: spawn_origin(sp.p, sp.ng, bs.wi, self.eps), dir: bs.wi, tmin: 0.0, tmax: f32::INFINITY };
        path.depth += 1;
        Step { shadow, next: true }
    }
}

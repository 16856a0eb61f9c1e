//! Unidirectional path tracing with next-event estimation on emissive triangles, multiple
//! importance sampling (power heuristic) between BSDF and light sampling, and Russian roulette.
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
use crate::bsdf::Bsdf;
use crate::intersect::{Intersector, Ray};
use crate::sampler::{dims, SampleSampler};
use crate::scene::Scene;
use glam::Vec3;

/// First-hit features of one sample (for denoising-style estimators).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstHit {
    /// Base colour at the first hit; emission for emitters seen from the front; 0 for a miss.
    pub albedo: Vec3,
    /// Shading normal facing the camera (world space); 0 for a miss.
    pub normal: Vec3,
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
fn spawn_origin(p: Vec3, ng: Vec3, dir: Vec3, eps: f32) -> Vec3 {
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
    mut ray: Ray,
    sampler: &SampleSampler,
    mut first: Option<&mut FirstHit>,
) -> Vec3 {
    let eps = scene.ray_epsilon();
    let textures = scene.textures();
    let lights = scene.lights();
    let max_depth = if limits.max_depth < 0 { u32::MAX } else { limits.max_depth as u32 };
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut eta_scale = 1.0f32;
    // Density of the BSDF sample that produced `ray`, and whether it was a delta lobe.
    let mut prev_pdf = 0.0f32;
    let mut prev_delta = true;
    // Segments so far, including `ray`.
    let mut depth = 1u32;
    while let Some(hit) = tracer.intersect(&ray) {
        let sp = scene.surface(hit.prim, hit.u, hit.v);
        let material = &scene.materials()[sp.material as usize];
        let front = ray.dir.dot(sp.ng) < 0.0;

        // Emission, MIS-weighted against light sampling unless the previous bounce was specular.
        let mut le = Vec3::ZERO;
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
            *f = FirstHit { albedo: if le != Vec3::ZERO { le } else { material.base_color_at(textures, sp.uv) }, normal: ns, depth: hit.t };
        }
        if depth >= max_depth {
            break;
        }

        let wo = -ray.dir;
        let params = material.params_at(textures, sp.uv);
        let bsdf = Bsdf::new(&params, sp.ns, sp.ng, wo);
        let vertex = depth - 1;

        // Next-event estimation: one point on one emissive triangle.
        if bsdf.has_non_delta() && !lights.is_empty() {
            let u_sel = sampler.get1d(dims::at(vertex, dims::LIGHT_SELECT));
            let u_pos = sampler.get2d(dims::at(vertex, dims::LIGHT_POS));
            if let Some(ls) = lights.sample(u_sel, u_pos, |p| scene.triangle_vertices(p)) {
                let to_light = ls.point - sp.p;
                let dist2 = to_light.length_squared();
                let n_l = scene.geometric_normal(ls.prim);
                if dist2 > 0.0 {
                    let dist = dist2.sqrt();
                    let wi = to_light / dist;
                    let cos_l = -wi.dot(n_l);
                    if cos_l > 0.0 {
                        let (f, pdf_bsdf) = bsdf.eval_pdf(wi);
                        if f != Vec3::ZERO {
                            let light_mat = scene.material_of(ls.prim);
                            let uv = light_uv(scene, ls.prim, ls.bary);
                            let le = light_mat.emission_at(textures, uv);
                            let pdf_light = ls.pdf_area * dist2 / cos_l;
                            if le != Vec3::ZERO && pdf_light > 0.0 {
                                let origin = spawn_origin(sp.p, sp.ng, wi, eps);
                                let target = ls.point + n_l * eps;
                                let shadow = Ray { origin, dir: target - origin, tmin: 0.0, tmax: 1.0 };
                                if !tracer.occluded(&shadow) {
                                    let w = power_heuristic(pdf_light, pdf_bsdf);
                                    l += beta * f * le * (w / pdf_light);
                                }
                            }
                        }
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let u_lobe = sampler.get1d(dims::at(vertex, dims::LOBE));
        let u_dir = sampler.get2d(dims::at(vertex, dims::BSDF_DIR));
        let u_choice = if bsdf.has_glass() { sampler.get1d(dims::at(vertex, dims::DIELECTRIC_CHOICE)) } else { 0.0 };
        let Some(bs) = bsdf.sample(u_lobe, u_dir, u_choice) else { break };
        beta *= bs.weight;
        if beta == Vec3::ZERO || !beta.is_finite() {
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
        depth += 1;
    }
    l
}

/// Texture coordinates of a point on a light (only needed for textured emitters).
#[inline]
fn light_uv(scene: &Scene, prim: u32, bary: glam::Vec2) -> glam::Vec2 {
    if scene.material_of(prim).emissive_texture.is_some() {
        scene.surface(prim, bary.x, bary.y).uv
    } else {
        glam::Vec2::ZERO
    }
}

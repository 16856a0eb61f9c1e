//! Many paths at once, bounce by bounce: every live path's vertex is shaded, then every
//! shadow ray is traced, then every continuation ray. Each path does exactly what
//! [`crate::integrator::radiance_from_hit`] does with it (the same vertex, the same random
//! numbers, its radiance summed in the same order), so the result is the same bit for bit.
//!
//! Why: a vertex on its own is a chain of dependent steps between two calls into the ray
//! caster, run one path after the other. Shading many paths' vertices together lets the
//! common vertex ([`lanes`]: diffuse material, an emissive triangle as the light sample) run
//! on [`lanes::W`] paths per instruction; every other vertex (glossy or glass materials,
//! textures, punctual lights, the environment, escaped rays) takes the scalar
//! [`crate::integrator::PathContext::vertex`].
mod lanes;

use crate::integrator::{FirstHit, Path, PathContext};
use crate::intersect::{Hit, Intersector, Ray};
use crate::sampler::{dims, SampleSampler};
use crate::scene::Scene;
use glam::Vec3A;
use lanes::{Consts, Kernel, LaneIn, LaneOut, W};

pub(crate) use lanes::Isa;

/// The paths of one wavefront and the scratch of its bounces, reused from batch to batch.
pub(crate) struct Wavefront {
    paths: Vec<Path>,
    samplers: Vec<SampleSampler>,
    hits: Vec<Option<Hit>>,
    firsts: Vec<FirstHit>,
    /// Indices of the paths that reach another vertex.
    active: Vec<u32>,
    next: Vec<u32>,
    /// Shadow rays of this bounce: path, ray, the light it brings.
    shadows: Vec<(u32, Ray, Vec3A)>,
    /// The lane kernel, or `None` to shade every vertex with the scalar code.
    kernel: Option<Kernel>,
    lanes_in: Box<LaneIn>,
    lanes_out: Box<LaneOut>,
    /// The path of each filled lane.
    lane_path: [u32; W],
    /// What the lanes read of the scene's materials and lights, for the scene of the last run.
    tables: Tables,
}

/// A material as the lane kernel reads it.
#[derive(Clone, Copy)]
struct LaneMaterial {
    /// Whether a vertex with it is the kernel's: diffuse, no texture.
    lanes: bool,
    base: Vec3A,
    /// The BSDF's albedo, `base` at least 0 (as [`crate::bsdf::Bsdf::diffuse`] takes it).
    albedo: Vec3A,
    emission: Vec3A,
}

/// An emitter as the lane kernel samples it: an emissive triangle without a texture.
#[derive(Clone, Copy)]
struct LaneLight {
    p: [Vec3A; 3],
    ng: Vec3A,
    pdf_area: f32,
    emission: Vec3A,
}

/// Per material and per emitter (in selection order) of one scene, what the lanes read.
#[derive(Default)]
struct Tables {
    /// The scene these are of (its address: a scene lives as long as its render).
    scene: usize,
    materials: Vec<LaneMaterial>,
    lights: Vec<Option<LaneLight>>,
}

impl Tables {
    fn of(&mut self, scene: &Scene) -> &Tables {
        let id = scene as *const Scene as usize;
        if self.scene != id || self.materials.len() != scene.materials().len() {
            self.scene = id;
            self.materials = scene
                .materials()
                .iter()
                .map(|m| LaneMaterial {
                    lanes: m.is_diffuse_only() && m.base_color_texture.is_none() && m.emissive_texture.is_none(),
                    base: m.base_color,
                    albedo: m.base_color.max(Vec3A::ZERO),
                    emission: m.emission,
                })
                .collect();
            let lights = scene.lights();
            self.lights = (0..lights.len())
                .map(|k| {
                    let prim = lights.emitter_triangle(k)?;
                    let m = scene.material_of(prim);
                    m.emissive_texture.is_none().then(|| LaneLight {
                        p: scene.triangle_vertices(prim),
                        ng: scene.geometric_normal(prim),
                        pdf_area: lights.pdf_area(prim),
                        emission: m.emission,
                    })
                })
                .collect();
        }
        self
    }
}

impl Default for Wavefront {
    fn default() -> Self {
        Wavefront::new(Isa::detect().kernel())
    }
}

impl Wavefront {
    /// A wavefront that shades its common vertices with `kernel` (all with the scalar code
    /// for `None`).
    pub fn new(kernel: Option<Kernel>) -> Wavefront {
        Wavefront {
            paths: Vec::new(),
            samplers: Vec::new(),
            hits: Vec::new(),
            firsts: Vec::new(),
            active: Vec::new(),
            next: Vec::new(),
            shadows: Vec::new(),
            kernel,
            lanes_in: Box::default(),
            lanes_out: Box::default(),
            lane_path: [0; W],
            tables: Tables::default(),
        }
    }

    /// Empties the wavefront.
    pub fn clear(&mut self) {
        self.paths.clear();
        self.samplers.clear();
        self.hits.clear();
        self.firsts.clear();
    }

    /// Adds a path starting with the camera ray `ray`, whose nearest hit is `hit`.
    pub fn push(&mut self, ray: Ray, hit: Option<Hit>, sampler: SampleSampler) {
        self.paths.push(Path::new(ray));
        self.hits.push(hit);
        self.samplers.push(sampler);
        self.firsts.push(FirstHit::default());
    }

    /// Follows every path to its end; then [`Wavefront::radiance`] and [`Wavefront::first_hit`]
    /// hold each path's results, in the order they were pushed.
    pub fn run<T: Intersector>(&mut self, ctx: &PathContext, tracer: &T, features: bool) {
        self.active.clear();
        self.active.extend(0..self.paths.len() as u32);
        if self.kernel.is_some() {
            self.tables.of(ctx.scene);
        }
        let consts = Consts { eps: ctx.eps, max_depth: ctx.max_depth, rr_depth: ctx.limits.rr_depth, normals: ctx.scene.has_normals() };
        let mut first_bounce = true;
        while !self.active.is_empty() {
            self.shadows.clear();
            self.next.clear();
            let want_first = features && first_bounce;
            let mut filled = 0;
            for a in 0..self.active.len() {
                let i = self.active[a] as usize;
                if self.kernel.is_some() && self.gather(ctx, i, filled) {
                    self.lane_path[filled] = i as u32;
                    filled += 1;
                    if filled == W {
                        self.shade_lanes(&consts, filled, want_first);
                        filled = 0;
                    }
                    continue;
                }
                let first = if want_first { Some(&mut self.firsts[i]) } else { None };
                let step = ctx.vertex(&mut self.paths[i], self.hits[i], &self.samplers[i], first);
                if let Some((ray, light)) = step.shadow {
                    self.shadows.push((i as u32, ray, light));
                }
                if step.next {
                    self.next.push(i as u32);
                }
            }
            if filled > 0 {
                self.shade_lanes(&consts, filled, want_first);
            }
            for (i, ray, light) in &self.shadows {
                if !tracer.occluded(ray) {
                    self.paths[*i as usize].l += *light;
                }
            }
            for &i in &self.next {
                let i = i as usize;
                self.hits[i] = tracer.intersect(&self.paths[i].ray);
            }
            std::mem::swap(&mut self.active, &mut self.next);
            first_bounce = false;
        }
    }

    /// Puts path `i`'s vertex into lane `l` if it is one the lane kernel shades (see [`lanes`]).
    #[inline]
    fn gather(&mut self, ctx: &PathContext, i: usize, l: usize) -> bool {
        assert!(l < W);
        let Some(hit) = self.hits[i] else { return false };
        let scene = ctx.scene;
        let material = &self.tables.materials[scene.triangle_materials()[hit.prim as usize] as usize];
        if !material.lanes {
            return false;
        }
        let path = &self.paths[i];
        let lights = scene.lights();
        let light = match lights.choose_index(self.samplers[i].get1d(dims::at(path.depth - 1, dims::LIGHT_SELECT))) {
            None => None,
            Some(k) => match &self.tables.lights[k] {
                Some(light) => Some(light),
                None => return false,
            },
        };
        let inp = &mut *self.lanes_in;
        let put = |a: &mut [[f32; W]; 3], v: Vec3A| {
            a[0][l] = v.x;
            a[1][l] = v.y;
            a[2][l] = v.z;
        };
        put(&mut inp.dir, path.ray.dir);
        (inp.t[l], inp.u[l], inp.v[l]) = (hit.t, hit.u, hit.v);
        put(&mut inp.beta, path.beta);
        inp.eta_scale[l] = path.eta_scale;
        inp.prev_pdf[l] = path.prev_pdf;
        inp.prev_delta[l] = path.prev_delta as u32;
        inp.depth[l] = path.depth;
        inp.key[l] = self.samplers[i].key();
        for (dst, p) in inp.p.iter_mut().zip(scene.triangle_vertices(hit.prim)) {
            put(dst, p);
        }
        if let Some(normals) = scene.triangle_normals(hit.prim) {
            for (dst, n) in inp.n.iter_mut().zip(normals) {
                put(dst, n);
            }
        }
        put(&mut inp.ng, scene.geometric_normal(hit.prim));
        put(&mut inp.base, material.base);
        put(&mut inp.albedo, material.albedo);
        put(&mut inp.emission, material.emission);
        inp.pdf_area[l] = lights.pdf_area(hit.prim);
        inp.has_light[l] = light.is_some() as u32;
        if let Some(light) = light {
            for (dst, p) in inp.light_p.iter_mut().zip(light.p) {
                put(dst, p);
            }
            put(&mut inp.light_ng, light.ng);
            inp.light_pdf_area[l] = light.pdf_area;
            put(&mut inp.light_emission, light.emission);
        }
        true
    }

    /// Runs the lane kernel on the first `filled` lanes and hands each path its results.
    fn shade_lanes(&mut self, consts: &Consts, filled: usize, want_first: bool) {
        let kernel = self.kernel.expect("lanes are filled only with a kernel");
        kernel(&self.lanes_in, &mut self.lanes_out, consts);
        let (inp, out) = (&*self.lanes_in, &*self.lanes_out);
        let get = |a: &[[f32; W]; 3], l: usize| Vec3A::new(a[0][l], a[1][l], a[2][l]);
        for l in 0..filled {
            let i = self.lane_path[l] as usize;
            let path = &mut self.paths[i];
            if out.emits[l] != 0 {
                path.l += get(&out.emitted, l);
            }
            if want_first {
                self.firsts[i] = FirstHit { albedo: get(&out.first_albedo, l), normal: get(&out.first_normal, l), depth: inp.t[l] };
            }
            if out.shadow[l] != 0 {
                let ray = Ray { origin: get(&out.shadow_origin, l), dir: get(&out.shadow_dir, l), tmin: 0.0, tmax: 1.0 };
                self.shadows.push((i as u32, ray, get(&out.shadow_light, l)));
            }
            if out.next[l] != 0 {
                path.beta = get(&out.beta, l);
                path.prev_pdf = out.pdf[l];
                path.prev_delta = false;
                path.ray = Ray { origin: get(&out.origin, l), dir: get(&out.next_dir, l), tmin: 0.0, tmax: f32::INFINITY };
                path.depth += 1;
                self.next.push(i as u32);
            }
        }
    }

    /// The radiance of path `i`.
    pub fn radiance(&self, i: usize) -> Vec3A {
        self.paths[i].l
    }

    /// The first-hit features of path `i` (default unless `run` was asked for them).
    pub fn first_hit(&self, i: usize) -> &FirstHit {
        &self.firsts[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::{radiance_from_hit, PathLimits};
    use crate::sampler::{StreamKind, StreamSampler};
    use crate::scene::Scene;
    use crate::testing::{cornell_box, cornell_box_parts, materials_box, BruteForce};

    /// The Cornell box with vertex normals: bent ones, some facing away from the geometry
    /// (the shading frame falls back to the geometric normal) and some zero (the surface
    /// keeps its geometric normal).
    fn bent_normals_box() -> Scene {
        let mut parts = cornell_box_parts();
        parts.normals = (0..parts.positions.len())
            .map(|i| match i % 7 {
                0 => Vec3A::ZERO,
                1 => Vec3A::new(0.9, -0.3, 0.2),
                k => Vec3A::new(0.3 * k as f32 - 1.0, 0.5, 1.0 - 0.2 * k as f32),
            })
            .collect();
        Scene::from_parts(parts).expect("the bent-normals box is valid")
    }

    /// Every path of a wavefront as `kernel` shades it: radiance and first-hit features.
    fn paths(scene: &Scene, limits: PathLimits, kernel: Option<Kernel>, seed: u64) -> Vec<(Vec3A, FirstHit)> {
        let tracer = BruteForce::new(scene);
        let frame = scene.camera().frame(24, 24);
        let stream = StreamSampler::new(seed, StreamKind::Pt);
        let mut wave = Wavefront::new(kernel);
        for pixel in 0..24 * 24u32 {
            for s in 0..2 {
                let smp = stream.sample(pixel as u64, s);
                let ray = frame.ray(pixel % 24, pixel / 24, smp.get2d(dims::PIXEL));
                wave.push(ray, tracer.intersect(&ray), smp);
            }
        }
        wave.run(&PathContext::new(scene, limits), &tracer, true);
        (0..wave.paths.len()).map(|i| (wave.radiance(i), *wave.first_hit(i))).collect()
    }

    /// Each build of the lane kernel this CPU runs gives every path the scalar vertex's radiance
    /// and first-hit features, bit for bit: on the Cornell box (every hit a lane vertex), with
    /// bent vertex normals, and on the material box (lane and scalar vertices mixed), with and
    /// without a depth limit and with Russian roulette from the first bounce.
    #[test]
    fn lanes_give_the_scalar_vertex_bit_for_bit() {
        let builds: Vec<(Isa, Kernel)> =
            [Isa::Portable, Isa::Avx2, Isa::Avx512].into_iter().filter_map(|i| Some((i, i.kernel()?))).collect();
        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
        for (name, scene) in [("cornell", cornell_box()), ("bent normals", bent_normals_box()), ("materials", materials_box())] {
            for limits in [PathLimits { max_depth: -1, rr_depth: 5 }, PathLimits { max_depth: 3, rr_depth: 1 }] {
                let want = paths(&scene, limits, None, 7);
                // The scalar wavefront is the per-path integrator on the same rays.
                let tracer = BruteForce::new(&scene);
                let frame = scene.camera().frame(24, 24);
                let stream = StreamSampler::new(7, StreamKind::Pt);
                for (k, (l, first)) in want.iter().enumerate().step_by(37) {
                    let (pixel, s) = ((k / 2) as u32, (k % 2) as u32);
                    let smp = stream.sample(pixel as u64, s);
                    let ray = frame.ray(pixel % 24, pixel / 24, smp.get2d(dims::PIXEL));
                    let mut fh = FirstHit::default();
                    let v = radiance_from_hit(&scene, &tracer, limits, ray, tracer.intersect(&ray), &smp, Some(&mut fh));
                    assert_eq!((bits(v), fh), (bits(*l), *first), "{name}: path {k}, scalar wavefront against the integrator");
                }
                assert!(want.iter().filter(|(l, _)| *l != Vec3A::ZERO).count() > want.len() / 4, "{name}: too few lit paths to compare");
                for (isa, kernel) in &builds {
                    let got = paths(&scene, limits, Some(*kernel), 7);
                    for (k, (a, b)) in got.iter().zip(&want).enumerate() {
                        assert_eq!((bits(a.0), a.1), (bits(b.0), b.1), "{name}, {limits:?}: path {k} with the {isa:?} lanes");
                    }
                }
            }
        }
    }
}

//! Many paths at once, bounce by bounce: every live path's vertex is shaded, then every
//! shadow ray is traced, then every continuation ray. Each path does exactly what
//! [`crate::transport::integrator::radiance_from_hit`] does with it (the same vertex, the same
//! random numbers, its radiance summed in the same order), so the result is the same bit for
//! bit.
//!
//! Why: a vertex on its own is a chain of dependent steps between two calls into the ray
//! caster, run one path after the other. The live paths are kept as structure-of-arrays
//! [`lanes::Chunk`]s of [`lanes::W`] paths, compacted after every bounce, so that the common
//! vertices ([`lanes`]: every glTF material, diffuse, glossy or glass, textured or not, lit by
//! any kind of light) run on a whole chunk per instruction, reading and updating the paths
//! where they are. What does not vectorise is done per lane before the kernel runs
//! ([`classify`]: the texture lookups, and the light samples other than on an untextured
//! emitter triangle). The other vertices (emission textures, escaped rays) take the scalar
//! [`crate::transport::integrator::PathContext::vertex`].
mod lanes;
// The lane kernel's builds for each instruction set, the one place the crate allows `unsafe`.
#[allow(unsafe_code)]
mod simd;

use crate::intersect::{Hit, Intersector, Ray, RayPacket};
use crate::sampler::{dims, SampleSampler};
use crate::scene::material::is_diffuse_only;
use crate::scene::world::Scene;
use crate::transport::bsdf::pbr::is_smooth_glass;
use crate::transport::integrator::{FirstHit, Path, PathContext};
use glam::Vec3A;
use lanes::{
    given_light, Blocks, Chunk, Consts, Kind, Out, DIFFUSE, GIVEN, GLASS, GLASS_LOBE, GLOSSY, HAS_LIGHT, MAT_ALBEDO, MAT_BASE,
    MAT_METALLIC, MAT_ROUGHNESS, W,
};
use simd::{Isa, Kernel};

pub(crate) use lanes::SceneLanes;

/// The paths of one wavefront and the scratch of its bounces, reused from batch to batch.
pub(crate) struct Wavefront {
    /// The live paths, `live` of them, in chunks of `W` (the last one partly filled).
    chunks: Vec<Chunk>,
    outs: Vec<Out>,
    live: usize,
    /// Per path, in the order pushed: its radiance once it has ended, and its first-hit features.
    radiance: Vec<Vec3A>,
    firsts: Vec<FirstHit>,
    /// The lane kernel, or `None` to shade every vertex with the scalar code.
    kernel: Option<Kernel>,
    /// The scene records of the chunk being shaded.
    blocks: Box<Blocks>,
    /// Vertices shaded so far, how many of them by the kernel, and how many of those by its
    /// glossy and by its glass lanes.
    vertices: u64,
    kernel_vertices: u64,
    glossy_vertices: u64,
    glass_vertices: u64,
}

impl Default for Wavefront {
    fn default() -> Self {
        Wavefront::new(Isa::detect().kernel())
    }
}

/// The chunk and lane of slot `s`.
#[inline(always)]
fn slot(s: usize) -> (usize, usize) {
    (s / W, s % W)
}

#[inline(always)]
fn get(a: &[[f32; W]; 3], l: usize) -> Vec3A {
    Vec3A::new(a[0][l], a[1][l], a[2][l])
}

#[inline(always)]
fn put(a: &mut [[f32; W]; 3], l: usize, v: Vec3A) {
    a[0][l] = v.x;
    a[1][l] = v.y;
    a[2][l] = v.z;
}

impl Wavefront {
    /// A wavefront that shades its common vertices with `kernel` (all with the scalar code
    /// for `None`).
    pub fn new(kernel: Option<Kernel>) -> Wavefront {
        Wavefront {
            chunks: Vec::new(),
            outs: Vec::new(),
            live: 0,
            radiance: Vec::new(),
            firsts: Vec::new(),
            kernel,
            blocks: Box::default(),
            vertices: 0,
            kernel_vertices: 0,
            glossy_vertices: 0,
            glass_vertices: 0,
        }
    }

    /// Empties the wavefront.
    pub fn clear(&mut self) {
        self.live = 0;
        self.radiance.clear();
        self.firsts.clear();
    }

    /// Adds a path starting with the camera ray `ray`, whose nearest hit is `hit`.
    pub fn push(&mut self, ray: Ray, hit: Option<Hit>, sampler: SampleSampler) {
        let id = self.radiance.len() as u32;
        self.radiance.push(Vec3A::ZERO);
        self.firsts.push(FirstHit::default());
        let (c, l) = slot(self.live);
        if c == self.chunks.len() {
            self.chunks.push(Chunk::default());
            self.outs.push(Out::default());
        }
        let ch = &mut self.chunks[c];
        set_lane_path(ch, l, &Path::new(ray), sampler.key(), id);
        set_hit(ch, l, hit);
        self.live += 1;
    }

    /// Follows every path to its end; then [`Wavefront::radiance`] and [`Wavefront::first_hit`]
    /// hold each path's results, in the order they were pushed. `lanes` is the scene as the
    /// kernel reads it (needed with a kernel).
    pub fn run<T: Intersector>(&mut self, ctx: &PathContext, lanes: Option<&SceneLanes>, tracer: &T, features: bool) {
        let consts = Consts { eps: ctx.eps, max_depth: ctx.max_depth, rr_depth: ctx.limits.rr_depth };
        let kernel = self.kernel.zip(lanes);
        let mut first_bounce = true;
        while self.live > 0 {
            let want_first = features && first_bounce;
            let chunks = self.live.div_ceil(W);
            for c in 0..chunks {
                let filled = (self.live - c * W).min(W);
                let ch = &mut self.chunks[c];
                let out = &mut self.outs[c];
                out.next = [0; W];
                out.shadow = [0; W];
                out.shadow_tmax = [1.0; W];
                let shaded = match kernel {
                    Some((_, lanes)) => classify(ctx, lanes, ch, &mut self.blocks, filled),
                    None => 0,
                };
                // A chunk with few lanes for the kernel is cheaper vertex by vertex.
                self.vertices += filled as u64;
                if let Some((kernel, lanes)) = kernel.filter(|_| shaded > 0) {
                    self.kernel_vertices += shaded as u64;
                    let of_kind = |kind: u32| ch.flags.iter().filter(|&&f| f & kind != 0).count() as u64;
                    self.glossy_vertices += of_kind(GLOSSY);
                    self.glass_vertices += of_kind(GLASS);
                    kernel.run(ch, out, &mut self.blocks, lanes.normals.is_some(), &consts);
                } else {
                    ch.shade = [0; W];
                }
                for l in 0..filled {
                    if ch.shade[l] != 0 {
                        if want_first {
                            self.firsts[ch.id[l] as usize] =
                                FirstHit { albedo: get(&out.first_albedo, l), normal: get(&out.first_normal, l), depth: ch.t[l] };
                        }
                        continue;
                    }
                    // The scalar vertex, on the lane's path.
                    let (mut path, key, id) = lane_path(ch, l);
                    let hit = (ch.hit[l] != 0).then(|| Hit { t: ch.t[l], prim: ch.prim[l], u: ch.u[l], v: ch.v[l] });
                    let first = if want_first { Some(&mut self.firsts[id as usize]) } else { None };
                    let step = ctx.vertex(&mut path, hit, &SampleSampler::from_key(key), first);
                    set_lane_path(ch, l, &path, key, id);
                    out.next[l] = step.next as u32;
                    out.shadow[l] = u32::from(step.shadow.is_some());
                    if let Some((ray, light)) = step.shadow {
                        debug_assert_eq!(ray.tmin, 0.0);
                        put(&mut out.shadow_origin, l, ray.origin);
                        put(&mut out.shadow_dir, l, ray.dir);
                        out.shadow_tmax[l] = ray.tmax;
                        put(&mut out.shadow_light, l, light);
                    }
                }
            }
            self.trace_shadows(tracer, chunks);
            self.compact();
            // The continuation rays, a chunk at a time (packets where the ray caster can trace
            // them with the single rays' bits).
            for c in 0..self.live.div_ceil(W) {
                let filled = (self.live - c * W).min(W);
                let ch = &mut self.chunks[c];
                let rays = RayPacket { origin: ch.origin, dir: ch.dir, tmin: [0.0; W], tmax: [f32::INFINITY; W] };
                let hits = tracer.intersect_packet(&rays, ((1u32 << filled) - 1) as u16);
                (ch.hit, ch.t, ch.u, ch.v, ch.prim) = (hits.hit, hits.t, hits.u, hits.v, hits.prim);
            }
            first_bounce = false;
        }
    }

    /// Traces the bounce's shadow rays, the kernel's and the scalar vertices', a chunk's as one
    /// packet, and adds the light of each unoccluded one to its path.
    fn trace_shadows<T: Intersector>(&mut self, tracer: &T, chunks: usize) {
        for c in 0..chunks {
            let (ch, out) = (&mut self.chunks[c], &self.outs[c]);
            let active = (0..W).filter(|&l| out.shadow[l] != 0).fold(0u16, |m, l| m | 1 << l);
            let rays = RayPacket { origin: out.shadow_origin, dir: out.shadow_dir, tmin: [0.0; W], tmax: out.shadow_tmax };
            let occluded = tracer.occluded_packet(&rays, active);
            for l in (0..W).filter(|&l| (active & !occluded) >> l & 1 != 0) {
                let lit = get(&ch.l, l) + get(&out.shadow_light, l);
                put(&mut ch.l, l, lit);
            }
        }
    }

    /// Records the radiance of every path that ended and moves the last live paths into the
    /// slots they left, so that the live ones fill the first slots again.
    fn compact(&mut self) {
        let mut s = 0;
        while s < self.live {
            let (c, l) = slot(s);
            if self.outs[c].next[l] != 0 {
                s += 1;
                continue;
            }
            let ch = &self.chunks[c];
            self.radiance[ch.id[l] as usize] = get(&ch.l, l);
            self.live -= 1;
            if s < self.live {
                let (cl, ll) = slot(self.live);
                self.move_slot((cl, ll), (c, l));
            }
        }
    }

    /// Copies the path in slot `from` (and whether it goes on) to slot `to`.
    fn move_slot(&mut self, (fc, fl): (usize, usize), (tc, tl): (usize, usize)) {
        let (path, key, id) = lane_path(&self.chunks[fc], fl);
        set_lane_path(&mut self.chunks[tc], tl, &path, key, id);
        self.outs[tc].next[tl] = self.outs[fc].next[fl];
    }

    /// Whether the kernel shaded enough of the vertices this wavefront has seen for following
    /// paths together to pay (it costs some 5–10% where every vertex takes the scalar code).
    /// Undecided (true) until it has seen a few thousand.
    pub fn pays(&self) -> bool {
        self.vertices < PROBE_VERTICES || self.kernel_vertices as f64 >= KERNEL_SHARE * self.vertices as f64
    }

    /// Vertices shaded so far: all, by the kernel, by its glossy lanes, by its glass lanes.
    pub fn vertex_counts(&self) -> [u64; 4] {
        [self.vertices, self.kernel_vertices, self.glossy_vertices, self.glass_vertices]
    }

    /// The radiance of path `i`.
    pub fn radiance(&self, i: usize) -> Vec3A {
        self.radiance[i]
    }

    /// The first-hit features of path `i` (default unless `run` was asked for them).
    pub fn first_hit(&self, i: usize) -> &FirstHit {
        &self.firsts[i]
    }
}

/// The path in lane `l`, its sampler key and its id.
#[inline(always)]
fn lane_path(ch: &Chunk, l: usize) -> (Path, u64, u32) {
    let path = Path {
        ray: Ray { origin: get(&ch.origin, l), dir: get(&ch.dir, l), tmin: 0.0, tmax: f32::INFINITY },
        beta: get(&ch.beta, l),
        l: get(&ch.l, l),
        eta_scale: ch.eta_scale[l],
        prev_pdf: ch.prev_pdf[l],
        prev_delta: ch.prev_delta[l] != 0,
        depth: ch.depth[l],
    };
    (path, ch.key[l], ch.id[l])
}

/// Puts `path` (whose ray must start at `tmin` 0 and have no end) into lane `l`.
#[inline(always)]
fn set_lane_path(ch: &mut Chunk, l: usize, path: &Path, key: u64, id: u32) {
    debug_assert!(path.ray.tmin == 0.0 && path.ray.tmax == f32::INFINITY);
    put(&mut ch.origin, l, path.ray.origin);
    put(&mut ch.dir, l, path.ray.dir);
    put(&mut ch.beta, l, path.beta);
    put(&mut ch.l, l, path.l);
    ch.eta_scale[l] = path.eta_scale;
    ch.prev_pdf[l] = path.prev_pdf;
    ch.prev_delta[l] = path.prev_delta as u32;
    ch.depth[l] = path.depth;
    ch.key[l] = key;
    ch.id[l] = id;
}

/// Sets lane `l`'s hit (index 0 where there is none, so that the kernel reads valid data).
#[inline(always)]
fn set_hit(ch: &mut Chunk, l: usize, hit: Option<Hit>) {
    let h = hit.unwrap_or(Hit { t: 0.0, prim: 0, u: 0.0, v: 0.0 });
    ch.hit[l] = hit.is_some() as u32;
    (ch.t[l], ch.u[l], ch.v[l], ch.prim[l]) = (h.t, h.u, h.v, h.prim);
}

/// Vertices a wavefront shades before [`Wavefront::pays`] decides.
const PROBE_VERTICES: u64 = 4096;
/// The share of vertices the kernel must shade for [`Wavefront::pays`]: render CPU time
/// against following each path on its own, on scenes where it shades 10% of the vertices
/// (bunny-glass) 1.04 ± 0.04, 35% (caustics) 0.99 ± 0.04, 60–70% (glass-of-water, engine,
/// door-ajar) 0.95–0.97, 78% (the Cornell box) 0.87.
const KERNEL_SHARE: f64 = 0.4;

/// The fewest lanes of a chunk the kernel shades (else every lane takes the scalar vertex).
const MIN_SHADED: usize = 4;

/// Marks the first `filled` lanes whose vertex the kernel shades (a hit on a material of its
/// kinds whose light sample, if any, is on an emitter of its kind), and which lanes shade each
/// (diffuse, glossy, glass); copies their records into `blocks` (with the material's textures
/// looked up at the hit) and returns how many there are. Lanes of a kind with fewer than
/// [`MIN_SHADED`] in the chunk are left to the scalar vertex.
#[inline]
fn classify(ctx: &PathContext, lanes: &SceneLanes, ch: &mut Chunk, blocks: &mut Blocks, filled: usize) -> usize {
    let scene = ctx.scene;
    let materials = scene.triangle_materials();
    let (mut diffuse, mut glossy, mut glass) = (0, 0, 0);
    for l in 0..filled {
        (ch.shade[l], ch.flags[l]) = (0, 0);
        if ch.hit[l] == 0 {
            continue;
        }
        let (prim, material) = (ch.prim[l] as usize, materials[ch.prim[l] as usize] as usize);
        let mut kind = lanes.material_kind[material];
        if kind == Kind::Scalar {
            continue;
        }
        // Smooth glass alone samples no light: its only lobe is a delta. (Where a texture makes
        // it something else, the light is sampled below.)
        let mut flags = if kind == Kind::Glass { 0 } else { light_sample(scene, lanes, ch, blocks, l) };
        blocks.triangle[l] = lanes.triangle[prim];
        blocks.material[l] = lanes.material[material];
        if lanes.material_textured[material] {
            // The parameters `Bsdf::at` resolves: the textures at the hit's UV.
            let m = &scene.materials()[material];
            let p = m.params_at(scene.textures(), scene.uv(prim as u32, ch.u[l], ch.v[l]));
            let record = &mut blocks.material[l];
            record[MAT_BASE..MAT_BASE + 3].copy_from_slice(&p.base_color.to_array());
            record[MAT_ALBEDO..MAT_ALBEDO + 3].copy_from_slice(&p.base_color.max(Vec3A::ZERO).to_array());
            (record[MAT_METALLIC], record[MAT_ROUGHNESS]) = (p.metallic, p.roughness);
            if kind == Kind::Glossy && is_diffuse_only(p.metallic, p.transmission, p.specular) {
                kind = Kind::Diffuse;
            }
            if kind == Kind::Glass && !is_smooth_glass(p.metallic, p.roughness, p.transmission, p.ior) {
                kind = Kind::Glossy;
                flags = light_sample(scene, lanes, ch, blocks, l);
            }
        }
        let transmission = lanes.material_transmission[material];
        blocks.transmission[l] = transmission;
        if kind == Kind::Glossy && transmission.clamp(0.0, 1.0) > 0.0 {
            flags |= GLASS_LOBE;
        }
        if let Some(normals) = &lanes.normals {
            blocks.normals[l] = normals[prim];
        }
        ch.shade[l] = 1;
        ch.flags[l] = flags
            | match kind {
                Kind::Glossy => GLOSSY,
                Kind::Glass => GLASS,
                _ => DIFFUSE,
            };
        diffuse += (kind == Kind::Diffuse) as usize;
        glossy += (kind == Kind::Glossy) as usize;
        glass += (kind == Kind::Glass) as usize;
    }
    ch.shade[filled..].fill(0);
    ch.flags[filled..].fill(0);
    // Too few lanes of a kind: their vertices are cheaper one by one.
    for (count, kind) in [(diffuse, DIFFUSE), (glossy, GLOSSY), (glass, GLASS)] {
        if count > 0 && count < MIN_SHADED {
            for l in 0..filled {
                if ch.flags[l] & kind != 0 {
                    (ch.shade[l], ch.flags[l]) = (0, 0);
                }
            }
        }
    }
    ch.shade.iter().filter(|&&s| s != 0).count()
}

/// The light sample of lane `l`'s vertex as the kernel takes it: the chosen emitter's record
/// in `blocks` (or, for a light the kernel does not sample itself, a sample drawn here at the
/// vertex) and the flags that say which.
#[inline(always)]
fn light_sample(scene: &Scene, lanes: &SceneLanes, ch: &Chunk, blocks: &mut Blocks, l: usize) -> u32 {
    let lights = scene.lights();
    let sampler = SampleSampler::from_key(ch.key[l]);
    let vertex = ch.depth[l] - 1;
    let u_select = sampler.get1d(dims::at(vertex, dims::LIGHT_SELECT));
    let Some(k) = lights.choose_index(u_select) else { return 0 };
    if lanes.light_flags[k] != GIVEN {
        blocks.light[l] = lanes.light[k];
        return HAS_LIGHT | lanes.light_flags[k];
    }
    // Other emitters are sampled here, at the point the kernel will shade.
    let p = scene.surface(ch.prim[l], ch.u[l], ch.v[l]).p;
    match lights.sample(scene, p, u_select, sampler.get2d(dims::at(vertex, dims::LIGHT_POS))) {
        Some(ls) => {
            blocks.light[l] = given_light(&ls);
            HAS_LIGHT | GIVEN
        }
        None => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{StreamKind, StreamSampler};
    use crate::scene::lights::{Environment, Punctual};
    use crate::scene::material::Material;
    use crate::scene::texture::Texture;
    use crate::scene::world::Scene;
    use crate::scene::world::SceneParts;
    use crate::settings::PathLimits;
    use crate::testing::{cornell_box, cornell_box_parts, materials_box, materials_box_parts, BruteForce};
    use crate::transport::integrator::radiance_from_hit;
    use glam::{Vec2, Vec3};

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

    /// The material box with textures: UVs on every vertex, a base-colour texture on a diffuse
    /// wall, on the plastic and on the glass, a metallic-roughness texture on the plastic, on a
    /// metal without a specular layer, whose texels of metallic 0 leave it purely diffuse, and
    /// on the glass made metallic, whose texels of metallic 0 (three in four) leave it smooth
    /// glass alone.
    fn textured_box_parts() -> SceneParts {
        let mut parts = materials_box_parts();
        parts.uvs = parts.positions.iter().map(|p| Vec2::new(1.7 * p.x + 0.3 * p.y, 2.3 * p.z - p.y)).collect();
        let texels = |n: usize, f: &dyn Fn(usize) -> Vec3| (0..n).map(f).collect();
        parts.textures = vec![
            Texture::new(5, 3, texels(15, &|i| Vec3::new(0.1 + 0.06 * i as f32, 0.9 - 0.05 * i as f32, (i % 3) as f32 * 0.4))).unwrap(),
            Texture::new(4, 4, texels(16, &|i| Vec3::new(0.0, 0.2 + 0.05 * i as f32, [0.0, 1.0, 0.5, 0.0][i % 4]))).unwrap(),
            Texture::new(4, 4, texels(16, &|i| Vec3::new(0.0, 1.0, [0.0, 0.0, 0.0, 0.7][i % 4]))).unwrap(),
        ];
        parts.materials[0].base_color_texture = Some(0);
        parts.materials[4].base_color_texture = Some(0);
        parts.materials[4].metallic_roughness_texture = Some(1);
        parts.materials[5].metallic_roughness_texture = Some(1);
        parts.materials[5].specular = 0.0;
        parts.materials[6].base_color_texture = Some(0);
        parts.materials[6].metallic_roughness_texture = Some(2);
        parts.materials[6].metallic = 1.0;
        parts
    }

    /// The textured box lit by every kind of light the kernel takes a drawn sample of: a point
    /// light, a spot, a sun, the environment (through the open side) and an emitter with an
    /// emission texture.
    fn lit_box() -> Scene {
        let mut parts = textured_box_parts();
        let v = Vec3A::new;
        parts.lights = vec![
            Punctual::Point { position: v(0.3, 0.6, 0.2), intensity: v(2.0, 1.5, 1.0) },
            Punctual::spot(v(-0.5, 0.8, 0.4), v(0.3, -1.0, -0.2).normalize(), v(3.0, 3.0, 2.0), 0.3, 0.7).unwrap(),
            Punctual::Directional { direction: v(-0.2, -0.3, -1.0).normalize(), irradiance: v(1.0, 0.9, 0.8) },
        ];
        parts.environment = Some(Environment::constant(v(0.3, 0.4, 0.5)).unwrap());
        parts.materials[3].emissive_texture = Some(0);
        Scene::from_parts(parts).expect("the lit box is valid")
    }

    /// The material box with every kind of glass lobe: rough glass, a frosted plastic (part
    /// rough glass) and a half-transmissive smooth glass over a diffuse base (a delta lobe
    /// beside others).
    fn glass_box() -> Scene {
        let mut parts = materials_box_parts();
        parts.materials[6] = Material::glass(1.5, 0.3);
        parts.materials[4].transmission = 0.5;
        parts.materials[4].roughness = 0.4;
        parts.materials[7] = Material { transmission: 0.6, roughness: 0.0, metallic: 0.0, ..Material::diffuse(Vec3A::new(0.9, 0.7, 0.3)) };
        parts.materials[7].specular = 1.0;
        Scene::from_parts(parts).expect("the glass box is valid")
    }

    fn textured_box() -> Scene {
        Scene::from_parts(textured_box_parts()).expect("the textured box is valid")
    }

    /// Every path of a wavefront as `kernel` shades it: radiance and first-hit features.
    fn paths(scene: &Scene, limits: PathLimits, kernel: Option<Kernel>, seed: u64) -> Vec<(Vec3A, FirstHit)> {
        paths_and_wave(scene, limits, kernel, seed, 24).0
    }

    /// [`paths`] on `n`×`n` pixels, and the wavefront that followed them.
    fn paths_and_wave(scene: &Scene, limits: PathLimits, kernel: Option<Kernel>, seed: u64, n: u32) -> (Vec<(Vec3A, FirstHit)>, Wavefront) {
        let tracer = BruteForce::new(scene);
        let frame = scene.camera().frame(n, n);
        let stream = StreamSampler::new(seed, StreamKind::Pt);
        let lanes = SceneLanes::new(scene);
        let mut wave = Wavefront::new(kernel);
        for pixel in 0..n * n {
            for s in 0..2 {
                let smp = stream.sample(pixel as u64, s);
                let ray = frame.ray(pixel % n, pixel / n, smp.get2d(dims::PIXEL));
                wave.push(ray, tracer.intersect(&ray), smp);
            }
        }
        wave.run(&PathContext::new(scene, limits), Some(&lanes), &tracer, true);
        ((0..wave.radiance.len()).map(|i| (wave.radiance(i), *wave.first_hit(i))).collect(), wave)
    }

    /// Each build of the lane kernel this CPU runs gives every path the scalar vertex's radiance
    /// and first-hit features, bit for bit: on the Cornell box (every hit a diffuse lane vertex),
    /// with bent vertex normals, on the material box (diffuse, glossy and glass vertices mixed),
    /// on it with textures, on it lit by every kind of light and on it with every kind of glass
    /// lobe, with and without a depth limit and with Russian roulette from the first bounce.
    #[test]
    fn lanes_give_the_scalar_vertex_bit_for_bit() {
        let builds: Vec<(Isa, Kernel)> =
            [Isa::Portable, Isa::Avx2, Isa::Avx512].into_iter().filter_map(|i| Some((i, i.kernel()?))).collect();
        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
        let scenes = [
            ("cornell", cornell_box()),
            ("bent normals", bent_normals_box()),
            ("materials", materials_box()),
            ("textured", textured_box()),
            ("lit", lit_box()),
            ("glass", glass_box()),
        ];
        for (name, scene) in scenes {
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
                    let (got, wave) = paths_and_wave(&scene, limits, Some(*kernel), 7, 24);
                    let glossy = wave.glossy_vertices as f64 / wave.vertices as f64;
                    let glass = wave.glass_vertices as f64 / wave.vertices as f64;
                    // The glass box's materials with a glass lobe take the glossy lanes too.
                    let least_glossy = if name == "glass" { 0.2 } else { 0.05 };
                    if name != "cornell" && name != "bent normals" {
                        assert!(glossy > least_glossy, "{name}: only {glossy} of the vertices in the glossy lanes");
                    }
                    if name != "cornell" && name != "bent normals" && name != "glass" {
                        assert!(glass > 0.01, "{name}: only {glass} of the vertices in the glass lanes");
                    }
                    for (k, (a, b)) in got.iter().zip(&want).enumerate() {
                        assert_eq!((bits(a.0), a.1), (bits(b.0), b.1), "{name}, {limits:?}: path {k} with the {isa:?} lanes");
                    }
                }
            }
        }
    }

    /// The kernel's builds give the scalar vertex's bits on two bundled scenes: glossy-room
    /// (textured glossy materials, metals, point and spot lights and an area light: most of
    /// its vertices take the glossy lanes, most light samples are drawn before the kernel
    /// runs) and glass-of-water (smooth glass and water: some take the glass lanes).
    #[test]
    fn lanes_give_the_scalar_vertex_bit_for_bit_on_bundled_scenes() {
        // Each scene, whether its lanes to count are the glass lanes (else the glossy ones), and
        // the least share of the vertices they shade.
        for (name, glass, least) in [("glossy-room", false, 0.5), ("glass-of-water", true, 0.03)] {
            let share = |w: &Wavefront| if glass { w.glass_vertices } else { w.glossy_vertices } as f64 / w.vertices as f64;
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}/scene.gltf"));
            let scene = Scene::load(&path).expect("the bundled scene loads");
            let limits = PathLimits { max_depth: -1, rr_depth: 5 };
            let (want, _) = paths_and_wave(&scene, limits, None, 3, 12);
            assert!(want.iter().filter(|(l, _)| *l != Vec3A::ZERO).count() > want.len() / 2, "{name}: too few lit paths to compare");
            let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
            for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
                let Some(kernel) = isa.kernel() else { continue };
                let (got, wave) = paths_and_wave(&scene, limits, Some(kernel), 3, 12);
                assert!(share(&wave) > least, "{name}, {isa:?}: the lanes of its kind shaded {} of the vertices", share(&wave));
                for (k, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert_eq!((bits(a.0), a.1), (bits(b.0), b.1), "{name}: path {k} with the {isa:?} lanes");
                }
            }
        }
    }
}

//! The common vertex of a wavefront, [`W`] paths at a time: a diffuse material without
//! textures, lit by next-event estimation towards an emissive triangle (the Cornell box's
//! every vertex). The arithmetic is that of [`crate::transport::integrator::PathContext::vertex`]
//! on such a vertex, operation by operation and in the same order (glam's `Vec3A` sums its dot
//! products as `(x·x' + y·y') + z·z'`, and so does [`V3::dot`]), with every branch replaced by a
//! select, so that the compiler can run each step on all lanes at once; the result is the same
//! bit for bit, which the tests check against the scalar vertex and the renders check end to
//! end.
//!
//! The kernel is written once, as loops over the lanes of a [`Chunk`] (structure of arrays),
//! and compiled three times (`simd`): for AVX-512, for AVX2 and for any CPU. Rust never fuses
//! a multiplication and an addition on its own, so all three do the same IEEE operations and
//! give the same bits: an image does not depend on the CPU it was rendered on, and a farm's
//! parts from different machines still merge into the one-shot file. What a lane reads of the
//! scene comes as one 16-value record per triangle, material and emitter ([`SceneLanes`]),
//! copied in per lane and turned into structure-of-arrays by a 16×16 transpose in registers
//! ([`Transpose`]): a gather of each value on its own cost several times as much. Nothing here
//! is `unsafe`: the instructions of each build are `simd`'s.
use crate::sampler::dims;
use crate::scene::world::Scene;
use glam::Vec3A;
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4};

/// Lanes per chunk: 16 single-precision values fill one AVX-512 register.
pub(crate) const W: usize = 16;

/// The state of [`W`] paths, structure of arrays: what the kernel reads, and updates in place
/// for the lanes it shades.
#[derive(Clone, Copy)]
pub(crate) struct Chunk {
    /// The ray whose nearest hit is the next vertex (`tmin` 0, `tmax` infinite).
    pub origin: [[f32; W]; 3],
    pub dir: [[f32; W]; 3],
    pub beta: [[f32; W]; 3],
    /// Radiance gathered so far.
    pub l: [[f32; W]; 3],
    pub eta_scale: [f32; W],
    pub prev_pdf: [f32; W],
    /// 1 where the previous bounce was a delta lobe (or the ray is the camera's).
    pub prev_delta: [u32; W],
    /// Segments so far, including the ray.
    pub depth: [u32; W],
    /// The sample's sampler key.
    pub key: [u64; W],
    /// Which of the wavefront's paths the lane holds.
    pub id: [u32; W],
    /// The ray's nearest hit: 1 where there is one; distance, barycentrics, triangle.
    pub hit: [u32; W],
    pub t: [f32; W],
    pub u: [f32; W],
    pub v: [f32; W],
    pub prim: [u32; W],
    /// Set before the kernel runs: 1 where it shades the lane's vertex, and 1 where
    /// next-event estimation samples an emitter there (whose record is in the blocks).
    pub shade: [u32; W],
    pub has_light: [u32; W],
}

impl Default for Chunk {
    fn default() -> Self {
        Chunk {
            origin: [[0.0; W]; 3],
            dir: [[0.0; W]; 3],
            beta: [[0.0; W]; 3],
            l: [[0.0; W]; 3],
            eta_scale: [0.0; W],
            prev_pdf: [0.0; W],
            prev_delta: [0; W],
            depth: [0; W],
            key: [0; W],
            id: [0; W],
            hit: [0; W],
            t: [0.0; W],
            u: [0.0; W],
            v: [0.0; W],
            prim: [0; W],
            shade: [0; W],
            has_light: [0; W],
        }
    }
}

/// What the kernel leaves beside the state, for the lanes it shades.
#[derive(Clone, Copy)]
pub(crate) struct Out {
    /// First-hit features: albedo and shading normal facing the ray (the depth is `t`).
    pub first_albedo: [[f32; W]; 3],
    pub first_normal: [[f32; W]; 3],
    /// 1 where a shadow ray is to be traced: origin, direction, `tmax` (1 towards a point, the
    /// kernel's; infinite towards the environment or a sun), the light it brings.
    pub shadow: [u32; W],
    pub shadow_origin: [[f32; W]; 3],
    pub shadow_dir: [[f32; W]; 3],
    pub shadow_tmax: [f32; W],
    pub shadow_light: [[f32; W]; 3],
    /// 1 where the path goes on (its new ray is in the chunk).
    pub next: [u32; W],
}

impl Default for Out {
    fn default() -> Self {
        Out {
            first_albedo: [[0.0; W]; 3],
            first_normal: [[0.0; W]; 3],
            shadow: [0; W],
            shadow_origin: [[0.0; W]; 3],
            shadow_dir: [[0.0; W]; 3],
            shadow_tmax: [1.0; W],
            shadow_light: [[0.0; W]; 3],
            next: [0; W],
        }
    }
}

/// One record of the scene as the kernel reads it: 16 values, one cache line, so that a lane
/// takes a triangle, a material or an emitter with one copy and a chunk's records are turned
/// into structure-of-arrays by one 16×16 transpose ([`Transpose`]).
pub(crate) type Record = [f32; W];

/// The offsets of a triangle record: its vertices, geometric normal and area density as a light.
const TRI_P: usize = 0;
const TRI_NG: usize = 9;
const TRI_PDF: usize = 12;
/// The offsets of a material record: base colour, the BSDF's albedo (at least 0), emission.
const MAT_BASE: usize = 0;
const MAT_ALBEDO: usize = 3;
const MAT_EMISSION: usize = 6;
/// The offsets of an emitter record: its triangle's vertices and normal, area density, emission.
const LIGHT_P: usize = 0;
const LIGHT_NG: usize = 9;
const LIGHT_PDF: usize = 12;
const LIGHT_EMISSION: usize = 13;

/// The scene as the kernel reads it: a record per triangle (and one of its vertex normals,
/// when the scene has them), per material and per emitter (in selection order), and which
/// materials and emitters are the kernel's (diffuse without texture; a triangle without an
/// emission texture). 64 bytes per triangle, twice that with vertex normals: 34 MB for the
/// 268,041 triangles of the largest validation scene, held while it renders.
pub(crate) struct SceneLanes {
    pub triangle: Vec<Record>,
    pub normals: Option<Vec<Record>>,
    pub material: Vec<Record>,
    pub material_shaded: Vec<bool>,
    pub light: Vec<Record>,
    pub light_sampled: Vec<bool>,
}

fn record(parts: &[(usize, &[f32])]) -> Record {
    let mut r = [0.0; W];
    for (at, values) in parts {
        r[*at..*at + values.len()].copy_from_slice(values);
    }
    r
}

impl SceneLanes {
    pub fn new(scene: &Scene) -> SceneLanes {
        let lights = scene.lights();
        let triangle_record = |p: u32| {
            let [p0, p1, p2] = scene.triangle_vertices(p).map(|v| v.to_array());
            record(&[
                (TRI_P, &p0),
                (TRI_P + 3, &p1),
                (TRI_P + 6, &p2),
                (TRI_NG, &scene.geometric_normal(p).to_array()),
                (TRI_PDF, &[lights.pdf_area(p)]),
            ])
        };
        let triangles = 0..scene.triangles().len() as u32;
        let normals = scene.has_normals().then(|| {
            let n = scene.vertex_normals();
            scene
                .triangles()
                .iter()
                .map(|t| {
                    let [n0, n1, n2] = t.map(|i| n[i as usize].to_array());
                    record(&[(0, &n0), (3, &n1), (6, &n2)])
                })
                .collect()
        });
        let emitters: Vec<Option<u32>> = (0..lights.len()).map(|k| lights.emitter_triangle(k)).collect();
        SceneLanes {
            triangle: triangles.map(triangle_record).collect(),
            normals,
            material: scene
                .materials()
                .iter()
                .map(|m| {
                    record(&[
                        (MAT_BASE, &m.base_color.to_array()),
                        (MAT_ALBEDO, &m.base_color.max(Vec3A::ZERO).to_array()),
                        (MAT_EMISSION, &m.emission.to_array()),
                    ])
                })
                .collect(),
            material_shaded: scene
                .materials()
                .iter()
                .map(|m| m.is_diffuse_only() && m.base_color_texture.is_none() && m.emissive_texture.is_none())
                .collect(),
            light: emitters
                .iter()
                .map(|e| match *e {
                    Some(p) => {
                        let [p0, p1, p2] = scene.triangle_vertices(p).map(|v| v.to_array());
                        record(&[
                            (LIGHT_P, &p0),
                            (LIGHT_P + 3, &p1),
                            (LIGHT_P + 6, &p2),
                            (LIGHT_NG, &scene.geometric_normal(p).to_array()),
                            (LIGHT_PDF, &[lights.pdf_area(p)]),
                            (LIGHT_EMISSION, &scene.material_of(p).emission.to_array()),
                        ])
                    }
                    None => [0.0; W],
                })
                .collect(),
            light_sampled: emitters.iter().map(|e| e.is_some_and(|p| scene.material_of(p).emissive_texture.is_none())).collect(),
        }
    }
}

impl SceneLanes {
    /// Whether the kernel can shade a vertex of this scene at all: some material is its kind,
    /// and so is some emitter (or there are none).
    pub fn can_shade(&self) -> bool {
        self.material_shaded.iter().any(|&m| m) && (self.light_sampled.is_empty() || self.light_sampled.iter().any(|&l| l))
    }
}

/// The records of a chunk's lanes: `[lane][value]` as the caller copies them in, and after
/// [`Transpose`] `[value][lane]` as the kernel reads them.
#[derive(Clone, Copy)]
pub(crate) struct Blocks {
    pub triangle: [Record; W],
    pub normals: [Record; W],
    pub material: [Record; W],
    pub light: [Record; W],
}

impl Default for Blocks {
    fn default() -> Self {
        Blocks { triangle: [[0.0; W]; W], normals: [[0.0; W]; W], material: [[0.0; W]; W], light: [[0.0; W]; W] }
    }
}

/// What every lane shares.
#[derive(Clone, Copy)]
pub(crate) struct Consts {
    pub eps: f32,
    pub max_depth: u32,
    pub rr_depth: u32,
}

/// A 3-vector of scalars whose operations round as glam's `Vec3A` does.
#[derive(Clone, Copy)]
struct V3 {
    x: f32,
    y: f32,
    z: f32,
}

impl V3 {
    #[inline(always)]
    fn lane(a: &[[f32; W]; 3], l: usize) -> V3 {
        V3 { x: a[0][l], y: a[1][l], z: a[2][l] }
    }
    /// Values `at..at + 3` of a transposed block.
    #[inline(always)]
    fn field(b: &[Record; W], at: usize, l: usize) -> V3 {
        V3 { x: b[at][l], y: b[at + 1][l], z: b[at + 2][l] }
    }
    #[inline(always)]
    fn put(self, a: &mut [[f32; W]; 3], l: usize) {
        a[0][l] = self.x;
        a[1][l] = self.y;
        a[2][l] = self.z;
    }
    #[inline(always)]
    fn splat(s: f32) -> V3 {
        V3 { x: s, y: s, z: s }
    }
    #[inline(always)]
    fn dot(self, o: V3) -> f32 {
        (self.x * o.x + self.y * o.y) + self.z * o.z
    }
    #[inline(always)]
    fn add(self, o: V3) -> V3 {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    #[inline(always)]
    fn sub(self, o: V3) -> V3 {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
    #[inline(always)]
    fn mul(self, o: V3) -> V3 {
        V3 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
    #[inline(always)]
    fn scale(self, s: f32) -> V3 {
        V3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    #[inline(always)]
    fn div(self, s: f32) -> V3 {
        V3 { x: self.x / s, y: self.y / s, z: self.z / s }
    }
    #[inline(always)]
    fn neg(self) -> V3 {
        V3 { x: -self.x, y: -self.y, z: -self.z }
    }
    /// `Vec3A != Vec3A::ZERO`.
    #[inline(always)]
    fn nonzero(self) -> bool {
        self.x != 0.0 || self.y != 0.0 || self.z != 0.0
    }
    /// `Vec3A::max_element` (`_mm_max_ps` keeps its second operand unless the first is larger).
    #[inline(always)]
    fn max_element(self) -> f32 {
        let m = |a: f32, b: f32| if a > b { a } else { b };
        m(m(self.x, self.z), m(self.y, self.z))
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
    #[inline(always)]
    fn select(c: bool, a: V3, b: V3) -> V3 {
        V3 { x: if c { a.x } else { b.x }, y: if c { a.y } else { b.y }, z: if c { a.z } else { b.z } }
    }
}

/// `crate::transport::integrator::power_heuristic`.
#[inline(always)]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    let sum = a2 + b2;
    let w = if sum > 0.0 { a2 / sum } else { 0.0 };
    if a2.is_infinite() {
        1.0
    } else {
        w
    }
}

/// `crate::transport::integrator::spawn_origin`.
#[inline(always)]
fn spawn_origin(p: V3, ng: V3, dir: V3, eps: f32) -> V3 {
    V3::select(dir.dot(ng) >= 0.0, p.add(ng.scale(eps)), p.sub(ng.scale(eps)))
}

/// `SampleSampler::get1d` of the sample with key `key`.
#[inline(always)]
fn get1d(key: u64, dim: u32) -> f32 {
    let h = crate::sampler::mix64(key.wrapping_add((dim as u64 + 1).wrapping_mul(GOLDEN)));
    ((h >> 40) as u32) as f32 * INV_2_24
}

/// `SampleSampler::get2d` of the sample with key `key`.
#[inline(always)]
fn get2d(key: u64, dim: u32) -> (f32, f32) {
    let h = crate::sampler::mix64(key.wrapping_add((dim as u64 + 1).wrapping_mul(GOLDEN)) ^ 0x2D00_0000_0000_0000);
    (((h >> 40) as u32) as f32 * INV_2_24, (((h >> 16) & 0xFF_FFFF) as u32) as f32 * INV_2_24)
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;
const INV_2_24: f32 = 1.0 / (1u32 << 24) as f32;

/// `bsdf::lambert::sample`: the cosine-weighted direction of `(ux, uy)`.
#[inline(always)]
fn cosine_direction(ux: f32, uy: f32) -> V3 {
    let (ox, oy) = (2.0 * ux - 1.0, 2.0 * uy - 1.0);
    let centre = ox == 0.0 && oy == 0.0;
    let x_major = ox.abs() > oy.abs();
    let (major, minor) = if x_major { (ox, oy) } else { (oy, ox) };
    let a = FRAC_PI_4 * (minor / major);
    let a2 = a * a;
    let s = a * (1.0 - a2 * (1.0 / 6.0) * (1.0 - a2 * (1.0 / 20.0) * (1.0 - a2 * (1.0 / 42.0))));
    let c = 1.0 - a2 * 0.5 * (1.0 - a2 * (1.0 / 12.0) * (1.0 - a2 * (1.0 / 30.0) * (1.0 - a2 * (1.0 / 56.0))));
    let (cos_t, sin_t) = if x_major { (c, s) } else { (s, c) };
    let (dx, dy, r) = if centre { (0.0, 0.0, 0.0) } else { (major * cos_t, major * sin_t, major.abs()) };
    V3 { x: dx, y: dy, z: (1.0 - r * r).max(0.0).sqrt() }
}

/// The random numbers of one vertex per lane: the BSDF pair, the light-position pair and
/// Russian roulette's.
struct Draws {
    bsdf: [[f32; W]; 2],
    light: [[f32; W]; 2],
    roulette: [f32; W],
}

/// The hashes in a loop of their own: on 64-bit lanes they would halve the width the rest
/// of the vertex runs at.
#[inline(always)]
fn draws(c: &Chunk) -> Draws {
    let mut d = Draws { bsdf: [[0.0; W]; 2], light: [[0.0; W]; 2], roulette: [0.0; W] };
    for l in 0..std::hint::black_box(W).min(W) {
        // Idle lanes hold depth 0; their draws are never read, but must not overflow.
        let (key, vertex) = (c.key[l], c.depth[l].saturating_sub(1));
        (d.bsdf[0][l], d.bsdf[1][l]) = get2d(key, dims::at(vertex, dims::BSDF_DIR));
        (d.light[0][l], d.light[1][l]) = get2d(key, dims::at(vertex, dims::LIGHT_POS));
        d.roulette[l] = get1d(key, dims::at(vertex, dims::RUSSIAN_ROULETTE));
    }
    d
}

/// One lane: the vertex of [`crate::transport::integrator::PathContext::vertex`] for a hit on a
/// diffuse, untextured material whose light sample (if any) is on a triangle. Where the scalar
/// code returns early on `x <= 0`, the lane keeps `!(x <= 0)`: the same side for NaN.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn lane<const NORMALS: bool>(c: &mut Chunk, o: &mut Out, blk: &Blocks, draws: &Draws, k: &Consts, l: usize) {
    let shade = c.shade[l] != 0;
    let d = V3::lane(&c.dir, l);
    let (t, u, v) = (c.t[l], c.u[l], c.v[l]);
    let beta = V3::lane(&c.beta, l);
    let prev_delta = c.prev_delta[l] != 0;
    let depth = c.depth[l];

    // Scene::surface.
    let w = 1.0 - u - v;
    let (p0, p1, p2) = (V3::field(&blk.triangle, TRI_P, l), V3::field(&blk.triangle, TRI_P + 3, l), V3::field(&blk.triangle, TRI_P + 6, l));
    let p = p0.scale(w).add(p1.scale(u)).add(p2.scale(v));
    let ng = V3::field(&blk.triangle, TRI_NG, l);
    let ns = if NORMALS {
        let (n0, n1, n2) = (V3::field(&blk.normals, 0, l), V3::field(&blk.normals, 3, l), V3::field(&blk.normals, 6, l));
        let n = n0.scale(w).add(n1.scale(u)).add(n2.scale(v));
        let len2 = n.dot(n);
        let unit = n.div(len2.sqrt());
        let unit = V3::select(unit.dot(ng) < 0.0, unit.neg(), unit);
        V3::select(len2 > 1e-12 && len2.is_finite(), unit, ng)
    } else {
        ng
    };
    let front = d.dot(ng) < 0.0;

    // Emission, MIS-weighted against light sampling unless the previous bounce was a delta.
    let emission = V3::field(&blk.material, MAT_EMISSION, l);
    let emits = front && emission.max_element() > 0.0;
    let le = V3::select(emits, emission, V3::splat(0.0));
    let cos_l = -d.dot(ng);
    let pdf_light = blk.triangle[TRI_PDF][l] * t * t / cos_l;
    let w_em = if prev_delta { 1.0 } else { power_heuristic(c.prev_pdf[l], pdf_light) };
    let path_l = V3::lane(&c.l, l);
    V3::select(shade && emits, path_l.add(beta.mul(le).scale(w_em)), path_l).put(&mut c.l, l);

    // First-hit features.
    V3::select(ns.dot(d) > 0.0, ns.neg(), ns).put(&mut o.first_normal, l);
    V3::select(le.nonzero(), le, V3::field(&blk.material, MAT_BASE, l)).put(&mut o.first_albedo, l);
    let goes_on = depth < k.max_depth;

    // Bsdf::diffuse: the frame around the shading normal (or the geometric one where the
    // shading normal disagrees with the geometry about the side of `wo`).
    let wo = d.neg();
    let fnrm = V3::select(ns.dot(wo) * ng.dot(wo) <= 0.0, ng, ns);
    let sign = if fnrm.z.is_nan() { f32::NAN } else { 1.0f32.copysign(fnrm.z) };
    let a = -1.0 / (sign + fnrm.z);
    let b = fnrm.x * fnrm.y * a;
    let fs = V3 { x: 1.0 + sign * fnrm.x * fnrm.x * a, y: sign * b, z: -sign * fnrm.x };
    let ft = V3 { x: b, y: sign + fnrm.y * fnrm.y * a, z: -fnrm.y };
    let wo_z = wo.dot(fnrm);
    let side = if wo_z < 0.0 { -1.0 } else { 1.0 };
    let wo_dot_ng = wo.dot(ng);
    let albedo = V3::field(&blk.material, MAT_ALBEDO, l);
    let lit = albedo.max_element() > 0.0;
    let cosine = cosine_direction(draws.bsdf[0][l], draws.bsdf[1][l]);

    // Next-event estimation towards a point on the chosen triangle (`light_sample::sample_area`).
    let (lx, ly) = (draws.light[0][l], draws.light[1][l]);
    let su = lx.sqrt();
    let (ba, bb) = (su * (1.0 - ly), su * ly);
    let (q0, q1, q2) = (V3::field(&blk.light, LIGHT_P, l), V3::field(&blk.light, LIGHT_P + 3, l), V3::field(&blk.light, LIGHT_P + 6, l));
    let point = q0.scale(1.0 - ba - bb).add(q1.scale(ba)).add(q2.scale(bb));
    let to_light = point.sub(p);
    let dist2 = to_light.dot(to_light);
    let n_l = V3::field(&blk.light, LIGHT_NG, l);
    let wi = to_light.div(dist2.sqrt());
    let cos_at_light = -wi.dot(n_l);
    let li = V3::field(&blk.light, LIGHT_EMISSION, l);
    let pdf = blk.light[LIGHT_PDF][l] * dist2 / cos_at_light;
    let sampled = c.has_light[l] != 0 && !(dist2 <= 0.0) && !(cos_at_light <= 0.0) && li.nonzero() && pdf > 0.0;
    // Diffuse::eval_pdf at `wi`.
    let wi_z = wi.dot(fnrm);
    let geometric_reflection = wi.dot(ng) * wo_dot_ng > 0.0;
    let shading_reflection = wi_z * wo_z > 0.0;
    let (o_z, i_z) = (wo_z * side, wi_z * side);
    let reflects = geometric_reflection == shading_reflection && wi_z != 0.0 && shading_reflection && lit && o_z > 0.0 && i_z > 0.0;
    let f = V3::select(reflects, albedo.scale(FRAC_1_PI).scale(wi_z.abs()), V3::splat(0.0));
    let pdf_bsdf = if reflects { i_z * FRAC_1_PI } else { 0.0 };
    let origin = spawn_origin(p, ng, wi, k.eps);
    let target = point.add(n_l.scale(k.eps));
    o.shadow[l] = (shade && goes_on && lit && sampled && f.nonzero()) as u32;
    origin.put(&mut o.shadow_origin, l);
    target.sub(origin).put(&mut o.shadow_dir, l);
    let w_light = power_heuristic(pdf, pdf_bsdf);
    beta.mul(f).mul(li).scale(w_light / pdf).put(&mut o.shadow_light, l);

    // Diffuse::sample_drawn, then the throughput and Russian roulette.
    let wi_l = V3 { x: cosine.x, y: cosine.y, z: cosine.z * side };
    let next_dir = fs.scale(wi_l.x).add(ft.scale(wi_l.y)).add(fnrm.scale(wi_l.z));
    let scattered = lit && !(wi_l.z == 0.0 || next_dir.dot(ng) * wo_dot_ng <= 0.0);
    let next_beta = beta.mul(albedo);
    let carries = next_beta.nonzero() && next_beta.is_finite();
    // `eta_scale *= bs.eta²` with a diffuse lobe's η = 1 changes no bit.
    let roulette = depth >= k.rr_depth;
    let q = (next_beta.max_element() * c.eta_scale[l]).min(0.95);
    let survives = !(draws.roulette[l] >= q);
    let next = shade && goes_on && scattered && carries && (!roulette || survives);
    o.next[l] = next as u32;
    V3::select(next, V3::select(roulette, next_beta.div(q), next_beta), beta).put(&mut c.beta, l);
    c.prev_pdf[l] = if next { wi_l.z.abs() * FRAC_1_PI } else { c.prev_pdf[l] };
    c.prev_delta[l] = if next { 0 } else { c.prev_delta[l] };
    c.depth[l] = if next { depth + 1 } else { depth };
    V3::select(next, spawn_origin(p, ng, next_dir, k.eps), V3::lane(&c.origin, l)).put(&mut c.origin, l);
    V3::select(next, next_dir, d).put(&mut c.dir, l);
}

#[inline(always)]
fn lanes<const NORMALS: bool>(c: &mut Chunk, o: &mut Out, b: &Blocks, k: &Consts) {
    let d = draws(c);
    // A trip count the compiler cannot see: a known 16 gets the loop fully unrolled before
    // the loop vectoriser runs, which then has nothing to vectorise.
    let n = std::hint::black_box(W).min(W);
    for l in 0..n {
        lane::<NORMALS>(c, o, b, &d, k, l);
    }
}

/// Turns a block of records `[lane][value]` into `[value][lane]`. Pure data movement, so every
/// build gives the same values. Implemented by each build's CPU-feature token (`simd`), which
/// [`shade`] passes on.
pub(crate) trait Transpose: Copy {
    fn transpose(self, block: &mut [Record; W]);
}

/// The kernel: shades the lanes of `c` whose `shade` is set, from the records the caller copied
/// into `b` (which it transposes in place; vertex normals only if `normals`). Each build
/// compiles it, inlined, for its own instructions (`simd`).
#[inline(always)]
pub(crate) fn shade<T: Transpose>(isa: T, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
    isa.transpose(&mut b.triangle);
    isa.transpose(&mut b.material);
    isa.transpose(&mut b.light);
    if normals {
        isa.transpose(&mut b.normals);
        lanes::<true>(c, o, b, k)
    } else {
        lanes::<false>(c, o, b, k)
    }
}

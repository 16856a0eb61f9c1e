//! The common vertices of a wavefront, [`W`] paths at a time, in three kinds of lanes: a
//! diffuse material ([`lane`], the Cornell box's every vertex) and any other glTF material
//! ([`glossy_lane`]: diffuse, GGX specular, metal and glass lobes, rough or smooth), both with
//! their textures looked up beforehand, lit by next-event estimation towards an emissive
//! triangle (worked out in the lane) or any other light (its sample drawn beforehand); and
//! smooth glass alone ([`glass_lane`]: reflect or refract, no light sample). The
//! arithmetic is that of [`crate::transport::integrator::PathContext::vertex`] on such a
//! vertex, operation by operation and in the same order (glam's `Vec3A` sums its dot products
//! as `(x·x' + y·y') + z·z'`, and so does [`V3::dot`]), with every branch replaced by a select,
//! so that the compiler can run each step on all lanes at once; the result is the same bit for
//! bit, which the tests check against the scalar vertex and the renders check end to end.
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
use crate::scene::lights::{Emitter, Punctual};
use crate::scene::world::Scene;
use crate::transport::bsdf::ggx::MIN_ALPHA;
use crate::transport::bsdf::pbr::{dielectric_layer, is_smooth_glass};
use crate::transport::light_sample::{LightSample, ShadowEnd};
use glam::Vec3A;
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4, PI};

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
    /// Set before the kernel runs: 1 where it shades the lane's vertex.
    pub shade: [u32; W],
    /// Set before the kernel runs, what it reads of the lane: [`DIFFUSE`] or [`GLOSSY`] (which
    /// lanes shade it), [`HAS_LIGHT`] (next-event estimation samples an emitter, whose record
    /// is in the blocks) and [`GIVEN`] (that sample was drawn before the kernel ran). One
    /// array rather than four: every array the loop reads is one more dependence for the
    /// compiler to check before it runs the loop on all lanes at once, and past a limit it
    /// gives up.
    pub flags: [u32; W],
}

/// The bits of [`Chunk::flags`].
pub(crate) const DIFFUSE: u32 = 1;
pub(crate) const GLOSSY: u32 = 2;
pub(crate) const HAS_LIGHT: u32 = 4;
/// The light sample's record is a [`given_light`] record: the environment, an emitter with an
/// emission texture.
pub(crate) const GIVEN: u32 = 8;
/// The chosen light is a point light, a spot or a directional light (a [`punctual_light`]
/// record), sampled in the lane.
pub(crate) const POINT: u32 = 16;
pub(crate) const SPOT: u32 = 32;
pub(crate) const SUN: u32 = 64;
/// The glass lanes shade the lane.
pub(crate) const GLASS: u32 = 128;
/// The lane's glossy material has a glass lobe (its transmission is in [`Blocks::transmission`]).
pub(crate) const GLASS_LOBE: u32 = 256;
/// The lights other than emitter triangles.
const OTHER_LIGHTS: u32 = GIVEN | POINT | SPOT | SUN;

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
            flags: [0; W],
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

impl Out {
    /// Lane `l` of `from`.
    #[inline(always)]
    fn take_lane(&mut self, from: &Out, l: usize) {
        for i in 0..3 {
            self.first_albedo[i][l] = from.first_albedo[i][l];
            self.first_normal[i][l] = from.first_normal[i][l];
            self.shadow_origin[i][l] = from.shadow_origin[i][l];
            self.shadow_dir[i][l] = from.shadow_dir[i][l];
            self.shadow_light[i][l] = from.shadow_light[i][l];
        }
        self.shadow[l] = from.shadow[l];
        self.shadow_tmax[l] = from.shadow_tmax[l];
        self.next[l] = from.next[l];
    }
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
/// The offsets of a material record: base colour, the BSDF's albedo (the base colour, at least
/// 0), emission; for the glossy lanes the dielectric layer's `F0` and strength
/// (`pbr::dielectric_layer`), metallic and roughness; for the glass lanes the index of
/// refraction (at least 1). Base colour, albedo, metallic and roughness are those at the hit
/// where the material has textures (`classify` looks them up).
pub(crate) const MAT_BASE: usize = 0;
pub(crate) const MAT_ALBEDO: usize = 3;
const MAT_EMISSION: usize = 6;
const MAT_F0: usize = 9;
const MAT_SPECULAR: usize = 12;
pub(crate) const MAT_METALLIC: usize = 13;
pub(crate) const MAT_ROUGHNESS: usize = 14;
const MAT_ETA: usize = 15;
/// The offsets of an emitter record: its triangle's vertices and normal, area density, emission.
const LIGHT_P: usize = 0;
const LIGHT_NG: usize = 9;
const LIGHT_PDF: usize = 12;
const LIGHT_EMISSION: usize = 13;
/// The offsets of a light sample drawn before the kernel ran: direction, radiance, density,
/// whether it is a delta, the shadow ray's end and whether it has none (a direction).
const GIVEN_WI: usize = 0;
const GIVEN_LI: usize = 3;
const GIVEN_PDF: usize = 6;
const GIVEN_DELTA: usize = 7;
const GIVEN_TARGET: usize = 8;
const GIVEN_INFINITE: usize = 11;

/// The offsets of a punctual light's record: position, direction (a spot's axis, a sun's
/// direction of travel), intensity (a sun's irradiance), a spot's cone cosines, the light's
/// selection probability.
const PUNCTUAL_POSITION: usize = 0;
const PUNCTUAL_DIRECTION: usize = 3;
const PUNCTUAL_INTENSITY: usize = 6;
const PUNCTUAL_COS_INNER: usize = 9;
const PUNCTUAL_COS_OUTER: usize = 10;
const PUNCTUAL_PROBABILITY: usize = 11;

/// A punctual light's record and its flag.
fn punctual_light(light: &Punctual, probability: f32) -> (Record, u32) {
    let (position, direction, intensity, cones, flag) = match *light {
        Punctual::Point { position, intensity } => (position, Vec3A::ZERO, intensity, [0.0, 0.0], POINT),
        Punctual::Spot { position, direction, intensity, cos_inner, cos_outer } => {
            (position, direction, intensity, [cos_inner, cos_outer], SPOT)
        }
        Punctual::Directional { direction, irradiance } => (Vec3A::ZERO, direction, irradiance, [0.0, 0.0], SUN),
    };
    let r = record(&[
        (PUNCTUAL_POSITION, &position.to_array()),
        (PUNCTUAL_DIRECTION, &direction.to_array()),
        (PUNCTUAL_INTENSITY, &intensity.to_array()),
        (PUNCTUAL_COS_INNER, &cones),
        (PUNCTUAL_PROBABILITY, &[probability]),
    ]);
    (r, flag)
}

/// The record of a light sample drawn before the kernel ran (`LightSet::sample`).
pub(crate) fn given_light(ls: &LightSample) -> Record {
    let (target, infinite) = match ls.end {
        ShadowEnd::Point(target) => (target, 0.0),
        ShadowEnd::Infinite => (Vec3A::ZERO, 1.0),
    };
    record(&[
        (GIVEN_WI, &ls.wi.to_array()),
        (GIVEN_LI, &ls.li.to_array()),
        (GIVEN_PDF, &[ls.pdf]),
        (GIVEN_DELTA, &[if ls.delta { 1.0 } else { 0.0 }]),
        (GIVEN_TARGET, &target.to_array()),
        (GIVEN_INFINITE, &[infinite]),
    ])
}

/// Which lanes shade a material's vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// The scalar vertex: an emission texture.
    Scalar,
    /// The diffuse lanes: the diffuse lobe alone (`pbr::Bsdf::Diffuse`).
    Diffuse,
    /// The glossy lanes: a mixture of diffuse, specular layer, metal and glass
    /// (`pbr::Mixture`), or the diffuse lanes at texels where its metallic-roughness texture
    /// leaves the diffuse lobe alone.
    Glossy,
    /// The glass lanes: a smooth dielectric alone (`pbr::is_smooth_glass`) at the hit; a
    /// material with a metallic-roughness texture takes the glossy lanes at texels where it
    /// is something else.
    Glass,
}

/// The scene as the kernel reads it: a record per triangle (and one of its vertex normals,
/// when the scene has them), per material and per emitter (in selection order), and which
/// materials are the kernel's (opaque, without an emission texture) and which emitters it
/// samples itself (a triangle without an emission texture). 64 bytes per triangle, twice that with vertex normals: 34 MB
/// for the 268,041 triangles of the largest validation scene, held while it renders.
pub(crate) struct SceneLanes {
    pub triangle: Vec<Record>,
    pub normals: Option<Vec<Record>>,
    pub material: Vec<Record>,
    pub material_kind: Vec<Kind>,
    /// Whether a material has a base-colour or metallic-roughness texture to look up per hit.
    pub material_textured: Vec<bool>,
    /// Each material's transmission (its glass lobe's share).
    pub material_transmission: Vec<f32>,
    pub light: Vec<Record>,
    /// How the kernel samples each emitter: 0 for a triangle it samples itself (untextured),
    /// [`POINT`], [`SPOT`] or [`SUN`] for a punctual light it samples itself, [`GIVEN`] for one
    /// whose samples are drawn before it runs.
    pub light_flags: Vec<u32>,
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
        let (light, light_flags) = (0..lights.len())
            .map(|k| match lights.emitter(k) {
                Emitter::Triangle(p) if scene.material_of(p).emissive_texture.is_none() => {
                    let [p0, p1, p2] = scene.triangle_vertices(p).map(|v| v.to_array());
                    let r = record(&[
                        (LIGHT_P, &p0),
                        (LIGHT_P + 3, &p1),
                        (LIGHT_P + 6, &p2),
                        (LIGHT_NG, &scene.geometric_normal(p).to_array()),
                        (LIGHT_PDF, &[lights.pdf_area(p)]),
                        (LIGHT_EMISSION, &scene.material_of(p).emission.to_array()),
                    ]);
                    (r, 0)
                }
                Emitter::Punctual(i) => punctual_light(&lights.punctual()[i as usize], lights.punctual_probability(i as usize)),
                Emitter::Triangle(_) | Emitter::Environment => ([0.0; W], GIVEN),
            })
            .unzip();
        SceneLanes {
            triangle: triangles.map(triangle_record).collect(),
            normals,
            material: scene
                .materials()
                .iter()
                .map(|m| {
                    let (f0, specular) = dielectric_layer(m.ior, m.specular_color, m.specular);
                    record(&[
                        (MAT_BASE, &m.base_color.to_array()),
                        (MAT_ALBEDO, &m.base_color.max(Vec3A::ZERO).to_array()),
                        (MAT_EMISSION, &m.emission.to_array()),
                        (MAT_F0, &f0.to_array()),
                        (MAT_SPECULAR, &[specular]),
                        (MAT_METALLIC, &[m.metallic]),
                        (MAT_ROUGHNESS, &[m.roughness]),
                        (MAT_ETA, &[m.ior.max(1.0)]),
                    ])
                })
                .collect(),
            material_kind: scene
                .materials()
                .iter()
                .map(|m| match () {
                    _ if m.emissive_texture.is_some() => Kind::Scalar,
                    _ if m.is_diffuse_only() => Kind::Diffuse,
                    // A metallic-roughness texture may make glass smooth and not metallic at
                    // some texels, which `classify` checks.
                    _ if is_smooth_glass(m.metallic, m.roughness, m.transmission, m.ior)
                        || (m.transmission.clamp(0.0, 1.0) == 1.0 && m.metallic_roughness_texture.is_some()) =>
                    {
                        Kind::Glass
                    }
                    _ => Kind::Glossy,
                })
                .collect(),
            material_textured: scene
                .materials()
                .iter()
                .map(|m| m.base_color_texture.is_some() || m.metallic_roughness_texture.is_some())
                .collect(),
            material_transmission: scene.materials().iter().map(|m| m.transmission).collect(),
            light,
            light_flags,
        }
    }
}

impl SceneLanes {
    /// Whether the kernel can shade a vertex of this scene at all: some material is its kind.
    pub fn can_shade(&self) -> bool {
        self.material_kind.iter().any(|&m| m != Kind::Scalar)
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
    /// The transmission of the glossy lanes' materials (read where a lane has [`GLASS_LOBE`]).
    pub transmission: [f32; W],
    /// What the glossy or the glass lanes leave, before it goes into the chunk's [`Out`] (see
    /// [`shade`]).
    pub scratch_out: Out,
}

impl Default for Blocks {
    fn default() -> Self {
        Blocks {
            triangle: [[0.0; W]; W],
            normals: [[0.0; W]; W],
            material: [[0.0; W]; W],
            light: [[0.0; W]; W],
            transmission: [0.0; W],
            scratch_out: Out::default(),
        }
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

/// The surface point at the lane's hit (`Scene::surface`): position, geometric normal and
/// shading normal.
#[inline(always)]
fn surface<const NORMALS: bool>(c: &Chunk, blk: &Blocks, l: usize) -> (V3, V3, V3) {
    let (u, v) = (c.u[l], c.v[l]);
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
    (p, ng, ns)
}

/// What every kind of lane starts a vertex with: whether the lane is its kind (`flag`), the
/// ray's direction, the path's throughput, the surface at the hit (position, geometric and
/// shading normal), whether the path may go on from it; the hit's emission and first-hit
/// features already in place.
struct Arrival {
    shade: bool,
    d: V3,
    beta: V3,
    p: V3,
    ng: V3,
    ns: V3,
    goes_on: bool,
}

#[inline(always)]
fn arrive<const NORMALS: bool>(c: &mut Chunk, o: &mut Out, blk: &Blocks, k: &Consts, l: usize, flag: u32) -> Arrival {
    let shade = c.flags[l] & flag != 0;
    let d = V3::lane(&c.dir, l);
    let beta = V3::lane(&c.beta, l);
    let (p, ng, ns) = surface::<NORMALS>(c, blk, l);
    emission_and_features(c, o, blk, l, shade, ng, ns);
    Arrival { shade, d, beta, p, ng, ns, goes_on: c.depth[l] < k.max_depth }
}

/// The hit's emission, MIS-weighted against light sampling unless the previous bounce was a
/// delta, added to the path's radiance where `shade`; then the first-hit features (albedo:
/// the emission where there is some, else the base colour; the shading normal facing the ray).
#[inline(always)]
fn emission_and_features(c: &mut Chunk, o: &mut Out, blk: &Blocks, l: usize, shade: bool, ng: V3, ns: V3) {
    let (d, t, beta) = (V3::lane(&c.dir, l), c.t[l], V3::lane(&c.beta, l));
    let front = d.dot(ng) < 0.0;
    let emission = V3::field(&blk.material, MAT_EMISSION, l);
    let emits = front && emission.max_element() > 0.0;
    let le = V3::select(emits, emission, V3::splat(0.0));
    let cos_l = -d.dot(ng);
    let pdf_light = blk.triangle[TRI_PDF][l] * t * t / cos_l;
    let w_em = if c.prev_delta[l] != 0 { 1.0 } else { power_heuristic(c.prev_pdf[l], pdf_light) };
    let path_l = V3::lane(&c.l, l);
    V3::select(shade && emits, path_l.add(beta.mul(le).scale(w_em)), path_l).put(&mut c.l, l);
    V3::select(ns.dot(d) > 0.0, ns.neg(), ns).put(&mut o.first_normal, l);
    V3::select(le.nonzero(), le, V3::field(&blk.material, MAT_BASE, l)).put(&mut o.first_albedo, l);
}

/// The shading frame (`Frame::from_normal`, glam's `any_orthonormal_pair`) around `wo`'s side
/// of the shading normal, or around the geometric normal where the shading normal disagrees
/// with the geometry about the side of `wo`: its tangents and normal.
#[inline(always)]
fn shading_frame(ns: V3, ng: V3, wo: V3) -> (V3, V3, V3) {
    let n = V3::select(ns.dot(wo) * ng.dot(wo) <= 0.0, ng, ns);
    let sign = if n.z.is_nan() { f32::NAN } else { 1.0f32.copysign(n.z) };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = V3 { x: 1.0 + sign * n.x * n.x * a, y: sign * b, z: -sign * n.x };
    let t = V3 { x: b, y: sign + n.y * n.y * a, z: -n.y };
    (s, t, n)
}

/// The lane's light sample: a point on its chosen emitter triangle (`light_sample::sample_area`)
/// seen from `p`, or the sample drawn before the kernel ran.
struct LightPoint {
    wi: V3,
    li: V3,
    pdf: f32,
    delta: bool,
    /// The shadow ray's end, unless it is `infinite` (a direction).
    target: V3,
    infinite: bool,
    /// Whether the sample is usable (an emitter was chosen, it faces `p`, it emits).
    sampled: bool,
}

#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn light_point<const OTHER: bool>(c: &Chunk, blk: &Blocks, draws: &Draws, l: usize, p: V3, eps: f32) -> LightPoint {
    let (lx, ly) = (draws.light[0][l], draws.light[1][l]);
    let su = lx.sqrt();
    let (ba, bb) = (su * (1.0 - ly), su * ly);
    let (q0, q1, q2) = (V3::field(&blk.light, LIGHT_P, l), V3::field(&blk.light, LIGHT_P + 3, l), V3::field(&blk.light, LIGHT_P + 6, l));
    let point = q0.scale(1.0 - ba - bb).add(q1.scale(ba)).add(q2.scale(bb));
    let to_light = point.sub(p);
    let dist2 = to_light.dot(to_light);
    let normal = V3::field(&blk.light, LIGHT_NG, l);
    let wi = to_light.div(dist2.sqrt());
    let cos_at_light = -wi.dot(normal);
    let li = V3::field(&blk.light, LIGHT_EMISSION, l);
    let pdf = blk.light[LIGHT_PDF][l] * dist2 / cos_at_light;
    let on_triangle = !(dist2 <= 0.0) && !(cos_at_light <= 0.0) && li.nonzero() && pdf > 0.0;
    // `Punctual::sample_li` where the light is punctual.
    let flags = c.flags[l];
    let (spot, sun) = (flags & SPOT != 0, flags & SUN != 0);
    let position = V3::field(&blk.light, PUNCTUAL_POSITION, l);
    let direction = V3::field(&blk.light, PUNCTUAL_DIRECTION, l);
    let intensity = V3::field(&blk.light, PUNCTUAL_INTENSITY, l);
    let to_punctual = position.sub(p);
    let dist2_punctual = to_punctual.dot(to_punctual);
    let wi_punctual = to_punctual.div(dist2_punctual.sqrt());
    let (cos_inner, cos_outer) = (blk.light[PUNCTUAL_COS_INNER][l], blk.light[PUNCTUAL_COS_OUTER][l]);
    let ramp = ((-wi_punctual.dot(direction) - cos_outer) * (1.0 / (cos_inner - cos_outer).max(1e-3))).clamp(0.0, 1.0);
    let falloff = ramp * ramp;
    let li_punctual =
        V3::select(sun, intensity, V3::select(spot, intensity.scale(falloff / dist2_punctual), intensity.div(dist2_punctual)));
    let lit = if sun {
        true
    } else if spot {
        !(dist2_punctual <= 0.0) && falloff > 0.0
    } else {
        dist2_punctual > 0.0
    };
    // Without other lights in the chunk (`OTHER` false), the selects fold away.
    let punctual = OTHER && flags & (POINT | SPOT | SUN) != 0;
    let given = OTHER && flags & GIVEN != 0;
    let wi = V3::select(punctual, V3::select(sun, direction.neg(), wi_punctual), wi);
    let li = V3::select(punctual, li_punctual, li);
    LightPoint {
        wi: V3::select(given, V3::field(&blk.light, GIVEN_WI, l), wi),
        li: V3::select(given, V3::field(&blk.light, GIVEN_LI, l), li),
        pdf: if given {
            blk.light[GIVEN_PDF][l]
        } else if punctual {
            blk.light[PUNCTUAL_PROBABILITY][l]
        } else {
            pdf
        },
        delta: punctual || (given && blk.light[GIVEN_DELTA][l] != 0.0),
        target: V3::select(given, V3::field(&blk.light, GIVEN_TARGET, l), V3::select(punctual, position, point.add(normal.scale(eps)))),
        infinite: (punctual && sun) || (given && blk.light[GIVEN_INFINITE][l] != 0.0),
        sampled: flags & HAS_LIGHT != 0 && (given || if punctual { lit && li_punctual.nonzero() } else { on_triangle }),
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn shadow_ray(o: &mut Out, l: usize, cast: bool, ls: &LightPoint, p: V3, ng: V3, beta: V3, f: V3, pdf_bsdf: f32, eps: f32) {
    let origin = spawn_origin(p, ng, ls.wi, eps);
    o.shadow[l] = cast as u32;
    origin.put(&mut o.shadow_origin, l);
    V3::select(ls.infinite, ls.wi, ls.target.sub(origin)).put(&mut o.shadow_dir, l);
    o.shadow_tmax[l] = if ls.infinite { f32::INFINITY } else { 1.0 };
    let w_light = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf_bsdf) };
    beta.mul(f).mul(ls.li).scale(w_light / ls.pdf).put(&mut o.shadow_light, l);
}

/// The sampled continuation of a vertex: where `scattered`, a direction `dir` with density
/// `pdf` (0 for a delta lobe, `delta`), throughput `beta` and relative index `eta`; and the
/// vertex's draw for Russian roulette.
struct Scatter {
    scattered: bool,
    dir: V3,
    beta: V3,
    pdf: f32,
    delta: bool,
    eta: f32,
    roulette: f32,
}

/// The path's next segment: the throughput check and Russian roulette of
/// `PathContext::vertex` on the continuation `s`, then the new ray in the lane (else the
/// lane's path is kept as it was).
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn continue_path(c: &mut Chunk, o: &mut Out, k: &Consts, l: usize, p: V3, ng: V3, s: Scatter) {
    let Scatter { scattered, dir: next_dir, beta: next_beta, pdf, delta, eta, roulette: roulette_draw } = s;
    let depth = c.depth[l];
    let carries = next_beta.nonzero() && next_beta.is_finite();
    // With the opaque lobes' η, a constant 1, the product folds away.
    let eta_scale = c.eta_scale[l] * (eta * eta);
    let roulette = depth >= k.rr_depth;
    let q = (next_beta.max_element() * eta_scale).min(0.95);
    let survives = !(roulette_draw >= q);
    let next = scattered && carries && (!roulette || survives);
    o.next[l] = next as u32;
    let beta = V3::lane(&c.beta, l);
    V3::select(next, V3::select(roulette, next_beta.div(q), next_beta), beta).put(&mut c.beta, l);
    c.eta_scale[l] = if next { eta_scale } else { c.eta_scale[l] };
    c.prev_pdf[l] = if next { pdf } else { c.prev_pdf[l] };
    c.prev_delta[l] = if next { delta as u32 } else { c.prev_delta[l] };
    c.depth[l] = if next { depth + 1 } else { depth };
    V3::select(next, spawn_origin(p, ng, next_dir, k.eps), V3::lane(&c.origin, l)).put(&mut c.origin, l);
    V3::select(next, next_dir, V3::lane(&c.dir, l)).put(&mut c.dir, l);
}

/// One lane: the vertex of [`crate::transport::integrator::PathContext::vertex`] for a hit on a
/// diffuse material whose light sample (if any) is on a triangle. Where the scalar code
/// returns early on `x <= 0`, the lane keeps `!(x <= 0)`: the same side for NaN.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn lane<const NORMALS: bool, const OTHER: bool>(c: &mut Chunk, o: &mut Out, blk: &Blocks, draws: &Draws, k: &Consts, l: usize) {
    let Arrival { shade, d, beta, p, ng, ns, goes_on } = arrive::<NORMALS>(c, o, blk, k, l, DIFFUSE);

    // Bsdf::diffuse.
    let wo = d.neg();
    let (fs, ft, fnrm) = shading_frame(ns, ng, wo);
    let wo_z = wo.dot(fnrm);
    let side = if wo_z < 0.0 { -1.0 } else { 1.0 };
    let wo_dot_ng = wo.dot(ng);
    let albedo = V3::field(&blk.material, MAT_ALBEDO, l);
    let lit = albedo.max_element() > 0.0;

    // Next-event estimation, with Diffuse::eval_pdf at the light's direction.
    let ls = light_point::<OTHER>(c, blk, draws, l, p, k.eps);
    let wi_z = ls.wi.dot(fnrm);
    let geometric_reflection = ls.wi.dot(ng) * wo_dot_ng > 0.0;
    let shading_reflection = wi_z * wo_z > 0.0;
    let (o_z, i_z) = (wo_z * side, wi_z * side);
    let reflects = geometric_reflection == shading_reflection && wi_z != 0.0 && shading_reflection && lit && o_z > 0.0 && i_z > 0.0;
    let f = V3::select(reflects, albedo.scale(FRAC_1_PI).scale(wi_z.abs()), V3::splat(0.0));
    let pdf_bsdf = if reflects { i_z * FRAC_1_PI } else { 0.0 };
    shadow_ray(o, l, shade && goes_on && lit && ls.sampled && f.nonzero(), &ls, p, ng, beta, f, pdf_bsdf, k.eps);

    // Diffuse::sample_drawn, then the throughput and Russian roulette.
    let cosine = cosine_direction(draws.bsdf[0][l], draws.bsdf[1][l]);
    let wi_l = V3 { x: cosine.x, y: cosine.y, z: cosine.z * side };
    let next_dir = fs.scale(wi_l.x).add(ft.scale(wi_l.y)).add(fnrm.scale(wi_l.z));
    let scattered = lit && !(wi_l.z == 0.0 || next_dir.dot(ng) * wo_dot_ng <= 0.0);
    let s = Scatter {
        scattered: shade && goes_on && scattered,
        dir: next_dir,
        beta: beta.mul(albedo),
        pdf: wi_l.z.abs() * FRAC_1_PI,
        delta: false,
        eta: 1.0,
        roulette: draws.roulette[l],
    };
    continue_path(c, o, k, l, p, ng, s);
}

/// The glossy lanes' extra random numbers: the lobe choice, the cosine and sine of the GGX
/// sample's azimuth (`Ggx::sample_visible`), whose library calls stay out of the lane loop,
/// and (with a glass lobe) the choice between reflection and refraction.
struct GlossyDraws {
    lobe: [f32; W],
    cos_phi: [f32; W],
    sin_phi: [f32; W],
    choice: [f32; W],
}

#[inline(always)]
fn glossy_draws<const GLASS: bool>(c: &Chunk, d: &Draws) -> GlossyDraws {
    let mut g = GlossyDraws { lobe: [0.0; W], cos_phi: [0.0; W], sin_phi: [0.0; W], choice: [0.0; W] };
    for l in 0..W {
        let (key, vertex) = (c.key[l], c.depth[l].saturating_sub(1));
        g.lobe[l] = get1d(key, dims::at(vertex, dims::LOBE));
        if GLASS {
            g.choice[l] = get1d(key, dims::at(vertex, dims::DIELECTRIC_CHOICE));
        }
        let phi = 2.0 * PI * d.bsdf[1][l];
        g.cos_phi[l] = phi.cos();
        g.sin_phi[l] = phi.sin();
    }
    g
}

/// `vector::unit`: `v` times the reciprocal of its length.
#[inline(always)]
fn unit(v: V3) -> V3 {
    v.scale(1.0 / v.dot(v).sqrt())
}

/// `fresnel::schlick`.
#[inline(always)]
fn schlick(f0: V3, f90: f32, cos: f32) -> V3 {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0.add(V3::splat(f90).sub(f0).scale(m))
}

/// `vector::luminance`.
#[inline(always)]
fn luminance(c: V3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// `Ggx::d`.
#[inline(always)]
fn ggx_d(alpha: f32, h: V3) -> f32 {
    let cos2 = h.z * h.z;
    let tan2 = (h.x * h.x + h.y * h.y) / cos2;
    let a2 = alpha * alpha;
    let e = 1.0 + tan2 / a2;
    let d = 1.0 / (PI * a2 * cos2 * cos2 * e * e);
    if h.z <= 0.0 {
        0.0
    } else {
        d
    }
}

/// `Ggx::lambda`.
#[inline(always)]
fn ggx_lambda(alpha: f32, w: V3) -> f32 {
    let cos2 = w.z * w.z;
    let tan2 = (w.x * w.x + w.y * w.y) / cos2;
    let lambda = 0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0);
    if cos2 == 0.0 {
        f32::INFINITY
    } else {
        lambda
    }
}

/// `Ggx::pdf_visible`.
#[inline(always)]
fn ggx_pdf_visible(alpha: f32, wo: V3, h: V3) -> f32 {
    let wo = V3::select(wo.z < 0.0, wo.neg(), wo);
    let pdf = 1.0 / (1.0 + ggx_lambda(alpha, wo)) * wo.dot(h).max(0.0) * ggx_d(alpha, h) / wo.z;
    if wo.z == 0.0 {
        0.0
    } else {
        pdf
    }
}

/// `Ggx::sample_visible` for `wo`, with the azimuth's cosine and sine drawn beforehand.
#[inline(always)]
fn ggx_sample_visible(alpha: f32, wo: V3, ux: f32, cos_phi: f32, sin_phi: f32) -> V3 {
    let wo = V3::select(wo.z < 0.0, wo.neg(), wo);
    let vh = unit(V3 { x: alpha * wo.x, y: alpha * wo.y, z: wo.z });
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = V3::select(lensq > 0.0, V3 { x: -vh.y, y: vh.x, z: 0.0 }.div(lensq.sqrt()), V3 { x: 1.0, y: 0.0, z: 0.0 });
    let t2 = V3 { x: vh.y * t1.z - vh.z * t1.y, y: vh.z * t1.x - vh.x * t1.z, z: vh.x * t1.y - vh.y * t1.x };
    let r = ux.sqrt();
    let p1 = r * cos_phi;
    let p2 = r * sin_phi;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
    let nh = t1.scale(p1).add(t2.scale(p2)).add(vh.scale((1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt()));
    unit(V3 { x: alpha * nh.x, y: alpha * nh.y, z: nh.z.max(1e-6) })
}

/// `frame::reflect`: `w` mirrored about `n`.
#[inline(always)]
fn reflect(w: V3, n: V3) -> V3 {
    n.scale(2.0 * w.dot(n)).sub(w)
}

/// `fresnel::dielectric`: the unpolarised reflectance at an interface of relative index `eta`
/// seen at `cos_i` (negative from inside).
#[inline(always)]
fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r = 0.5 * (r_parl * r_parl + r_perp * r_perp);
    if sin2_t >= 1.0 {
        1.0
    } else {
        r
    }
}

/// `fresnel::refract` of `w` through the interface of normal `n` and relative index `eta`:
/// the refracted direction, the relative index it crossed, and whether there is one (not
/// total internal reflection).
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn refract(w: V3, n: V3, eta: f32) -> (V3, f32, bool) {
    let cos_i = n.dot(w);
    let inside = cos_i < 0.0;
    let (eta, cos_i, n) = if inside { (1.0 / eta, -cos_i, n.neg()) } else { (eta, cos_i, n) };
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    let cos_t = (1.0 - sin2_t).sqrt();
    (w.neg().div(eta).add(n.scale(cos_i / eta - cos_t)), eta, !(sin2_t >= 1.0))
}

/// A sample of a smooth interface (`Dielectric::sample` when it is smooth): the local
/// direction, `f · |cos θi|`, its probability, the relative index crossed, whether it was
/// reflected, and whether there is one.
struct SmoothSample {
    wi: V3,
    f_cos: f32,
    pdf: f32,
    eta: f32,
    reflected: bool,
    ok: bool,
}

#[inline(always)]
fn smooth_dielectric(wo: V3, eta: f32, u_choice: f32) -> SmoothSample {
    let r = fresnel_dielectric(wo.z, eta);
    let reflected = u_choice < r;
    let (refracted, etap, refracts) = refract(wo, V3 { x: 0.0, y: 0.0, z: 1.0 }, eta);
    let transmittance = 1.0 - r;
    let (f_cos, pdf) = if reflected { (r, r) } else { (transmittance / (etap * etap), transmittance) };
    SmoothSample {
        wi: V3::select(reflected, V3 { x: -wo.x, y: -wo.y, z: wo.z }, refracted),
        f_cos,
        pdf,
        eta: if reflected { 1.0 } else { etap },
        reflected,
        ok: wo.z != 0.0 && (reflected || refracts),
    }
}

/// The lobes of `pbr::Mixture` at one vertex: what `Mixture::new` works out, in the shading
/// frame `(s, t, n)`. Without `GLASS`, for a material without transmission: its glass lobe
/// has no weight, and the code for it folds away.
struct Lobes<const GLASS: bool> {
    s: V3,
    t: V3,
    n: V3,
    ng: V3,
    wo: V3,
    side: f32,
    wo_dot_ng: f32,
    diffuse: V3,
    alpha: f32,
    f0: V3,
    f90: f32,
    glass_weight: V3,
    glass_scalar: f32,
    eta: f32,
    smooth: bool,
    p_diffuse: f32,
    p_spec: f32,
    p_glass: f32,
}

impl<const GLASS: bool> Lobes<GLASS> {
    #[inline(always)]
    fn new(blk: &Blocks, l: usize, ns: V3, ng: V3, wo: V3) -> Self {
        let (s, t, n) = shading_frame(ns, ng, wo);
        let wo_l = V3 { x: wo.dot(s), y: wo.dot(t), z: wo.dot(n) };
        let side = if wo_l.z < 0.0 { -1.0 } else { 1.0 };
        let cos_o = wo_l.z.abs();
        let m = blk.material[MAT_METALLIC][l].clamp(0.0, 1.0);
        let transmission = if GLASS { blk.transmission[l].clamp(0.0, 1.0) } else { 0.0 };
        let opaque = (1.0 - m) * (1.0 - transmission);
        let base = V3::field(&blk.material, MAT_ALBEDO, l);
        let (f0_dielectric, spec_factor) = (V3::field(&blk.material, MAT_F0, l), blk.material[MAT_SPECULAR][l]);
        let f_view = schlick(f0_dielectric, spec_factor, cos_o);
        let diffuse = base.scale(opaque * (1.0 - f_view.max_element()));
        let alpha_raw = blk.material[MAT_ROUGHNESS][l].clamp(0.0, 1.0).powi(2);
        let alpha = alpha_raw.max(MIN_ALPHA);
        let f0 = f0_dielectric.scale(opaque).add(base.scale(m));
        let f90 = spec_factor * opaque + m;
        let glass_scalar = (1.0 - m) * transmission;
        let eta = blk.material[MAT_ETA][l];
        let w_d = luminance(diffuse);
        let w_s = luminance(schlick(f0, f90, cos_o));
        // Without glass, its weight is still added, as in the scalar sum (a −0 becomes +0).
        let w_g = if GLASS && glass_scalar > 0.0 { glass_scalar * (0.5 + 0.5 * luminance(base)) } else { 0.0 };
        let total = w_d + w_s + w_g;
        let (a, b) = (w_d / total, w_s / total);
        let (p_diffuse, p_spec, p_glass) = if total <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if GLASS && w_g > 0.0 {
            (a, b, 1.0 - a - b)
        } else if w_s > 0.0 {
            (a, 1.0 - a, 0.0)
        } else {
            (1.0, 0.0, 0.0)
        };
        Lobes {
            s,
            t,
            n,
            ng,
            wo: wo_l,
            side,
            wo_dot_ng: wo.dot(ng),
            diffuse,
            alpha,
            f0,
            f90,
            glass_weight: base.scale(glass_scalar),
            glass_scalar,
            eta,
            smooth: alpha_raw < MIN_ALPHA || eta == 1.0,
            p_diffuse,
            p_spec,
            p_glass,
        }
    }

    #[inline(always)]
    fn opaque_local(&self, v: V3) -> V3 {
        V3 { x: v.x, y: v.y, z: v.z * self.side }
    }

    #[inline(always)]
    fn to_world(&self, v: V3) -> V3 {
        self.s.scale(v.x).add(self.t.scale(v.y)).add(self.n.scale(v.z))
    }

    /// `Mixture::has_non_delta`: light sampling can help.
    #[inline(always)]
    fn has_non_delta(&self) -> bool {
        self.p_diffuse > 0.0 || self.p_spec > 0.0 || (GLASS && self.p_glass > 0.0 && !self.smooth)
    }

    /// `Dielectric::eval_pdf` of the rough interface for the local directions `wo`, `wi`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn rough_dielectric(&self, wo: V3, wi: V3) -> (f32, f32) {
        // `Dielectric::half_vector`.
        let (co, ci) = (wo.z, wi.z);
        let reflection = co * ci > 0.0;
        let etap = if reflection {
            1.0
        } else if co > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let wm = wi.scale(etap).add(wo);
        let nonzero = wm.dot(wm) != 0.0;
        let wm = unit(wm);
        let wm = V3::select(wm.z < 0.0, wm.neg(), wm);
        let (wm_i, wm_o) = (wm.dot(wi), wm.dot(wo));
        let found = co != 0.0 && ci != 0.0 && nonzero && !(wm_i * ci < 0.0 || wm_o * co < 0.0);

        let alpha = self.alpha;
        let r = fresnel_dielectric(wm_o, self.eta);
        let t = 1.0 - r;
        let d = ggx_d(alpha, wm);
        let g = 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
        let pdf_h = ggx_pdf_visible(alpha, wo, wm);
        let (f, pdf) = if reflection {
            (d * g * r / (4.0 * (wi.z * wo.z).abs()), pdf_h / (4.0 * wm_o.abs()) * r)
        } else {
            let denom = wm_i + wm_o / etap;
            let denom2 = denom * denom;
            (d * g * t * (wm_i * wm_o / (wi.z * wo.z * denom2)).abs() / (etap * etap), pdf_h * wm_i.abs() / denom2 * t)
        };
        if found {
            (f, pdf)
        } else {
            (0.0, 0.0)
        }
    }

    /// `Mixture::eval_pdf`: `(f · |cos θi|, pdf)` at the world direction `wi`. Where the
    /// scalar code returns early on `x <= 0`, the lane keeps `!(x <= 0)`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn eval_pdf(&self, wi: V3) -> (V3, f32) {
        let wi_l = V3 { x: wi.dot(self.s), y: wi.dot(self.t), z: wi.dot(self.n) };
        let geometric_reflection = wi.dot(self.ng) * self.wo_dot_ng > 0.0;
        let shading_reflection = wi_l.z * self.wo.z > 0.0;
        let (o, i) = (self.opaque_local(self.wo), self.opaque_local(wi_l));
        // lambert::eval and lambert::pdf.
        let (lambert_f, lambert_pdf) = if o.z > 0.0 && i.z > 0.0 { (FRAC_1_PI, i.z * FRAC_1_PI) } else { (0.0, 0.0) };
        let both = !(o.z <= 0.0) && !(i.z <= 0.0);
        // MicrofacetReflection::eval and ::pdf.
        let h = unit(o.add(i));
        let d = ggx_d(self.alpha, h);
        let (lambda_o, lambda_i) = (ggx_lambda(self.alpha, o), ggx_lambda(self.alpha, i));
        let g2 = 1.0 / (1.0 + lambda_o + lambda_i);
        let g1 = 1.0 / (1.0 + lambda_o);
        let spec_f = schlick(self.f0, self.f90, o.dot(h)).scale(d * g2 / (4.0 * o.z * i.z));
        let spec_f = V3::select(both, spec_f, V3::splat(0.0));
        let spec_pdf = if both { g1 * d / (4.0 * o.z) } else { 0.0 };
        let zero = V3::splat(0.0);
        let (mut f, mut pdf) = (zero, 0.0);
        let with_diffuse = shading_reflection && self.p_diffuse > 0.0;
        f = V3::select(with_diffuse, f.add(self.diffuse.scale(lambert_f)), f);
        pdf = if with_diffuse { pdf + self.p_diffuse * lambert_pdf } else { pdf };
        let with_spec = shading_reflection && self.p_spec > 0.0;
        f = V3::select(with_spec, f.add(spec_f), f);
        pdf = if with_spec { pdf + self.p_spec * spec_pdf } else { pdf };
        if GLASS {
            let (fg, pg) = self.rough_dielectric(self.wo, wi_l);
            // Glass tints transmission only; reflection off the interface is white.
            let w = V3::select(shading_reflection, V3::splat(self.glass_scalar), self.glass_weight);
            let with_glass = self.p_glass > 0.0 && !self.smooth;
            f = V3::select(with_glass, f.add(w.scale(fg)), f);
            pdf = if with_glass { pdf + self.p_glass * pg } else { pdf };
        }
        let none = geometric_reflection != shading_reflection || wi_l.z == 0.0;
        (V3::select(none, zero, f.scale(wi_l.z.abs())), if none { 0.0 } else { pdf })
    }
}

/// One lane: the vertex of [`crate::transport::integrator::PathContext::vertex`] for a hit on
/// a glTF material of several lobes (`pbr::Mixture`; with `GLASS`, one whose glass lobe
/// may be chosen).
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn glossy_lane<const NORMALS: bool, const GLASS: bool>(
    c: &mut Chunk,
    o: &mut Out,
    blk: &Blocks,
    draws: &Draws,
    g: &GlossyDraws,
    k: &Consts,
    l: usize,
) {
    let Arrival { shade, d, beta, p, ng, ns, goes_on } = arrive::<NORMALS>(c, o, blk, k, l, GLOSSY);
    let bsdf = Lobes::<GLASS>::new(blk, l, ns, ng, d.neg());

    // Next-event estimation.
    let ls = light_point::<true>(c, blk, draws, l, p, k.eps);
    let (f, pdf_bsdf) = bsdf.eval_pdf(ls.wi);
    shadow_ray(o, l, shade && goes_on && bsdf.has_non_delta() && ls.sampled && f.nonzero(), &ls, p, ng, beta, f, pdf_bsdf, k.eps);

    // Mixture::sample_drawn: the lobe, then its direction.
    let u_lobe = g.lobe[l];
    let (ux, cos_phi, sin_phi) = (draws.bsdf[0][l], g.cos_phi[l], g.sin_phi[l]);
    let pick_diffuse = u_lobe < bsdf.p_diffuse;
    let pick_spec = !pick_diffuse && (u_lobe < bsdf.p_diffuse + bsdf.p_spec || (bsdf.p_glass == 0.0 && bsdf.p_spec > 0.0));
    let pick_glass = GLASS && !pick_diffuse && !pick_spec && bsdf.p_glass > 0.0;
    let cosine = cosine_direction(ux, draws.bsdf[1][l]);
    let o_l = bsdf.opaque_local(bsdf.wo);
    // MicrofacetReflection::sample.
    let spec_dir = reflect(o_l, ggx_sample_visible(bsdf.alpha, o_l, ux, cos_phi, sin_phi));
    let spec_ok = !(o_l.z <= 0.0) && spec_dir.z > 0.0;
    let mut wi_l = bsdf.opaque_local(V3::select(pick_diffuse, cosine, spec_dir));
    let mut lobe_ok = pick_diffuse || (pick_spec && spec_ok);
    let mut delta = Scatter { scattered: false, dir: wi_l, beta, pdf: 0.0, delta: true, eta: 1.0, roulette: draws.roulette[l] };
    if GLASS {
        let wo_l = bsdf.wo;
        let u_choice = g.choice[l];
        // Dielectric::sample of a rough interface.
        let wm = ggx_sample_visible(bsdf.alpha, wo_l, ux, cos_phi, sin_phi);
        let r = fresnel_dielectric(wo_l.dot(wm), bsdf.eta);
        let reflected = u_choice < r;
        let (refracted, _, refracts) = refract(wo_l, wm, bsdf.eta);
        let rough_dir = V3::select(reflected, reflect(wo_l, wm), refracted);
        let (_, rough_pdf) = bsdf.rough_dielectric(wo_l, rough_dir);
        let rough_ok = wo_l.z != 0.0
            && if reflected { !(rough_dir.z * wo_l.z <= 0.0) } else { refracts && !(rough_dir.z * wo_l.z >= 0.0) }
            && !(rough_pdf <= 0.0)
            && rough_pdf.is_finite();
        // Its smooth interface: a delta lobe, its weight worked out here.
        let sm = smooth_dielectric(wo_l, bsdf.eta, u_choice);
        let dir = bsdf.to_world(sm.wi);
        let sides = (dir.dot(ng) * bsdf.wo_dot_ng > 0.0) == sm.reflected;
        let tint = V3::select(sm.reflected, V3::splat(bsdf.glass_scalar), bsdf.glass_weight);
        delta = Scatter {
            scattered: sm.ok && sides,
            dir,
            beta: beta.mul(tint.scale(sm.f_cos / (sm.pdf * bsdf.p_glass))),
            pdf: 0.0,
            delta: true,
            eta: sm.eta,
            roulette: draws.roulette[l],
        };
        wi_l = V3::select(pick_glass, rough_dir, wi_l);
        lobe_ok = if pick_glass { !bsdf.smooth && rough_ok } else { lobe_ok };
    }
    let next_dir = bsdf.to_world(wi_l);
    let (f, pdf) = bsdf.eval_pdf(next_dir);
    let sampled = lobe_ok && !(pdf <= 0.0) && pdf.is_finite() && f.nonzero();
    let eta = if GLASS && wi_l.z * bsdf.wo.z < 0.0 {
        if bsdf.wo.z > 0.0 {
            bsdf.eta
        } else {
            1.0 / bsdf.eta
        }
    } else {
        1.0
    };
    let smooth_glass = GLASS && pick_glass && bsdf.smooth;
    let s = if smooth_glass {
        Scatter { scattered: shade && goes_on && delta.scattered, ..delta }
    } else {
        Scatter {
            scattered: shade && goes_on && sampled,
            dir: next_dir,
            beta: beta.mul(f.div(pdf)),
            pdf,
            delta: false,
            eta,
            roulette: draws.roulette[l],
        }
    };
    continue_path(c, o, k, l, p, ng, s);
}

#[inline(always)]
fn glossy_lanes<const NORMALS: bool, const GLASS: bool>(c: &mut Chunk, o: &mut Out, b: &Blocks, k: &Consts) {
    let d = draws(c);
    let g = glossy_draws::<GLASS>(c, &d);
    let n = std::hint::black_box(W).min(W);
    for l in 0..n {
        glossy_lane::<NORMALS, GLASS>(c, o, b, &d, &g, k, l);
    }
}

/// One lane: the vertex of [`crate::transport::integrator::PathContext::vertex`] for a hit on
/// smooth glass alone (`pbr::Mixture` whose only lobe is `Dielectric`'s delta, chosen with
/// probability 1): no light sample, a mirror reflection or a refraction chosen by Fresnel,
/// transmission tinted by the base colour.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn glass_lane<const NORMALS: bool>(c: &mut Chunk, o: &mut Out, blk: &Blocks, g: &GlassDraws, k: &Consts, l: usize) {
    let Arrival { shade, d, beta, p, ng, ns, goes_on } = arrive::<NORMALS>(c, o, blk, k, l, GLASS);
    let wo = d.neg();
    let (s, t, n) = shading_frame(ns, ng, wo);
    let wo_l = V3 { x: wo.dot(s), y: wo.dot(t), z: wo.dot(n) };
    o.shadow[l] = 0;

    let sm = smooth_dielectric(wo_l, blk.material[MAT_ETA][l], g.choice[l]);

    // Mixture::sample_drawn's glass lobe: the direction on the side the geometry agrees with,
    // its weight with the lobe's probability 1 and the glass weights 1 and the base colour.
    let wi = s.scale(sm.wi.x).add(t.scale(sm.wi.y)).add(n.scale(sm.wi.z));
    let sides = (wi.dot(ng) * wo.dot(ng) > 0.0) == sm.reflected;
    let tint = V3::select(sm.reflected, V3::splat(1.0), V3::field(&blk.material, MAT_ALBEDO, l));
    let s = Scatter {
        scattered: shade && goes_on && sm.ok && sides,
        dir: wi,
        beta: beta.mul(tint.scale(sm.f_cos / sm.pdf)),
        pdf: 0.0,
        delta: true,
        eta: sm.eta,
        roulette: g.roulette[l],
    };
    continue_path(c, o, k, l, p, ng, s);
}

/// The glass lanes' random numbers: reflect or refract, and Russian roulette's.
struct GlassDraws {
    choice: [f32; W],
    roulette: [f32; W],
}

#[inline(always)]
fn glass_lanes<const NORMALS: bool>(c: &mut Chunk, o: &mut Out, b: &Blocks, k: &Consts) {
    let mut g = GlassDraws { choice: [0.0; W], roulette: [0.0; W] };
    for l in 0..std::hint::black_box(W).min(W) {
        let (key, vertex) = (c.key[l], c.depth[l].saturating_sub(1));
        g.choice[l] = get1d(key, dims::at(vertex, dims::DIELECTRIC_CHOICE));
        g.roulette[l] = get1d(key, dims::at(vertex, dims::RUSSIAN_ROULETTE));
    }
    for l in 0..std::hint::black_box(W).min(W) {
        glass_lane::<NORMALS>(c, o, b, &g, k, l);
    }
}

#[inline(always)]
fn lanes<const NORMALS: bool, const OTHER: bool>(c: &mut Chunk, o: &mut Out, b: &Blocks, k: &Consts) {
    let d = draws(c);
    // A trip count the compiler cannot see: a known 16 gets the loop fully unrolled before
    // the loop vectoriser runs, which then has nothing to vectorise.
    let n = std::hint::black_box(W).min(W);
    for l in 0..n {
        lane::<NORMALS, OTHER>(c, o, b, &d, k, l);
    }
}

/// Turns a block of records `[lane][value]` into `[value][lane]`. Pure data movement, so every
/// build gives the same values. Implemented by each build's CPU-feature token (`simd`), which
/// [`shade`] passes on.
pub(crate) trait Transpose: Copy {
    fn transpose(self, block: &mut [Record; W]);
}

/// The kernel: shades the lanes of `c` whose `shade` is set (with the diffuse, then the
/// glossy, then the glass lanes, as their flags say), from the records the caller copied into `b`
/// (which it transposes in place; vertex normals only if `normals`). Each build compiles it,
/// inlined, for its own instructions (`simd`).
#[inline(always)]
pub(crate) fn shade<T: Transpose>(isa: T, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
    isa.transpose(&mut b.triangle);
    isa.transpose(&mut b.material);
    isa.transpose(&mut b.light);
    let diffuse = c.flags.iter().any(|&f| f & DIFFUSE != 0);
    let glossy = c.flags.iter().any(|&f| f & GLOSSY != 0);
    if normals {
        isa.transpose(&mut b.normals);
    }
    if diffuse {
        // The diffuse lanes are the common vertex of every scene: a build without the other
        // lights than emitter triangles for chunks that have none.
        match (normals, c.flags.iter().any(|&f| f & OTHER_LIGHTS != 0)) {
            (true, true) => lanes::<true, true>(c, o, b, k),
            (true, false) => lanes::<true, false>(c, o, b, k),
            (false, true) => lanes::<false, true>(c, o, b, k),
            (false, false) => lanes::<false, false>(c, o, b, k),
        }
    }
    // The glossy and the glass lanes write their outputs into a scratch `Out`, which then goes
    // into `o` lane by lane where a lane is theirs: writing `o` only there would read it in
    // the loop, one more array for the compiler to check (see `Chunk::flags`). No closures
    // here: a closure is a function of its own, compiled without the build's instructions
    // unless it is inlined.
    let glass = c.flags.iter().any(|&f| f & GLASS != 0);
    if !glossy && !glass {
        return;
    }
    let mut scratch = std::mem::take(&mut b.scratch_out);
    if glossy {
        // The glass lobe's build only for chunks that have one.
        match (normals, c.flags.iter().any(|&f| f & GLASS_LOBE != 0)) {
            (true, true) => glossy_lanes::<true, true>(c, &mut scratch, b, k),
            (true, false) => glossy_lanes::<true, false>(c, &mut scratch, b, k),
            (false, true) => glossy_lanes::<false, true>(c, &mut scratch, b, k),
            (false, false) => glossy_lanes::<false, false>(c, &mut scratch, b, k),
        }
        take_lanes(c, o, &scratch, GLOSSY);
    }
    if glass {
        if normals {
            glass_lanes::<true>(c, &mut scratch, b, k);
        } else {
            glass_lanes::<false>(c, &mut scratch, b, k);
        }
        take_lanes(c, o, &scratch, GLASS);
    }
    b.scratch_out = scratch;
}

/// The lanes of `scratch` whose flags have `flag`, into `o`.
#[inline(always)]
fn take_lanes(c: &Chunk, o: &mut Out, scratch: &Out, flag: u32) {
    for l in 0..W {
        if c.flags[l] & flag != 0 {
            o.take_lane(scratch, l);
        }
    }
}

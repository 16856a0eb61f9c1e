//! The common vertex of a wavefront, [`W`] paths at a time: a diffuse material without
//! textures, lit by next-event estimation towards an emissive triangle (the Cornell box's
//! every vertex). The arithmetic is that of [`crate::integrator::PathContext::vertex`] on such a
//! vertex, operation by operation and in the same order (glam's `Vec3A` sums its dot products
//! as `(x·x' + y·y') + z·z'`, and so does [`V3::dot`]), with every branch replaced by a select,
//! so that the compiler can run each step on all lanes at once; the result is the same bit
//! for bit, which `tests` checks against the scalar vertex and the renders check end to end.
//!
//! The kernel is written once, as a loop over the lanes of structure-of-arrays inputs, and
//! compiled three times ([`kernel`]): for AVX-512, for AVX2 and for any x86-64 (or other) CPU.
//! Rust never fuses a multiplication and an addition on its own, so all three do the same
//! IEEE operations and give the same bits: an image does not depend on the CPU it was
//! rendered on, and a farm's parts from different machines still merge into the one-shot file.
use crate::sampler::dims;
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4};

/// Lanes per kernel call: 16 single-precision values fill one AVX-512 register.
pub(crate) const W: usize = 16;

/// What the kernel reads of one lane's path, hit and scene data (gathered by the caller).
#[derive(Clone, Copy, Default)]
pub(crate) struct LaneIn {
    /// The ray that found the vertex: its unit direction.
    pub dir: [[f32; W]; 3],
    /// Hit distance and barycentrics of vertices 1 and 2.
    pub t: [f32; W],
    pub u: [f32; W],
    pub v: [f32; W],
    pub beta: [[f32; W]; 3],
    pub eta_scale: [f32; W],
    pub prev_pdf: [f32; W],
    /// 1 where the previous bounce was a delta lobe (or the ray is the camera's), else 0.
    pub prev_delta: [u32; W],
    /// Segments so far, including the ray.
    pub depth: [u32; W],
    /// The sample's sampler key.
    pub key: [u64; W],
    /// The hit triangle's vertices, vertex normals (when the scene has them) and geometric normal.
    pub p: [[[f32; W]; 3]; 3],
    pub n: [[[f32; W]; 3]; 3],
    pub ng: [[f32; W]; 3],
    /// The material's base colour (the albedo feature) and the BSDF's albedo (at least 0).
    pub base: [[f32; W]; 3],
    pub albedo: [[f32; W]; 3],
    /// The material's emission (0 for a non-emitter) and the hit triangle's area density as a
    /// light.
    pub emission: [[f32; W]; 3],
    pub pdf_area: [f32; W],
    /// 1 where next-event estimation has a triangle to sample (then the light fields are set).
    pub has_light: [u32; W],
    /// The chosen light triangle: vertices, geometric normal, area density, emission.
    pub light_p: [[[f32; W]; 3]; 3],
    pub light_ng: [[f32; W]; 3],
    pub light_pdf_area: [f32; W],
    pub light_emission: [[f32; W]; 3],
}

/// What the kernel leaves for each lane.
#[derive(Clone, Copy, Default)]
pub(crate) struct LaneOut {
    /// 1 where the vertex emits towards the ray: `emitted` is then added to the path's radiance.
    pub emits: [u32; W],
    pub emitted: [[f32; W]; 3],
    /// First-hit features: albedo, shading normal facing the ray, depth.
    pub first_albedo: [[f32; W]; 3],
    pub first_normal: [[f32; W]; 3],
    /// 1 where a shadow ray is to be traced: origin, direction (`tmax` 1), the light it brings.
    pub shadow: [u32; W],
    pub shadow_origin: [[f32; W]; 3],
    pub shadow_dir: [[f32; W]; 3],
    pub shadow_light: [[f32; W]; 3],
    /// 1 where the path goes on: its new ray, throughput and BSDF density.
    pub next: [u32; W],
    pub origin: [[f32; W]; 3],
    pub next_dir: [[f32; W]; 3],
    pub beta: [[f32; W]; 3],
    pub pdf: [f32; W],
}

/// What every lane shares.
#[derive(Clone, Copy)]
pub(crate) struct Consts {
    pub eps: f32,
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Whether the scene has vertex normals (else the shading normal is the geometric one).
    pub normals: bool,
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
    fn at(a: &[[f32; W]; 3], l: usize) -> V3 {
        V3 { x: a[0][l], y: a[1][l], z: a[2][l] }
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

/// `crate::integrator::power_heuristic`.
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

/// `crate::integrator::spawn_origin`.
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

/// One lane: the vertex of [`crate::integrator::PathContext::vertex`] for a hit on a diffuse,
/// untextured material whose light sample (if any) is on a triangle. Where the scalar code
/// returns early on `x <= 0`, the lane keeps `!(x <= 0)`: the same side for NaN.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn lane<const NORMALS: bool>(i: &LaneIn, draws: &Draws, o: &mut LaneOut, k: &Consts, l: usize) {
    let d = V3::at(&i.dir, l);
    let (t, u, v) = (i.t[l], i.u[l], i.v[l]);
    let beta = V3::at(&i.beta, l);
    let prev_delta = i.prev_delta[l] != 0;
    let depth = i.depth[l];

    // Scene::surface.
    let w = 1.0 - u - v;
    let [p0, p1, p2] = [0, 1, 2].map(|c| V3::at(&i.p[c], l));
    let p = p0.scale(w).add(p1.scale(u)).add(p2.scale(v));
    let ng = V3::at(&i.ng, l);
    let ns = if NORMALS {
        let [n0, n1, n2] = [0, 1, 2].map(|c| V3::at(&i.n[c], l));
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
    let emission = V3::at(&i.emission, l);
    let emits = front && emission.max_element() > 0.0;
    let le = V3::select(emits, emission, V3::splat(0.0));
    let cos_l = -d.dot(ng);
    let pdf_light = i.pdf_area[l] * t * t / cos_l;
    let w_em = if prev_delta { 1.0 } else { power_heuristic(i.prev_pdf[l], pdf_light) };
    o.emits[l] = emits as u32;
    beta.mul(le).scale(w_em).put(&mut o.emitted, l);

    // First-hit features.
    V3::select(ns.dot(d) > 0.0, ns.neg(), ns).put(&mut o.first_normal, l);
    V3::select(le.nonzero(), le, V3::at(&i.base, l)).put(&mut o.first_albedo, l);
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
    let albedo = V3::at(&i.albedo, l);
    let lit = albedo.max_element() > 0.0;
    let cosine = cosine_direction(draws.bsdf[0][l], draws.bsdf[1][l]);

    // Next-event estimation towards a point on the chosen triangle (`lights::sample_area`).
    let (lx, ly) = (draws.light[0][l], draws.light[1][l]);
    let su = lx.sqrt();
    let (ba, bb) = (su * (1.0 - ly), su * ly);
    let [q0, q1, q2] = [0, 1, 2].map(|c| V3::at(&i.light_p[c], l));
    let point = q0.scale(1.0 - ba - bb).add(q1.scale(ba)).add(q2.scale(bb));
    let to_light = point.sub(p);
    let dist2 = to_light.dot(to_light);
    let n_l = V3::at(&i.light_ng, l);
    let wi = to_light.div(dist2.sqrt());
    let cos_at_light = -wi.dot(n_l);
    let li = V3::at(&i.light_emission, l);
    let pdf = i.light_pdf_area[l] * dist2 / cos_at_light;
    let sampled = i.has_light[l] != 0 && !(dist2 <= 0.0) && !(cos_at_light <= 0.0) && li.nonzero() && pdf > 0.0;
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
    o.shadow[l] = (goes_on && lit && sampled && f.nonzero()) as u32;
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
    let eta_scale = i.eta_scale[l] * 1.0;
    let roulette = depth >= k.rr_depth;
    let q = (next_beta.max_element() * eta_scale).min(0.95);
    let survives = !(draws.roulette[l] >= q);
    o.next[l] = (goes_on && scattered && carries && (!roulette || survives)) as u32;
    V3::select(roulette, next_beta.div(q), next_beta).put(&mut o.beta, l);
    o.pdf[l] = wi_l.z.abs() * FRAC_1_PI;
    spawn_origin(p, ng, next_dir, k.eps).put(&mut o.origin, l);
    next_dir.put(&mut o.next_dir, l);
}

/// The random numbers of one vertex per lane: the BSDF pair, the light-position pair and
/// Russian roulette's.
#[derive(Clone, Copy)]
struct Draws {
    bsdf: [[f32; W]; 2],
    light: [[f32; W]; 2],
    roulette: [f32; W],
}

/// The hashes in a loop of their own: on 64-bit lanes they would halve the width the rest
/// of the vertex runs at.
#[inline(always)]
fn draws(i: &LaneIn) -> Draws {
    let mut d = Draws { bsdf: [[0.0; W]; 2], light: [[0.0; W]; 2], roulette: [0.0; W] };
    for l in 0..W {
        let (key, vertex) = (i.key[l], i.depth[l].wrapping_sub(1));
        (d.bsdf[0][l], d.bsdf[1][l]) = get2d(key, dims::at(vertex, dims::BSDF_DIR));
        (d.light[0][l], d.light[1][l]) = get2d(key, dims::at(vertex, dims::LIGHT_POS));
        d.roulette[l] = get1d(key, dims::at(vertex, dims::RUSSIAN_ROULETTE));
    }
    d
}

#[inline(always)]
fn lanes<const NORMALS: bool>(i: &LaneIn, o: &mut LaneOut, k: &Consts) {
    let d = draws(i);
    for l in 0..W {
        lane::<NORMALS>(i, &d, o, k, l);
    }
}

#[inline(always)]
fn generic(i: &LaneIn, o: &mut LaneOut, k: &Consts) {
    if k.normals {
        lanes::<true>(i, o, k)
    } else {
        lanes::<false>(i, o, k)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
unsafe fn avx512(i: &LaneIn, o: &mut LaneOut, k: &Consts) {
    generic(i, o, k)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn avx2(i: &LaneIn, o: &mut LaneOut, k: &Consts) {
    generic(i, o, k)
}

fn portable(i: &LaneIn, o: &mut LaneOut, k: &Consts) {
    generic(i, o, k)
}

/// The kernel: all lanes of `i` into `o`.
pub(crate) type Kernel = fn(&LaneIn, &mut LaneOut, &Consts);

/// Which build of the kernel runs on this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    Avx512,
    Avx2,
    Portable,
}

impl Isa {
    /// The widest build this CPU runs.
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512dq")
                && std::is_x86_feature_detected!("avx512vl")
                && std::is_x86_feature_detected!("avx512bw")
            {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// The kernel of this build, or `None` if the CPU lacks its instructions.
    pub fn kernel(self) -> Option<Kernel> {
        match self {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                let ok = std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512dq")
                    && std::is_x86_feature_detected!("avx512vl")
                    && std::is_x86_feature_detected!("avx512bw");
                // SAFETY: called only where the CPU has the instructions `avx512` is compiled for.
                ok.then_some((|i: &LaneIn, o: &mut LaneOut, k: &Consts| unsafe { avx512(i, o, k) }) as Kernel)
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                // SAFETY: called only where the CPU has AVX2.
                std::is_x86_feature_detected!("avx2")
                    .then_some((|i: &LaneIn, o: &mut LaneOut, k: &Consts| unsafe { avx2(i, o, k) }) as Kernel)
            }
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx512 | Isa::Avx2 => None,
            Isa::Portable => Some(portable as Kernel),
        }
    }
}

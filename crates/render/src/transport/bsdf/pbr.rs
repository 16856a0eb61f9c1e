//! glTF 2.0's metallic-roughness material as a mixture of three lobes:
//!
//! * **diffuse** — Lambertian base colour under the dielectric specular layer, weighted by
//!   `(1 − m)(1 − t)(1 − max F_d(n·wo))`;
//! * **specular** — one GGX reflection lobe whose Schlick Fresnel blends the dielectric layer
//!   (`F0 = min(0.04·specularColour, 1)·specular` for IOR 1.5, `F90 = specular`, from
//!   `KHR_materials_specular`) with the metal (`F0 = baseColour`, `F90 = 1`) by `metallic`;
//! * **glass** — a dielectric interface (`KHR_materials_transmission` + `KHR_materials_ior`)
//!   with weight `(1 − m)·t`, transmission tinted by the base colour.
//!
//! Approximation (documented, as in many production glTF renderers): the layer's energy split
//! uses Fresnel at the *viewing* angle for the diffuse weight rather than a layered model, so
//! the material is not exactly reciprocal, and it can reflect slightly more than it receives:
//! up to 0.13% for a white plastic (roughness ≈ 0.3, viewed at ≈ 55°), because the specular
//! lobe's Fresnel, averaged over microfacets, exceeds the viewing-angle Fresnel the diffuse
//! weight leaves room for (measured by the quadrature test below). `specularFactor = 0` leaves
//! a pure Lambertian surface. Opaque lobes are two-sided (they act on the side `wo` is on);
//! glass distinguishes inside from outside by the geometric normal's orientation (winding).
use super::dielectric::Dielectric;
use super::diffuse::Diffuse;
use super::frame::Frame;
use super::ggx::Ggx;
use super::lambert;
use super::microfacet::MicrofacetReflection;
use super::sample::{BsdfSample, SampleDraw};
use crate::scene::material::{is_diffuse_only, Material, PbrParams};
use crate::scene::texture::Texture;
use crate::vector::luminance;
use glam::{Vec2, Vec3A};

/// The BSDF at one surface point for one outgoing direction: the glTF model, as its diffuse
/// lobe alone when that is all a material has (the common case, made cheap), else as the
/// mixture of its lobes.
#[derive(Clone, Copy, Debug)]
pub enum Bsdf {
    Diffuse(Diffuse),
    Mixture(Mixture),
}

impl Bsdf {
    /// `ns`, `ng`: unit shading and geometric normals with `ns·ng ≥ 0` (ng from the winding);
    /// `wo`: unit direction towards the previous vertex.
    pub fn new(params: &PbrParams, ns: Vec3A, ng: Vec3A, wo: Vec3A) -> Bsdf {
        if is_diffuse_only(params.metallic, params.transmission, params.specular) {
            return Bsdf::diffuse(params.base_color, ns, ng, wo);
        }
        Bsdf::Mixture(Mixture::new(params, shading_frame(ns, ng, wo), ng, wo))
    }

    /// The BSDF of `material` at texture coordinate `uv` of a point with shading and geometric
    /// normals `ns`, `ng`, seen from the unit direction `wo` (see [`Bsdf::new`]).
    #[inline]
    pub fn at(material: &Material, textures: &[Texture], uv: Vec2, ns: Vec3A, ng: Vec3A, wo: Vec3A) -> Bsdf {
        if material.is_diffuse_only() {
            Bsdf::diffuse(material.base_color_at(textures, uv), ns, ng, wo)
        } else {
            Bsdf::new(&material.params_at(textures, uv), ns, ng, wo)
        }
    }

    /// The BSDF of a purely diffuse material with base colour `base` (see [`Bsdf::new`]).
    #[inline]
    pub fn diffuse(base: Vec3A, ns: Vec3A, ng: Vec3A, wo: Vec3A) -> Bsdf {
        let frame = shading_frame(ns, ng, wo);
        // `wo`'s local z is its dot product with the frame's normal, as in `to_local`.
        Bsdf::Diffuse(Diffuse::new(frame, ng, wo, wo.dot(frame.n), base.max(Vec3A::ZERO)))
    }

    /// The general mixture even for a purely diffuse material (to test [`Diffuse`] against it).
    #[cfg(test)]
    pub(crate) fn mixture(params: &PbrParams, ns: Vec3A, ng: Vec3A, wo: Vec3A) -> Mixture {
        Mixture::new(params, shading_frame(ns, ng, wo), ng, wo)
    }

    /// True if some lobe is not a delta distribution (light sampling can help).
    #[inline]
    pub fn has_non_delta(&self) -> bool {
        match self {
            Bsdf::Diffuse(d) => d.is_lit(),
            Bsdf::Mixture(m) => m.has_non_delta(),
        }
    }

    /// True if the glass lobe can be chosen (it needs the reflect-or-refract random number).
    #[inline]
    pub fn has_glass(&self) -> bool {
        match self {
            Bsdf::Diffuse(_) => false,
            Bsdf::Mixture(m) => m.p_glass > 0.0,
        }
    }

    /// `(f · |cos θi|, pdf)` for the world direction `wi`, over the non-delta lobes.
    #[inline]
    pub fn eval_pdf(&self, wi: Vec3A) -> (Vec3A, f32) {
        match self {
            Bsdf::Diffuse(d) => d.eval_pdf(wi),
            Bsdf::Mixture(m) => m.eval_pdf(wi),
        }
    }

    /// `f · |cos θi|` for the world direction `wi`.
    #[inline]
    pub fn eval(&self, wi: Vec3A) -> Vec3A {
        self.eval_pdf(wi).0
    }

    #[inline]
    pub fn pdf(&self, wi: Vec3A) -> f32 {
        self.eval_pdf(wi).1
    }

    /// Picks a lobe with `u_lobe`, a direction with `u`, and for glass reflect-or-refract with
    /// `u_choice`. `None` when the path ends here (black BSDF or a direction below the surface).
    pub fn sample(&self, u_lobe: f32, u: Vec2, u_choice: f32) -> Option<BsdfSample> {
        self.sample_drawn(&SampleDraw::new(u_lobe, u, u_choice))
    }

    /// [`Bsdf::sample`] with its random numbers drawn (and the cosine direction worked out)
    /// beforehand.
    #[inline]
    pub fn sample_drawn(&self, draw: &SampleDraw) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse(d) => d.sample_drawn(draw),
            Bsdf::Mixture(m) => m.sample_drawn(draw),
        }
    }
}

/// The frame around the shading normal `ns`, or around `ng` where `ns` would put `wo` on the
/// other side than the geometry does (such shading normals are discarded).
#[inline]
fn shading_frame(ns: Vec3A, ng: Vec3A, wo: Vec3A) -> Frame {
    Frame::from_normal(if ns.dot(wo) * ng.dot(wo) <= 0.0 { ng } else { ns })
}

/// The dielectric layer's Fresnel at normal incidence and its strength (`F90`), which depend
/// on the material alone, not on the point or the direction.
#[inline]
pub(crate) fn dielectric_layer(ior: f32, specular_color: Vec3A, specular: f32) -> (Vec3A, f32) {
    let spec_factor = specular.clamp(0.0, 1.0);
    let r0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
    ((Vec3A::splat(r0) * specular_color.max(Vec3A::ZERO)).min(Vec3A::ONE) * spec_factor, spec_factor)
}

/// Whether a material with these factors is a smooth dielectric and nothing else: full
/// transmission and no metal leave the diffuse and specular lobes no weight (the glass lobe
/// is chosen with probability 1), and a roughness below GGX's smallest, or no change of
/// index, makes its interface a delta.
#[inline]
pub(crate) fn is_smooth_glass(metallic: f32, roughness: f32, transmission: f32, ior: f32) -> bool {
    transmission.clamp(0.0, 1.0) == 1.0
        && metallic.clamp(0.0, 1.0) == 0.0
        && Dielectric::new(ior.max(1.0), roughness.clamp(0.0, 1.0).powi(2)).smooth
}

/// The glTF model as a mixture of its lobes (see the module doc).
#[derive(Clone, Copy, Debug)]
pub struct Mixture {
    frame: Frame,
    /// Geometric normal (winding orientation), to reject light leaks through shading normals.
    ng: Vec3A,
    /// `wo` in the local frame.
    wo: Vec3A,
    /// Which side of the shading frame `wo` is on: opaque lobes are evaluated as if it were +z.
    side: f32,
    diffuse: Vec3A,
    spec: MicrofacetReflection,
    glass: Dielectric,
    /// Glass transmission weight (tinted) and reflection weight (white).
    glass_weight: Vec3A,
    glass_scalar: f32,
    /// `wo · ng`, whose sign tells the geometric side `wo` is on.
    wo_dot_ng: f32,
    /// Lobe-selection probabilities; they sum to 1 unless the BSDF is black.
    p_diffuse: f32,
    p_spec: f32,
    p_glass: f32,
}

impl Mixture {
    /// `frame` around the shading normal in use; the rest as for [`Bsdf::new`].
    fn new(params: &PbrParams, frame: Frame, ng: Vec3A, wo: Vec3A) -> Mixture {
        let wo_local = frame.to_local(wo);
        let side = if wo_local.z < 0.0 { -1.0 } else { 1.0 };
        let cos_o = wo_local.z.abs();

        let m = params.metallic.clamp(0.0, 1.0);
        let t = params.transmission.clamp(0.0, 1.0);
        let opaque = (1.0 - m) * (1.0 - t);
        let base = params.base_color.max(Vec3A::ZERO);
        let (f0_dielectric, spec_factor) = dielectric_layer(params.ior, params.specular_color, params.specular);
        let f_view = super::fresnel::schlick(f0_dielectric, spec_factor, cos_o);
        let diffuse = base * (opaque * (1.0 - f_view.max_element()));
        let alpha = params.roughness.clamp(0.0, 1.0).powi(2);
        let spec = MicrofacetReflection { ggx: Ggx::new(alpha), f0: f0_dielectric * opaque + base * m, f90: spec_factor * opaque + m };
        let glass_scalar = (1.0 - m) * t;
        let glass_weight = base * glass_scalar;
        let glass = Dielectric::new(params.ior.max(1.0), alpha);

        let w_d = luminance(diffuse);
        let w_s = luminance(super::fresnel::schlick(spec.f0, spec.f90, cos_o));
        let w_g = if glass_scalar > 0.0 { glass_scalar * (0.5 + 0.5 * luminance(base)) } else { 0.0 };
        let total = w_d + w_s + w_g;
        // Probabilities that sum to exactly 1: the last lobe in use takes the remainder.
        let (p_d, p_s, p_g) = if total <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if w_g > 0.0 {
            let (a, b) = (w_d / total, w_s / total);
            (a, b, 1.0 - a - b)
        } else if w_s > 0.0 {
            let a = w_d / total;
            (a, 1.0 - a, 0.0)
        } else {
            (1.0, 0.0, 0.0)
        };
        Mixture {
            frame,
            ng,
            wo: wo_local,
            side,
            diffuse,
            spec,
            glass,
            glass_weight,
            glass_scalar,
            wo_dot_ng: wo.dot(ng),
            p_diffuse: p_d,
            p_spec: p_s,
            p_glass: p_g,
        }
    }

    #[inline]
    fn has_non_delta(&self) -> bool {
        self.p_diffuse > 0.0 || self.p_spec > 0.0 || (self.p_glass > 0.0 && !self.glass.smooth)
    }

    #[inline]
    fn opaque_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.x, v.y, v.z * self.side)
    }

    #[inline]
    pub(crate) fn eval_pdf(&self, wi: Vec3A) -> (Vec3A, f32) {
        let wi_l = self.frame.to_local(wi);
        let wo_l = self.wo;
        let geometric_reflection = wi.dot(self.ng) * self.wo_dot_ng > 0.0;
        let shading_reflection = wi_l.z * wo_l.z > 0.0;
        if geometric_reflection != shading_reflection || wi_l.z == 0.0 {
            return (Vec3A::ZERO, 0.0);
        }
        let mut f = Vec3A::ZERO;
        let mut pdf = 0.0;
        if shading_reflection {
            let (o, i) = (self.opaque_local(wo_l), self.opaque_local(wi_l));
            if self.p_diffuse > 0.0 {
                f += self.diffuse * lambert::eval(o, i);
                pdf += self.p_diffuse * lambert::pdf(o, i);
            }
            if self.p_spec > 0.0 {
                f += self.spec.eval(o, i);
                pdf += self.p_spec * self.spec.pdf(o, i);
            }
        }
        if self.p_glass > 0.0 && !self.glass.smooth {
            let (fg, pg) = self.glass.eval_pdf(wo_l, wi_l);
            // Glass tints transmission only; reflection off the interface is white.
            let w = if shading_reflection { Vec3A::splat(self.glass_scalar) } else { self.glass_weight };
            f += w * fg;
            pdf += self.p_glass * pg;
        }
        (f * wi_l.z.abs(), pdf)
    }

    pub(crate) fn sample_drawn(&self, draw: &SampleDraw) -> Option<BsdfSample> {
        let SampleDraw { u_lobe, u, u_choice, cosine } = *draw;
        let wo_l = self.wo;
        let wi_l = if u_lobe < self.p_diffuse {
            self.opaque_local(cosine)
        } else if u_lobe < self.p_diffuse + self.p_spec || (self.p_glass == 0.0 && self.p_spec > 0.0) {
            self.opaque_local(self.spec.sample(self.opaque_local(wo_l), u)?)
        } else if self.p_glass > 0.0 {
            let s = self.glass.sample(wo_l, u_choice, u)?;
            if s.delta {
                let wi = self.frame.to_world(s.wi);
                if (wi.dot(self.ng) * self.wo_dot_ng > 0.0) == s.transmitted {
                    return None;
                }
                let tint = if s.transmitted { self.glass_weight } else { Vec3A::splat(self.glass_scalar) };
                return Some(BsdfSample { wi, weight: tint * (s.f_cos / (s.pdf * self.p_glass)), pdf: 0.0, delta: true, eta: s.eta });
            }
            s.wi
        } else {
            return None;
        };
        let wi = self.frame.to_world(wi_l);
        let (f, pdf) = self.eval_pdf(wi);
        if pdf <= 0.0 || !pdf.is_finite() || f == Vec3A::ZERO {
            return None;
        }
        let eta = if wi_l.z * wo_l.z < 0.0 {
            if wo_l.z > 0.0 {
                self.glass.eta
            } else {
                1.0 / self.glass.eta
            }
        } else {
            1.0
        };
        Some(BsdfSample { wi, weight: f / pdf, pdf, delta: false, eta })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{StreamKind, StreamSampler};
    use std::f32::consts::PI;

    fn params(metallic: f32, roughness: f32, specular: f32, transmission: f32) -> PbrParams {
        PbrParams { base_color: Vec3A::ONE, metallic, roughness, specular, transmission, ..Default::default() }
    }

    fn wo_at(cos: f32) -> Vec3A {
        Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos)
    }

    /// Mean and standard error of a scalar sample.
    struct Stats {
        n: f64,
        sum: f64,
        sum2: f64,
    }
    impl Stats {
        fn new() -> Self {
            Stats { n: 0.0, sum: 0.0, sum2: 0.0 }
        }
        fn add(&mut self, v: f64) {
            self.n += 1.0;
            self.sum += v;
            self.sum2 += v * v;
        }
        fn mean(&self) -> f64 {
            self.sum / self.n
        }
        fn se(&self) -> f64 {
            let m = self.mean();
            ((self.sum2 / self.n - m * m).max(0.0) / self.n).sqrt()
        }
    }

    /// Importance-sampled ∫ f |cos| (max channel), the fraction of samples that are valid
    /// non-delta directions, and the largest mismatch between the sampled weight and eval/pdf.
    fn sample_stats(b: &Bsdf, n: u32, seed: u64) -> (Stats, Stats, f32) {
        let st = StreamSampler::new(seed, StreamKind::Pt);
        let (mut albedo, mut non_delta) = (Stats::new(), Stats::new());
        let mut worst = 0.0f32;
        for i in 0..n {
            let s = st.sample(0, i);
            let r = b.sample(s.get1d(0), s.get2d(1), s.get1d(3));
            albedo.add(r.map(|r| r.weight.max_element() as f64).unwrap_or(0.0));
            non_delta.add(r.is_some_and(|r| !r.delta) as u8 as f64);
            if let Some(r) = r.filter(|r| !r.delta) {
                let (f, pdf) = b.eval_pdf(r.wi);
                assert!(pdf > 0.0, "sampled direction has zero pdf");
                assert!((pdf - r.pdf).abs() <= 1e-3 * pdf, "pdf {pdf} vs sampled {}", r.pdf);
                let rel = ((f / pdf - r.weight).abs().max_element()) / r.weight.max_element().max(1e-3);
                worst = worst.max(rel);
            }
        }
        (albedo, non_delta, worst)
    }

    /// Uniform-sphere MC estimates of ∫ pdf dω and ∫ f |cos| dω (max channel).
    fn sphere_stats(b: &Bsdf, n: u32, seed: u64) -> (Stats, Stats) {
        let st = StreamSampler::new(seed, StreamKind::Pt);
        let (mut pdf_int, mut f_int) = (Stats::new(), Stats::new());
        for i in 0..n {
            let u = st.sample(1, i).get2d(0);
            let z = 1.0 - 2.0 * u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * u.y;
            let wi = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
            let (f, pdf) = b.eval_pdf(wi);
            pdf_int.add((pdf * 4.0 * PI) as f64);
            f_int.add((f.max_element() * 4.0 * PI) as f64);
        }
        (pdf_int, f_int)
    }

    fn cases() -> Vec<(&'static str, PbrParams)> {
        vec![
            ("lambert", params(0.0, 1.0, 0.0, 0.0)),
            ("plastic r0.5", params(0.0, 0.5, 1.0, 0.0)),
            ("plastic r0.15", params(0.0, 0.15, 1.0, 0.0)),
            ("metal r0.2", params(1.0, 0.2, 1.0, 0.0)),
            ("metal r0.5", params(1.0, 0.5, 1.0, 0.0)),
            ("metal r1", params(1.0, 1.0, 1.0, 0.0)),
            ("half metal r0.4", params(0.5, 0.4, 1.0, 0.0)),
            ("rough glass r0.4", params(0.0, 0.4, 1.0, 1.0)),
            ("rough glass r0.7", params(0.0, 0.7, 1.0, 1.0)),
            ("frosted mix", params(0.0, 0.5, 1.0, 0.5)),
        ]
    }

    #[test]
    fn white_furnace_conserves_energy_and_sampling_matches_eval() {
        for (name, p) in cases() {
            for cos in [0.95f32, 0.5, 0.15] {
                let b = Bsdf::new(&p, Vec3A::Z, Vec3A::Z, wo_at(cos));
                let (albedo, _, worst) = sample_stats(&b, 20_000, 7);
                assert!(worst < 2e-3, "{name} cos {cos}: weight differs from eval/pdf by {worst}");
                // From outside, refraction's 1/η² only lowers the integral, so ≤ 1 holds for all.
                assert!(albedo.mean() <= 1.0 + 5.0 * albedo.se() + 1e-4, "{name} cos {cos}: albedo {} ± {}", albedo.mean(), albedo.se());
                // Too little energy: `albedo_matches_an_independent_quadrature_of_the_model`.
            }
        }
        // A pure Lambertian white surface reflects everything.
        let b = Bsdf::new(&params(0.0, 1.0, 0.0, 0.0), Vec3A::Z, Vec3A::Z, wo_at(0.7));
        let (albedo, _, _) = sample_stats(&b, 2_000, 1);
        assert!((albedo.mean() - 1.0).abs() < 1e-5, "{}", albedo.mean());
    }

    #[test]
    fn pdf_integrates_to_the_sampling_probability_and_eval_agrees_with_importance_sampling() {
        // ∫ pdf dω over the sphere = P(a non-delta direction is produced); and ∫ f|cos| by uniform
        // sampling must equal the importance-sampled estimate (a wrong pdf would bias the latter).
        for (name, p) in cases() {
            for cos in [0.9f32, 0.4] {
                let b = Bsdf::new(&p, Vec3A::Z, Vec3A::Z, wo_at(cos));
                let (albedo, valid, _) = sample_stats(&b, 40_000, 11);
                let (pdf_int, f_int) = sphere_stats(&b, 200_000, 13);
                let tol = |a: &Stats, b: &Stats| 5.0 * (a.se().powi(2) + b.se().powi(2)).sqrt() + 2e-3;
                assert!(
                    (pdf_int.mean() - valid.mean()).abs() < tol(&pdf_int, &valid),
                    "{name} cos {cos}: ∫pdf {} ± {} vs P(valid) {} ± {}",
                    pdf_int.mean(),
                    pdf_int.se(),
                    valid.mean(),
                    valid.se()
                );
                assert!(
                    (f_int.mean() - albedo.mean()).abs() < tol(&f_int, &albedo),
                    "{name} cos {cos}: uniform ∫f|cos| {} ± {} vs importance {} ± {}",
                    f_int.mean(),
                    f_int.se(),
                    albedo.mean(),
                    albedo.se()
                );
            }
        }
    }

    /// Per-channel importance-sampled albedo `E[weight]` (delta samples included) and the fraction
    /// of samples that are valid non-delta directions.
    fn sampled_albedo(b: &Bsdf, n: u32, seed: u64) -> ([Stats; 3], Stats) {
        let st = StreamSampler::new(seed, StreamKind::Pt);
        let (mut albedo, mut non_delta) = ([Stats::new(), Stats::new(), Stats::new()], Stats::new());
        for i in 0..n {
            let s = st.sample(0, i);
            let r = b.sample(s.get1d(0), s.get2d(1), s.get1d(3));
            let w = r.map_or(Vec3A::ZERO, |r| r.weight);
            for (c, a) in albedo.iter_mut().enumerate() {
                a.add(w[c] as f64);
            }
            non_delta.add(r.is_some_and(|r| !r.delta) as u8 as f64);
        }
        (albedo, non_delta)
    }

    /// Every lobe and mix, white and coloured, glass from both sides (`true`: `wo` inside).
    fn quadrature_cases() -> Vec<(&'static str, PbrParams, bool)> {
        let mut v: Vec<_> = cases().into_iter().map(|(name, p)| (name, p, false)).collect();
        let coloured = |base: Vec3A, p: PbrParams| PbrParams { base_color: base, ..p };
        v.extend([
            ("mirror metal r0", params(1.0, 0.0, 1.0, 0.0), false),
            ("gold r0.3", coloured(Vec3A::new(1.0, 0.78, 0.34), params(1.0, 0.3, 1.0, 0.0)), false),
            ("blue half metal r0.4", coloured(Vec3A::new(0.2, 0.6, 0.9), params(0.5, 0.4, 1.0, 0.0)), false),
            (
                "red plastic r0.6 specular 0.7 coloured",
                PbrParams { specular_color: Vec3A::new(1.0, 0.5, 2.0), ..coloured(Vec3A::new(0.8, 0.1, 0.1), params(0.0, 0.6, 0.7, 0.0)) },
                false,
            ),
            ("tinted frosted mix", coloured(Vec3A::new(0.9, 0.6, 0.3), params(0.0, 0.5, 1.0, 0.5)), false),
            ("tinted rough water r0.5", PbrParams { ior: 1.33, ..coloured(Vec3A::new(0.6, 0.9, 1.0), params(0.0, 0.5, 1.0, 1.0)) }, false),
            ("rough glass r0.4", params(0.0, 0.4, 1.0, 1.0), true),
            ("rough glass r0.7", params(0.0, 0.7, 1.0, 1.0), true),
            ("smooth tinted glass", coloured(Vec3A::new(0.6, 0.9, 1.0), params(0.0, 0.0, 1.0, 1.0)), false),
            ("smooth tinted glass", coloured(Vec3A::new(0.6, 0.9, 1.0), params(0.0, 0.0, 1.0, 1.0)), true),
        ]);
        v
    }

    #[test]
    fn albedo_matches_an_independent_quadrature_of_the_model() {
        // Three estimates of ∫ f |cos θi| dωi per channel: (a) the importance-sampled mean of the
        // `sample` weights, (b) a deterministic quadrature of the model's formulas, written out
        // again in `reference.rs` without calling the lobes, (c) the same quadrature of the
        // code's `eval_pdf`. (a) = (b) catches a wrong factor anywhere in eval or sampling;
        // (a) = (c) catches sampling that disagrees with eval/pdf; (b) = (c) pins eval without
        // Monte Carlo noise. The quadrature of the pdf must equal the probability that `sample`
        // returns a non-delta direction: 1 for a Lambertian, less where a microfacet sample
        // leaves the hemisphere (the lobe-selection probabilities sum to 1).
        use super::super::reference::{quadrature, Reference};
        let n = 20_000u32;
        // A loss of probability < ~5/n may be absent from n samples, leaving the sample's
        // standard error blind to it (near-mirror lobes lose ~1e-5 below the horizon).
        let rare = 5.0 / n as f64;
        let (mut report, mut failures, mut checks) = (String::new(), Vec::new(), 0);
        let mut check = |ok: bool, msg: String| {
            checks += 1;
            if !ok {
                failures.push(msg);
            }
        };
        for (name, p, inside) in quadrature_cases() {
            for cos in [0.95f32, 0.5, 0.15] {
                let wo = wo_at(cos) * Vec3A::new(1.0, 1.0, if inside { -1.0 } else { 1.0 });
                let b = Bsdf::new(&p, Vec3A::Z, Vec3A::Z, wo);
                let reference = Reference::new(&p, wo);
                let (albedo, valid) = sampled_albedo(&b, n, 17);
                let (q, err) = quadrature(reference.clusters(), 16, |wi| {
                    let r = reference.f_cos(wi);
                    let (f, pdf) = b.eval_pdf(wi.as_vec3a());
                    [r.x, r.y, r.z, f.x as f64, f.y as f64, f.z as f64, pdf as f64]
                });
                // Smooth glass: its delta lobes have no density to integrate.
                let delta = reference.delta_albedo();
                let case = format!("{name}, cos θo {cos}{}", if inside { " inside" } else { "" });
                for c in 0..3 {
                    let (mc, se) = (albedo[c].mean(), albedo[c].se());
                    let (model, e_model) = (q[c] + delta[c], err[c]);
                    let (eval, e_eval) = (q[3 + c] + delta[c], err[3 + c]);
                    report += &format!(
                        "{case} ch {c}: sampled {mc:.5} ± {se:.1e}, model {model:.5} ± {e_model:.0e} ({:+.2} se), eval {eval:.5}\n",
                        (mc - model) / se
                    );
                    check(
                        (mc - model).abs() <= 5.0 * se + e_model + rare,
                        format!(
                            "{case}, channel {c}: importance-sampled albedo {mc:.5} ± {se:.1e} is {:+.1} se from the model's {model:.5} (quadrature error ≤ {e_model:.1e})",
                            (mc - model) / se
                        ),
                    );
                    // (Delta lobes have no eval: there (a) = (b) is the whole check.)
                    check(
                        delta[c] != 0.0 || (mc - eval).abs() <= 5.0 * se + e_eval + rare,
                        format!("{case}, channel {c}: sampling disagrees with eval: sampled albedo {mc:.5} ± {se:.1e}, ∫ eval = {eval:.5} (quadrature error ≤ {e_eval:.1e})"),
                    );
                    check(
                        (eval - model).abs() <= e_eval + e_model + 2e-5 * model.max(1.0),
                        format!("{case}, channel {c}: ∫ eval = {eval:.6} but the model integrates to {model:.6} (quadrature errors ≤ {e_eval:.1e}, {e_model:.1e})"),
                    );
                    if !inside {
                        // From outside, refraction's 1/η² only lowers the integral. The layered
                        // approximation is not exactly conserving: the diffuse weight uses Fresnel
                        // at n·wo but the specular lobe reflects the mean of F(wo·h), which is
                        // larger (F is convex); the excess peaks at 1.3e-3 (white plastic,
                        // roughness ≈ 0.28, cos θo ≈ 0.58).
                        let excess = 1.5e-3;
                        check(
                            model <= 1.0 + excess + e_model && mc <= 1.0 + excess + 5.0 * se + rare,
                            format!("{case}, channel {c}: creates energy: model {model:.5}, sampled {mc:.5} ± {se:.1e}"),
                        );
                    }
                }
                let (pdf_int, e_pdf) = (q[6], err[6]);
                report +=
                    &format!("{case}: ∫pdf {pdf_int:.5} ± {e_pdf:.0e}, P(non-delta sample) {:.5} ± {:.1e}\n", valid.mean(), valid.se());
                check(
                    (pdf_int - valid.mean()).abs() <= 5.0 * valid.se() + e_pdf + rare,
                    format!(
                        "{case}: ∫ pdf dω = {pdf_int:.5} (quadrature error ≤ {e_pdf:.1e}) but `sample` yields a non-delta direction with probability {:.5} ± {:.1e}",
                        valid.mean(),
                        valid.se()
                    ),
                );
                check(pdf_int <= 1.0 + e_pdf + 1e-6, format!("{case}: ∫ pdf dω = {pdf_int:.6} > 1"));
                if matches!(b, Bsdf::Diffuse(_)) {
                    check((pdf_int - 1.0).abs() <= e_pdf + 1e-6, format!("{case}: a Lambertian's pdf integrates to {pdf_int:.6}, not 1"));
                }
            }
        }
        // The whole table is shown on failure (or with --nocapture).
        println!("{report}");
        assert!(failures.is_empty(), "{} of {checks} checks failed:\n{}", failures.len(), failures.join("\n"));
    }

    #[test]
    fn smooth_glass_alone_is_the_glass_lobe_with_probability_one() {
        let tinted = |p: PbrParams| PbrParams { base_color: Vec3A::new(0.6, 0.9, 0.0), ..p };
        let glass = [
            params(0.0, 0.0, 1.0, 1.0),
            tinted(params(0.0, 0.03, 0.5, 1.0)),
            PbrParams { ior: 1.33, ..tinted(params(-0.5, 0.0, 1.0, 2.0)) },
            PbrParams { ior: 1.0, ..params(0.0, 0.8, 1.0, 1.0) },
        ];
        let not_glass = [params(0.0, 0.0, 1.0, 0.99), params(0.01, 0.0, 1.0, 1.0), params(0.0, 0.04, 1.0, 1.0), params(0.0, 0.0, 1.0, 0.0)];
        let smooth = |p: &PbrParams| is_smooth_glass(p.metallic, p.roughness, p.transmission, p.ior);
        for p in &glass {
            assert!(smooth(p), "{p:?}");
            for wo in [wo_at(0.9), wo_at(0.2), -wo_at(0.5), -wo_at(0.05)] {
                let m = Bsdf::mixture(p, Vec3A::Z, Vec3A::Z, wo);
                assert_eq!((m.p_diffuse, m.p_spec, m.p_glass), (0.0, 0.0, 1.0), "{p:?}, wo {wo}");
                assert!(m.glass.smooth && !m.has_non_delta(), "{p:?}, wo {wo}");
                assert_eq!((m.glass_weight, m.glass_scalar), (p.base_color.max(Vec3A::ZERO), 1.0), "{p:?}");
            }
        }
        for p in &not_glass {
            assert!(!smooth(p), "{p:?}");
        }
    }

    #[test]
    fn smooth_glass_splits_by_exact_fresnel() {
        let eta = 1.5f32;
        for cos in [0.9f32, 0.3] {
            let b = Bsdf::new(&params(0.0, 0.0, 1.0, 1.0), Vec3A::Z, Vec3A::Z, wo_at(cos));
            assert!(!b.has_non_delta());
            let (albedo, valid, _) = sample_stats(&b, 20_000, 3);
            assert_eq!(valid.mean(), 0.0, "smooth glass must only produce delta samples");
            let r = super::super::fresnel::dielectric(cos, eta) as f64;
            let expect = r + (1.0 - r) / (eta * eta) as f64;
            // Each sample is 1 (reflect, prob r) or 1/η² (refract): binomial standard error.
            let se = (r * (1.0 - r) / 20_000.0).sqrt() * (1.0 - 1.0 / (eta * eta) as f64);
            assert!((albedo.mean() - expect).abs() < 5.0 * se + 1e-6, "cos {cos}: {} vs {expect}", albedo.mean());
        }
        // From inside beyond the critical angle everything reflects, with weight 1.
        let b = Bsdf::new(&params(0.0, 0.0, 1.0, 1.0), Vec3A::Z, Vec3A::Z, -wo_at(0.3));
        let (albedo, _, _) = sample_stats(&b, 1_000, 3);
        assert!((albedo.mean() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn geometric_normal_blocks_light_leaks() {
        // Shading normal tilted 30° from the geometric one: a direction below the geometric
        // surface but above the shading hemisphere must not reflect.
        let ng = Vec3A::Z;
        let ns = Vec3A::new(0.5, 0.0, 0.75f32.sqrt());
        let b = Bsdf::new(&params(0.0, 1.0, 0.0, 0.0), ns, ng, wo_at(0.8));
        let leak = Vec3A::new(0.99, 0.0, -0.1).normalize();
        assert!(ns.dot(leak) > 0.0);
        assert_eq!(b.eval(leak), Vec3A::ZERO);
        assert!(b.eval(Vec3A::new(0.3, 0.0, 0.9).normalize()).max_element() > 0.0);
        // Specular layer off and metallic 0 with black base: a black BSDF samples nothing.
        let black = PbrParams { base_color: Vec3A::ZERO, ..params(0.0, 1.0, 0.0, 0.0) };
        assert!(Bsdf::new(&black, Vec3A::Z, Vec3A::Z, wo_at(0.5)).sample(0.5, glam::Vec2::splat(0.5), 0.5).is_none());
    }

    #[test]
    fn the_diffuse_bsdf_agrees_with_the_pbr_model_without_specular() {
        // The same white Lambertian built by the general mixture (through its diffuse lobe
        // only, with the specular layer's weight at zero) and by `Diffuse` must agree exactly.
        let st = StreamSampler::new(11, StreamKind::Pt);
        let params = PbrParams { base_color: Vec3A::new(0.8, 0.5, 0.2), specular: 0.0, ..Default::default() };
        for i in 0..2000 {
            let s = st.sample(0, i);
            let unit = |u: glam::Vec2| lambert::sample(u) * if s.get1d(9) < 0.5 { 1.0 } else { -1.0 };
            let (ns, wo, wi) = (crate::vector::unit(unit(s.get2d(0)) + Vec3A::Z * 0.3), unit(s.get2d(2)), unit(s.get2d(4)));
            let Bsdf::Diffuse(d) = Bsdf::new(&params, ns, ns, wo) else { panic!("not the diffuse BSDF") };
            let m = Bsdf::mixture(&params, ns, ns, wo);
            assert_eq!(d.eval_pdf(wi), m.eval_pdf(wi), "eval at {wi}");
            // Sampling: the same direction and weight; the mixture's density comes back from
            // `eval_pdf` through the frame, so it may differ in the last bits.
            let draw = SampleDraw::new(0.5, s.get2d(6), 0.0);
            match (d.sample_drawn(&draw), m.sample_drawn(&draw)) {
                (Some(a), Some(b)) => {
                    assert_eq!(a.wi, b.wi);
                    // Densities are at most 1/π: an absolute bound.
                    assert!((a.pdf - b.pdf).abs() <= 1e-6 && (a.weight - b.weight).abs().max_element() <= 1e-5, "{a:?} vs {b:?}");
                }
                (None, None) => {}
                (a, b) => panic!("{a:?} vs {b:?}"),
            }
        }
    }
}

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
//! the material is energy conserving but not exactly reciprocal; `specularFactor = 0` leaves
//! a pure Lambertian surface. Opaque lobes are two-sided (they act on the side `wo` is on);
//! glass distinguishes inside from outside by the geometric normal's orientation (winding).
use super::dielectric::Dielectric;
use super::ggx::Ggx;
use super::microfacet::MicrofacetReflection;
use super::{lambert, luminance, Frame};
use glam::{Vec2, Vec3};

/// Material parameters resolved at a surface point (textures already applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PbrParams {
    pub base_color: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    /// `KHR_materials_specular` specularFactor (1 by default, 0 = no specular layer).
    pub specular: f32,
    pub specular_color: Vec3,
    /// `KHR_materials_transmission` transmissionFactor.
    pub transmission: f32,
    /// `KHR_materials_ior` (1.5 by default).
    pub ior: f32,
}

impl Default for PbrParams {
    fn default() -> Self {
        PbrParams {
            base_color: Vec3::ONE,
            metallic: 0.0,
            roughness: 1.0,
            specular: 1.0,
            specular_color: Vec3::ONE,
            transmission: 0.0,
            ior: 1.5,
        }
    }
}

/// A sampled direction with its Monte Carlo weight.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// World-space direction (unit).
    pub wi: Vec3,
    /// `f · |cos θi| / pdf`.
    pub weight: Vec3,
    /// Solid-angle density of the non-delta lobes at `wi` (0 for a delta sample).
    pub pdf: f32,
    /// Sampled from a delta lobe: the next emitter hit must not be MIS-weighted.
    pub delta: bool,
    /// Relative index crossed (η_t/η_i), 1 unless refracted.
    pub eta: f32,
}

/// The BSDF at one surface point for one outgoing direction.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    frame: Frame,
    /// Geometric normal (winding orientation), to reject light leaks through shading normals.
    ng: Vec3,
    /// `wo` in the local frame.
    wo: Vec3,
    /// Which side of the shading frame `wo` is on: opaque lobes are evaluated as if it were +z.
    side: f32,
    diffuse: Vec3,
    spec: MicrofacetReflection,
    glass: Dielectric,
    /// Glass transmission weight (tinted) and reflection weight (white).
    glass_weight: Vec3,
    glass_scalar: f32,
    /// `wo · ng`, whose sign tells the geometric side `wo` is on.
    wo_dot_ng: f32,
    /// Lobe-selection probabilities; they sum to 1 unless the BSDF is black.
    p_diffuse: f32,
    p_spec: f32,
    p_glass: f32,
}

impl Bsdf {
    /// `ns`, `ng`: unit shading and geometric normals with `ns·ng ≥ 0` (ng from the winding);
    /// `wo`: unit direction towards the previous vertex.
    pub fn new(params: &PbrParams, ns: Vec3, ng: Vec3, wo: Vec3) -> Bsdf {
        // Shading normals that put `wo` on the other side than the geometry are discarded.
        let ns = if ns.dot(wo) * ng.dot(wo) <= 0.0 { ng } else { ns };
        let frame = Frame::from_normal(ns);
        let wo_local = frame.to_local(wo);
        let side = if wo_local.z < 0.0 { -1.0 } else { 1.0 };
        let cos_o = wo_local.z.abs();

        let m = params.metallic.clamp(0.0, 1.0);
        let t = params.transmission.clamp(0.0, 1.0);
        let opaque = (1.0 - m) * (1.0 - t);
        let base = params.base_color.max(Vec3::ZERO);
        let r0 = ((params.ior - 1.0) / (params.ior + 1.0)).powi(2);
        let spec_factor = params.specular.clamp(0.0, 1.0);
        let f0_dielectric = (Vec3::splat(r0) * params.specular_color.max(Vec3::ZERO)).min(Vec3::ONE) * spec_factor;
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
        Bsdf {
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

    /// True if some lobe is not a delta distribution (light sampling can help).
    #[inline]
    pub fn has_non_delta(&self) -> bool {
        self.p_diffuse > 0.0 || self.p_spec > 0.0 || (self.p_glass > 0.0 && !self.glass.smooth)
    }

    #[inline]
    fn opaque_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.x, v.y, v.z * self.side)
    }

    /// `(f · |cos θi|, pdf)` for the world direction `wi`, over the non-delta lobes.
    #[inline]
    pub fn eval_pdf(&self, wi: Vec3) -> (Vec3, f32) {
        let wi_l = self.frame.to_local(wi);
        let wo_l = self.wo;
        let geometric_reflection = wi.dot(self.ng) * self.wo_dot_ng > 0.0;
        let shading_reflection = wi_l.z * wo_l.z > 0.0;
        if geometric_reflection != shading_reflection || wi_l.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let mut f = Vec3::ZERO;
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
            let w = if shading_reflection { Vec3::splat(self.glass_scalar) } else { self.glass_weight };
            f += w * fg;
            pdf += self.p_glass * pg;
        }
        (f * wi_l.z.abs(), pdf)
    }

    /// `f · |cos θi|` for the world direction `wi`.
    #[inline]
    pub fn eval(&self, wi: Vec3) -> Vec3 {
        self.eval_pdf(wi).0
    }

    #[inline]
    pub fn pdf(&self, wi: Vec3) -> f32 {
        self.eval_pdf(wi).1
    }

    /// Picks a lobe with `u_lobe`, a direction with `u`, and for glass reflect-or-refract with
    /// `u_choice`. `None` when the path ends here (black BSDF or a direction below the surface).
    pub fn sample(&self, u_lobe: f32, u: Vec2, u_choice: f32) -> Option<BsdfSample> {
        let wo_l = self.wo;
        let wi_l = if u_lobe < self.p_diffuse {
            self.opaque_local(lambert::sample(u))
        } else if u_lobe < self.p_diffuse + self.p_spec || (self.p_glass == 0.0 && self.p_spec > 0.0) {
            self.opaque_local(self.spec.sample(self.opaque_local(wo_l), u)?)
        } else if self.p_glass > 0.0 {
            let s = self.glass.sample(wo_l, u_choice, u)?;
            if s.delta {
                let wi = self.frame.to_world(s.wi);
                if (wi.dot(self.ng) * self.wo_dot_ng > 0.0) == s.transmitted {
                    return None;
                }
                let tint = if s.transmitted { self.glass_weight } else { Vec3::splat(self.glass_scalar) };
                return Some(BsdfSample { wi, weight: tint * (s.f_cos / (s.pdf * self.p_glass)), pdf: 0.0, delta: true, eta: s.eta });
            }
            s.wi
        } else {
            return None;
        };
        let wi = self.frame.to_world(wi_l);
        let (f, pdf) = self.eval_pdf(wi);
        if pdf <= 0.0 || !pdf.is_finite() || f == Vec3::ZERO {
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

//! A dielectric interface (glass) with exact Fresnel: smooth (delta reflection/refraction) when
//! the roughness is negligible, else rough (Walter et al. 2007, GGX with visible-normal
//! sampling). The local z axis points to the *outside*; `eta = n_inside / n_outside`.
//! Transmission uses the same masking-shadowing `G2 = 1/(1 + Λo + Λi)` as reflection, as pbrt-v4
//! does; the exact height-correlated form for transmission (a Beta function of the Λs) agrees at
//! normal incidence and transmits less at grazing angles on very rough glass.
//!
//! glTF's `KHR_materials_transmission` without `KHR_materials_volume` is defined as thin-walled;
//! cvtrace instead treats closed transmissive meshes as solid glass with `KHR_materials_ior`
//! (default 1.5), which is what glass scenes are modelled for.
use super::frame::reflect;
use super::fresnel::{dielectric as fresnel, refract};
use super::ggx::{Ggx, MIN_ALPHA};
use crate::vector::unit;
use glam::{Vec2, Vec3A};

/// Result of sampling a dielectric in local coordinates.
#[derive(Clone, Copy, Debug)]
pub struct DielectricSample {
    pub wi: Vec3A,
    /// `f · |cos θi|` (delta: the discrete weight), not yet divided by `pdf`.
    pub f_cos: f32,
    /// Density (or probability for delta lobes) of choosing `wi`.
    pub pdf: f32,
    /// Relative index crossed (`η_t/η_i`), 1 for reflection.
    pub eta: f32,
    pub transmitted: bool,
    pub delta: bool,
}

#[derive(Clone, Copy, Debug)]
pub struct Dielectric {
    pub eta: f32,
    pub ggx: Ggx,
    pub smooth: bool,
}

impl Dielectric {
    /// `alpha` below [`MIN_ALPHA`] (or an index of 1) gives the smooth, delta interface.
    pub fn new(eta: f32, alpha: f32) -> Dielectric {
        Dielectric { eta, ggx: Ggx::new(alpha), smooth: alpha < MIN_ALPHA || eta == 1.0 }
    }

    /// `f(wo, wi)` of the rough interface (zero for smooth ones).
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        self.eval_pdf(wo, wi).0
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// The generalised half vector of Walter et al., facing +z, with the relative index crossed.
    #[inline]
    fn half_vector(&self, wo: Vec3A, wi: Vec3A) -> Option<(Vec3A, f32, bool)> {
        let (co, ci) = (wo.z, wi.z);
        if co == 0.0 || ci == 0.0 {
            return None;
        }
        let reflect = co * ci > 0.0;
        let etap = if reflect {
            1.0
        } else if co > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let wm = wi * etap + wo;
        if wm.length_squared() == 0.0 {
            return None;
        }
        let wm = unit(wm);
        let wm = if wm.z < 0.0 { -wm } else { wm };
        // Microfacets seen from behind contribute nothing.
        if wm.dot(wi) * ci < 0.0 || wm.dot(wo) * co < 0.0 {
            return None;
        }
        Some((wm, etap, reflect))
    }

    /// `(f, pdf)` of the rough interface at once (they share the half vector and Fresnel term).
    pub fn eval_pdf(&self, wo: Vec3A, wi: Vec3A) -> (f32, f32) {
        if self.smooth {
            return (0.0, 0.0);
        }
        let Some((wm, etap, is_reflection)) = self.half_vector(wo, wi) else { return (0.0, 0.0) };
        let r = fresnel(wo.dot(wm), self.eta);
        let t = 1.0 - r;
        let d = self.ggx.d(wm);
        let g = self.ggx.g2(wo, wi);
        let pdf_h = self.ggx.pdf_visible(wo, wm);
        if is_reflection {
            let f = d * g * r / (4.0 * (wi.z * wo.z).abs());
            let pdf = pdf_h / (4.0 * wo.dot(wm).abs()) * r;
            (f, pdf)
        } else {
            let denom = wi.dot(wm) + wo.dot(wm) / etap;
            let denom2 = denom * denom;
            let f = d * g * t * (wi.dot(wm) * wo.dot(wm) / (wi.z * wo.z * denom2)).abs() / (etap * etap);
            let pdf = pdf_h * wi.dot(wm).abs() / denom2 * t;
            (f, pdf)
        }
    }

    /// Samples reflection or refraction with probability equal to their Fresnel weights.
    pub fn sample(&self, wo: Vec3A, u_choice: f32, u: Vec2) -> Option<DielectricSample> {
        if wo.z == 0.0 {
            return None;
        }
        if self.smooth {
            let r = fresnel(wo.z, self.eta);
            if u_choice < r {
                let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
                return Some(DielectricSample { wi, f_cos: r, pdf: r, eta: 1.0, transmitted: false, delta: true });
            }
            let (wi, etap) = refract(wo, Vec3A::Z, self.eta)?;
            let t = 1.0 - r;
            return Some(DielectricSample { wi, f_cos: t / (etap * etap), pdf: t, eta: etap, transmitted: true, delta: true });
        }
        let wm = self.ggx.sample_visible(wo, u);
        let r = fresnel(wo.dot(wm), self.eta);
        let wi = if u_choice < r {
            let wi = reflect(wo, wm);
            if wi.z * wo.z <= 0.0 {
                return None;
            }
            wi
        } else {
            let (wi, _) = refract(wo, wm, self.eta)?;
            if wi.z * wo.z >= 0.0 {
                return None;
            }
            wi
        };
        let (f, pdf) = self.eval_pdf(wo, wi);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let transmitted = wi.z * wo.z < 0.0;
        let eta = if !transmitted {
            1.0
        } else if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        Some(DielectricSample { wi, f_cos: f * wi.z.abs(), pdf, eta, transmitted, delta: false })
    }
}

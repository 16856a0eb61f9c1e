//! Test-only reference for the energy tests: the documented scattering model written out again in
//! f64 from the published formulas — GGX `D` (Walter et al. 2007, eq. 33), Smith's Λ for GGX
//! (Heitz 2014, eq. 72) in the height-correlated `G2 = 1/(1 + Λo + Λi)` that `ggx.rs` documents,
//! Schlick and exact Fresnel (Walter's eq. 22 form), Walter's refraction BTDF (eq. 21) and the
//! glTF lobe weights of `pbr.rs` — without calling the lobes' code, plus a deterministic
//! quadrature over the sphere. A wrong factor in `eval` then shows as a gap between the
//! quadrature of this model and the importance-sampled albedo.
use super::ggx::MIN_ALPHA;
use crate::scene::material::PbrParams;
use glam::{DVec3, Vec3A};
use std::f64::consts::PI;

/// GGX normal distribution of a unit microfacet normal `m`.
fn ggx_d(alpha: f64, m: DVec3) -> f64 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let cos2 = m.z * m.z;
    let tan2 = (m.x * m.x + m.y * m.y) / cos2;
    let a2 = alpha * alpha;
    a2 / (PI * cos2 * cos2 * (a2 + tan2) * (a2 + tan2))
}

/// Smith's Λ for GGX: `(√(1 + 1/a²) − 1)/2` with `a = 1/(α tan θ)`.
fn smith_lambda(alpha: f64, w: DVec3) -> f64 {
    let sin = (w.x * w.x + w.y * w.y).sqrt();
    if sin == 0.0 {
        return 0.0;
    }
    let a = w.z.abs() / (alpha * sin);
    0.5 * ((1.0 + 1.0 / (a * a)).sqrt() - 1.0)
}

/// Height-correlated masking-shadowing, with the χ⁺ back-facing terms.
fn smith_g2(alpha: f64, wo: DVec3, wi: DVec3, m: DVec3) -> f64 {
    if wo.dot(m) * wo.z <= 0.0 || wi.dot(m) * wi.z <= 0.0 {
        return 0.0;
    }
    1.0 / (1.0 + smith_lambda(alpha, wo) + smith_lambda(alpha, wi))
}

/// Unpolarised Fresnel reflectance for `c = |cos|` against the facet on the incident side and
/// `eta = η_transmitted / η_incident`; 1 under total internal reflection.
fn fresnel_exact(c: f64, eta: f64) -> f64 {
    let g2 = eta * eta - 1.0 + c * c;
    if g2 < 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

fn schlick(f0: DVec3, f90: f64, c: f64) -> DVec3 {
    f0 + (DVec3::splat(f90) - f0) * (1.0 - c).powi(5)
}

/// The material of `PbrParams` seen from `wo`, in a frame whose z axis is the normal (both the
/// shading and the geometric one: the tests do not tilt them).
pub struct Reference {
    wo: DVec3,
    /// Alpha of the opaque specular lobe (clamped to `MIN_ALPHA`) and of the glass.
    alpha: f64,
    glass_alpha: f64,
    diffuse: DVec3,
    f0: DVec3,
    f90: f64,
    /// Weight of the glass interface; its transmission is also tinted by `tint`.
    glass: f64,
    tint: DVec3,
    eta: f64,
    smooth_glass: bool,
}

impl Reference {
    pub fn new(p: &PbrParams, wo: Vec3A) -> Reference {
        let wo = wo.as_dvec3().normalize();
        let m = p.metallic.clamp(0.0, 1.0) as f64;
        let t = p.transmission.clamp(0.0, 1.0) as f64;
        let spec = p.specular.clamp(0.0, 1.0) as f64;
        let base = p.base_color.as_dvec3().max(DVec3::ZERO);
        let ior = p.ior as f64;
        // glTF: the dielectric layer's F0 from KHR_materials_ior, coloured and scaled by
        // KHR_materials_specular; its F90 is the specular factor.
        let f0_layer =
            (DVec3::splat(((ior - 1.0) / (ior + 1.0)).powi(2)) * p.specular_color.as_dvec3().max(DVec3::ZERO)).min(DVec3::ONE) * spec;
        let opaque = (1.0 - m) * (1.0 - t);
        // Diffuse under the layer, weighted by what the layer does not reflect at the view angle.
        let diffuse = base * opaque * (1.0 - schlick(f0_layer, spec, wo.z.abs()).max_element());
        let roughness = p.roughness.clamp(0.0, 1.0) as f64;
        let glass_alpha = roughness * roughness;
        Reference {
            wo,
            alpha: glass_alpha.max(MIN_ALPHA as f64),
            glass_alpha,
            diffuse,
            f0: f0_layer * opaque + base * m,
            f90: spec * opaque + m,
            glass: (1.0 - m) * t,
            tint: base,
            eta: ior.max(1.0),
            smooth_glass: glass_alpha < MIN_ALPHA as f64 || ior <= 1.0,
        }
    }

    /// Indices of refraction on `wo`'s side and on the other side.
    fn indices(&self) -> (f64, f64) {
        if self.wo.z > 0.0 {
            (1.0, self.eta)
        } else {
            (self.eta, 1.0)
        }
    }

    /// `f(wo, wi) · |cos θi|` of the non-delta lobes, per channel.
    pub fn f_cos(&self, wi: DVec3) -> DVec3 {
        let wo = self.wo;
        if wo.z == 0.0 || wi.z == 0.0 {
            return DVec3::ZERO;
        }
        let mut f = DVec3::ZERO;
        if wo.z * wi.z > 0.0 {
            // Opaque lobes are two-sided: mirror both directions to +z.
            let flip = DVec3::new(1.0, 1.0, wo.z.signum());
            let (o, i) = (wo * flip, wi * flip);
            f += self.diffuse / PI;
            let h = (o + i).normalize();
            let spec = ggx_d(self.alpha, h) * smith_g2(self.alpha, o, i, h) / (4.0 * o.z * i.z);
            f += schlick(self.f0, self.f90, o.dot(h)) * spec;
        }
        if self.glass > 0.0 && !self.smooth_glass {
            let a = self.glass_alpha;
            let (eta_o, eta_i) = self.indices();
            if wo.z * wi.z > 0.0 {
                // Reflection off the interface, untinted.
                let h = (wo + wi).normalize() * wo.z.signum();
                let r = fresnel_exact(wo.dot(h).abs(), eta_i / eta_o);
                f += DVec3::splat(self.glass * r * ggx_d(a, h) * smith_g2(a, wo, wi, h) / (4.0 * (wo.z * wi.z).abs()));
            } else {
                // Walter's refraction: h_t ∝ −(η_i wi + η_o wo), with η_o on wo's side and η_i
                // on the other; (η_i wi·h + η_o wo·h)² = |η_i wi + η_o wo|².
                let sum = eta_i * wi + eta_o * wo;
                let h = -sum.normalize();
                let h = if h.z < 0.0 { -h } else { h };
                let t = 1.0 - fresnel_exact(wo.dot(h).abs(), eta_i / eta_o);
                let jac = (wi.dot(h) * wo.dot(h) / (wi.z * wo.z)).abs() * eta_o * eta_o / sum.length_squared();
                f += self.glass * self.tint * (t * ggx_d(a, h) * smith_g2(a, wo, wi, h) * jac);
            }
        }
        f * wi.z.abs()
    }

    /// Albedo of the delta lobes (smooth glass): Fresnel reflection plus the tinted
    /// transmission, scaled by `(η_o/η_i)²` for radiance.
    pub fn delta_albedo(&self) -> DVec3 {
        if self.glass == 0.0 || !self.smooth_glass {
            return DVec3::ZERO;
        }
        let (eta_o, eta_i) = self.indices();
        let r = fresnel_exact(self.wo.z.abs(), eta_i / eta_o);
        self.glass * (DVec3::splat(r) + self.tint * ((1.0 - r) * (eta_o / eta_i).powi(2)))
    }

    /// Where to cluster quadrature nodes in the upper and the lower hemisphere (`wo` must lie in
    /// the xz plane with x ≥ 0, so every lobe centre is at φ = π).
    pub fn clusters(&self) -> [Cluster; 2] {
        let cos_o = self.wo.z.abs();
        let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let (eta_o, eta_i) = self.indices();
        // Tilting h by δ moves the mirror direction by 2δ in the plane of incidence but by
        // 2δ cos θo across it: grazing lobes are thin in φ.
        let mirror = Cluster { theta: cos_o.acos(), width: self.alpha, phi_width: self.alpha * cos_o / sin_o.max(1e-3), kink: None };
        // Around the refracted direction (the horizon under total internal reflection); its lobe
        // is narrower than the reflected one. Where Walter's h_t crosses the horizon,
        // η_i cos θi = −η_o cos θo, D(h_t) > 0 and the integrand jumps: a cell boundary there
        // keeps the quadrature's accuracy.
        let sin_t = sin_o * eta_o / eta_i;
        let cos_kink = cos_o * eta_o / eta_i;
        let theta_t = if sin_t < 1.0 { sin_t.asin() } else { 0.5 * PI };
        let refracted = Cluster {
            theta: theta_t,
            width: 0.5 * self.alpha,
            phi_width: 0.5 * self.alpha / theta_t.sin().max(1e-3),
            kink: (cos_kink < 1.0).then(|| cos_kink.acos()),
        };
        let below = |c: Cluster| Cluster { theta: PI - c.theta, kink: c.kink.map(|t| PI - t), ..c };
        if self.wo.z > 0.0 {
            [mirror, below(refracted)]
        } else {
            [refracted, below(mirror)]
        }
    }
}

/// Where a hemisphere's integrand peaks (at φ = π): polar angle, widths in θ and in φ, and the
/// polar angle of a discontinuity, if any.
#[derive(Clone, Copy, Debug)]
pub struct Cluster {
    pub theta: f64,
    pub width: f64,
    pub phi_width: f64,
    pub kink: Option<f64>,
}

/// Breakpoints of `[a, b]`: `n` equal intervals merged with `n` intervals on each side of `c`
/// whose lengths grow geometrically from `w`, so a peak of width `w` and its power-law tails
/// (GGX's fall as a power of the angle) are resolved at every scale.
fn breaks(a: f64, b: f64, c: f64, w: f64, n: usize) -> Vec<f64> {
    let mut x: Vec<f64> = (0..=n).map(|j| a + (b - a) * j as f64 / n as f64).collect();
    for (len, dir) in [(b - c, 1.0), (c - a, -1.0)] {
        if len > 0.0 {
            let l = (len / w).ln_1p();
            x.extend((1..n).map(|j| c + dir * w * (l * j as f64 / n as f64).exp_m1()));
        }
    }
    x.push(c);
    x.retain(|v| (a..=b).contains(v));
    x.sort_by(f64::total_cmp);
    x.dedup();
    x
}

/// Three-point Gauss–Legendre nodes and weights of the intervals between consecutive
/// breakpoints (exact for quintics, so smooth pieces converge as h⁶).
fn nodes(x: &[f64]) -> Vec<(f64, f64)> {
    const G: [(f64, f64); 3] = [(-0.774_596_669_241_483_4, 5.0 / 9.0), (0.0, 8.0 / 9.0), (0.774_596_669_241_483_4, 5.0 / 9.0)];
    x.windows(2).flat_map(|p| G.map(|(t, w)| (0.5 * (p[0] + p[1]) + 0.5 * (p[1] - p[0]) * t, 0.5 * (p[1] - p[0]) * w))).collect()
}

/// `∫ g(ω) dω` over the sphere by a tensor-product Gauss rule in (θ, φ), θ from +z, one grid per
/// hemisphere so the horizon (where a pdf may jump) is a cell boundary. Each grid has about `3n`
/// cells per axis, clustered about its lobe centre and φ = π.
fn integrate<const K: usize>(clusters: [Cluster; 2], n: usize, g: &mut impl FnMut(DVec3) -> [f64; K]) -> [f64; K] {
    let mut total = [0.0; K];
    for (k, cl) in clusters.into_iter().enumerate() {
        let (a, b) = if k == 0 { (0.0, 0.5 * PI) } else { (0.5 * PI, PI) };
        let mut theta = breaks(a, b, cl.theta, cl.width.max(1e-4), n);
        if let Some(t) = cl.kink.filter(|t| (a..=b).contains(t)) {
            theta.push(t);
            theta.sort_by(f64::total_cmp);
            theta.dedup();
        }
        let phi = nodes(&breaks(0.0, 2.0 * PI, PI, cl.phi_width.clamp(1e-4, PI), n));
        for (t, dt) in nodes(&theta) {
            let (st, ct) = t.sin_cos();
            for &(p, dp) in &phi {
                let (sp, cp) = p.sin_cos();
                let v = g(DVec3::new(st * cp, st * sp, ct));
                let d_omega = st * dt * dp;
                for (acc, v) in total.iter_mut().zip(v) {
                    *acc += v * d_omega;
                }
            }
        }
    }
    total
}

/// The quadrature at `2n` base intervals per axis, and its difference from the one at `n` as a
/// bound on its error: conservative, as halving the cells divides the error by ~64 where the
/// integrand is smooth, and by at least ~3 at the remaining kinks (the horizon under grazing
/// lobes, Fresnel's √ at the critical angle, the χ⁺ edges of refraction).
pub fn quadrature<const K: usize>(clusters: [Cluster; 2], n: usize, mut g: impl FnMut(DVec3) -> [f64; K]) -> ([f64; K], [f64; K]) {
    let coarse = integrate(clusters, n, &mut g);
    let fine = integrate(clusters, 2 * n, &mut g);
    (fine, std::array::from_fn(|k| (fine[k] - coarse[k]).abs()))
}

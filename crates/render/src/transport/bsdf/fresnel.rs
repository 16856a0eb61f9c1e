//! Fresnel reflectance: Schlick's approximation for the glTF layers, the exact dielectric
//! formula for glass.
use glam::Vec3A;

/// Schlick's approximation with an explicit grazing value `f90` (glTF's `KHR_materials_specular`).
#[inline]
pub fn schlick(f0: Vec3A, f90: f32, cos: f32) -> Vec3A {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3A::splat(f90) - f0) * m
}

/// Unpolarised reflectance of a smooth dielectric interface. `cos_i` is measured against the
/// normal on the *outside*; `eta = n_inside / n_outside`. A negative `cos_i` means the light
/// arrives from inside. Returns 1 under total internal reflection.
#[inline]
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Refracts `wi` (pointing away from the surface) through the interface with normal `n` and
/// relative index `eta = n_inside / n_outside` (`n` points outside). Returns the transmitted
/// direction and the relative index actually crossed (`η_t / η_i`), or `None` under total
/// internal reflection.
#[inline]
pub fn refract(wi: Vec3A, mut n: Vec3A, mut eta: f32) -> Option<(Vec3A, f32)> {
    let mut cos_i = n.dot(wi);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_fresnel_known_values() {
        // Normal incidence: ((η-1)/(η+1))².
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((dielectric(-1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything; beyond the critical angle inside: TIR.
        assert!(dielectric(1e-4, 1.5) > 0.99);
        assert_eq!(dielectric(-0.5, 1.5), 1.0);
        // Brewster angle: the parallel component vanishes, so R = r_perp²/2.
        let tb = 1.5f32.atan();
        let r = dielectric(tb.cos(), 1.5);
        let ct = (1.0 - (tb.sin() / 1.5).powi(2)).sqrt();
        let rp = (tb.cos() - 1.5 * ct) / (tb.cos() + 1.5 * ct);
        assert!((r - 0.5 * rp * rp).abs() < 1e-5, "{r}");
    }

    #[test]
    fn refraction_obeys_snell() {
        let wi = Vec3A::new(0.6, 0.0, 0.8);
        let (wt, etap) = refract(wi, Vec3A::Z, 1.5).unwrap();
        assert_eq!(etap, 1.5);
        assert!((wt.length() - 1.0).abs() < 1e-5);
        assert!(wt.z < 0.0);
        assert!((0.6 - 1.5 * (-wt.x)).abs() < 1e-5, "sin ratio, wt {wt}");
        // Reversibility: light travelling back along -wt leaves along the original wi.
        let (back, etap2) = refract(wt, Vec3A::Z, 1.5).unwrap();
        assert!((etap2 - 1.0 / 1.5).abs() < 1e-6);
        assert!((back - wi).length() < 1e-5, "{back}");
        assert!(refract(Vec3A::new(0.9, 0.0, -0.43589).normalize(), Vec3A::Z, 1.5).is_none());
    }
}

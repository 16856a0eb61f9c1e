//! `KHR_lights_punctual` lights: point, spot and directional ("sun").
//!
//! They are delta lights: no ray ever hits them, so they are reached only by next-event
//! estimation and need no MIS. Units follow the project convention (glTF's photometric units
//! read 1:1 as linear-RGB radiometric ones): point and spot lights have radiant intensity
//! `I = colour × intensity` (radiance arriving ∝ I/d², `range` ignored); a directional light
//! gives irradiance `E = colour × intensity` on a surface facing it.
use crate::intersect::MAX_COORDINATE;
use crate::vector::luminance;
use glam::Vec3A;
use std::f32::consts::FRAC_PI_2;

/// One punctual light in world space. Directions are unit vectors *along which light travels*
/// (a node's local −Z).
#[derive(Clone, Debug, PartialEq)]
pub enum Punctual {
    Point { position: Vec3A, intensity: Vec3A },
    Spot { position: Vec3A, direction: Vec3A, intensity: Vec3A, cos_inner: f32, cos_outer: f32 },
    Directional { direction: Vec3A, irradiance: Vec3A },
}

/// Light arriving at a point from a punctual light.
#[derive(Clone, Copy, Debug)]
pub struct PunctualSample {
    /// Unit direction from the receiving point towards the light.
    pub wi: Vec3A,
    /// Where a shadow ray ends: the light's position, `None` for a light at infinity.
    pub position: Option<Vec3A>,
    /// `I·falloff/d²` or `E`: what multiplies `f·|cos θ|` (no density: the light is a delta).
    pub li: Vec3A,
}

impl Punctual {
    /// A spot light with the glTF cone angles (radians), checked: `0 ≤ inner < outer ≤ π/2`.
    pub fn spot(position: Vec3A, direction: Vec3A, intensity: Vec3A, inner: f32, outer: f32) -> Result<Punctual, String> {
        if !(inner.is_finite() && outer.is_finite() && 0.0 <= inner && inner < outer && outer <= FRAC_PI_2) {
            return Err(format!("spot cone angles inner {inner} and outer {outer} must satisfy 0 ≤ innerConeAngle < outerConeAngle ≤ π/2"));
        }
        Ok(Punctual::Spot { position, direction, intensity, cos_inner: inner.cos(), cos_outer: outer.cos() })
    }

    /// Finite, non-negative colour × intensity, unit directions, finite positions.
    pub fn validate(&self) -> Result<(), String> {
        let (value, dir, pos) = match self {
            Punctual::Point { position, intensity } => (*intensity, None, Some(*position)),
            Punctual::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                if !(cos_inner > cos_outer && *cos_outer >= 0.0 && *cos_inner <= 1.0) {
                    return Err("spot cone must satisfy 0 ≤ innerConeAngle < outerConeAngle ≤ π/2".into());
                }
                (*intensity, Some(*direction), Some(*position))
            }
            Punctual::Directional { direction, irradiance } => (*irradiance, Some(*direction), None),
        };
        if !(value.is_finite() && value.min_element() >= 0.0) {
            return Err(format!("colour × intensity {value} must be finite and non-negative"));
        }
        if dir.is_some_and(|d| !d.is_finite() || (d.length() - 1.0).abs() > 1e-3) {
            return Err("direction is not a unit vector (degenerate node transform?)".into());
        }
        if pos.is_some_and(|p| !p.is_finite()) {
            return Err("position is not finite".into());
        }
        let far = MAX_COORDINATE;
        if pos.is_some_and(|p| p.abs().max_element() > far) {
            return Err(format!("position is farther than {far:e} from the origin"));
        }
        Ok(())
    }

    /// Emitted power in luminance units, for light selection (pbrt's estimates): point `4π·I`,
    /// spot `2π(1 − cos((θi + θo)/2))·I`, directional `π r²·E` with `r` the scene's
    /// bounding-sphere radius (the disc of the scene it can light).
    pub fn power(&self, scene_radius: f32) -> f64 {
        let lum = |c: Vec3A| luminance(c.max(Vec3A::ZERO)) as f64;
        match self {
            Punctual::Point { intensity, .. } => 4.0 * std::f64::consts::PI * lum(*intensity),
            Punctual::Spot { intensity, cos_inner, cos_outer, .. } => {
                let half = 0.5 * ((*cos_inner as f64).acos() + (*cos_outer as f64).acos());
                2.0 * std::f64::consts::PI * (1.0 - half.cos()) * lum(*intensity)
            }
            Punctual::Directional { irradiance, .. } => std::f64::consts::PI * (scene_radius as f64).powi(2) * lum(*irradiance),
        }
    }

    /// The light arriving at `p`; `None` if none does (outside a spot's cone, at the light).
    #[inline]
    pub fn sample_li(&self, p: Vec3A) -> Option<PunctualSample> {
        match *self {
            Punctual::Point { position, intensity } => {
                let d = position - p;
                let dist2 = d.length_squared();
                (dist2 > 0.0).then(|| PunctualSample { wi: d / dist2.sqrt(), position: Some(position), li: intensity / dist2 })
            }
            Punctual::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                let d = position - p;
                let dist2 = d.length_squared();
                if dist2 <= 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let falloff = spot_falloff(-wi.dot(direction), cos_inner, cos_outer);
                (falloff > 0.0).then(|| PunctualSample { wi, position: Some(position), li: intensity * (falloff / dist2) })
            }
            Punctual::Directional { direction, irradiance } => Some(PunctualSample { wi: -direction, position: None, li: irradiance }),
        }
    }
}

/// The glTF spec's spot attenuation for `cos_angle` between the spot axis and the direction to
/// the lit point: 1 inside the inner cone, 0 outside the outer, and between them the square of
/// the linear ramp in cosine (`saturate(cd · scale + offset)²` of the spec's sample code).
#[inline]
pub fn spot_falloff(cos_angle: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
    let t = ((cos_angle - cos_outer) * scale).clamp(0.0, 1.0);
    t * t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_with_the_square_of_the_distance() {
        let l = Punctual::Point { position: Vec3A::new(0.0, 2.0, 0.0), intensity: Vec3A::new(4.0, 8.0, 12.0) };
        let s = l.sample_li(Vec3A::ZERO).unwrap();
        assert_eq!(s.wi, Vec3A::Y);
        assert_eq!(s.position, Some(Vec3A::new(0.0, 2.0, 0.0)));
        assert_eq!(s.li, Vec3A::new(1.0, 2.0, 3.0));
        assert!(l.sample_li(Vec3A::new(0.0, 2.0, 0.0)).is_none());
    }

    #[test]
    fn spot_is_full_inside_the_inner_cone_zero_outside_the_outer_and_monotone_between() {
        let (inner, outer) = (0.3f32, 0.6f32);
        let l = Punctual::spot(Vec3A::ZERO, Vec3A::NEG_Y, Vec3A::ONE, inner, outer).unwrap();
        // A receiver one unit below at angle `a` from the axis, at distance 1.
        let at = |a: f32| l.sample_li(Vec3A::new(a.sin(), -a.cos(), 0.0)).map_or(0.0, |s| s.li.x);
        assert!((at(0.0) - 1.0).abs() < 1e-6);
        assert!((at(0.29) - 1.0).abs() < 1e-6);
        assert_eq!(at(0.61), 0.0);
        assert_eq!(at(1.2), 0.0);
        let mut last = 1.0;
        for k in 1..100 {
            let a = inner + (outer - inner) * k as f32 / 100.0;
            let v = at(a);
            assert!(v <= last + 1e-6 && v > 0.0, "not monotone at {a}: {v} after {last}");
            // The spec's formula.
            let t = ((a.cos() - outer.cos()) / (inner.cos() - outer.cos())).clamp(0.0, 1.0);
            assert!((v - t * t).abs() < 1e-4, "{a}: {v} vs {}", t * t);
            last = v;
        }
        for (i, o) in [(0.5, 0.5), (0.6, 0.3), (-0.1, 0.3), (0.2, 1.7), (f32::NAN, 0.5)] {
            let e = Punctual::spot(Vec3A::ZERO, Vec3A::NEG_Y, Vec3A::ONE, i, o).unwrap_err();
            assert!(e.contains("innerConeAngle"), "{e}");
        }
    }

    #[test]
    fn directional_light_comes_from_against_its_direction() {
        let d = Vec3A::new(0.0, -0.6, -0.8);
        let s = Punctual::Directional { direction: d, irradiance: Vec3A::splat(3.0) }.sample_li(Vec3A::new(5.0, 1.0, 2.0)).unwrap();
        assert_eq!((s.wi, s.position, s.li), (-d, None, Vec3A::splat(3.0)));
    }

    #[test]
    fn validation_rejects_negative_and_non_finite_values() {
        assert!(Punctual::Point { position: Vec3A::ZERO, intensity: Vec3A::new(1.0, -1.0, 0.0) }.validate().is_err());
        assert!(Punctual::Point { position: Vec3A::ZERO, intensity: Vec3A::splat(f32::INFINITY) }.validate().is_err());
        assert!(Punctual::Directional { direction: Vec3A::ZERO, irradiance: Vec3A::ONE }.validate().is_err());
        assert!(Punctual::Directional { direction: Vec3A::Y, irradiance: Vec3A::ONE }.validate().is_ok());
        // Powers: 4π I, π r² E.
        let p = Punctual::Point { position: Vec3A::ZERO, intensity: Vec3A::ONE }.power(1.0);
        assert!((p - 4.0 * std::f64::consts::PI).abs() < 1e-5);
        let d = Punctual::Directional { direction: Vec3A::Y, irradiance: Vec3A::ONE }.power(2.0);
        assert!((d - 4.0 * std::f64::consts::PI).abs() < 1e-5);
    }
}

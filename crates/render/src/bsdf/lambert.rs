//! The Lambertian lobe: `f = 1/π` on the upper hemisphere, cosine-weighted sampling.
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4};

/// `f` (without albedo) for local directions; zero unless both are above the surface.
#[inline]
pub fn eval(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z > 0.0 && wi.z > 0.0 {
        FRAC_1_PI
    } else {
        0.0
    }
}

#[inline]
pub fn pdf(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z > 0.0 && wi.z > 0.0 {
        wi.z * FRAC_1_PI
    } else {
        0.0
    }
}

/// Shirley–Chiu concentric map of the unit square onto the unit disk (area preserving).
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() { (o.x, FRAC_PI_4 * (o.y / o.x)) } else { (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y)) };
    Vec2::new(r * theta.cos(), r * theta.sin())
}

/// A cosine-distributed direction on the upper hemisphere (Malley's method).
#[inline]
pub fn sample(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

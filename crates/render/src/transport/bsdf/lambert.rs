//! The Lambertian lobe: `f = 1/π` on the upper hemisphere, cosine-weighted sampling.
use crate::select::select_pair;
use glam::{Vec2, Vec3A};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4};

/// `f` (without albedo) for local directions; zero unless both are above the surface.
#[inline]
pub fn eval(wo: Vec3A, wi: Vec3A) -> f32 {
    if wo.z > 0.0 && wi.z > 0.0 {
        FRAC_1_PI
    } else {
        0.0
    }
}

#[inline]
pub fn pdf(wo: Vec3A, wi: Vec3A) -> f32 {
    if wo.z > 0.0 && wi.z > 0.0 {
        wi.z * FRAC_1_PI
    } else {
        0.0
    }
}

/// `(sin a, cos a)` for `|a| ≤ π/4` by Taylor polynomials (error < 4e-7, below f32's
/// resolution of the result): the concentric map only needs this range, and libm's general
/// `sincosf` was a measurable share of the render time.
#[inline]
fn sin_cos_quarter(a: f32) -> (f32, f32) {
    // Multiplications by the reciprocals: the compiler may not turn `x / 6.0` into one, and
    // seven dependent divisions were most of this function's cost.
    let a2 = a * a;
    let s = a * (1.0 - a2 * (1.0 / 6.0) * (1.0 - a2 * (1.0 / 20.0) * (1.0 - a2 * (1.0 / 42.0))));
    let c = 1.0 - a2 * 0.5 * (1.0 - a2 * (1.0 / 12.0) * (1.0 - a2 * (1.0 / 30.0) * (1.0 - a2 * (1.0 / 56.0))));
    (s, c)
}

/// Shirley–Chiu concentric map of the unit square onto the unit disk (area preserving).
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    concentric_disk_radius(u).0
}

/// [`concentric_disk`] and the point's distance from the centre, which the map knows before
/// the angle: it is `|major|` below.
#[inline]
fn concentric_disk_radius(u: Vec2) -> (Vec2, f32) {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return (Vec2::ZERO, 0.0);
    }
    // The two octant cases as selects: which one applies is random, so a branch would be
    // mispredicted half the time. With `a = π/4 · minor/major`, θ = a in the x-major case and
    // θ = π/2 − a in the y-major one, where cos θ = sin a and sin θ = cos a.
    let x_major = o.x.abs() > o.y.abs();
    let (major, minor) = select_pair(x_major, (o.x, o.y), (o.y, o.x));
    let (s, c) = sin_cos_quarter(FRAC_PI_4 * (minor / major));
    let (cos_t, sin_t) = select_pair(x_major, (c, s), (s, c));
    (Vec2::new(major * cos_t, major * sin_t), major.abs())
}

/// A cosine-distributed direction on the upper hemisphere (Malley's method).
///
/// The height comes from the disk radius `r` as `√(1 − r²)`, not from the mapped point's
/// length: the two agree to the polynomials' rounding, and this way the square root does not
/// wait for the division and the polynomials (this sampling lies on the path from one ray to
/// the next; docs/performance.md).
#[inline]
pub fn sample(u: Vec2) -> Vec3A {
    let (d, r) = concentric_disk_radius(u);
    let z = (1.0 - r * r).max(0.0).sqrt();
    Vec3A::new(d.x, d.y, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sin_cos_matches_libm() {
        for i in 0..=1000 {
            let a = -FRAC_PI_4 + i as f32 * (std::f32::consts::FRAC_PI_2 / 1000.0);
            let (s, c) = sin_cos_quarter(a);
            assert!((s - a.sin()).abs() < 4e-7 && (c - a.cos()).abs() < 4e-7, "{a}: {s} {c}");
        }
    }

    #[test]
    fn concentric_map_matches_the_trigonometric_form() {
        for (x, y) in [(0.9f32, 0.3f32), (0.1, 0.95), (0.5, 0.2), (0.05, 0.5), (0.77, 0.77)] {
            let o = 2.0 * Vec2::new(x, y) - Vec2::ONE;
            let (r, t) = if o.x.abs() > o.y.abs() {
                (o.x, FRAC_PI_4 * (o.y / o.x))
            } else {
                (o.y, std::f32::consts::FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
            };
            let expect = Vec2::new(r * t.cos(), r * t.sin());
            assert!((concentric_disk(Vec2::new(x, y)) - expect).length() < 1e-6);
        }
    }

    #[test]
    fn directions_are_unit_and_cosine_distributed() {
        // Under the cosine density p(ω) = cos θ / π: z² is uniform on [0, 1) (so P(z² < k/8) = k/8),
        // the azimuth is uniform (each quadrant 1/4), E[x] = E[y] = 0 and E[x²] = E[y²] = 1/4.
        // Bounds are 5 standard deviations of each estimate at this n.
        use crate::sampler::{StreamKind, StreamSampler};
        let st = StreamSampler::new(3, StreamKind::Pt);
        let n = 200_000;
        let (mut zbins, mut quadrants) = ([0u32; 8], [0u32; 4]);
        let (mut sx, mut sy, mut sxx, mut syy) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let w = sample(st.sample(0, i).get2d(0));
            assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0, "{w}");
            zbins[((w.z * w.z * 8.0) as usize).min(7)] += 1;
            quadrants[(w.x < 0.0) as usize * 2 + (w.y < 0.0) as usize] += 1;
            (sx, sy, sxx, syy) = (sx + w.x as f64, sy + w.y as f64, sxx + (w.x * w.x) as f64, syy + (w.y * w.y) as f64);
        }
        let nf = n as f64;
        let count_ok = |count: u32, p: f64| (count as f64 - nf * p).abs() < 5.0 * (nf * p * (1.0 - p)).sqrt();
        assert!(zbins.iter().all(|&c| count_ok(c, 1.0 / 8.0)), "{zbins:?}");
        assert!(quadrants.iter().all(|&c| count_ok(c, 1.0 / 4.0)), "{quadrants:?}");
        // Var[x] = 1/4; Var[x²] = E[x⁴] − 1/16 = 1/8 − 1/16.
        let (sd_mean, sd_sq) = ((0.25 / nf).sqrt(), ((0.125 - 0.0625) / nf).sqrt());
        assert!((sx / nf).abs() < 5.0 * sd_mean && (sy / nf).abs() < 5.0 * sd_mean, "{} {}", sx / nf, sy / nf);
        assert!((sxx / nf - 0.25).abs() < 5.0 * sd_sq && (syy / nf - 0.25).abs() < 5.0 * sd_sq, "{} {}", sxx / nf, syy / nf);
    }
}

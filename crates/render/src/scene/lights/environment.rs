//! The environment light: radiance arriving from infinitely far away, seen by every ray that
//! escapes the scene, either a constant colour or a lat-long (equirectangular) map.
//!
//! **Lat-long convention** (world +Y up, see docs/scene-format.md): for a unit direction `d`
//! in map space, `u = 0.5 + atan2(d.x, −d.z) / 2π`, `v = acos(d.y) / π`; pixel row 0 is the top
//! (`v = 0`, +Y); the centre column (`u = 0.5`) is −Z, `u = 0` and `1` are +Z, `u` grows towards
//! +X. A rotation of `α` degrees turns the map about +Y: world direction `d` looks up the map at
//! `R_y(−α)·d`. Texels are looked up nearest-neighbour so that `eval` is exactly the
//! piecewise-constant function the sampler's density is built from.
//!
//! **Sampling.** A map is importance-sampled with a [`Distribution2D`] over `luminance ×
//! sin θ` (sin θ averaged exactly over each row's band): the density in `(u, v)` converts to
//! solid angle as `pdf_ω = pdf_uv / (2π² sin θ)`. A constant colour is sampled uniformly over
//! the sphere (`1/4π`): it has no preferred direction and, unlike cosine sampling about the
//! surface normal, needs nothing from the shading point, so it keeps `LIGHT_POS` meaning the
//! same direction for every CRN pixel.
use super::distribution::Distribution2D;
use crate::scene::fingerprint::Canonical;
use crate::vector::luminance;
use cvtrace_streams::Image;
use glam::{Mat3, Vec2, Vec3A};
use std::f32::consts::PI;

/// Where the radiance comes from.
#[derive(Clone, Debug)]
enum Source {
    Constant(Vec3A),
    Map(LatLong),
}

/// The environment light (radiance already multiplied by its strength).
#[derive(Clone, Debug)]
pub struct Environment {
    source: Source,
    /// Map space → world (rotation about +Y) and back.
    from_map: Mat3,
    to_map: Mat3,
    /// Solid-angle mean of the luminance, for light selection.
    mean_luminance: f64,
}

/// A direction sampled towards the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSample {
    pub wi: Vec3A,
    pub li: Vec3A,
    /// Solid-angle density of `wi`.
    pub pdf: f32,
}

#[derive(Clone)]
struct LatLong {
    width: usize,
    height: usize,
    /// 12-byte `Vec3`s (a third less memory than `Vec3A`).
    texels: Vec<glam::Vec3>,
    dist: Distribution2D,
    /// Hash of the texels, so `Debug` (used for scene hashes) stays short.
    hash: u64,
}

impl std::fmt::Debug for LatLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LatLong {{ {}x{}, texel hash {:016x} }}", self.width, self.height, self.hash)
    }
}

impl Environment {
    /// Feeds everything that decides the radiance to the scene fingerprint: the kind, the
    /// colour or the map's size and texels (bit patterns), and the rotation.
    pub(crate) fn fingerprint_into(&self, h: &mut Canonical) {
        match &self.source {
            Source::Constant(c) => {
                h.word(0);
                h.vec(*c);
            }
            Source::Map(m) => {
                h.word(1);
                h.word(m.width as u64);
                h.word(m.height as u64);
                h.floats(m.texels.iter().flat_map(|t| t.to_array()));
            }
        }
        h.floats(self.from_map.to_cols_array());
    }

    /// Constant radiance `color` from every direction.
    pub fn constant(color: Vec3A) -> Result<Environment, String> {
        if !(color.is_finite() && color.min_element() >= 0.0) {
            return Err(format!("environment colour {color} must be finite and non-negative"));
        }
        Ok(Environment {
            source: Source::Constant(color),
            from_map: Mat3::IDENTITY,
            to_map: Mat3::IDENTITY,
            mean_luminance: luminance(color) as f64,
        })
    }

    /// A lat-long map (row 0 at the top) times `strength`. Errors for an empty image and for
    /// non-finite or negative texels (naming the texel).
    pub fn from_image(image: &Image, strength: f32) -> Result<Environment, String> {
        let (w, h) = (image.width, image.height);
        if w == 0 || h == 0 || image.pixels.len() != w * h {
            return Err(format!("the environment map is empty ({w}x{h})"));
        }
        if !(strength.is_finite() && strength >= 0.0) {
            return Err(format!("environment strength {strength} must be finite and non-negative"));
        }
        let mut texels = Vec::with_capacity(w * h);
        let mut hash = 0xcbf2_9ce4_8422_2325u64;
        for (i, p) in image.pixels.iter().enumerate() {
            if let Some(c) = p.iter().position(|v| !v.is_finite() || *v < 0.0) {
                return Err(format!(
                    "environment map texel ({}, {}) channel {} is {}; texels must be finite and non-negative",
                    i % w,
                    i / w,
                    ["R", "G", "B"][c],
                    p[c]
                ));
            }
            for v in p {
                hash = (hash ^ v.to_bits() as u64).wrapping_mul(0x100_0000_01b3);
            }
            texels.push(glam::Vec3::from_array(*p) * strength);
        }
        // luminance × (mean of sin θ over the row's band of v).
        let mut func = Vec::with_capacity(w * h);
        for row in 0..h {
            let (t0, t1) = (PI as f64 * row as f64 / h as f64, PI as f64 * (row + 1) as f64 / h as f64);
            let sin_mean = ((t0.cos() - t1.cos()) / (t1 - t0)) as f32;
            func.extend(texels[row * w..(row + 1) * w].iter().map(|t| luminance((*t).into()) * sin_mean));
        }
        let dist = Distribution2D::new(&func, w, h);
        // ∫ L dω / 4π = 2π² ∫ lum · sin θ du dv / 4π.
        let mean_luminance = dist.integral() * std::f64::consts::PI / 2.0;
        Ok(Environment {
            source: Source::Map(LatLong { width: w, height: h, texels, dist, hash }),
            from_map: Mat3::IDENTITY,
            to_map: Mat3::IDENTITY,
            mean_luminance,
        })
    }

    /// Turns the environment by `degrees` about +Y.
    pub fn rotated(mut self, degrees: f32) -> Result<Environment, String> {
        if !degrees.is_finite() {
            return Err(format!("environment rotation {degrees} must be finite"));
        }
        if degrees != 0.0 {
            self.from_map = Mat3::from_rotation_y(degrees.to_radians());
            self.to_map = self.from_map.transpose();
        }
        Ok(self)
    }

    /// A constant colour (not a map).
    pub fn is_constant(&self) -> bool {
        matches!(self.source, Source::Constant(_))
    }

    /// Mean luminance over the sphere of directions.
    pub fn mean_luminance(&self) -> f64 {
        self.mean_luminance
    }

    /// Power for light selection (pbrt's estimate): `4π² r² · mean luminance`, with `r` the
    /// scene's bounding-sphere radius.
    pub fn power(&self, scene_radius: f32) -> f64 {
        let r = scene_radius as f64;
        4.0 * std::f64::consts::PI * std::f64::consts::PI * r * r * self.mean_luminance
    }

    /// Radiance arriving along `-dir` (i.e. seen looking towards unit `dir`) and the solid-angle
    /// density with which [`Environment::sample`] picks `dir`.
    #[inline]
    pub fn eval_pdf(&self, dir: Vec3A) -> (Vec3A, f32) {
        match &self.source {
            Source::Constant(c) => (*c, 1.0 / (4.0 * PI)),
            Source::Map(m) => {
                let d = self.to_map * dir;
                let (uv, sin_theta) = direction_to_uv(d);
                let (col, row) = m.cell(uv);
                let pdf = if sin_theta > 0.0 { m.dist.pdf(col, row) / (2.0 * PI * PI * sin_theta) } else { 0.0 };
                (m.texels[row * m.width + col].into(), pdf)
            }
        }
    }

    /// Radiance seen looking towards unit `dir`.
    #[inline]
    pub fn eval(&self, dir: Vec3A) -> Vec3A {
        self.eval_pdf(dir).0
    }

    /// A direction from `u ∈ [0, 1)²`; `None` if it carries no light or has zero density.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        match &self.source {
            Source::Constant(c) => {
                let y = 1.0 - 2.0 * u.x;
                let r = (1.0 - y * y).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let wi = Vec3A::new(r * phi.sin(), y, -r * phi.cos());
                (*c != Vec3A::ZERO).then_some(EnvironmentSample { wi, li: *c, pdf: 1.0 / (4.0 * PI) })
            }
            Source::Map(m) => {
                let (uv, (col, row)) = m.dist.sample(u);
                let theta = uv.y * PI;
                let sin_theta = theta.sin();
                let pdf_uv = m.dist.pdf(col, row);
                if sin_theta <= 0.0 || pdf_uv <= 0.0 {
                    return None;
                }
                let phi = 2.0 * PI * (uv.x - 0.5);
                let d = Vec3A::new(sin_theta * phi.sin(), theta.cos(), -sin_theta * phi.cos());
                let li = Vec3A::from(m.texels[row * m.width + col]);
                Some(EnvironmentSample { wi: self.from_map * d, li, pdf: pdf_uv / (2.0 * PI * PI * sin_theta) })
            }
        }
    }
}

impl LatLong {
    #[inline]
    fn cell(&self, uv: Vec2) -> (usize, usize) {
        let col = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let row = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        (col, row)
    }
}

/// `(u, v)` of a unit map-space direction (see the module doc) and `sin θ`.
#[inline]
pub fn direction_to_uv(d: Vec3A) -> (Vec2, f32) {
    let y = d.y.clamp(-1.0, 1.0);
    let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    let v = y.acos() / PI;
    // sin θ from x and z, not √(1 − y²), which loses precision near the poles.
    (Vec2::new(u.clamp(0.0, 1.0), v), (d.x * d.x + d.z * d.z).sqrt().min(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{StreamKind, StreamSampler};

    /// A small map with a bright sun-like blob, a gradient and a black region.
    fn test_map() -> Image {
        Image::from_fn(32, 16, |x, y| {
            let base = 0.2 + 0.05 * x as f32 / 32.0;
            let sun = if (10..13).contains(&x) && (3..5).contains(&y) { 40.0 } else { 0.0 };
            let black = if y >= 13 { 0.0 } else { 1.0 };
            [(base + sun) * black, (0.5 * base + sun) * black, base * black]
        })
    }

    #[test]
    fn lat_long_convention() {
        let uv = |d: Vec3A| direction_to_uv(d).0;
        assert!((uv(Vec3A::NEG_Z) - Vec2::new(0.5, 0.5)).length() < 1e-6);
        assert!((uv(Vec3A::X) - Vec2::new(0.75, 0.5)).length() < 1e-6);
        assert!((uv(Vec3A::NEG_X) - Vec2::new(0.25, 0.5)).length() < 1e-6);
        assert!(uv(Vec3A::Y).y.abs() < 1e-6 && (uv(Vec3A::NEG_Y).y - 1.0).abs() < 1e-6);
        let u_pz = uv(Vec3A::new(1e-4, 0.0, 1.0)).x;
        assert!(u_pz > 0.99, "{u_pz}");
        // A map whose only bright column is u ∈ [0.75, 0.875) shows it towards +X; rotated by
        // 90° about +Y it shows it towards −Z (R_y(90°) takes +X to −Z).
        let img = Image::from_fn(8, 4, |x, _| if x == 6 { [1.0; 3] } else { [0.0; 3] });
        let env = Environment::from_image(&img, 1.0).unwrap();
        let d = Vec3A::new(1.0, 0.0, 0.2).normalize();
        assert_eq!(env.eval(d), Vec3A::ONE);
        let env = env.rotated(90.0).unwrap();
        assert_eq!(env.eval(d), Vec3A::ZERO);
        assert_eq!(env.eval(Vec3A::new(0.2, 0.0, -1.0).normalize()), Vec3A::ONE);
    }

    #[test]
    fn map_pdf_integrates_to_one_over_the_sphere() {
        for rot in [0.0, 37.0] {
            let env = Environment::from_image(&test_map(), 1.5).unwrap().rotated(rot).unwrap();
            // Fine enough to resolve every texel.
            let total = sphere_integral(800, |d| env.eval_pdf(d).1 as f64);
            assert!((total - 1.0).abs() < 2e-3, "rotation {rot}: ∫pdf = {total}");
        }
    }

    #[test]
    fn sampled_directions_have_the_density_pdf_reports() {
        // E[f(ω)/pdf(ω)] = ∫ f dω for test functions f; and pdf() of the sample equals its pdf.
        let env = Environment::from_image(&test_map(), 1.0).unwrap().rotated(-20.0).unwrap();
        let st = StreamSampler::new(3, StreamKind::Pt);
        type TestFn = (&'static str, fn(Vec3A) -> f64, f64);
        let tests: [TestFn; 3] = [
            ("1", |_| 1.0, 4.0 * std::f64::consts::PI),
            ("max(y,0)", |d| d.y.max(0.0) as f64, std::f64::consts::PI),
            ("x²", |d| (d.x * d.x) as f64, 4.0 * std::f64::consts::PI / 3.0),
        ];
        let n = 200_000;
        let mut sums = [0.0f64; 3];
        let mut sq = [0.0f64; 3];
        for i in 0..n {
            let s = env.sample(st.sample(0, i).get2d(0)).expect("every sample lands on a lit texel");
            let (li, pdf) = env.eval_pdf(s.wi);
            assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "pdf {pdf} vs sample pdf {}", s.pdf);
            assert_eq!(li, s.li);
            for (k, (_, f, _)) in tests.iter().enumerate() {
                let v = f(s.wi) / s.pdf as f64;
                sums[k] += v;
                sq[k] += v * v;
            }
        }
        for (k, (name, _, exact)) in tests.iter().enumerate() {
            let mean = sums[k] / n as f64;
            let se = ((sq[k] / n as f64 - mean * mean) / n as f64).sqrt();
            eprintln!("∫{name} dω: {mean} ± {se} (exact {exact})");
            // The black region is never sampled, so only functions vanishing there integrate
            // exactly: restrict the check to the part the sampler covers.
            let covered = covered_integral(&env, tests[k].1);
            assert!((mean - covered).abs() < 5.0 * se + 1e-9, "∫{name}: {mean} ± {se} vs {covered}");
            assert!(covered <= exact * (1.0 + 1e-4), "{covered} > {exact}");
        }
    }

    /// ∫ f over the directions where the map is non-black (numerically).
    fn covered_integral(env: &Environment, f: fn(Vec3A) -> f64) -> f64 {
        sphere_integral(600, |d| if env.eval_pdf(d).1 > 0.0 { f(d) } else { 0.0 })
    }

    /// ∫ f dω over the sphere by the midpoint rule in (θ, φ) with `nt × 2nt` cells.
    fn sphere_integral(nt: usize, f: impl Fn(Vec3A) -> f64) -> f64 {
        let np = 2 * nt;
        let mut total = 0.0f64;
        for i in 0..nt {
            let theta = PI * (i as f32 + 0.5) / nt as f32;
            for j in 0..np {
                let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                let d = Vec3A::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
                total += f(d) * theta.sin() as f64;
            }
        }
        total * (PI as f64 / nt as f64) * (2.0 * PI as f64 / np as f64)
    }

    #[test]
    fn constant_colour_and_constant_map_agree() {
        let c = Vec3A::new(0.6, 0.7, 1.0);
        let a = Environment::constant(c).unwrap();
        let b = Environment::from_image(&Image::from_fn(16, 8, |_, _| [0.3, 0.35, 0.5]), 2.0).unwrap();
        let expect = luminance(c) as f64;
        assert!((a.mean_luminance() - expect).abs() < 1e-6);
        assert!((b.mean_luminance() - expect).abs() < 1e-5 * expect, "{} vs {expect}", b.mean_luminance());
        for d in [Vec3A::Y, Vec3A::new(0.3, -0.4, 0.866).normalize(), Vec3A::NEG_Z] {
            assert!((b.eval(d) - c).length() < 1e-6);
            assert_eq!(a.eval(d), c);
        }
        // Both samplers draw unit directions with the density they report.
        let st = StreamSampler::new(9, StreamKind::Pt);
        for env in [&a, &b] {
            for i in 0..1000 {
                let s = env.sample(st.sample(1, i).get2d(0)).unwrap();
                assert!((s.wi.length() - 1.0).abs() < 1e-5);
                assert!((env.eval_pdf(s.wi).1 - s.pdf).abs() < 1e-3 * s.pdf);
            }
        }
    }

    #[test]
    fn invalid_maps_and_values_are_errors() {
        let mut img = test_map();
        img.pixels[40][1] = -1.0;
        let e = Environment::from_image(&img, 1.0).unwrap_err();
        assert!(e.contains("texel (8, 1) channel G"), "{e}");
        img.pixels[40][1] = f32::NAN;
        assert!(Environment::from_image(&img, 1.0).is_err());
        assert!(Environment::from_image(&Image::new(0, 0), 1.0).unwrap_err().contains("empty"));
        assert!(Environment::from_image(&test_map(), -1.0).is_err());
        assert!(Environment::constant(Vec3A::new(1.0, -0.1, 0.0)).is_err());
        assert!(Environment::constant(Vec3A::ONE).unwrap().rotated(f32::NAN).is_err());
    }
}

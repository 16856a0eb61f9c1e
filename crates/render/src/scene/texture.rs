//! Linear-RGB textures with bilinear lookup and repeat wrapping.
//!
//! Colour textures (base colour, emission) are decoded from sRGB to linear once at load time,
//! data textures (metallic-roughness) are kept as they are, so lookups never convert.
use glam::{Vec2, Vec3, Vec3A};

/// A texture in linear RGB, row-major, top row first (glTF's UV origin is the top-left).
/// Texels are stored as 12-byte `Vec3` (a third less memory than the 16-byte SIMD `Vec3A` the
/// renderer computes with; a lookup converts the four it reads).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec3>,
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture from texels; `None` if the sizes do not match or it is empty.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Option<Texture> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then_some(Texture { width, height, texels })
    }

    /// A 1×1 texture, handy for tests.
    pub fn constant(c: Vec3A) -> Texture {
        Texture { width: 1, height: 1, texels: vec![c.into()] }
    }

    /// Bilinear lookup at `uv` with repeat wrapping.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec3A {
        let (w, h) = (self.width as usize, self.height as usize);
        if w == 1 && h == 1 {
            return self.texels[0].into();
        }
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return self.texels[0].into();
        }
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let wrap = |i: f32, n: usize| (i as i64).rem_euclid(n as i64) as usize;
        let (x0, y0) = (wrap(fx, w), wrap(fy, h));
        let (x1, y1) = ((x0 + 1) % w, (y0 + 1) % h);
        let t = |x: usize, y: usize| Vec3A::from(self.texels[y * w + x]);
        let top = t(x0, y0).lerp(t(x1, y0), tx);
        let bottom = t(x0, y1).lerp(t(x1, y1), tx);
        top.lerp(bottom, ty)
    }

    /// Mean texel value (used to weight textured emitters for light selection).
    pub fn mean(&self) -> Vec3A {
        let s: glam::DVec3 = self.texels.iter().map(|t| t.as_dvec3()).sum();
        (s / self.texels.len() as f64).as_vec3a()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decoding_matches_known_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.21404).abs() < 1e-4);
    }

    #[test]
    fn bilinear_lookup_hits_texel_centres_and_wraps() {
        let tex = Texture::new(2, 1, vec![Vec3::ZERO, Vec3::ONE]).unwrap();
        assert_eq!(tex.sample(Vec2::new(0.25, 0.5)), Vec3A::ZERO);
        assert_eq!(tex.sample(Vec2::new(0.75, 0.5)), Vec3A::ONE);
        assert!((tex.sample(Vec2::new(0.5, 0.5)) - Vec3A::splat(0.5)).length() < 1e-6);
        // Repeat: u = 1.25 is u = 0.25; u = 0.0 is halfway between the last and first texel.
        assert_eq!(tex.sample(Vec2::new(1.25, 0.5)), Vec3A::ZERO);
        assert!((tex.sample(Vec2::new(0.0, 0.5)) - Vec3A::splat(0.5)).length() < 1e-6);
        assert!(Texture::new(2, 2, vec![Vec3::ZERO]).is_none());
    }
}

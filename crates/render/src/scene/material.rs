//! Materials as loaded from glTF 2.0 (metallic-roughness + the KHR extensions cvtrace reads),
//! kept in a flat `Vec` indexed by the per-triangle material id.
use crate::scene::texture::Texture;
use glam::{Vec2, Vec3A};

/// One material. Texture fields index the scene's texture list; colour textures are stored
/// linear (decoded from sRGB at load time). Only `TEXCOORD_0` is used.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// baseColorFactor (RGB; alpha is ignored: all surfaces are opaque or glass).
    pub base_color: Vec3A,
    pub base_color_texture: Option<u32>,
    pub metallic: f32,
    pub roughness: f32,
    /// glTF metallicRoughnessTexture: roughness in G, metallic in B (linear).
    pub metallic_roughness_texture: Option<u32>,
    /// `KHR_materials_specular`: specularFactor and specularColorFactor.
    pub specular: f32,
    pub specular_color: Vec3A,
    /// `KHR_materials_transmission`: transmissionFactor.
    pub transmission: f32,
    /// `KHR_materials_ior`.
    pub ior: f32,
    /// Emitted radiance: emissiveFactor × `KHR_materials_emissive_strength`.
    pub emission: Vec3A,
    pub emissive_texture: Option<u32>,
}

impl Default for Material {
    /// glTF's default material (used for primitives without one): white, fully metallic and rough.
    fn default() -> Self {
        Material {
            name: "default".into(),
            base_color: Vec3A::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            specular: 1.0,
            specular_color: Vec3A::ONE,
            transmission: 0.0,
            ior: 1.5,
            emission: Vec3A::ZERO,
            emissive_texture: None,
        }
    }
}

impl Material {
    /// A pure Lambertian surface (specular layer off, as the Cornell box uses).
    pub fn diffuse(albedo: Vec3A) -> Material {
        Material { name: "diffuse".into(), base_color: albedo, metallic: 0.0, specular: 0.0, ..Default::default() }
    }

    /// A Lambertian surface that also emits `radiance` from its front face.
    pub fn emissive(albedo: Vec3A, radiance: Vec3A) -> Material {
        Material { name: "emitter".into(), emission: radiance, ..Material::diffuse(albedo) }
    }

    /// A smooth or rough glass.
    pub fn glass(ior: f32, roughness: f32) -> Material {
        Material { name: "glass".into(), metallic: 0.0, roughness, transmission: 1.0, ior, ..Default::default() }
    }

    /// A metal with base colour `f0` (its normal-incidence reflectance).
    pub fn metal(f0: Vec3A, roughness: f32) -> Material {
        Material { name: "metal".into(), base_color: f0, metallic: 1.0, roughness, ..Default::default() }
    }

    /// True if some part of the material emits light.
    #[inline]
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// True if the material is its diffuse lobe alone at every texel: no metal, transmission or
    /// specular layer (textures only scale metallic, so they cannot add one). Its BSDF is then
    /// `Bsdf::diffuse` of the base colour, which skips resolving the other parameters.
    #[inline]
    pub fn is_diffuse_only(&self) -> bool {
        is_diffuse_only(self.metallic, self.transmission, self.specular)
    }

    /// The BSDF parameters at texture coordinate `uv`.
    #[inline]
    pub fn params_at(&self, textures: &[Texture], uv: Vec2) -> PbrParams {
        let mut base = self.base_color;
        if let Some(t) = self.base_color_texture {
            base *= textures[t as usize].sample(uv);
        }
        let (mut metallic, mut roughness) = (self.metallic, self.roughness);
        if let Some(t) = self.metallic_roughness_texture {
            let mr = textures[t as usize].sample(uv);
            roughness *= mr.y;
            metallic *= mr.z;
        }
        PbrParams {
            base_color: base,
            metallic,
            roughness,
            specular: self.specular,
            specular_color: self.specular_color,
            transmission: self.transmission,
            ior: self.ior,
        }
    }

    /// Base colour at `uv` (the albedo feature).
    #[inline]
    pub fn base_color_at(&self, textures: &[Texture], uv: Vec2) -> Vec3A {
        match self.base_color_texture {
            Some(t) => self.base_color * textures[t as usize].sample(uv),
            None => self.base_color,
        }
    }

    /// Emitted radiance at `uv` (front face only; the caller checks the side).
    #[inline]
    pub fn emission_at(&self, textures: &[Texture], uv: Vec2) -> Vec3A {
        match self.emissive_texture {
            Some(t) => self.emission * textures[t as usize].sample(uv),
            None => self.emission,
        }
    }

    /// Average emitted radiance over the surface, to weight light selection by power.
    pub fn mean_emission(&self, textures: &[Texture]) -> Vec3A {
        match self.emissive_texture {
            Some(t) => self.emission * textures[t as usize].mean(),
            None => self.emission,
        }
    }
}

/// Material parameters resolved at a surface point (textures already applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PbrParams {
    pub base_color: Vec3A,
    pub metallic: f32,
    pub roughness: f32,
    /// `KHR_materials_specular` specularFactor (1 by default, 0 = no specular layer).
    pub specular: f32,
    pub specular_color: Vec3A,
    /// `KHR_materials_transmission` transmissionFactor.
    pub transmission: f32,
    /// `KHR_materials_ior` (1.5 by default).
    pub ior: f32,
}

impl Default for PbrParams {
    fn default() -> Self {
        PbrParams {
            base_color: Vec3A::ONE,
            metallic: 0.0,
            roughness: 1.0,
            specular: 1.0,
            specular_color: Vec3A::ONE,
            transmission: 0.0,
            ior: 1.5,
        }
    }
}

/// True if these glTF factors leave the diffuse lobe alone: no metal, no transmission, no
/// specular layer (each clamped to [0, 1] as the model uses it).
#[inline]
pub fn is_diffuse_only(metallic: f32, transmission: f32, specular: f32) -> bool {
    metallic.clamp(0.0, 1.0) == 0.0 && transmission.clamp(0.0, 1.0) == 0.0 && specular.clamp(0.0, 1.0) == 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_modulate_factors_with_gltf_channel_layout() {
        // Texture 0: colour; texture 1: metallic-roughness (G = roughness, B = metallic).
        let textures = vec![Texture::constant(Vec3A::new(0.5, 1.0, 0.25)), Texture::constant(Vec3A::new(0.9, 0.5, 0.2))];
        let m = Material {
            base_color: Vec3A::new(0.8, 0.6, 1.0),
            base_color_texture: Some(0),
            metallic: 1.0,
            roughness: 0.8,
            metallic_roughness_texture: Some(1),
            emission: Vec3A::splat(2.0),
            emissive_texture: Some(0),
            ..Default::default()
        };
        let p = m.params_at(&textures, Vec2::new(0.3, 0.7));
        assert_eq!(p.base_color, Vec3A::new(0.4, 0.6, 0.25));
        assert!((p.roughness - 0.4).abs() < 1e-6 && (p.metallic - 0.2).abs() < 1e-6, "{p:?}");
        assert_eq!(m.emission_at(&textures, Vec2::ZERO), Vec3A::new(1.0, 2.0, 0.5));
        assert_eq!(m.mean_emission(&textures), Vec3A::new(1.0, 2.0, 0.5));
        assert!(m.is_emissive() && !Material::diffuse(Vec3A::ONE).is_emissive());
    }
}

//! Next-event estimation's light sample: one emitter chosen from the scene's [`LightSet`] and
//! one point or direction on it, with the shadow ray's end. Choosing needs only the set; the
//! point on an emissive triangle needs the scene's geometry and materials, which is why the
//! sampling is here and not with the set, which the scene holds.
use crate::scene::lights::{sample_triangle, Emitter, LightSet};
use crate::scene::world::Scene;
use glam::{Vec2, Vec3A};

/// Where a shadow ray towards a light sample ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShadowEnd {
    /// At this point (just off an emitter's surface, or a punctual light's position).
    Point(Vec3A),
    /// At infinity along the sample direction (environment, sun).
    Infinite,
}

/// Light arriving at a shading point from one sampled emitter.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3A,
    /// Incident radiance (area lights, environment) or `I/d²`, `E` for delta lights; never 0.
    pub li: Vec3A,
    /// Solid-angle density including the selection probability; for delta lights the
    /// selection probability alone. Always > 0.
    pub pdf: f32,
    /// A delta light: no MIS (BSDF sampling can never hit it).
    pub delta: bool,
    pub end: ShadowEnd,
}

impl LightSet {
    /// Chooses an emitter with `u_select` and a point or direction on it with `u`, for the
    /// shading point `p`. `None` when the choice brings no light to `p` (back of an emitter,
    /// outside a spot cone, a black texel).
    #[inline]
    pub fn sample(&self, scene: &Scene, p: Vec3A, u_select: f32, u: Vec2) -> Option<LightSample> {
        match self.choose(u_select)? {
            Emitter::Triangle(prim) => sample_area(scene, prim, self.pdf_area(prim), p, u),
            Emitter::Punctual(k) => {
                let s = self.punctual()[k as usize].sample_li(p)?;
                let end = s.position.map_or(ShadowEnd::Infinite, ShadowEnd::Point);
                (s.li != Vec3A::ZERO).then_some(LightSample {
                    wi: s.wi,
                    li: s.li,
                    pdf: self.punctual_probability(k as usize),
                    delta: true,
                    end,
                })
            }
            Emitter::Environment => {
                let s = self.environment()?.sample(u)?;
                let pdf = self.environment_probability() * s.pdf;
                (s.li != Vec3A::ZERO && pdf > 0.0).then_some(LightSample {
                    wi: s.wi,
                    li: s.li,
                    pdf,
                    delta: false,
                    end: ShadowEnd::Infinite,
                })
            }
        }
    }
}

/// A uniform point on emissive triangle `prim` seen from `p`.
#[inline]
fn sample_area(scene: &Scene, prim: u32, pdf_area: f32, p: Vec3A, u: Vec2) -> Option<LightSample> {
    let (point, bary) = sample_triangle(u, scene.triangle_vertices(prim));
    let to_light = point - p;
    let dist2 = to_light.length_squared();
    if dist2 <= 0.0 {
        return None;
    }
    let n_l = scene.geometric_normal(prim);
    let wi = to_light / dist2.sqrt();
    let cos_l = -wi.dot(n_l);
    if cos_l <= 0.0 {
        return None;
    }
    let material = scene.material_of(prim);
    let uv = if material.emissive_texture.is_some() { scene.surface(prim, bary.x, bary.y).uv } else { Vec2::ZERO };
    let li = material.emission_at(scene.textures(), uv);
    let pdf = pdf_area * dist2 / cos_l;
    (li != Vec3A::ZERO && pdf > 0.0).then_some(LightSample {
        wi,
        li,
        pdf,
        delta: false,
        end: ShadowEnd::Point(point + n_l * scene.ray_epsilon()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::lights::{Environment, Punctual};
    use crate::scene::material::Material;
    use crate::scene::world::SceneParts;

    #[test]
    fn every_kind_is_selected_in_proportion_to_its_power() {
        // One unit-luminance triangle of area 2 (power 2), a point light of power 4π·0.5,
        // a sun of power π r²·1 and a white environment of power 4π² r²·0.25 with r = 1.
        let point = Punctual::Point { position: Vec3A::new(0.0, 3.0, 0.0), intensity: Vec3A::splat(0.5) };
        let sun = Punctual::Directional { direction: Vec3A::NEG_Y, irradiance: Vec3A::ONE };
        let env = Environment::constant(Vec3A::splat(0.25)).unwrap();
        let ls = LightSet::new(&[2.0, 0.0], &[2.0, 1.0], vec![point, sun], Some(env), 1.0);
        let pi = std::f64::consts::PI;
        let powers = [2.0, 2.0 * pi, pi, pi * pi];
        let total: f64 = powers.iter().sum();
        assert_eq!(ls.len(), 4);
        assert!((ls.pdf_area(0) as f64 - powers[0] / total / 2.0).abs() < 1e-6);
        assert!((ls.punctual_probability(0) as f64 - powers[1] / total).abs() < 1e-6);
        assert!((ls.punctual_probability(1) as f64 - powers[2] / total).abs() < 1e-6);
        assert!((ls.environment_probability() as f64 - powers[3] / total).abs() < 1e-6);
        // The pdf NEE reports for each kind carries its selection probability.
        let mut parts = SceneParts {
            positions: vec![Vec3A::new(-1.0, 2.0, -1.0), Vec3A::new(1.0, 2.0, -1.0), Vec3A::new(1.0, 2.0, 1.0), Vec3A::new(5.0, 5.0, 5.0)],
            triangles: vec![[0, 1, 2], [3, 3, 3]], // the emitter faces down, towards the origin
            triangle_materials: vec![0, 1],
            materials: vec![Material::emissive(Vec3A::ZERO, Vec3A::ONE), Material::diffuse(Vec3A::ONE)],
            ..Default::default()
        };
        parts.lights = ls.punctual().to_vec();
        let scene = Scene::from_parts(parts).unwrap();
        let n = 10_000;
        let mut counts = [0usize; 4];
        for k in 0..n {
            let u_sel = (k as f32 + 0.5) / n as f32;
            let Some(s) = ls.sample(&scene, Vec3A::ZERO, u_sel, Vec2::new(0.3, 0.6)) else { continue };
            let kind = match (s.delta, s.end) {
                (false, ShadowEnd::Point(_)) => 0,
                (true, ShadowEnd::Point(_)) => 1,
                (true, ShadowEnd::Infinite) => 2,
                (false, ShadowEnd::Infinite) => 3,
            };
            counts[kind] += 1;
            if kind == 1 {
                assert_eq!(s.pdf, ls.punctual_probability(0));
                assert!((s.li - Vec3A::splat(0.5 / 9.0)).length() < 1e-6);
            }
            if kind == 3 {
                assert!((s.pdf - ls.environment_probability() / (4.0 * std::f32::consts::PI)).abs() < 1e-6);
            }
        }
        for k in 0..4 {
            let expect = powers[k] / total * n as f64;
            assert!((counts[k] as f64 - expect).abs() <= 1.0, "kind {k}: {} vs {expect}", counts[k]);
        }
    }
}

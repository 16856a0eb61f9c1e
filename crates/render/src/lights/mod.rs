//! Every emitter of a scene and the one distribution next-event estimation picks them from.
//!
//! Emitters are emissive triangles ([`area`]), `KHR_lights_punctual` lights ([`punctual`]) and
//! the environment ([`environment`]). One light is chosen per shading point in proportion to
//! its power (pbrt's heuristic, see each kind's `power`), with the single `LIGHT_SELECT`
//! number; the point or direction on it uses the `LIGHT_POS` pair. Keeping one selection for all
//! kinds keeps the sampler's dimension blocks fixed, so CRN pixels make the same choices.
//!
//! Triangles come first in the selection order, so a scene with only emissive triangles gets
//! exactly the distribution it had before other kinds of light existed.
pub mod area;
pub mod distribution;
pub mod environment;
pub mod punctual;
#[cfg(test)]
mod transport_tests;

pub use area::{sample_triangle, triangle_power};
pub use environment::Environment;
pub use punctual::Punctual;

use crate::scene::Scene;
use glam::{Vec2, Vec3A};

/// One entry of the selection distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Emitter {
    Triangle(u32),
    Punctual(u32),
    Environment,
}

/// The light-selection distribution over all emitters.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    emitters: Vec<Emitter>,
    /// Cumulative selection probability, `cdf[i]` = P(emitter ≤ i); the last entry is 1.
    cdf: Vec<f32>,
    /// Per triangle: selection probability / area (0 for non-emitters), i.e. the area density.
    pdf_area: Vec<f32>,
    punctual: Vec<Punctual>,
    /// Selection probability of each punctual light.
    punctual_prob: Vec<f32>,
    environment: Option<Environment>,
    /// Selection probability of the environment (0 without one or if it is black).
    env_prob: f32,
    total_power: f64,
}

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
    /// Builds the distribution from per-triangle power (`0` for non-emitters) and areas, the
    /// punctual lights and the environment; `scene_radius` (bounding sphere) scales the power
    /// of lights at infinity.
    pub fn new(
        triangle_power: &[f64],
        triangle_area: &[f32],
        punctual: Vec<Punctual>,
        environment: Option<Environment>,
        scene_radius: f32,
    ) -> LightSet {
        let usable = |p: f64| p.is_finite() && p > 0.0;
        let mut candidates: Vec<(Emitter, f64)> = Vec::new();
        for (i, &p) in triangle_power.iter().enumerate() {
            if usable(p) && triangle_area[i] > 0.0 {
                candidates.push((Emitter::Triangle(i as u32), p));
            }
        }
        for (i, l) in punctual.iter().enumerate() {
            candidates.push((Emitter::Punctual(i as u32), l.power(scene_radius)));
        }
        if let Some(env) = &environment {
            candidates.push((Emitter::Environment, env.power(scene_radius)));
        }
        candidates.retain(|(_, p)| usable(*p));
        let total: f64 = candidates.iter().map(|(_, p)| p).sum();
        let mut set = LightSet {
            pdf_area: vec![0.0; triangle_power.len()],
            punctual_prob: vec![0.0; punctual.len()],
            punctual,
            environment,
            ..LightSet::default()
        };
        if !(total > 0.0 && total.is_finite()) {
            return set;
        }
        let mut acc = 0.0f64;
        for (e, p) in candidates {
            acc += p;
            set.emitters.push(e);
            set.cdf.push((acc / total) as f32);
            let prob = p / total;
            match e {
                Emitter::Triangle(i) => set.pdf_area[i as usize] = (prob / triangle_area[i as usize] as f64) as f32,
                Emitter::Punctual(i) => set.punctual_prob[i as usize] = prob as f32,
                Emitter::Environment => set.env_prob = prob as f32,
            }
        }
        if let Some(last) = set.cdf.last_mut() {
            *last = 1.0;
        }
        set.total_power = total;
        set
    }

    /// No emitter with positive power: next-event estimation has nothing to sample.
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

    /// Number of emitters in the selection distribution.
    pub fn len(&self) -> usize {
        self.emitters.len()
    }

    /// Total emitted power (in luminance units), for diagnostics.
    pub fn total_power(&self) -> f64 {
        self.total_power
    }

    pub fn punctual(&self) -> &[Punctual] {
        &self.punctual
    }

    pub fn environment(&self) -> Option<&Environment> {
        self.environment.as_ref()
    }

    /// Selection probability of punctual light `i`.
    pub fn punctual_probability(&self, i: usize) -> f32 {
        self.punctual_prob[i]
    }

    /// Selection probability of the environment.
    pub fn environment_probability(&self) -> f32 {
        self.env_prob
    }

    /// Area density of `prim` as a light (selection probability / area); 0 if it is not one.
    #[inline]
    pub fn pdf_area(&self, prim: u32) -> f32 {
        self.pdf_area[prim as usize]
    }

    /// Radiance of the environment towards unit `dir` and the density (selection × solid angle)
    /// with which next-event estimation samples `dir`; zeros without an environment.
    #[inline]
    pub fn environment_radiance(&self, dir: Vec3A) -> (Vec3A, f32) {
        match &self.environment {
            Some(env) => {
                let (le, pdf) = env.eval_pdf(dir);
                (le, self.env_prob * pdf)
            }
            None => (Vec3A::ZERO, 0.0),
        }
    }

    /// Chooses an emitter with `u_select` and a point or direction on it with `u`, for the
    /// shading point `p`. `None` when the choice brings no light to `p` (back of an emitter,
    /// outside a spot cone, a black texel).
    #[inline]
    pub fn sample(&self, scene: &Scene, p: Vec3A, u_select: f32, u: Vec2) -> Option<LightSample> {
        match self.choose(u_select)? {
            Emitter::Triangle(prim) => sample_area(scene, prim, self.pdf_area[prim as usize], p, u),
            Emitter::Punctual(k) => {
                let s = self.punctual[k as usize].sample_li(p)?;
                let end = s.position.map_or(ShadowEnd::Infinite, ShadowEnd::Point);
                (s.li != Vec3A::ZERO).then_some(LightSample { wi: s.wi, li: s.li, pdf: self.punctual_prob[k as usize], delta: true, end })
            }
            Emitter::Environment => {
                let s = self.environment.as_ref()?.sample(u)?;
                let pdf = self.env_prob * s.pdf;
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

impl LightSet {
    /// The emitter `u_select` chooses (`None` without emitters).
    #[inline]
    fn choose(&self, u_select: f32) -> Option<Emitter> {
        self.choose_index(u_select).map(|i| self.emitters[i])
    }

    /// The index (in selection order) of the emitter [`LightSet::sample`] samples for
    /// `u_select` (`None` without emitters).
    #[inline]
    pub(crate) fn choose_index(&self, u_select: f32) -> Option<usize> {
        let last = self.emitters.len().checked_sub(1)?;
        Some(self.cdf.partition_point(|&c| c <= u_select).min(last))
    }

    /// The triangle of emitter `index` (selection order), if it is one.
    pub(crate) fn emitter_triangle(&self, index: usize) -> Option<u32> {
        match self.emitters[index] {
            Emitter::Triangle(prim) => Some(prim),
            Emitter::Punctual(_) | Emitter::Environment => None,
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
    use crate::material::Material;
    use crate::scene::SceneParts;

    #[test]
    fn selection_follows_power_and_density_integrates_to_one() {
        let power = [0.0, 1.0, 3.0, 0.0];
        let area = [1.0, 2.0, 0.5, 1.0];
        let ls = LightSet::new(&power, &area, Vec::new(), None, 1.0);
        assert_eq!(ls.len(), 2);
        assert_eq!(ls.pdf_area(0), 0.0);
        // Σ pdf_area · area = 1 over the lights.
        let s: f32 = (0..4).map(|i| ls.pdf_area(i) * area[i as usize]).sum();
        assert!((s - 1.0).abs() < 1e-6);
        assert!(LightSet::new(&[0.0, 0.0], &[1.0, 1.0], Vec::new(), None, 1.0).is_empty());
    }

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
        let scene = crate::Scene::from_parts(parts).unwrap();
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

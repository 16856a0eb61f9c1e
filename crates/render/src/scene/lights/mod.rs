//! Every emitter of a scene and the one distribution next-event estimation picks them from.
//!
//! Emitters are emissive triangles ([`area`]), `KHR_lights_punctual` lights ([`punctual`]) and
//! the environment ([`environment`]). One light is chosen per shading point in proportion to
//! its power (pbrt's heuristic, see each kind's `power`), with the single `LIGHT_SELECT`
//! number; the point or direction on it uses the `LIGHT_POS` pair. Keeping one selection for all
//! kinds keeps the sampler's dimension blocks fixed, so CRN pixels make the same choices. The
//! sample itself ([`LightSet::sample`]) is next-event estimation's, in
//! [`crate::transport::light_sample`]: a point on a triangle needs the scene's geometry.
//!
//! Triangles come first in the selection order, so a scene with only emissive triangles gets
//! exactly the distribution it had before other kinds of light existed.
pub mod area;
pub mod distribution;
pub mod environment;
pub mod punctual;

pub use area::{sample_triangle, triangle_power};
pub use environment::Environment;
pub use punctual::Punctual;

use glam::Vec3A;

/// One entry of the selection distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Emitter {
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

    /// The emitter `u_select` chooses (`None` without emitters).
    #[inline]
    pub(crate) fn choose(&self, u_select: f32) -> Option<Emitter> {
        self.choose_index(u_select).map(|i| self.emitters[i])
    }

    /// The index (in selection order) of the emitter [`LightSet::sample`] samples for
    /// `u_select` (`None` without emitters).
    #[inline]
    pub(crate) fn choose_index(&self, u_select: f32) -> Option<usize> {
        let last = self.emitters.len().checked_sub(1)?;
        Some(self.cdf.partition_point(|&c| c <= u_select).min(last))
    }

    /// Emitter `index` (selection order).
    pub(crate) fn emitter(&self, index: usize) -> Emitter {
        self.emitters[index]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}

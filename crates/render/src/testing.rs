//! Test support, public so the Embree side can compare against it: a brute-force
//! [`Intersector`] (Möller–Trumbore with Embree's `(u, v)` convention), small procedural
//! scenes (a Cornell-style box, a closed furnace box, a plane for light tests) and a
//! radiance estimator along one ray.
use crate::intersect::{Hit, Intersector, Ray};
use crate::sampler::{StreamKind, StreamSampler};
use crate::scene::camera::Camera;
use crate::scene::material::Material;
use crate::scene::world::{Scene, SceneParts};
use crate::settings::PathLimits;
use crate::transport::integrator::radiance;
use glam::{DVec3, Vec3A};

/// Tests every triangle for every ray: O(n) per ray, exact and obviously correct.
pub struct BruteForce {
    v0: Vec<Vec3A>,
    e1: Vec<Vec3A>,
    e2: Vec<Vec3A>,
}

impl BruteForce {
    pub fn new(scene: &Scene) -> BruteForce {
        let n = scene.triangles().len();
        let (mut v0, mut e1, mut e2) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
        for i in 0..n as u32 {
            let [a, b, c] = scene.triangle_vertices(i);
            v0.push(a);
            e1.push(b - a);
            e2.push(c - a);
        }
        BruteForce { v0, e1, e2 }
    }

    /// Möller–Trumbore: `(t, u, v)` with `p = (1−u−v)·p0 + u·p1 + v·p2`.
    #[inline]
    fn test(&self, i: usize, ray: &Ray, tmax: f32) -> Option<(f32, f32, f32)> {
        let (e1, e2) = (self.e1[i], self.e2[i]);
        let pvec = ray.dir.cross(e2);
        let det = e1.dot(pvec);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let tvec = ray.origin - self.v0[i];
        let u = tvec.dot(pvec) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let qvec = tvec.cross(e1);
        let v = ray.dir.dot(qvec) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(qvec) * inv;
        (t >= ray.tmin && t <= tmax).then_some((t, u, v))
    }
}

impl Intersector for BruteForce {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut tmax = ray.tmax;
        for i in 0..self.v0.len() {
            if let Some((t, u, v)) = self.test(i, ray, tmax) {
                tmax = t;
                best = Some(Hit { t, prim: i as u32, u, v });
            }
        }
        best
    }

    fn occluded(&self, ray: &Ray) -> bool {
        (0..self.v0.len()).any(|i| self.test(i, ray, ray.tmax).is_some())
    }
}

/// Appends the quad `a b c d` (counter-clockwise seen from its front) as two triangles.
pub fn add_quad(parts: &mut SceneParts, [a, b, c, d]: [Vec3A; 4], material: u32) {
    let base = parts.positions.len() as u32;
    parts.positions.extend_from_slice(&[a, b, c, d]);
    parts.triangles.push([base, base + 1, base + 2]);
    parts.triangles.push([base, base + 2, base + 3]);
    parts.triangle_materials.extend_from_slice(&[material, material]);
}

/// Appends an axis-aligned box with outward-facing sides.
pub fn add_box(parts: &mut SceneParts, lo: Vec3A, hi: Vec3A, material: u32) {
    let p = |x: bool, y: bool, z: bool| Vec3A::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z });
    let (f, t) = (false, true);
    add_quad(parts, [p(f, f, t), p(t, f, t), p(t, t, t), p(f, t, t)], material); // +z
    add_quad(parts, [p(t, f, f), p(f, f, f), p(f, t, f), p(t, t, f)], material); // -z
    add_quad(parts, [p(t, f, t), p(t, f, f), p(t, t, f), p(t, t, t)], material); // +x
    add_quad(parts, [p(f, f, f), p(f, f, t), p(f, t, t), p(f, t, f)], material); // -x
    add_quad(parts, [p(f, t, t), p(t, t, t), p(t, t, f), p(f, t, f)], material); // +y
    add_quad(parts, [p(f, f, f), p(t, f, f), p(t, f, t), p(f, f, t)], material);
    // -y
}

/// A Cornell-style box: room `[-1, 1]³` open towards +z, red left and green right walls, a
/// downward-facing area light under the ceiling and two white blocks; Lambertian throughout.
pub fn cornell_box() -> Scene {
    Scene::from_parts(cornell_box_parts()).expect("the built-in Cornell box is valid")
}

/// The parts of [`cornell_box`], to vary it.
pub fn cornell_box_parts() -> SceneParts {
    let mut parts = SceneParts {
        materials: vec![
            Material::diffuse(Vec3A::splat(0.73)),
            Material::diffuse(Vec3A::new(0.65, 0.05, 0.05)),
            Material::diffuse(Vec3A::new(0.12, 0.45, 0.15)),
            Material::emissive(Vec3A::splat(0.78), Vec3A::new(17.0, 12.0, 4.0)),
        ],
        ..Default::default()
    };
    let v = Vec3A::new;
    add_quad(&mut parts, [v(-1., -1., 1.), v(1., -1., 1.), v(1., -1., -1.), v(-1., -1., -1.)], 0); // floor, up
    add_quad(&mut parts, [v(-1., 1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(-1., 1., 1.)], 0); // ceiling, down
    add_quad(&mut parts, [v(-1., -1., -1.), v(1., -1., -1.), v(1., 1., -1.), v(-1., 1., -1.)], 0); // back, +z
    add_quad(&mut parts, [v(-1., -1., 1.), v(-1., -1., -1.), v(-1., 1., -1.), v(-1., 1., 1.)], 1); // left, +x
    add_quad(&mut parts, [v(1., -1., -1.), v(1., -1., 1.), v(1., 1., 1.), v(1., 1., -1.)], 2); // right, -x
    let y = 0.998;
    add_quad(&mut parts, [v(-0.25, y, -0.25), v(0.25, y, -0.25), v(0.25, y, 0.25), v(-0.25, y, 0.25)], 3); // light, down
    add_box(&mut parts, v(-0.65, -1.0, -0.6), v(-0.05, 0.2, -0.05), 0);
    add_box(&mut parts, v(0.1, -1.0, -0.1), v(0.65, -0.4, 0.5), 0);
    parts.camera = Some(Camera { eye: v(0.0, 0.0, 3.9), target: v(0.0, 0.0, 0.0), up: Vec3A::Y, vfov_deg: 38.0, width: 256, height: 256 });
    parts
}

/// The Cornell-style box with a material line-up: a glossy plastic floor, a rough gold tall
/// block, a smooth glass short block and a small mirror-like chrome cube: a visual check of
/// every lobe.
pub fn materials_box() -> Scene {
    Scene::from_parts(materials_box_parts()).expect("the built-in material box is valid")
}

/// The parts of [`materials_box`], to vary it.
pub fn materials_box_parts() -> SceneParts {
    let mut parts = SceneParts {
        materials: vec![
            Material::diffuse(Vec3A::splat(0.73)),
            Material::diffuse(Vec3A::new(0.65, 0.05, 0.05)),
            Material::diffuse(Vec3A::new(0.12, 0.45, 0.15)),
            Material::emissive(Vec3A::splat(0.78), Vec3A::new(17.0, 12.0, 4.0)),
            Material {
                name: "plastic".into(),
                base_color: Vec3A::new(0.2, 0.3, 0.6),
                metallic: 0.0,
                roughness: 0.25,
                ..Default::default()
            },
            Material::metal(Vec3A::new(1.0, 0.78, 0.34), 0.35),
            Material::glass(1.5, 0.0),
            Material::metal(Vec3A::splat(0.95), 0.0),
        ],
        ..Default::default()
    };
    let v = Vec3A::new;
    add_quad(&mut parts, [v(-1., -1., 1.), v(1., -1., 1.), v(1., -1., -1.), v(-1., -1., -1.)], 4);
    add_quad(&mut parts, [v(-1., 1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(-1., 1., 1.)], 0);
    add_quad(&mut parts, [v(-1., -1., -1.), v(1., -1., -1.), v(1., 1., -1.), v(-1., 1., -1.)], 0);
    add_quad(&mut parts, [v(-1., -1., 1.), v(-1., -1., -1.), v(-1., 1., -1.), v(-1., 1., 1.)], 1);
    add_quad(&mut parts, [v(1., -1., -1.), v(1., -1., 1.), v(1., 1., 1.), v(1., 1., -1.)], 2);
    let y = 0.998;
    add_quad(&mut parts, [v(-0.25, y, -0.25), v(0.25, y, -0.25), v(0.25, y, 0.25), v(-0.25, y, 0.25)], 3);
    add_box(&mut parts, v(-0.65, -1.0, -0.6), v(-0.05, 0.2, -0.05), 5);
    add_box(&mut parts, v(0.1, -1.0, -0.1), v(0.65, -0.4, 0.5), 6);
    add_box(&mut parts, v(0.35, -1.0, -0.8), v(0.75, -0.6, -0.4), 7);
    parts.camera = Some(Camera { eye: v(0.0, 0.0, 3.9), target: v(0.0, 0.0, 0.0), up: Vec3A::Y, vfov_deg: 38.0, width: 256, height: 256 });
    parts
}

/// A closed cube `[-1, 1]³` whose inward-facing walls all emit `le` and reflect `albedo`
/// (Lambertian), seen from its centre: radiance is `le / (1 − albedo)` everywhere.
pub fn furnace_box(le: f32, albedo: f32) -> Scene {
    let mut parts = SceneParts { materials: vec![Material::emissive(Vec3A::splat(albedo), Vec3A::splat(le))], ..Default::default() };
    let (lo, hi) = (Vec3A::splat(-1.0), Vec3A::ONE);
    add_box(&mut parts, lo, hi, 0);
    // Turn the outward box inside out so the walls face the interior.
    for t in &mut parts.triangles {
        t.swap(1, 2);
    }
    parts.camera = Some(Camera {
        eye: Vec3A::new(0.1, -0.05, 0.2),
        target: Vec3A::new(0.3, 0.2, -1.0),
        up: Vec3A::Y,
        vfov_deg: 90.0,
        width: 16,
        height: 16,
    });
    Scene::from_parts(parts).expect("the furnace box is valid")
}

/// A square Lambertian plane `[−half, half]²` in `y = 0` facing +Y with albedo `rho`
/// (material 0), seen from above; add lights, occluders or an environment to the parts.
pub fn plane_parts(rho: f32, half: f32) -> SceneParts {
    let mut parts = SceneParts { materials: vec![Material::diffuse(Vec3A::splat(rho))], ..Default::default() };
    let v = Vec3A::new;
    add_quad(&mut parts, [v(-half, 0.0, half), v(half, 0.0, half), v(half, 0.0, -half), v(-half, 0.0, -half)], 0);
    parts.camera = Some(Camera { eye: v(0.0, 3.0, 0.01), target: Vec3A::ZERO, up: Vec3A::NEG_Z, vfov_deg: 60.0, width: 16, height: 16 });
    parts
}

/// Mean and standard error (per channel) of the path tracer's radiance along `ray` over PT
/// samples `0..n` of `seed` (one pixel key, so the samples are independent).
pub fn estimate_radiance<T: Intersector>(scene: &Scene, tracer: &T, ray: Ray, max_depth: i32, n: u32, seed: u64) -> (Vec3A, Vec3A) {
    let st = StreamSampler::new(seed, StreamKind::Pt);
    let limits = PathLimits { max_depth, rr_depth: 5 };
    let (mut sum, mut sq) = (DVec3::ZERO, DVec3::ZERO);
    for s in 0..n {
        let v = radiance(scene, tracer, limits, ray, &st.sample(0, s), None).as_dvec3();
        sum += v;
        sq += v * v;
    }
    let mean = sum / n as f64;
    let var = (sq / n as f64 - mean * mean).max(DVec3::ZERO) * (n as f64 / (n as f64 - 1.0).max(1.0));
    (mean.as_vec3a(), (var / n as f64).map(f64::sqrt).as_vec3a())
}

/// A ray from `eye` through `target` (unit direction).
pub fn ray_through(eye: Vec3A, target: Vec3A) -> Ray {
    Ray { origin: eye, dir: (target - eye).normalize(), tmin: 0.0, tmax: f32::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brute_force_uses_embree_barycentrics_and_nearest_hit() {
        let scene = cornell_box();
        let bf = BruteForce::new(&scene);
        let ray = Ray { origin: Vec3A::new(0.3, -0.7, 3.0), dir: Vec3A::new(0.0, 0.0, -1.0), tmin: 0.0, tmax: f32::INFINITY };
        let hit = bf.intersect(&ray).expect("looks into the box");
        let sp = scene.surface(hit.prim, hit.u, hit.v);
        let p = ray.origin + ray.dir * hit.t;
        assert!((sp.p - p).length() < 1e-5, "barycentric point {} vs ray point {p}", sp.p);
        // The near block's front face is at z = 0.5 (x = 0.3 is inside [0.1, 0.65]).
        assert!((p.z - 0.5).abs() < 1e-5, "{p}");
        assert!(bf.occluded(&Ray { tmax: 10.0, ..ray }));
        assert!(!bf.occluded(&Ray { tmax: 2.0, ..ray }));
    }

    #[test]
    fn furnace_walls_face_inwards() {
        let s = furnace_box(1.0, 0.5);
        for i in 0..s.triangles().len() as u32 {
            let [a, b, c] = s.triangle_vertices(i);
            let centroid = (a + b + c) / 3.0;
            assert!(s.geometric_normal(i).dot(-centroid) > 0.0, "triangle {i} faces out");
        }
    }
}

//! Ray casting behind a trait: the renderer needs "nearest hit" and "anything in between",
//! nothing else. The root crate implements it with Embree; tests implement it by brute force.
use glam::Vec3A;

/// Largest coordinate magnitude a scene, camera or light may have. Embree refuses (and its
/// debug checks abort on) ray origins and directions beyond about 1.8e18; spawned rays add up
/// to twice the scene's extent, so the bound leaves a wide margin while allowing any real scene
/// (the Earth's orbit is 1.5e11 m). A limit of the ray caster, so it is stated with its
/// contract; the scene, camera and lights check against it.
pub const MAX_COORDINATE: f32 = 1e15;

/// A ray segment `origin + t * dir`, `t` in `[tmin, tmax]`. `dir` need not be normalised.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3A,
    pub dir: Vec3A,
    pub tmin: f32,
    pub tmax: f32,
}

/// The nearest hit: `prim` indexes the scene's flat triangle list, `(u, v)` are the
/// barycentrics of vertices 1 and 2 (Embree's convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// A committed, immutable acceleration structure over the scene's triangles.
pub trait Intersector: Sync {
    fn intersect(&self, ray: &Ray) -> Option<Hit>;
    fn occluded(&self, ray: &Ray) -> bool;

    /// `hits[i] = intersect(&rays[i])` for rays that start close together and point alike, such
    /// as the camera rays of one pixel: an implementation may trace them together (Embree's
    /// coherent stream mode is about 2.5× cheaper per ray there), but must give the same hits
    /// (Embree's stream code may round a distance differently in the last bit).
    fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.intersect(ray);
        }
    }
}

//! Ray casting behind a trait: the renderer needs "nearest hit" and "anything in between",
//! nothing else. The root crate implements it with Embree; tests implement it by brute force.
use glam::Vec3;

/// A ray segment `origin + t * dir`, `t` in `[tmin, tmax]`. `dir` need not be normalised.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
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
}

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

/// Lanes of a [`RayPacket`]: the wavefront's chunk of paths, and the width of Embree's widest
/// packet call.
pub const PACKET: usize = 16;

/// Up to [`PACKET`] rays as structure of arrays (`origin[axis][lane]`), in the form of Embree's
/// packet calls; which lanes are rays is a bit mask beside it.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket {
    pub origin: [[f32; PACKET]; 3],
    pub dir: [[f32; PACKET]; 3],
    pub tmin: [f32; PACKET],
    pub tmax: [f32; PACKET],
}

impl RayPacket {
    /// Lane `l`'s ray.
    #[inline]
    pub fn ray(&self, l: usize) -> Ray {
        Ray {
            origin: Vec3A::new(self.origin[0][l], self.origin[1][l], self.origin[2][l]),
            dir: Vec3A::new(self.dir[0][l], self.dir[1][l], self.dir[2][l]),
            tmin: self.tmin[l],
            tmax: self.tmax[l],
        }
    }
}

/// The nearest hits of a [`RayPacket`]'s lanes, structure of arrays: `hit[l]` is 1 where lane
/// `l` hit something (then `t`, `prim`, `u`, `v` are [`Hit`]'s), 0 where it missed or was not
/// traced (then the rest is 0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HitPacket {
    pub hit: [u32; PACKET],
    pub t: [f32; PACKET],
    pub prim: [u32; PACKET],
    pub u: [f32; PACKET],
    pub v: [f32; PACKET],
}

impl HitPacket {
    /// Sets lane `l` to `hit`.
    #[inline]
    pub fn set(&mut self, l: usize, hit: Option<Hit>) {
        let h = hit.unwrap_or(Hit { t: 0.0, prim: 0, u: 0.0, v: 0.0 });
        (self.hit[l], self.t[l], self.prim[l], self.u[l], self.v[l]) = (u32::from(hit.is_some()), h.t, h.prim, h.u, h.v);
    }

    /// Lane `l`'s hit.
    #[inline]
    pub fn get(&self, l: usize) -> Option<Hit> {
        (self.hit[l] != 0).then(|| Hit { t: self.t[l], prim: self.prim[l], u: self.u[l], v: self.v[l] })
    }
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

    /// `intersect` of the lanes of `rays` whose bit is set in `active`, the others missing. An
    /// implementation may trace them as a packet (Embree's `rtcIntersect16`), but must give
    /// the hits of `intersect`, bit for bit.
    fn intersect_packet(&self, rays: &RayPacket, active: u16) -> HitPacket {
        let mut hits = HitPacket::default();
        for l in (0..PACKET).filter(|l| active >> l & 1 != 0) {
            hits.set(l, self.intersect(&rays.ray(l)));
        }
        hits
    }

    /// `occluded` of the lanes of `rays` whose bit is set in `active`, as a mask of the
    /// occluded ones (an implementation may trace them as a packet, with the answers of
    /// `occluded`).
    fn occluded_packet(&self, rays: &RayPacket, active: u16) -> u16 {
        (0..PACKET).filter(|&l| active >> l & 1 != 0 && self.occluded(&rays.ray(l))).fold(0, |m, l| m | 1 << l)
    }
}

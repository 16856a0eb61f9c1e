//! The local shading frame every lobe works in, and the mirror direction.
use glam::Vec3A;

/// An orthonormal basis around a normal: world ↔ local (z = normal).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3A,
    pub t: Vec3A,
    pub n: Vec3A,
}

impl Frame {
    /// A frame around the unit vector `n` (Duff et al. 2017 branchless basis).
    #[inline]
    pub fn from_normal(n: Vec3A) -> Frame {
        let (s, t) = n.any_orthonormal_pair();
        Frame { s, t, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Mirror `w` about the normal `n` (both pointing away from the surface).
#[inline]
pub fn reflect(w: Vec3A, n: Vec3A) -> Vec3A {
    2.0 * w.dot(n) * n - w
}

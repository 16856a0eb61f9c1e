//! Where fast and robust traversal disagree on a real render: every ray the render casts is
//! traced through a robust and a fast BVH of the same triangles, the render follows the robust
//! answer, and the rays where one traversal passes a surface the other hits are counted.
//!
//! Why: fast traversal (Embree's default, Mitsuba 3's default) is cheaper but its triangle test
//! is not watertight, so a ray can slip between two triangles that share an edge. Whether the
//! default should pay for robust traversal depends on how often that happens on real scenes,
//! which a synthetic edge test cannot say.
use crate::{BuildOptions, Device, EmbreeError, EmbreeScene};
use cvtrace_render::{Hit, Intersector, Ray};
use glam::Vec3A;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

/// A hit whose smallest barycentric coordinate is below this lies on an edge of its triangle.
const EDGE_BARYCENTRIC: f32 = 1e-3;

/// Counts of one comparison. A "pass" is a ray one traversal lets through where the other
/// stops it: a nearest-hit ray that misses or hits farther, a shadow ray found unoccluded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeakCounts {
    pub nearest_rays: u64,
    pub shadow_rays: u64,
    /// Nearest-hit rays fast traversal let through, and of those the ones whose robust hit lies
    /// on an edge that another triangle shares (the leak the robust test exists to prevent).
    pub fast_nearest: u64,
    pub fast_nearest_shared_edge: u64,
    /// Shadow rays fast traversal found unoccluded where robust traversal found them blocked,
    /// and of those the ones whose robust hit lies on a shared edge.
    pub fast_shadow: u64,
    pub fast_shadow_shared_edge: u64,
    /// The same the other way round: rays robust traversal let through where fast stopped them.
    pub robust_nearest: u64,
    pub robust_shadow: u64,
}

impl LeakCounts {
    pub fn rays(&self) -> u64 {
        self.nearest_rays + self.shadow_rays
    }
}

/// An [`Intersector`] that answers with robust traversal and counts where fast traversal would
/// have answered otherwise.
pub struct TraversalComparison {
    robust: EmbreeScene,
    fast: EmbreeScene,
    positions: Vec<Vec3A>,
    triangles: Vec<[u32; 3]>,
    /// How many triangles use each edge, keyed by its end points' bits (vertices are often
    /// duplicated per face, so indices would not find the neighbour).
    edge_uses: HashMap<[u32; 6], u32>,
    /// Distance beyond the robust hit at which a fast hit is another surface.
    tolerance: f32,
    counters: [AtomicU64; 8],
}

fn edge_key(a: Vec3A, b: Vec3A) -> [u32; 6] {
    let (a, b) = (a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits));
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
}

impl TraversalComparison {
    /// Builds both BVHs (quads, high quality, as the renderer does); `tolerance` is the distance
    /// beyond which two hits are different surfaces (the scene's ray epsilon is the natural one).
    pub fn build(positions: &[Vec3A], triangles: &[[u32; 3]], tolerance: f32) -> Result<TraversalComparison, EmbreeError> {
        let device = Device::new()?;
        let robust = device.build_scene(positions, triangles, &BuildOptions { robust: true, ..BuildOptions::default() })?;
        let fast = device.build_scene(positions, triangles, &BuildOptions { robust: false, ..BuildOptions::default() })?;
        let mut edge_uses = HashMap::new();
        for t in triangles {
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                *edge_uses.entry(edge_key(positions[t[i] as usize], positions[t[j] as usize])).or_insert(0) += 1;
            }
        }
        Ok(TraversalComparison {
            robust,
            fast,
            positions: positions.to_vec(),
            triangles: triangles.to_vec(),
            edge_uses,
            tolerance,
            counters: Default::default(),
        })
    }

    pub fn counts(&self) -> LeakCounts {
        let c = |i: usize| self.counters[i].load(Ordering::Relaxed);
        LeakCounts {
            nearest_rays: c(0),
            shadow_rays: c(1),
            fast_nearest: c(2),
            fast_nearest_shared_edge: c(3),
            fast_shadow: c(4),
            fast_shadow_shared_edge: c(5),
            robust_nearest: c(6),
            robust_shadow: c(7),
        }
    }

    fn count(&self, i: usize) {
        self.counters[i].fetch_add(1, Ordering::Relaxed);
    }

    /// Whether a hit lies on an edge of its triangle that another triangle also uses.
    fn on_shared_edge(&self, hit: &Hit) -> bool {
        let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let t = self.triangles[hit.prim as usize];
        // The edge opposite the vertex of the smallest weight is the one the hit is closest to.
        let (k, &w) = bary.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).expect("three weights");
        if w > EDGE_BARYCENTRIC {
            return false;
        }
        let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
        self.edge_uses.get(&edge_key(self.positions[a as usize], self.positions[b as usize])).is_some_and(|&n| n >= 2)
    }
}

impl Intersector for TraversalComparison {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.count(0);
        let robust = self.robust.intersect(ray);
        let fast = self.fast.intersect(ray);
        let beyond = |near: &Hit, far: Option<Hit>| far.is_none_or(|f| f.t > near.t + self.tolerance.max(near.t * 1e-4));
        if let Some(r) = &robust {
            if beyond(r, fast) {
                self.count(2);
                if self.on_shared_edge(r) {
                    self.count(3);
                }
            }
        }
        if let Some(f) = &fast {
            if beyond(f, robust) {
                self.count(6);
            }
        }
        robust
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.count(1);
        let robust = self.robust.occluded(ray);
        let fast = self.fast.occluded(ray);
        if robust && !fast {
            self.count(4);
            if self.robust.intersect(ray).is_some_and(|h| self.on_shared_edge(&h)) {
                self.count(5);
            }
        } else if fast && !robust {
            self.count(7);
        }
        robust
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box and rays from inside aimed exactly at its face diagonals: fast traversal
    /// lets some through (on shared edges), robust traversal none.
    #[test]
    fn it_counts_the_rays_fast_traversal_lets_through_shared_edges() {
        let (lo, hi) = (Vec3A::new(-0.7, -0.9, -0.3), Vec3A::new(1.3, 1.1, 1.7));
        let corner = |i: usize| Vec3A::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1]);
        let positions: Vec<Vec3A> = (0..8).map(corner).collect();
        let faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
        let triangles: Vec<[u32; 3]> = faces.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
        let check = TraversalComparison::build(&positions, &triangles, 1e-5).unwrap();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let n = 100_000;
        for i in 0..n {
            let origin = lo + (hi - lo) * Vec3A::new(0.2 + 0.6 * next(), 0.2 + 0.6 * next(), 0.2 + 0.6 * next());
            let [a, _, c, _] = faces[i % 6];
            let dir = corner(a as usize).lerp(corner(c as usize), next()) - origin;
            let hit = check.intersect(&Ray { origin, dir, tmin: 0.0, tmax: f32::INFINITY });
            assert!(hit.is_some(), "robust traversal let ray {i} out of the closed box");
            // A shadow ray to a point outside the box, through the same diagonal.
            assert!(check.occluded(&Ray { origin, dir: dir * 2.0, tmin: 0.0, tmax: 1.0 }), "shadow ray {i} left the box");
        }
        let counts = check.counts();
        eprintln!("rays from inside a closed box through its face diagonals: {counts:?}");
        assert_eq!((counts.nearest_rays, counts.shadow_rays), (n as u64, n as u64));
        // About 0.5% of such rays leak with fast traversal (tests/embree_intersect.rs); a count
        // near zero means the comparison no longer sees them.
        assert!(counts.fast_nearest > n as u64 / 1000, "{counts:?}");
        assert!(counts.fast_shadow > n as u64 / 1000, "{counts:?}");
        // Every leak here is through a diagonal two triangles share.
        assert_eq!(counts.fast_nearest_shared_edge, counts.fast_nearest, "{counts:?}");
        assert_eq!(counts.fast_shadow_shared_edge, counts.fast_shadow, "{counts:?}");
        assert_eq!((counts.robust_nearest, counts.robust_shadow), (0, 0), "{counts:?}");
    }
}

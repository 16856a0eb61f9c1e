//! Triangle pairs as Embree quads.
//!
//! Why: meshes from modelling tools are mostly quads split into two consecutive triangles, and
//! Embree intersects its quad primitive (two triangles sharing a diagonal, tested together)
//! faster than the same two triangles apart: 1.2× the single-ray rate on the Cornell box with
//! robust traversal (docs/performance.md). The renderer still sees triangles: every quad
//! remembers which triangle each of its halves is, and hits are mapped back to that triangle's
//! index and barycentrics.
//!
//! Embree splits quad `(w0, w1, w2, w3)` into the halves `(w0, w1, w3)` and `(w2, w3, w1)` and
//! reports `(u, v)` of the first, or `(1 − u', 1 − v')` of the second, so that `u + v ≤ 1`
//! means the first half. A pair `(x0, x1, x2)`, `(…)` sharing the edge `x_k x_{k+1}` becomes
//! `(x_{k+2}, x_k, y, x_{k+1})`, whose diagonal is that edge; a triangle without a partner
//! becomes `(a, b, c, c)`, whose second half has no area. Both halves use the mesh's own vertex
//! indices, so the watertightness of robust traversal at shared edges is unchanged.

use cvtrace_render::select::select4;
use glam::Vec4;

/// One half of a quad as a triangle of the input mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Half {
    /// Index of the input triangle.
    pub prim: u32,
    /// For each vertex of the half (in Embree's order), which corner (0, 1, 2) of the input
    /// triangle it is.
    pub corners: [u8; 3],
    /// `corners` as 0/1 weights: `[c][k]` is 1 if vertex `k` is corner `c + 1`. Hits multiply
    /// by these instead of comparing corners, which the compiler would turn into branches.
    picks: [[f32; 3]; 2],
}

/// The quads to hand to Embree, with the way back to triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuadMesh {
    pub quads: Vec<[u32; 4]>,
    pub halves: QuadHalves,
}

/// For each quad, the input triangles its two halves are.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuadHalves(pub Vec<[Half; 2]>);

/// Pairs consecutive triangles that share an edge; the rest become one-triangle quads.
/// Consecutive pairs are how exporters write split quads, and keeping to them leaves the
/// pairing linear in time and deterministic.
pub fn pair_triangles(triangles: &[[u32; 3]]) -> QuadMesh {
    let mut mesh = QuadMesh::default();
    let mut i = 0;
    while i < triangles.len() {
        if let Some((quad, halves)) = triangles.get(i + 1).and_then(|next| pair(i as u32, &triangles[i], next)) {
            mesh.quads.push(quad);
            mesh.halves.0.push(halves);
            i += 2;
        } else {
            let [a, b, c] = triangles[i];
            mesh.quads.push([a, b, c, c]);
            let prim = i as u32;
            mesh.halves.0.push([Half::new(prim, [0, 1, 2]), Half::new(prim, [2, 2, 1])]);
            i += 1;
        }
    }
    mesh
}

/// The quad of triangles `t1` (index `i`) and `t2` (index `i + 1`), if they share exactly one
/// edge and neither repeats a vertex.
fn pair(i: u32, t1: &[u32; 3], t2: &[u32; 3]) -> Option<([u32; 4], [Half; 2])> {
    let distinct = |t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    if !distinct(t1) || !distinct(t2) {
        return None;
    }
    let position = |t: &[u32; 3], v: u32| t.iter().position(|&x| x == v);
    let shared = t1.iter().filter(|&&v| position(t2, v).is_some()).count();
    if shared != 2 {
        return None;
    }
    // The edge x_k x_{k+1} of t1 that t2 shares, and t2's vertex y off it.
    let k = (0..3).find(|&k| position(t2, t1[k]).is_some() && position(t2, t1[(k + 1) % 3]).is_some())?;
    let (xk, xk1, x_opposite) = (t1[k], t1[(k + 1) % 3], t1[(k + 2) % 3]);
    let y_corner = (0..3).find(|&c| t2[c] != xk && t2[c] != xk1)?;
    let corner2 = |v: u32| position(t2, v).map(|c| c as u8);
    let first = Half::new(i, [((k + 2) % 3) as u8, k as u8, ((k + 1) % 3) as u8]);
    let second = Half::new(i + 1, [y_corner as u8, corner2(xk1)?, corner2(xk)?]);
    Some(([x_opposite, xk, t2[y_corner], xk1], [first, second]))
}

impl Half {
    fn new(prim: u32, corners: [u8; 3]) -> Half {
        let picks = [1, 2].map(|c| corners.map(|k| if k == c { 1.0 } else { 0.0 }));
        Half { prim, corners, picks }
    }

    /// The input triangle's barycentrics `(u, v)` (weights of its corners 1 and 2) of the point
    /// with weights `w` on this half's vertices. Masks, not branches: which corner is which
    /// differs from hit to hit, so a branch here is mispredicted about half the time.
    #[inline]
    fn barycentrics(&self, w: [f32; 3]) -> (f32, f32) {
        // `w` is finite, so `w · 0` is ±0, and adding a zero changes no sum: this adds exactly
        // the weights of the matching vertices, in order.
        let weight_of = |p: [f32; 3]| 0.0 + w[0] * p[0] + w[1] * p[1] + w[2] * p[2];
        (weight_of(self.picks[0]), weight_of(self.picks[1]))
    }
}

impl QuadHalves {
    /// The input triangle and its barycentrics for Embree's hit `(quad, u, v)`.
    #[inline]
    pub fn triangle_hit(&self, quad: u32, u: f32, v: f32) -> (u32, f32, f32) {
        let halves = &self.0[quad as usize];
        // Which half a ray hits is a coin toss for the branch predictor: select instead.
        let second = u + v > 1.0;
        let half = &halves[second as usize];
        let w = select4(second, Vec4::new(u + v - 1.0, 1.0 - u, 1.0 - v, 0.0), Vec4::new(1.0 - u - v, u, v, 0.0));
        let (tu, tv) = half.barycentrics([w.x, w.y, w.z]);
        (half.prim, tu, tv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn splitmix(state: &mut u64) -> f32 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Vertex `i` at a distinct point, so positions identify vertices.
    fn point(i: u32) -> [f32; 3] {
        let i = i as f32;
        [i, i * i * 0.5, (i * 1.7).sin()]
    }

    fn lerp3(w: [f32; 3], p: [[f32; 3]; 3]) -> [f32; 3] {
        let mut out = [0.0; 3];
        for (wk, pk) in w.iter().zip(p) {
            for (o, c) in out.iter_mut().zip(pk) {
                *o += wk * c;
            }
        }
        out
    }

    /// Every point of every quad half maps to the same point of the triangle it names.
    fn assert_halves_map_back(triangles: &[[u32; 3]]) {
        let mesh = pair_triangles(triangles);
        let mut rng = 11u64;
        for (q, quad) in mesh.quads.iter().enumerate() {
            for _ in 0..64 {
                let (u, v) = (splitmix(&mut rng), splitmix(&mut rng));
                // Embree's quad parameterisation: bilinear-looking, but each half is linear.
                let on_quad = if u + v <= 1.0 {
                    lerp3([1.0 - u - v, u, v], [point(quad[0]), point(quad[1]), point(quad[3])])
                } else {
                    let (u2, v2) = (1.0 - u, 1.0 - v);
                    lerp3([1.0 - u2 - v2, u2, v2], [point(quad[2]), point(quad[3]), point(quad[1])])
                };
                let (prim, tu, tv) = mesh.halves.triangle_hit(q as u32, u, v);
                let t = triangles[prim as usize];
                let on_triangle = lerp3([1.0 - tu - tv, tu, tv], [point(t[0]), point(t[1]), point(t[2])]);
                for (a, b) in on_quad.iter().zip(on_triangle) {
                    assert!((a - b).abs() < 1e-4, "quad {q} ({u}, {v}) → triangle {prim}: {on_quad:?} vs {on_triangle:?}");
                }
            }
        }
    }

    #[test]
    fn split_quads_pair_up_in_either_winding_and_rotation() {
        // (a,b,c),(a,c,d) as exporters write them; a rotated partner; an opposite winding.
        let tris = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [7, 6, 5], [8, 9, 10], [8, 10, 11]];
        let mesh = pair_triangles(&tris);
        assert_eq!(mesh.quads.len(), 3, "{mesh:?}");
        assert_halves_map_back(&tris);
        let covered: Vec<u32> = mesh.halves.0.iter().flat_map(|h| h.iter().map(|x| x.prim)).collect();
        assert_eq!(covered, [0, 1, 2, 3, 4, 5]);
    }

    #[test]
    fn unpaired_and_degenerate_triangles_stay_single() {
        // No shared edge; a shared vertex only; a repeated index; the same triangle twice; an odd last one.
        let tris = [[0, 1, 2], [3, 4, 5], [5, 6, 7], [8, 8, 9], [8, 9, 10], [10, 11, 12], [12, 11, 10], [13, 14, 15]];
        let mesh = pair_triangles(&tris);
        let pairs: Vec<bool> = mesh.halves.0.iter().map(|h| h[0].prim != h[1].prim).collect();
        assert_eq!(pairs, [false, false, false, false, false, false, false, false], "{mesh:?}");
        assert_halves_map_back(&tris);
    }

    #[test]
    fn the_diagonal_is_the_shared_edge() {
        let mesh = pair_triangles(&[[0, 1, 2], [0, 2, 3]]);
        let q = mesh.quads[0];
        // Embree's diagonal is w1–w3; it must be the shared edge 0–2, or the halves would be
        // different triangles from the input ones.
        let mut diagonal = [q[1], q[3]];
        diagonal.sort();
        assert_eq!(diagonal, [0, 2]);
    }
}

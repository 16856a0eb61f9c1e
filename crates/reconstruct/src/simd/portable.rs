//! The portable build: plain loops with the operations, and the order of operations, of the
//! vector builds.
use super::{
    check_iduw_bounds, check_knn_bounds, check_pair_bounds, check_row_bounds, dist2, knn_key, lane_sum, CandidateRow, IduwPlanes, Pairs,
    SharedWeights, Simd, Windows, IDUW_MAX_WINDOW,
};
use crate::fast_exp::exp_neg;

/// The portable build, available on every CPU.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Portable;

impl Simd for Portable {
    type V = [f32; 8];

    #[inline(always)]
    fn load8(self, a: &[f32; 8]) -> [f32; 8] {
        *a
    }

    #[inline(always)]
    fn store8(self, a: &mut [f32; 8], v: [f32; 8]) {
        *a = v;
    }

    #[inline(always)]
    fn splat8(self, x: f32) -> [f32; 8] {
        [x; 8]
    }

    #[inline(always)]
    fn add8(self, a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] + b[l])
    }

    #[inline(always)]
    fn sub8(self, a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] - b[l])
    }

    #[inline(always)]
    fn mul8(self, a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] * b[l])
    }

    #[inline(always)]
    fn div8(self, a: [f32; 8], b: [f32; 8]) -> [f32; 8] {
        std::array::from_fn(|l| a[l] / b[l])
    }

    #[inline(always)]
    fn sqrt8(self, a: [f32; 8]) -> [f32; 8] {
        a.map(f32::sqrt)
    }

    #[inline(always)]
    fn neg8(self, a: [f32; 8]) -> [f32; 8] {
        a.map(|x| -x)
    }

    #[inline(always)]
    fn square_add8(self, acc: &mut [f64; 8], v: [f32; 8]) {
        for (a, x) in acc.iter_mut().zip(v) {
            *a += f64::from(x) * f64::from(x);
        }
    }

    #[inline(always)]
    fn exp_weighted(self, t: &[f32], d: &[f32], gamma: f32) -> (f32, f32) {
        let (mut acc, mut wacc) = ([0.0f32; 8], [0.0f32; 8]);
        let (tc, dc) = (t.chunks_exact(8), d.chunks_exact(8));
        let (tr, dr) = (tc.remainder(), dc.remainder());
        for (t8, d8) in tc.zip(dc) {
            for l in 0..8 {
                let w = exp_neg(-gamma * t8[l]);
                acc[l] += w * d8[l];
                wacc[l] += w;
            }
        }
        for (l, (tv, dv)) in tr.iter().zip(dr).enumerate() {
            let w = exp_neg(-gamma * tv);
            acc[l] += w * dv;
            wacc[l] += w;
        }
        (lane_sum(acc), lane_sum(wacc))
    }

    #[inline(always)]
    fn exp_weighted_gammas(self, t: &[f32], d: &[f32], gammas: &[f32], out: &mut [(f32, f32)]) {
        for (o, &gamma) in out.iter_mut().zip(gammas) {
            *o = self.exp_weighted(t, d, gamma);
        }
    }

    #[inline(always)]
    fn exp_neg_in_place(self, t: &mut [f32]) {
        for v in t {
            *v = exp_neg(-*v);
        }
    }

    #[inline(always)]
    fn iduw_sums8(self, p: &IduwPlanes, win: Windows, gammas: &[f32], acc: &mut [[f32; 8]], wsum: &mut [[f32; 8]]) {
        check_iduw_bounds(p, &win, gammas.len(), acc.len(), wsum.len());
        let IduwPlanes { h, g, x, y, m } = *p;
        let Windows { c0, n0, offsets } = win;
        let n = offsets.len();
        let (mut tb, mut db) = ([0.0f32; IDUW_MAX_WINDOW], [0.0f32; IDUW_MAX_WINDOW]);
        let (t, d) = (&mut tb[..n], &mut db[..n]);
        for l in 0..8 {
            let c = c0 + l;
            for (i, &o) in offsets.iter().enumerate() {
                let j = n0 + o + l;
                let v = (x[c] - x[j]) - (y[c] - y[j]);
                t[i] = m * v * v;
                d[i] = (g[c] - g[j]) - (h[c] - h[j]);
            }
            for (q, &gamma) in gammas.iter().enumerate() {
                (acc[q][l], wsum[q][l]) = self.exp_weighted(t, d, gamma);
            }
        }
    }

    #[inline(always)]
    fn iduw_pair_weights(self, p: &IduwPlanes, pairs: Pairs, gamma: f32, out: &mut [f32]) {
        check_pair_bounds(p, &pairs, out);
        let (x, y, m) = (p.x, p.y, p.m);
        for (k, o) in out[..pairs.n].iter_mut().enumerate() {
            let (p, q) = (pairs.p0 + k, pairs.p0 + k + pairs.off);
            let v = (x[p] - x[q]) - (y[p] - y[q]);
            *o = exp_neg(-gamma * (m * v * v));
        }
    }

    #[inline(always)]
    fn iduw_row_sums_weighted(
        self,
        p: &IduwPlanes,
        win: Windows,
        weights: SharedWeights,
        part: &mut [[[f32; 8]; 16]],
        out: &mut [([f32; 8], [f32; 8])],
    ) {
        let blocks = check_row_bounds(p, &win, &weights, part.len(), out.len());
        let (h, g) = (p.h, p.g);
        let Windows { c0, n0, offsets } = win;
        let part = &mut part[..blocks];
        part.fill([[0.0; 8]; 16]);
        for (i, (&o, &s)) in offsets.iter().zip(weights.src).enumerate() {
            let a = i % 8;
            for (b, pb) in part.iter_mut().enumerate() {
                for l in 0..8 {
                    let (c, j) = (c0 + 8 * b + l, n0 + 8 * b + o + l);
                    let w = weights.values[8 * b + s + l];
                    pb[a][l] += w * ((g[c] - g[j]) - (h[c] - h[j]));
                    pb[8 + a][l] += w;
                }
            }
        }
        for (o, pb) in out.iter_mut().zip(part.iter()) {
            for l in 0..8 {
                o.0[l] = lane_sum(std::array::from_fn(|a| pb[a][l]));
                o.1[l] = lane_sum(std::array::from_fn(|a| pb[8 + a][l]));
            }
        }
    }

    #[inline(always)]
    fn gram_block<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], a0: usize, b0: usize) -> [[f32; 8]; 8] {
        let mut acc = [[0.0f32; 8]; 8];
        for (r, ej) in d.iter().zip(e) {
            for q in 0..8 {
                let ra = ej[a0 + q];
                for l in 0..8 {
                    acc[q][l] += ra * r[b0 + l];
                }
            }
        }
        acc
    }

    #[inline(always)]
    fn dot32<const P: usize>(self, a: &[f32; P], b: &[f32; P]) -> f32 {
        let mut acc = [0.0f32; 8];
        for i in (0..P).step_by(8) {
            for l in 0..8 {
                acc[l] += a[i + l] * b[i + l];
            }
        }
        ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    }

    #[inline(always)]
    fn dot32x8<const P: usize>(self, rows: [&[f32; P]; 8], b: &[f32; P]) -> [f32; 8] {
        rows.map(|r| self.dot32(r, b))
    }

    #[inline(always)]
    fn transpose8(self, m: [&[f32; 8]; 8]) -> [[f32; 8]; 8] {
        std::array::from_fn(|l| std::array::from_fn(|r| m[r][l]))
    }

    #[inline(always)]
    fn knn_keys(self, planes: [&[f32]; 3], centre: [f32; 3], row: CandidateRow, out: &mut [u64]) {
        check_knn_bounds(&planes, &row, out);
        let CandidateRow { p0, n, offset: [dx0, dy], local0 } = row;
        for (l, key) in out[..n].iter_mut().enumerate() {
            let p = p0 + l;
            let primary = dist2(&centre, &[planes[0][p], planes[1][p], planes[2][p]]).to_bits();
            let (dx, dy) = ((dx0 + l as i32) as i64, dy as i64);
            *key = knn_key(primary, (dx * dx + dy * dy) as u64, (local0 + l as u32) as u64);
        }
    }
}

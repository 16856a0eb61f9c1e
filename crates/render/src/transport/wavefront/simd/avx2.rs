//! The kernel for CPUs with AVX2: the lane loops compiled for 8-wide registers, and the 16×16
//! transpose as four 8×8 ones in them.
use super::super::lanes::{shade, Blocks, Chunk, Consts, Out, Record, Transpose, W};
use std::arch::x86_64::*;

/// Proof that this CPU runs AVX2: only [`Avx2::detect`] makes one (the field is private), so a
/// function that takes it may use AVX2 instructions.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx2 {
    _detected: (),
}

impl Avx2 {
    /// The token, if this CPU has AVX2.
    pub fn detect() -> Option<Avx2> {
        std::is_x86_feature_detected!("avx2").then_some(Avx2 { _detected: () })
    }

    /// The kernel (see [`shade`]) in AVX2 instructions.
    pub fn run(self, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
        // SAFETY: `self` exists only where `detect` found AVX2, the feature `kernel` enables.
        unsafe { kernel(self, c, o, b, normals, k) }
    }
}

#[target_feature(enable = "avx2")]
fn kernel(isa: Avx2, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
    shade(isa, c, o, b, normals, k)
}

/// The transposed 8×8 block of `block` at row `r0`, column `c0`, as eight rows.
#[inline(always)]
fn transpose8(_: Avx2, block: &[Record; W], r0: usize, c0: usize) -> [__m256; 8] {
    // SAFETY: the token proves the CPU has AVX2; every load is of the eight values of a
    // bounds-checked slice of one row of `block`.
    unsafe {
        let mut r = [_mm256_setzero_ps(); 8];
        for i in 0..8 {
            r[i] = _mm256_loadu_ps(block[r0 + i][c0..c0 + 8].as_ptr());
        }
        let mut t = [_mm256_setzero_ps(); 8];
        for p in 0..4 {
            t[2 * p] = _mm256_unpacklo_ps(r[2 * p], r[2 * p + 1]);
            t[2 * p + 1] = _mm256_unpackhi_ps(r[2 * p], r[2 * p + 1]);
        }
        // u[4g + q]: rows 4g..4g+4 of columns q and q + 4 (one per 128-bit lane).
        let mut u = [_mm256_setzero_ps(); 8];
        for g in 0..2 {
            for h in 0..2 {
                let (a, b) = (_mm256_castps_pd(t[4 * g + h]), _mm256_castps_pd(t[4 * g + 2 + h]));
                u[4 * g + 2 * h] = _mm256_castpd_ps(_mm256_unpacklo_pd(a, b));
                u[4 * g + 2 * h + 1] = _mm256_castpd_ps(_mm256_unpackhi_pd(a, b));
            }
        }
        let mut out = [_mm256_setzero_ps(); 8];
        for q in 0..4 {
            out[q] = _mm256_permute2f128_ps::<0x20>(u[q], u[4 + q]);
            out[q + 4] = _mm256_permute2f128_ps::<0x31>(u[q], u[4 + q]);
        }
        out
    }
}

impl Transpose for Avx2 {
    #[inline(always)]
    fn transpose(self, block: &mut [Record; W]) {
        let q00 = transpose8(self, block, 0, 0);
        let q01 = transpose8(self, block, 0, 8);
        let q10 = transpose8(self, block, 8, 0);
        let q11 = transpose8(self, block, 8, 8);
        for i in 0..8 {
            // SAFETY: `self` proves the CPU has AVX2; every store is of the eight values of a
            // bounds-checked slice of one row of `block`.
            unsafe {
                _mm256_storeu_ps(block[i][..8].as_mut_ptr(), q00[i]);
                _mm256_storeu_ps(block[i][8..].as_mut_ptr(), q10[i]);
                _mm256_storeu_ps(block[8 + i][..8].as_mut_ptr(), q01[i]);
                _mm256_storeu_ps(block[8 + i][8..].as_mut_ptr(), q11[i]);
            }
        }
    }
}

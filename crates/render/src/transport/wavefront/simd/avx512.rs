//! The kernel for CPUs with AVX-512 (F, DQ, VL, BW): the lane loops compiled for 16-wide
//! registers, and the 16×16 transpose in them.
use super::super::lanes::{shade, Blocks, Chunk, Consts, Out, Record, Transpose, W};
use std::arch::x86_64::*;

/// Proof that this CPU runs AVX-512F, DQ, VL and BW: only [`Avx512::detect`] makes one (the
/// field is private), so a function that takes it may use those instructions.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The token, if this CPU has every feature [`kernel`] is compiled for.
    pub fn detect() -> Option<Avx512> {
        let detected = std::is_x86_feature_detected!("avx512f")
            && std::is_x86_feature_detected!("avx512dq")
            && std::is_x86_feature_detected!("avx512vl")
            && std::is_x86_feature_detected!("avx512bw");
        detected.then_some(Avx512 { _detected: () })
    }

    /// The kernel (see [`shade`]) in AVX-512 instructions.
    pub fn run(self, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
        // SAFETY: `self` exists only where `detect` found every feature `kernel` enables.
        unsafe { kernel(self, c, o, b, normals, k) }
    }
}

#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
fn kernel(isa: Avx512, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
    shade(isa, c, o, b, normals, k)
}

/// The 16×16 transpose in AVX-512 registers: 32-bit and 64-bit interleaves within 128-bit
/// lanes, then two rounds of 128-bit lane shuffles (64 shuffles for 256 values). Plain loops,
/// not closures: a closure would not inherit the caller's target features, and every
/// intrinsic in it would become a call.
impl Transpose for Avx512 {
    #[inline(always)]
    fn transpose(self, block: &mut [Record; W]) {
        // SAFETY: `self` proves the CPU has AVX-512F; every load and store is of one whole
        // 16-value row of `block`.
        unsafe {
            let mut r = [_mm512_setzero_ps(); W];
            for i in 0..W {
                r[i] = _mm512_loadu_ps(block[i].as_ptr());
            }
            let mut t = [_mm512_setzero_ps(); W];
            for p in 0..W / 2 {
                t[2 * p] = _mm512_unpacklo_ps(r[2 * p], r[2 * p + 1]);
                t[2 * p + 1] = _mm512_unpackhi_ps(r[2 * p], r[2 * p + 1]);
            }
            // u[4g + q]: rows 4g..4g+4 of columns q, q + 4, q + 8, q + 12 (one per 128-bit lane).
            let mut u = [_mm512_setzero_ps(); W];
            for g in 0..4 {
                for h in 0..2 {
                    let (a, b) = (_mm512_castps_pd(t[4 * g + h]), _mm512_castps_pd(t[4 * g + 2 + h]));
                    u[4 * g + 2 * h] = _mm512_castpd_ps(_mm512_unpacklo_pd(a, b));
                    u[4 * g + 2 * h + 1] = _mm512_castpd_ps(_mm512_unpackhi_pd(a, b));
                }
            }
            for q in 0..4 {
                let v0 = _mm512_shuffle_f32x4::<0b10_00_10_00>(u[q], u[4 + q]);
                let v1 = _mm512_shuffle_f32x4::<0b11_01_11_01>(u[q], u[4 + q]);
                let v2 = _mm512_shuffle_f32x4::<0b10_00_10_00>(u[8 + q], u[12 + q]);
                let v3 = _mm512_shuffle_f32x4::<0b11_01_11_01>(u[8 + q], u[12 + q]);
                _mm512_storeu_ps(block[q].as_mut_ptr(), _mm512_shuffle_f32x4::<0b10_00_10_00>(v0, v2));
                _mm512_storeu_ps(block[q + 8].as_mut_ptr(), _mm512_shuffle_f32x4::<0b11_01_11_01>(v0, v2));
                _mm512_storeu_ps(block[q + 4].as_mut_ptr(), _mm512_shuffle_f32x4::<0b10_00_10_00>(v1, v3));
                _mm512_storeu_ps(block[q + 12].as_mut_ptr(), _mm512_shuffle_f32x4::<0b11_01_11_01>(v1, v3));
            }
        }
    }
}

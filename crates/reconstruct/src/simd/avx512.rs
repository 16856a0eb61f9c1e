//! The one AVX-512 kernel of the AVX2 build: the panel's Gram matrix at row width 16.
use std::arch::x86_64::*;

/// The AVX-512 subsets [`Avx512::gram16`] uses (F and VL, with AVX2). Only [`Avx512::detect`]
/// makes one, on CPUs that have them, so a value proves that the CPU runs their instructions.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The subsets, if this CPU has them.
    #[inline]
    pub(crate) fn detect() -> Option<Self> {
        let has =
            std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512vl");
        has.then_some(Avx512 { _detected: () })
    }

    /// [`super::Simd::gram_lower`] at `P = 16` (panics at any other width): rows 8–15 of both
    /// lower blocks are one 16-wide accumulator each, so every `e_j[8 + q]` is broadcast once
    /// for the two blocks, and the broadcasts fold into the multiplications. Each element is
    /// still `Σ_j e_j[a]·d_j[b]` in `j` order, no FMA: the bits of
    /// [`super::Simd::gram_block`].
    #[inline(always)]
    pub(crate) fn gram16<const P: usize>(self, d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
        // SAFETY: `self` exists, so `detect` found every feature `gram16_avx512` is compiled
        // with on this CPU.
        unsafe { gram16_avx512(d, e, out) }
    }
}

/// The body of [`Avx512::gram16`]: a function of its own, so that only these explicit loops
/// are compiled with AVX-512.
#[target_feature(enable = "avx2,avx512f,avx512vl")]
#[inline(never)]
fn gram16_avx512<const P: usize>(d: &[&[f32; P]], e: &[[f32; P]], out: &mut [[f32; P]; P]) {
    assert!(P == 16, "the AVX-512 Gram kernel takes rows of 16");
    // SAFETY: AVX-512F/VL are enabled here; every row is 16 values (asserted above), and every
    // load and store is one whole row or its first 8 values.
    unsafe {
        let mut lo = [_mm256_setzero_ps(); 8];
        let mut hi = [_mm512_setzero_ps(); 8];
        for (r, ej) in d.iter().zip(e) {
            let r8 = _mm256_loadu_ps(r.as_ptr());
            let r16 = _mm512_loadu_ps(r.as_ptr());
            for q in 0..8 {
                lo[q] = _mm256_add_ps(lo[q], _mm256_mul_ps(_mm256_set1_ps(ej[q]), r8));
                hi[q] = _mm512_add_ps(hi[q], _mm512_mul_ps(_mm512_set1_ps(ej[8 + q]), r16));
            }
        }
        for q in 0..8 {
            _mm256_storeu_ps(out[q].as_mut_ptr(), lo[q]);
            _mm512_storeu_ps(out[8 + q].as_mut_ptr(), hi[q]);
        }
    }
}

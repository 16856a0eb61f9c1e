//! A branch-free `exp` for non-positive f32 arguments.
//!
//! IDUW and the cross-bilateral filter evaluate hundreds of weights `exp(-t)` per pixel;
//! the libm call does not vectorise, this does. Relative error below 3e-7 (about 2.5 ulp) on [-87, 0].

/// e^x for x ≤ 0; arguments below -87 give ≈ 1.6e-38 (not 0), above 0 are clamped to 0.
#[inline(always)]
pub fn exp_neg(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    const ROUND: f32 = 12_582_912.0; // 1.5·2^23: adding it rounds to an integer.
    let x = x.clamp(-87.0, 0.0);
    // kf's low mantissa bits hold n = round(x·log2 e) (|n| ≤ 126 < 2^22), so 2^n is built
    // with integer ops on the bits; a float-to-int cast would not vectorise.
    let kf = x * LOG2E + ROUND;
    let n = kf - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // Taylor/minimax-quality polynomial of e^r on |r| ≤ ln2/2.
    let p = 1.0 + r * (1.0 + r * (0.5 + r * (0.166_666_67 + r * (0.041_666_668 + r * (0.008_333_452 + r * 0.001_388_720_5)))));
    let bits = kf.to_bits().wrapping_sub(ROUND.to_bits()).wrapping_add(127) << 23;
    p * f32::from_bits(bits)
}

/// Eight [`exp_neg`]s with AVX2, the same IEEE operations in the same order (bit-identical).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub unsafe fn exp_neg8_avx2(x: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: the caller guarantees AVX2 (this function's contract); the intrinsics only
    // compute on values, with no memory access.
    unsafe {
        const ROUND: f32 = 12_582_912.0;
        let c = |v: f32| _mm256_set1_ps(v);
        let x = _mm256_max_ps(_mm256_min_ps(x, c(0.0)), c(-87.0));
        let kf = _mm256_add_ps(_mm256_mul_ps(x, c(std::f32::consts::LOG2_E)), c(ROUND));
        let n = _mm256_sub_ps(kf, c(ROUND));
        let r = _mm256_sub_ps(_mm256_sub_ps(x, _mm256_mul_ps(n, c(0.693_145_75))), _mm256_mul_ps(n, c(1.428_606_8e-6)));
        let mut p = _mm256_add_ps(c(0.008_333_452), _mm256_mul_ps(r, c(0.001_388_720_5)));
        for k in [0.041_666_668, 0.166_666_67, 0.5, 1.0, 1.0] {
            p = _mm256_add_ps(c(k), _mm256_mul_ps(r, p));
        }
        let bits = _mm256_slli_epi32::<23>(_mm256_add_epi32(
            _mm256_sub_epi32(_mm256_castps_si256(kf), _mm256_set1_epi32(ROUND.to_bits() as i32)),
            _mm256_set1_epi32(127),
        ));
        _mm256_mul_ps(p, _mm256_castsi256_ps(bits))
    }
}

/// `N` independent [`exp_neg8_avx2`]s computed step by step together, the same bits per lane.
/// One exponential is a chain of about twenty dependent operations; a loop of them fills the
/// core's floating-point scheduler with one chain at a time, so interleaving independent ones
/// keeps more of them in flight.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub unsafe fn exp_neg8xn_avx2<const N: usize>(x: [std::arch::x86_64::__m256; N]) -> [std::arch::x86_64::__m256; N] {
    use std::arch::x86_64::*;
    // Plain loops, no closures: a closure does not inherit the caller's AVX2 and would call
    // every intrinsic instead of inlining it.
    // SAFETY: as for `exp_neg8_avx2`: the caller guarantees AVX2, and nothing touches memory.
    unsafe {
        const ROUND: f32 = 12_582_912.0;
        let (lo, hi) = (_mm256_set1_ps(-87.0), _mm256_setzero_ps());
        let (log2e, round) = (_mm256_set1_ps(std::f32::consts::LOG2_E), _mm256_set1_ps(ROUND));
        let (ln2_hi, ln2_lo) = (_mm256_set1_ps(0.693_145_75), _mm256_set1_ps(1.428_606_8e-6));
        let mut kf = x;
        let mut r = x;
        let mut p = x;
        for i in 0..N {
            let xi = _mm256_max_ps(_mm256_min_ps(x[i], hi), lo);
            kf[i] = _mm256_add_ps(_mm256_mul_ps(xi, log2e), round);
            let n = _mm256_sub_ps(kf[i], round);
            r[i] = _mm256_sub_ps(_mm256_sub_ps(xi, _mm256_mul_ps(n, ln2_hi)), _mm256_mul_ps(n, ln2_lo));
            p[i] = _mm256_add_ps(_mm256_set1_ps(0.008_333_452), _mm256_mul_ps(r[i], _mm256_set1_ps(0.001_388_720_5)));
        }
        for k in [0.041_666_668, 0.166_666_67, 0.5, 1.0, 1.0] {
            let kv = _mm256_set1_ps(k);
            for i in 0..N {
                p[i] = _mm256_add_ps(kv, _mm256_mul_ps(r[i], p[i]));
            }
        }
        let (bias, one27) = (_mm256_set1_epi32(ROUND.to_bits() as i32), _mm256_set1_epi32(127));
        for i in 0..N {
            let bits = _mm256_slli_epi32::<23>(_mm256_add_epi32(_mm256_sub_epi32(_mm256_castps_si256(kf[i]), bias), one27));
            p[i] = _mm256_mul_ps(p[i], _mm256_castsi256_ps(bits));
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_build_is_bit_identical() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        use std::arch::x86_64::*;
        for i in 0..20_000 {
            let x: [f32; 8] = std::array::from_fn(|l| -(i as f32 * 8.0 + l as f32) * 0.0006 + if i % 7 == 0 { 1.0 } else { 0.0 });
            let mut out = [0.0f32; 8];
            // SAFETY: AVX2 detected above.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), exp_neg8_avx2(_mm256_loadu_ps(x.as_ptr()))) };
            assert_eq!(out.map(f32::to_bits), x.map(|v| exp_neg(v).to_bits()), "{x:?}");
            let mut four = [[0.0f32; 8]; 3];
            // SAFETY: AVX2 detected above.
            unsafe {
                let v = _mm256_loadu_ps(x.as_ptr());
                let got = exp_neg8xn_avx2([v, _mm256_mul_ps(v, _mm256_set1_ps(0.5)), _mm256_set1_ps(-0.0)]);
                for (o, g) in four.iter_mut().zip(got) {
                    _mm256_storeu_ps(o.as_mut_ptr(), g);
                }
            }
            assert_eq!(four[0].map(f32::to_bits), out.map(f32::to_bits));
            assert_eq!(four[1].map(f32::to_bits), x.map(|v| exp_neg(v * 0.5).to_bits()));
            assert_eq!(four[2], [1.0; 8]);
        }
    }

    #[test]
    fn matches_std_exp() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -87.0 * i as f32 / 200_000.0;
            let want = (x as f64).exp();
            let rel = ((exp_neg(x) as f64 - want) / want).abs();
            worst = worst.max(rel);
        }
        assert!(worst < 3e-7, "worst relative error {worst}");
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(3.0), 1.0);
    }
}

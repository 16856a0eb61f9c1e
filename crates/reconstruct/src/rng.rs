//! Counter-based random numbers: a value is a pure function of (seed, counters), so results
//! do not depend on thread count or evaluation order.

/// A 64-bit mix (the SplitMix64 finaliser) of a seed and three counters.
#[inline]
pub fn hash4(seed: u64, a: u64, b: u64, c: u64) -> u64 {
    let mut z = seed;
    for v in [a, b, c] {
        z = mix(z ^ v.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    }
    z
}

#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform number in [0, 1) from the top 53 bits of a hash.
#[inline]
pub fn uniform(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_moments_match_u01() {
        // Mean 1/2 and variance 1/12; with n draws the sample mean has sd sqrt(1/12/n).
        let n = 200_000u64;
        let xs: Vec<f64> = (0..n).map(|i| uniform(hash4(7, i, 3, 1))).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd_mean = (1.0f64 / 12.0 / n as f64).sqrt();
        assert!((mean - 0.5).abs() < 5.0 * sd_mean, "mean {mean}");
        // Var of the sample variance of U(0,1): (m4 - s^4)/n with m4 = 1/80.
        let sd_var = ((1.0 / 80.0 - 1.0 / 144.0) / n as f64).sqrt();
        assert!((var - 1.0 / 12.0).abs() < 5.0 * sd_var, "var {var}");
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
    }
}

//! Exact, order-free sums of samples: every per-pixel mean cvtrace writes (stream means,
//! features, references) is a fixed-point sum of its samples divided by their count.
//!
//! Floating-point addition is not associative, so a sum built in pieces (passes, checkpoints,
//! parts rendered on other machines) would differ in its last bits from one built in one go.
//! Integer addition is: each sample is rounded once to a multiple of 2⁻⁴⁸ (its only rounding),
//! and the sums of any split of the samples add up to the same integer. The format is in
//! docs/stream-format.md ("Exact sums").
use crate::error::StreamError;
use crate::exr_io::ExrChannels;
use std::path::Path;

/// Fraction bits of the fixed-point samples.
pub const FRACTION_BITS: i32 = 48;
/// Largest magnitude of one sample. With at most 2³¹ samples per pixel the sum stays below
/// 2⁴⁷⁺⁴⁸⁺³¹ = 2¹²⁶, so it never overflows an i128; larger samples are clamped to this.
pub const MAX_SAMPLE: f64 = (1u64 << 47) as f64;
/// An i128 is stored as eight 16-bit pieces, each exact in an f32 channel.
pub const PIECES: usize = 8;

const SCALE: f64 = (1u64 << FRACTION_BITS) as f64;

/// One sample as a fixed-point integer (NaN counts as zero; renderers replace those before).
#[inline]
pub fn fixed(v: f32) -> i128 {
    fixed_f64(v as f64)
}

/// [`fixed`] of a wider value (a sum rebuilt from a mean).
#[inline]
pub fn fixed_f64(v: f64) -> i128 {
    let x = v.clamp(-MAX_SAMPLE, MAX_SAMPLE) * SCALE;
    // Every sample of a render lands here, and on baseline x86-64 both `f64::round` and a
    // conversion to i128 are library calls. Below 2⁶² the same rounding (half away from zero)
    // is a hardware truncation to i64 and an exact comparison of the remainder.
    if x.abs() < I64_RANGE {
        let t = x as i64;
        let rest = x - t as f64;
        (t + i64::from(rest >= 0.5) - i64::from(rest <= -0.5)) as i128
    } else {
        x.round() as i128
    }
}

/// Magnitude below which [`fixed_f64`] rounds through i64.
const I64_RANGE: f64 = (1u64 << 62) as f64;

/// The mean of `n` samples whose fixed-point sum is `sum` (0 for no samples).
#[inline]
pub fn mean(sum: i128, n: u64) -> f32 {
    if n == 0 {
        return 0.0;
    }
    ((sum as f64 / SCALE) / n as f64) as f32
}

/// Three channels of one pixel.
#[inline]
pub fn fixed3(v: [f32; 3]) -> [i128; 3] {
    v.map(fixed)
}

#[inline]
pub fn add3(a: &mut [i128; 3], b: [i128; 3]) {
    for c in 0..3 {
        a[c] += b[c];
    }
}

#[inline]
pub fn mean3(sum: [i128; 3], n: u64) -> [f32; 3] {
    sum.map(|s| mean(s, n))
}

/// `name.w0` … `name.w7`: piece `w` holds bits `16·w` to `16·w + 15` of the sum's two's
/// complement bit pattern, as an integer 0 … 65535.
pub fn piece_channel(name: &str, piece: usize) -> String {
    format!("{name}.w{piece}")
}

/// Stores `sums` under `name` as [`PIECES`] exact f32 planes.
pub fn insert_sums(ch: &mut ExrChannels, name: &str, sums: impl Iterator<Item = i128> + Clone) {
    for piece in 0..PIECES {
        let plane = sums.clone().map(|s| ((s as u128 >> (16 * piece)) & 0xffff) as f32).collect();
        ch.insert(piece_channel(name, piece), plane);
    }
}

/// Reads the sums stored under `name` by [`insert_sums`]; a missing channel or a value that
/// is not an integer 0 … 65535 is an error naming `path` and the channel.
pub fn take_sums(ch: &mut ExrChannels, path: &Path, name: &str) -> Result<Vec<i128>, StreamError> {
    let mut bits = vec![0u128; ch.width * ch.height];
    for piece in 0..PIECES {
        let channel = piece_channel(name, piece);
        let plane = ch.take(path, &channel)?;
        for (b, v) in bits.iter_mut().zip(plane) {
            if !(0.0..=65535.0).contains(&v) || v.fract() != 0.0 {
                return Err(StreamError::invalid(path, format!("channel {channel} is corrupt (not an integer 0 … 65535)")));
            }
            *b |= (v as u128) << (16 * piece);
        }
    }
    Ok(bits.into_iter().map(|b| b as i128).collect())
}

/// Three colour channels `R, G, B` (or `X, Y, Z`) under `prefix` (`sum.pt.R.w0` …).
pub fn insert_sums3(ch: &mut ExrChannels, prefix: &str, names: [&str; 3], sums: &[[i128; 3]]) {
    for (c, n) in names.iter().enumerate() {
        insert_sums(ch, &format!("{prefix}{n}"), sums.iter().map(|s| s[c]));
    }
}

pub fn take_sums3(ch: &mut ExrChannels, path: &Path, prefix: &str, names: [&str; 3]) -> Result<Vec<[i128; 3]>, StreamError> {
    let mut out = vec![[0i128; 3]; ch.width * ch.height];
    for (c, n) in names.iter().enumerate() {
        for (o, s) in out.iter_mut().zip(take_sums(ch, path, &format!("{prefix}{n}"))?) {
            o[c] = s;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fast_rounding_is_rounding_half_away_from_zero() {
        let reference = |v: f64| (v.clamp(-MAX_SAMPLE, MAX_SAMPLE) * SCALE).round() as i128;
        let ulp = 1.0 / SCALE;
        let mut values = vec![0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, MAX_SAMPLE, -MAX_SAMPLE, 1e300, -1e300];
        for k in -60..60 {
            let p = 2f64.powi(k);
            for v in [p, p * 1.5, p * (1.0 - f64::EPSILON), p + ulp * 0.5, p - ulp * 0.5, p + ulp * 0.49999, p + ulp * 1.5] {
                values.extend([v, -v]);
            }
        }
        for i in 0..100_000u64 {
            let bits = i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
            values.push(f64::from(f32::from_bits((bits >> 32) as u32)));
            values.push(f64::from_bits(bits));
        }
        for v in values {
            assert_eq!(fixed_f64(v), reference(v), "{v:e}");
        }
    }

    #[test]
    fn sums_of_any_split_agree_and_round_trip_through_the_pieces() {
        let samples: Vec<f32> = (0..1000).map(|i| ((i * 7919) % 1013) as f32 * 1e-3 + if i % 97 == 0 { 1e9 } else { 0.0 }).collect();
        let whole: i128 = samples.iter().map(|&v| fixed(v)).sum();
        let halves: i128 = samples[..313].iter().map(|&v| fixed(v)).sum::<i128>() + samples[313..].iter().map(|&v| fixed(v)).sum::<i128>();
        assert_eq!(whole, halves);
        let exact: f64 = samples.iter().map(|&v| v as f64).sum::<f64>() / 1000.0;
        assert!((mean(whole, 1000) as f64 - exact).abs() <= exact * 1e-6);
        assert_eq!(fixed(f32::MAX), fixed(-f32::MAX).abs());

        let mut ch = ExrChannels::new(3, 1);
        let sums = [whole, -whole, i128::MAX >> 2];
        insert_sums(&mut ch, "sum.x", sums.iter().copied());
        assert_eq!(take_sums(&mut ch, Path::new("t.exr"), "sum.x").unwrap(), sums);
    }
}

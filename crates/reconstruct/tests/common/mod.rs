//! Helpers shared by the integration tests: a counter-based normal generator and small
//! hand-made stream sets.
#![allow(dead_code)]
use cvtrace_streams::{Image, Stream, StreamMeta, StreamSet};

/// SplitMix64 of a seed and a counter.
pub fn hash(seed: u64, i: u64) -> u64 {
    let mut z = seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A standard normal number (Box–Muller), a pure function of (seed, i).
pub fn normal(seed: u64, i: u64) -> f64 {
    let u1 = ((hash(seed, 2 * i) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (hash(seed, 2 * i + 1) >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A stream set whose batch `b` of pixel `i` is `truth_i + crn(b, i)` (CRN) and
/// `truth_i + pt(b, i)` (PT), all channels equal.
pub fn stream_set(
    w: usize,
    h: usize,
    batches: usize,
    spp: u32,
    truth: impl Fn(usize) -> f64,
    crn: impl Fn(usize, usize) -> f64,
    pt: impl Fn(usize, usize) -> f64,
) -> StreamSet {
    let mk = |noise: &dyn Fn(usize, usize) -> f64| {
        let bs: Vec<Image> = (0..batches)
            .map(|b| Image { width: w, height: h, pixels: (0..w * h).map(|i| [(truth(i) + noise(b, i)) as f32; 3]).collect() })
            .collect();
        Stream::from_batches(bs)
    };
    StreamSet { width: w, height: h, pt: mk(&pt), crn: mk(&crn), features: None, meta: StreamMeta { spp, ..Default::default() } }
}

/// Mean squared difference over pixels and channels.
pub fn msd(a: &Image, b: &Image) -> f64 {
    a.pixels.iter().zip(&b.pixels).map(|(p, q)| (0..3).map(|c| (p[c] as f64 - q[c] as f64).powi(2)).sum::<f64>()).sum::<f64>()
        / (3 * a.pixels.len()) as f64
}

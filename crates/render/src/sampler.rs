//! A counter-based sampler: every random number is a pure function of
//! `(stream key, pixel key, sample index, dimension)`.
//!
//! Why counter-based: CRN needs "sample `s`, dimension `d`" to be the *same* number in every
//! pixel, PT needs it to be independent across pixels, and both need results that do not depend
//! on thread scheduling or on how a render is split into passes. A hash of the four keys gives
//! all three with no state to carry around.
//!
//! Dimensions are allocated in fixed blocks (as pbrt-v4 does) so that dimension `d` means the
//! same decision in every pixel and every path: [`dims::PIXEL`] (2, sub-pixel jitter),
//! [`dims::LENS`] (2, reserved for a thin lens), then one block of [`dims::BOUNCE_BLOCK`]
//! dimensions per path vertex (see [`dims`]).

/// The dimension layout shared by the camera and the integrator.
pub mod dims {
    /// Sub-pixel jitter, 2D.
    pub const PIXEL: u32 = 0;
    /// Lens position, 2D (reserved: the camera is a pinhole).
    pub const LENS: u32 = 2;
    /// First dimension of the block of path vertex 0 (the first hit).
    pub const FIRST_BOUNCE: u32 = 4;
    /// Dimensions per path vertex.
    pub const BOUNCE_BLOCK: u32 = 8;
    /// Offsets inside a vertex block.
    pub const LIGHT_SELECT: u32 = 0;
    /// Position on the chosen light, 2D.
    pub const LIGHT_POS: u32 = 1;
    /// Which BSDF lobe to sample.
    pub const LOBE: u32 = 3;
    /// Direction from the chosen lobe, 2D.
    pub const BSDF_DIR: u32 = 4;
    /// Russian roulette.
    pub const RUSSIAN_ROULETTE: u32 = 6;
    /// Reflect-or-refract choice of a dielectric.
    pub const DIELECTRIC_CHOICE: u32 = 7;

    /// Absolute dimension of `offset` in the block of path vertex `vertex`.
    #[inline]
    pub fn at(vertex: u32, offset: u32) -> u32 {
        FIRST_BOUNCE + vertex * BOUNCE_BLOCK + offset
    }
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's output function: a bijective 64-bit mixer with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Which of the two paired streams a sample belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamKind {
    /// Independent random numbers per pixel.
    Pt,
    /// Common random numbers: one random vector per sample index, shared by all pixels.
    Crn,
}

/// The pixel key every CRN pixel shares.
const CRN_PIXEL_KEY: u64 = u64::MAX;

/// One stream's key, derived from the user's seed; PT and CRN get distinct keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamSampler {
    kind: StreamKind,
    key: u64,
}

impl StreamSampler {
    pub fn new(seed: u64, kind: StreamKind) -> Self {
        let id = match kind {
            StreamKind::Pt => 0u64,
            StreamKind::Crn => 1u64,
        };
        StreamSampler { kind, key: mix64(mix64(seed ^ 0x6376_7472_6163_6500) ^ mix64(id.wrapping_add(GOLDEN))) }
    }

    pub fn kind(&self) -> StreamKind {
        self.kind
    }

    /// The sampler of sample `sample` of pixel `pixel` (row-major index). In the CRN stream
    /// the pixel is ignored, which is exactly the CRN property.
    #[inline]
    pub fn sample(&self, pixel: u64, sample: u32) -> SampleSampler {
        let pixel_key = match self.kind {
            StreamKind::Pt => pixel,
            StreamKind::Crn => CRN_PIXEL_KEY,
        };
        let h = mix64(self.key ^ mix64(pixel_key.wrapping_add(GOLDEN)));
        SampleSampler { key: mix64(h ^ mix64((sample as u64).wrapping_mul(GOLDEN).wrapping_add(0x5851_F42D_4C95_7F2D))) }
    }
}

/// The random vector of one sample of one pixel: dimension `d` → a number in `[0, 1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSampler {
    key: u64,
}

const INV_2_24: f32 = 1.0 / (1u32 << 24) as f32;

impl SampleSampler {
    /// The key every dimension of this sample is hashed with (for code that draws the same
    /// numbers for many samples at once).
    #[inline]
    pub(crate) fn key(&self) -> u64 {
        self.key
    }

    /// The sample whose [`SampleSampler::key`] is `key`.
    #[inline]
    pub(crate) fn from_key(key: u64) -> SampleSampler {
        SampleSampler { key }
    }

    /// Dimension `dim` as a float in `[0, 1)` with 24 random bits (exactly representable).
    #[inline]
    pub fn get1d(&self, dim: u32) -> f32 {
        let h = mix64(self.key.wrapping_add((dim as u64 + 1).wrapping_mul(GOLDEN)));
        (h >> 40) as f32 * INV_2_24
    }

    /// Dimensions `dim` and `dim + 1` as a pair. Both come from one 64-bit hash (its top and
    /// next 24 bits), which halves the hashing cost of 2D decisions; so `get2d(d)` is *not*
    /// `(get1d(d), get1d(d + 1))`, but it is just as deterministic and shared in CRN.
    #[inline]
    pub fn get2d(&self, dim: u32) -> glam::Vec2 {
        let h = mix64(self.key.wrapping_add((dim as u64 + 1).wrapping_mul(GOLDEN)) ^ 0x2D00_0000_0000_0000);
        glam::Vec2::new((h >> 40) as f32 * INV_2_24, ((h >> 16) & 0xFF_FFFF) as f32 * INV_2_24)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_keys_give_same_values_and_different_seeds_differ() {
        let a = StreamSampler::new(7, StreamKind::Pt).sample(123, 9);
        let b = StreamSampler::new(7, StreamKind::Pt).sample(123, 9);
        let c = StreamSampler::new(8, StreamKind::Pt).sample(123, 9);
        let va: Vec<f32> = (0..64).map(|d| a.get1d(d)).collect();
        let vb: Vec<f32> = (0..64).map(|d| b.get1d(d)).collect();
        let vc: Vec<f32> = (0..64).map(|d| c.get1d(d)).collect();
        assert_eq!(va, vb);
        assert!(va.iter().zip(&vc).filter(|(x, y)| x == y).count() < 2, "seed does not change the stream");
        assert!(va.iter().all(|v| (0.0..1.0).contains(v)));
    }

    #[test]
    fn crn_shares_the_random_vector_across_pixels_and_pt_does_not() {
        let crn = StreamSampler::new(42, StreamKind::Crn);
        let pt = StreamSampler::new(42, StreamKind::Pt);
        for s in 0..16 {
            let reference: Vec<f32> = (0..40).map(|d| crn.sample(0, s).get1d(d)).collect();
            for pixel in [1u64, 17, 4095, 1 << 20] {
                let v: Vec<f32> = (0..40).map(|d| crn.sample(pixel, s).get1d(d)).collect();
                assert_eq!(v, reference, "CRN sample {s} differs in pixel {pixel}");
            }
            let p0: Vec<f32> = (0..40).map(|d| pt.sample(0, s).get1d(d)).collect();
            let p1: Vec<f32> = (0..40).map(|d| pt.sample(1, s).get1d(d)).collect();
            assert!(p0.iter().zip(&p1).filter(|(a, b)| a == b).count() < 2);
            // The two streams come from one seed but must not coincide.
            assert!(p0.iter().zip(&reference).filter(|(a, b)| a == b).count() < 2);
        }
    }

    fn correlation(x: &[f64], y: &[f64]) -> f64 {
        let n = x.len() as f64;
        let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for (a, b) in x.iter().zip(y) {
            sxy += (a - mx) * (b - my);
            sxx += (a - mx) * (a - mx);
            syy += (b - my) * (b - my);
        }
        sxy / (sxx * syy).sqrt()
    }

    #[test]
    fn pt_neighbours_are_uncorrelated() {
        // Under independence the sample correlation has standard deviation ~1/sqrt(n).
        let pt = StreamSampler::new(3, StreamKind::Pt);
        let n = 4096u32;
        for (pa, pb) in [(0u64, 1u64), (100, 101), (100, 356), (5, 6)] {
            for dim in [0u32, 1, 5, 37] {
                let x: Vec<f64> = (0..n).map(|s| pt.sample(pa, s).get1d(dim) as f64).collect();
                let y: Vec<f64> = (0..n).map(|s| pt.sample(pb, s).get1d(dim) as f64).collect();
                let r = correlation(&x, &y);
                assert!(r.abs() < 4.0 / (n as f64).sqrt(), "pixels {pa},{pb} dim {dim}: corr {r}");
            }
        }
        // Consecutive dimensions and consecutive samples of one pixel are independent too.
        let x: Vec<f64> = (0..n).map(|s| pt.sample(9, s).get1d(4) as f64).collect();
        let y: Vec<f64> = (0..n).map(|s| pt.sample(9, s).get1d(5) as f64).collect();
        assert!(correlation(&x, &y).abs() < 4.0 / (n as f64).sqrt());
        let z: Vec<f64> = (0..n).map(|s| pt.sample(9, s + 1).get1d(4) as f64).collect();
        assert!(correlation(&x, &z).abs() < 4.0 / (n as f64).sqrt());
    }

    #[test]
    fn pairs_are_uniform_and_their_components_independent() {
        let st = StreamSampler::new(4, StreamKind::Pt);
        let n = 100_000u32;
        let (mut sx, mut sy, mut sxy) = (0.0f64, 0.0f64, 0.0f64);
        let mut quadrants = [0u32; 4];
        for i in 0..n {
            let v = st.sample(i as u64 % 101, i).get2d(4 + i % 7);
            assert!((0.0..1.0).contains(&v.x) && (0.0..1.0).contains(&v.y));
            sx += v.x as f64;
            sy += v.y as f64;
            sxy += (v.x as f64 - 0.5) * (v.y as f64 - 0.5);
            quadrants[(v.x >= 0.5) as usize * 2 + (v.y >= 0.5) as usize] += 1;
        }
        let sd_mean = (1.0 / 12.0 / n as f64).sqrt();
        assert!((sx / n as f64 - 0.5).abs() < 5.0 * sd_mean && (sy / n as f64 - 0.5).abs() < 5.0 * sd_mean);
        // Covariance of independent U(0,1): 0 with sd 1/12/sqrt(n).
        assert!((sxy / n as f64).abs() < 5.0 / 12.0 / (n as f64).sqrt(), "cov {}", sxy / n as f64);
        for q in quadrants {
            assert!((q as f64 - n as f64 / 4.0).abs() < 5.0 * (n as f64 * 0.25 * 0.75).sqrt(), "{quadrants:?}");
        }
    }

    #[test]
    fn values_are_uniform() {
        // Mean of U(0,1) has sd sqrt(1/12/n); also check a coarse histogram with a chi-square bound.
        for kind in [StreamKind::Pt, StreamKind::Crn] {
            let st = StreamSampler::new(11, kind);
            let n = 200_000usize;
            let mut sum = 0.0f64;
            let mut bins = [0u32; 16];
            for i in 0..n {
                let v = st.sample(i as u64 % 977, i as u32).get1d((i % 13) as u32);
                sum += v as f64;
                bins[(v * 16.0) as usize] += 1;
            }
            let mean = sum / n as f64;
            let sd = (1.0 / 12.0 / n as f64).sqrt();
            assert!((mean - 0.5).abs() < 5.0 * sd, "{kind:?} mean {mean}");
            let expect = n as f64 / 16.0;
            let chi2: f64 = bins.iter().map(|&b| (b as f64 - expect).powi(2) / expect).sum();
            // 15 degrees of freedom: P(chi2 > 45) < 1e-4.
            assert!(chi2 < 45.0, "{kind:?} chi2 {chi2} bins {bins:?}");
        }
    }
}

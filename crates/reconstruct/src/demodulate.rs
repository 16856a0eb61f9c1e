//! Albedo demodulation: reconstruct illumination instead of radiance, where the first-hit albedo
//! is known.
//!
//! Every pixel value of both streams (means and batches) is divided by the pixel's first-hit
//! albedo, the control-variate estimate is computed on the quotient, and it is multiplied back
//! by the same albedo. A texture edge then no longer separates pixels that receive the same
//! light: the k-NN selection by CRN colour and the PT error filter see the illumination, which
//! is smooth where the texture is not.
//!
//! The transform is exact for the centre (`a_c·(ḡ_c/a_c) = ḡ_c`); for a neighbour it rescales
//! the control variate `ḡ_i − h̄_i` by `a_c/a_i`. That keeps its mean at zero only if `a_i`
//! does not depend on the samples it divides, and the albedo feature is averaged over the PT
//! samples: where the texture varies inside a pixel, `h̄_i/a_i` follows the PT samples' own
//! texels and `ḡ_i/a_i` does not, so the quotient's control variates are not centred (+1.3% of
//! the image mean on a textured bundled scene when nothing corrected it). The estimators
//! therefore run their low-pass correction on radiance, after multiplying back, which removes
//! that bias at every scale coarser than its σ.
use crate::{Input, ReconError};
use cvtrace_streams::{Image, Stream, StreamSet};

crate::named::named_enum! {
    /// Whether an estimator reconstructs radiance or illumination (radiance ÷ first-hit albedo).
    pub enum Demodulation: "demodulate" {
        /// Illumination where the input has first-hit features, radiance where it has none.
        Auto => "auto",
        /// Illumination; the input must have features.
        On => "on",
        /// Radiance, as the paper's estimators do.
        Off => "off",
    }
}

impl Demodulation {
    /// What the estimator needs features for, when it needs them whatever the input.
    pub fn needs_features(self) -> Option<&'static str> {
        (self == Demodulation::On).then_some("with demodulate = on")
    }
}

/// Albedo channels below this are raised to it before dividing: a black (or pure-colour)
/// albedo channel would otherwise turn that channel's specular light and noise into a huge
/// quotient that dominates the CRN-colour distance of k-NN selection.
pub const ALBEDO_FLOOR: f32 = 0.05;

/// The per-pixel, per-channel divisor: the albedo, each channel at least [`ALBEDO_FLOOR`].
pub fn divisor(albedo: &Image) -> Image {
    let mut d = albedo.clone();
    for p in &mut d.pixels {
        for v in p.iter_mut() {
            *v = if v.is_finite() { v.max(ALBEDO_FLOOR) } else { 1.0 };
        }
    }
    d
}

/// `image / d` per pixel and channel, in one pass (no copy to divide in place).
pub fn divided(image: &Image, d: &Image) -> Image {
    if image.pixels.len() != d.pixels.len() {
        // As before: the pixels the divisor does not reach stay as they are.
        let mut out = image.clone();
        out.pixels.iter_mut().zip(&d.pixels).for_each(|(o, q)| *o = std::array::from_fn(|ch| o[ch] / q[ch]));
        return out;
    }
    let pixels = image.pixels.iter().zip(&d.pixels).map(|(p, q)| std::array::from_fn(|ch| p[ch] / q[ch])).collect();
    Image { width: image.width, height: image.height, pixels }
}

/// The stream set with every mean and batch of both streams divided by `d` (features and
/// metadata unchanged).
pub fn demodulated(set: &StreamSet, d: &Image) -> StreamSet {
    let stream = |s: &Stream| Stream { mean: divided(&s.mean, d), batches: s.batches.iter().map(|b| divided(b, d)).collect() };
    StreamSet {
        width: set.width,
        height: set.height,
        pt: stream(&set.pt),
        crn: stream(&set.crn),
        features: set.features.clone(),
        meta: set.meta.clone(),
    }
}

/// Multiplies per-pixel values back by `d`, raised to `power` (1 for an image, 2 for a variance).
pub fn remodulate(pixels: &mut [[f32; 3]], d: &Image, power: i32) {
    for (o, q) in pixels.iter_mut().zip(&d.pixels) {
        for ch in 0..3 {
            o[ch] = (f64::from(o[ch]) * f64::from(q[ch]).powi(power)) as f32;
        }
    }
}

/// The divisor when `mode` asks for demodulation of this input, `None` when it does not;
/// an error when `mode` is `on` and the input has no features.
pub fn divisor_for(mode: Demodulation, method: &'static str, input: &Input) -> Result<Option<Image>, ReconError> {
    let features = match (mode, input.streams.features.as_ref()) {
        (Demodulation::Off, _) | (Demodulation::Auto, None) => return Ok(None),
        (Demodulation::On, None) => {
            return Err(ReconError::MissingFeatures { origin: input.streams_name.to_string(), method, why: "with demodulate = on" })
        }
        (_, Some(f)) => f,
    };
    if !features.albedo.same_size(&input.streams.pt.mean) {
        return Err(ReconError::SizeMismatch {
            origin: input.streams_name.to_string(),
            layer: "albedo.*".into(),
            width: features.albedo.width,
            height: features.albedo.height,
            expected_width: input.streams.width,
            expected_height: input.streams.height,
        });
    }
    Ok(Some(divisor(&features.albedo)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demodulating_and_remodulating_restores_the_streams() {
        let albedo = Image::from_fn(5, 4, |x, y| [0.1 * x as f32, 0.9, if y == 0 { 0.0 } else { 0.5 }]);
        let d = divisor(&albedo);
        assert!(d.pixels.iter().flatten().all(|v| *v >= ALBEDO_FLOOR));
        let im = |k: f32| Image::from_fn(5, 4, |x, y| [k + x as f32, k * y as f32, 2.0]);
        let set = StreamSet {
            width: 5,
            height: 4,
            pt: Stream::from_batches(vec![im(1.0), im(2.0)]),
            crn: Stream::from_batches(vec![im(3.0), im(4.0)]),
            features: None,
            meta: Default::default(),
        };
        let q = demodulated(&set, &d);
        let mut back = q.crn.batches[1].clone();
        remodulate(&mut back.pixels, &d, 1);
        for (a, b) in back.pixels.iter().flatten().zip(set.crn.batches[1].pixels.iter().flatten()) {
            assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{a} vs {b}");
        }
        // A variance scales by the square.
        let mut v = Image::from_fn(5, 4, |_, _| [1.0; 3]);
        remodulate(&mut v.pixels, &d, 2);
        assert_eq!(v.pixels[0][2], ALBEDO_FLOOR * ALBEDO_FLOOR);
    }
}

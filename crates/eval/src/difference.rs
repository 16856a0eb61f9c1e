//! Signed difference maps: where an image is brighter or darker than the reference.
//!
//! The value of a pixel is `(x̄ − r̄) / √(r̄² + ε)`, with `x̄`, `r̄` the means of the image's and
//! the reference's channels and ε the relMSE's ([`REL_MSE_EPSILON`]): the signed counterpart of
//! the per-pixel relMSE, so a bright light and a dark corner with the same relative error look
//! the same. It is drawn through a diverging colour map with a dark centre (no difference is
//! dark, like low error in the relMSE maps), blue for darker and orange for brighter, on a
//! linear scale symmetric about zero and shared by all methods of a scene.
use crate::metrics::REL_MSE_EPSILON;
use crate::results::DifferenceScale;
use crate::EvalError;
use cvtrace_streams::Image;
use std::path::Path;

/// Name recorded in the results JSON.
pub const COLORMAP_NAME: &str = "blue-black-orange";

/// From the centre outwards: the negative side (darker than the reference) and the positive.
const CENTRE: [f64; 3] = [0.0, 0.0, 0.0];
const NEGATIVE: [[f64; 3]; 2] = [[0x2c as f64, 0x7b as f64, 0xe0 as f64], [0xbf as f64, 0xe3 as f64, 0xff as f64]];
const POSITIVE: [[f64; 3]; 2] = [[0xe0 as f64, 0x6c as f64, 0x1c as f64], [0xff as f64, 0xe0 as f64, 0xb8 as f64]];

/// The signed relative difference of every pixel of `image` to `reference`.
pub fn signed_difference(image: &Image, reference: &Image) -> Result<Vec<f32>, EvalError> {
    if !image.same_size(reference) {
        return Err(EvalError::invalid(
            "difference map",
            format!("image is {}x{}, the reference {}x{}", image.width, image.height, reference.width, reference.height),
        ));
    }
    Ok(image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(x, r)| {
            let mean = |p: &[f32; 3]| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
            let r = mean(r);
            ((mean(x) - r) / (r * r + REL_MSE_EPSILON).sqrt()) as f32
        })
        .collect())
}

/// One symmetric scale for several maps: the 99th percentile of their pooled absolute values,
/// so a few fireflies do not wash out the rest.
pub fn scale_for_differences(maps: &[&[f32]]) -> DifferenceScale {
    let total: usize = maps.iter().map(|m| m.len()).sum();
    let stride = (total / 2_000_000).max(1);
    let mut abs: Vec<f64> =
        maps.iter().flat_map(|m| m.iter()).step_by(stride).filter(|v| v.is_finite()).map(|v| (*v as f64).abs()).collect();
    abs.sort_by(|a, b| a.total_cmp(b));
    let q = abs.get(((abs.len().max(1) - 1) as f64 * 0.99).round() as usize).copied().unwrap_or(0.0);
    // Images equal to the reference still get a usable scale.
    DifferenceScale { max_abs: if q > 1e-6 { q } else { 1e-6 }, colormap: COLORMAP_NAME.into() }
}

/// The colour at `t ∈ [−1, 1]` (clamped; NaN is the centre) as sRGB bytes.
pub fn diverging(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(-1.0, 1.0) };
    let side = if t < 0.0 { &NEGATIVE } else { &POSITIVE };
    let a = t.abs();
    // The first two thirds rise from the centre to the saturated colour, the rest lighten it.
    let (from, to, f) = if a < 2.0 / 3.0 { (CENTRE, side[0], a * 1.5) } else { (side[0], side[1], (a - 2.0 / 3.0) * 3.0) };
    [0, 1, 2].map(|k| (from[k] + f * (to[k] - from[k])).round().clamp(0.0, 255.0) as u8)
}

/// Maps signed differences to sRGB bytes.
pub fn difference_rgb8(map: &[f32], scale: &DifferenceScale) -> Vec<u8> {
    map.iter().flat_map(|v| diverging(*v as f64 / scale.max_abs)).collect()
}

/// Writes a false-colour PNG of a signed difference map, atomically.
pub fn write_difference_png(
    path: &Path,
    map: &[f32],
    width: usize,
    height: usize,
    scale: &DifferenceScale,
    overwrite: bool,
) -> Result<(), EvalError> {
    if map.len() != width * height {
        return Err(EvalError::invalid(
            path.display().to_string(),
            format!("difference map has {} values, expected {width}x{height}", map.len()),
        ));
    }
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &difference_rgb8(map, scale), overwrite)?;
    Ok(())
}

/// A horizontal colour bar of the diverging map (left = −max, centre = 0) for legends.
pub fn write_difference_colorbar_png(path: &Path, width: usize, height: usize, overwrite: bool) -> Result<(), EvalError> {
    let row: Vec<u8> = (0..width).flat_map(|x| diverging(2.0 * x as f64 / (width.max(2) - 1) as f64 - 1.0)).collect();
    let bytes: Vec<u8> = (0..height).flat_map(|_| row.iter().copied()).collect();
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &bytes, overwrite)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn difference_is_signed_and_relative() {
        let reference = Image { width: 3, height: 1, pixels: vec![[1.0; 3], [0.0; 3], [10.0; 3]] };
        let image = Image { width: 3, height: 1, pixels: vec![[1.5, 1.5, 1.5], [0.0, 0.0, 0.3], [9.0; 3]] };
        let d = signed_difference(&image, &reference).unwrap();
        assert!((d[0] as f64 - 0.5 / 1.01f64.sqrt()).abs() < 1e-6, "{d:?}");
        assert!((d[1] as f64 - 0.1 / 0.1).abs() < 1e-5, "{d:?}");
        assert!((d[2] as f64 + 1.0 / 100.01f64.sqrt()).abs() < 1e-6, "{d:?}");
        assert!(signed_difference(&Image::new(2, 1), &reference).is_err());
    }

    #[test]
    fn palette_is_dark_at_zero_and_tells_the_signs_apart() {
        assert_eq!(diverging(0.0), [0, 0, 0]);
        assert_eq!(diverging(f64::NAN), [0, 0, 0]);
        let (neg, pos) = (diverging(-1.0), diverging(1.0));
        assert!(neg[2] > neg[0] && pos[0] > pos[2], "{neg:?} {pos:?}");
        assert_eq!(diverging(-5.0), neg);
        // Brightness grows with |t| on both sides.
        let sum = |c: [u8; 3]| c.iter().map(|&v| v as u32).sum::<u32>();
        for k in 1..20 {
            let (a, b) = (k as f64 / 20.0, (k + 1) as f64 / 20.0);
            assert!(sum(diverging(b)) > sum(diverging(a)) && sum(diverging(-b)) > sum(diverging(-a)), "{a}");
        }
    }

    #[test]
    fn scale_is_symmetric_and_ignores_the_last_percent() {
        let mut a: Vec<f32> = (0..1000).map(|i| if i % 2 == 0 { i as f32 / 1000.0 } else { -(i as f32) / 1000.0 }).collect();
        a[0] = 1e9;
        let s = scale_for_differences(&[&a]);
        assert!((s.max_abs - 0.99).abs() < 0.01, "{s:?}");
        assert!(scale_for_differences(&[&[0.0; 4]]).max_abs > 0.0);
        let rgb = difference_rgb8(&[0.0, -0.99, 0.99, 5.0], &s);
        assert_eq!(&rgb[0..3], &[0, 0, 0]);
        assert_eq!(&rgb[9..12], &diverging(1.0));
    }
}

//! sRGB-encoded 8-bit PNG previews of linear images (for people and for the viewer).
use crate::atomic::write_atomically;
use crate::{Image, StreamError};
use std::path::Path;

/// The sRGB transfer function (IEC 61966-2-1), input clamped to [0, 1].
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Encodes `img * 2^exposure` as sRGB bytes, row-major RGB.
pub fn to_srgb8(img: &Image, exposure: f32) -> Vec<u8> {
    let scale = exposure.exp2();
    img.pixels.iter().flat_map(|p| p.map(|v| (linear_to_srgb(v * scale) * 255.0 + 0.5) as u8)).collect()
}

/// Writes an sRGB PNG preview atomically.
pub fn write_png(path: &Path, img: &Image, exposure: f32, overwrite: bool) -> Result<(), StreamError> {
    let bytes = to_srgb8(img, exposure);
    write_rgb8_png(path, img.width, img.height, &bytes, overwrite)
}

/// Writes 8-bit RGB bytes as a PNG atomically.
pub fn write_rgb8_png(path: &Path, width: usize, height: usize, rgb: &[u8], overwrite: bool) -> Result<(), StreamError> {
    crate::atomic::check_extension(path, "png")?;
    write_atomically(path, overwrite, |tmp| -> Result<(), Box<dyn std::error::Error>> {
        let file = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        let mut enc = png::Encoder::new(file, width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header()?;
        w.write_image_data(rgb)?;
        w.finish()?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        // 18% grey encodes to about 46% in sRGB.
        assert!((linear_to_srgb(0.18) - 0.4614).abs() < 1e-3);
    }
}

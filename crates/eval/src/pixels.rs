//! The linear values behind the viewer's pixel readout.
//!
//! The viewer shows 8-bit tonemapped PNGs, which cannot say what a pixel's radiance is. A study
//! therefore keeps, next to each preview, a small EXR with the image's linear `R`, `G`, `B`, the
//! per-pixel relMSE of its error map (`relmse`) and the per-pixel HDR-FLIP of its FLIP map
//! (`flip`); the reference gets one with `R`, `G`, `B`.
//! The report embeds them as little-endian f32, base64 in one plain script per scene,
//! `images/<scene>/pixels.js`: a page opened from `file://` may not fetch files but may load
//! scripts, and the viewer loads that one only when a pixel is first pointed at. f32 and not
//! f16: the readout then shows exactly the EXR's values, and per-pixel relMSE of clean regions
//! (1e-8 and below) lies beneath f16's normal range.
use crate::EvalError;
use cvtrace_streams::exr_io::ExrChannels;
use cvtrace_streams::Image;
use std::path::Path;

/// The channel of the per-pixel relMSE in a values file.
pub const RELMSE_CHANNEL: &str = "relmse";
/// The channel of the per-pixel HDR-FLIP in a values file.
pub const FLIP_CHANNEL: &str = "flip";

/// Writes the values file of one image (and its relMSE and FLIP maps when given), atomically.
pub fn write_values_exr(
    path: &Path,
    image: &Image,
    relmse: Option<&[f32]>,
    flip: Option<&[f32]>,
    overwrite: bool,
) -> Result<(), EvalError> {
    let mut ch = ExrChannels::new(image.width, image.height);
    cvtrace_streams::exr_io::put_rgb(&mut ch, "", image);
    for (channel, what, map) in [(RELMSE_CHANNEL, "relMSE", relmse), (FLIP_CHANNEL, "FLIP", flip)] {
        if let Some(map) = map {
            if map.len() != image.width * image.height {
                return Err(EvalError::invalid(
                    path.display().to_string(),
                    format!("{what} map has {} values, expected {}x{}", map.len(), image.width, image.height),
                ));
            }
            ch.insert(channel, map.to_vec());
        }
    }
    ch.write(path, overwrite)?;
    Ok(())
}

/// The planes of a values file: `[R, G, B]`, and the relMSE and FLIP when the file has them.
pub struct Values {
    pub width: usize,
    pub height: usize,
    pub rgb: [Vec<f32>; 3],
    pub relmse: Option<Vec<f32>>,
    pub flip: Option<Vec<f32>>,
}

/// Reads a values file.
pub fn read_values_exr(path: &Path) -> Result<Values, EvalError> {
    let mut ch = ExrChannels::read(path)?;
    let mut optional = |name: &str| if ch.channels.contains_key(name) { ch.take(path, name).map(Some) } else { Ok(None) };
    let relmse = optional(RELMSE_CHANNEL)?;
    let flip = optional(FLIP_CHANNEL)?;
    let rgb = [ch.take(path, "R")?, ch.take(path, "G")?, ch.take(path, "B")?];
    Ok(Values { width: ch.width, height: ch.height, rgb, relmse, flip })
}

impl Values {
    /// The JSON object the viewer decodes: `{"rgb": <R, G, B interleaved>, "relmse": ...,
    /// "flip": ...}`, each little-endian f32 in base64.
    pub fn to_json(&self) -> serde_json::Value {
        let interleaved: Vec<f32> = (0..self.width * self.height).flat_map(|i| self.rgb.iter().map(move |c| c[i])).collect();
        let mut v = serde_json::json!({ "rgb": base64_f32(&interleaved) });
        if let Some(r) = &self.relmse {
            v["relmse"] = serde_json::Value::String(base64_f32(r));
        }
        if let Some(f) = &self.flip {
            v["flip"] = serde_json::Value::String(base64_f32(f));
        }
        v
    }
}

/// Little-endian f32 bytes in standard base64 (with padding), as `atob` reads them.
pub fn base64_f32(values: &[f32]) -> String {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    base64(&bytes)
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_standard_alphabet_and_padding() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[0xff, 0xfe, 0xfd]), "//79");
        // 1.0f32 is 00 00 80 3f little-endian.
        assert_eq!(base64_f32(&[1.0]), "AACAPw==");
    }

    #[test]
    fn values_round_trip_through_the_exr() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.values.exr");
        let img = Image { width: 2, height: 1, pixels: vec![[0.1, 0.2, 0.3], [1e-9, 5.0, 65504.5]] };
        write_values_exr(&p, &img, Some(&[1e-9, 0.25]), Some(&[0.0, 0.5]), false).unwrap();
        let v = read_values_exr(&p).unwrap();
        assert_eq!((v.width, v.height), (2, 1));
        assert_eq!(v.rgb[2], vec![0.3, 65504.5]);
        assert_eq!(v.relmse.as_deref(), Some(&[1e-9f32, 0.25][..]));
        assert_eq!(v.flip.as_deref(), Some(&[0.0f32, 0.5][..]));
        let json = v.to_json();
        assert_eq!(json["relmse"].as_str().unwrap(), base64_f32(&[1e-9, 0.25]));
        assert_eq!(json["flip"].as_str().unwrap(), base64_f32(&[0.0, 0.5]));
        assert_eq!(json["rgb"].as_str().unwrap(), base64_f32(&[0.1, 0.2, 0.3, 1e-9, 5.0, 65504.5]));
        // Without maps (the reference's file), no relmse or flip entry.
        write_values_exr(&p, &img, None, None, true).unwrap();
        let json = read_values_exr(&p).unwrap().to_json();
        assert!(json.get("relmse").is_none() && json.get("flip").is_none());
        assert!(write_values_exr(&p, &img, Some(&[0.0]), None, true).is_err());
        assert!(write_values_exr(&p, &img, None, Some(&[0.0]), true).unwrap_err().to_string().contains("FLIP map"));
    }
}

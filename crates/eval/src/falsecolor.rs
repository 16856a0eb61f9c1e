//! False-colour relMSE maps: per-pixel relMSE on a log scale through a perceptual colour map.
//!
//! The map runs through five colours of matplotlib's viridis (at 0, ¼, ½, ¾, 1) and is
//! interpolated in OKLab, so lightness rises monotonically and evenly: darker = lower error.
//! All methods of a scene share one scale so their maps can be compared by eye.
use crate::results::ErrorMapScale;
use crate::EvalError;
use std::path::Path;

/// Name recorded in the results JSON.
pub const COLORMAP_NAME: &str = "viridis-oklab";

const ANCHORS: [[u8; 3]; 5] = [[0x44, 0x01, 0x54], [0x3b, 0x52, 0x8b], [0x21, 0x91, 0x8c], [0x5e, 0xc9, 0x62], [0xfd, 0xe7, 0x25]];

/// At most this many decades between the ends of a scale: beyond it, the dark end only
/// spreads noise-free pixels over colours nobody can tell apart.
pub const MAX_DECADES: f64 = 4.0;

fn srgb_to_linear(u: f64) -> f64 {
    if u <= 0.04045 {
        u / 12.92
    } else {
        ((u + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// OKLab (Ottosson 2020) from linear sRGB.
pub fn linear_srgb_to_oklab(c: [f64; 3]) -> [f64; 3] {
    let l = 0.412_221_470_8 * c[0] + 0.536_332_536_3 * c[1] + 0.051_445_992_9 * c[2];
    let m = 0.211_903_498_2 * c[0] + 0.680_699_545_1 * c[1] + 0.107_396_956_6 * c[2];
    let s = 0.088_302_461_9 * c[0] + 0.281_718_837_6 * c[1] + 0.629_978_700_5 * c[2];
    let (l, m, s) = (l.cbrt(), m.cbrt(), s.cbrt());
    [
        0.210_454_255_3 * l + 0.793_617_785_0 * m - 0.004_072_046_8 * s,
        1.977_998_495_1 * l - 2.428_592_205_0 * m + 0.450_593_709_9 * s,
        0.025_904_037_1 * l + 0.782_771_766_2 * m - 0.808_675_766_0 * s,
    ]
}

/// Linear sRGB from OKLab.
pub fn oklab_to_linear_srgb(c: [f64; 3]) -> [f64; 3] {
    let l = c[0] + 0.396_337_777_4 * c[1] + 0.215_803_757_3 * c[2];
    let m = c[0] - 0.105_561_345_8 * c[1] - 0.063_854_172_8 * c[2];
    let s = c[0] - 0.089_484_177_5 * c[1] - 1.291_485_548_0 * c[2];
    let (l, m, s) = (l * l * l, m * m * m, s * s * s);
    [
        4.076_741_662_1 * l - 3.307_711_591_3 * m + 0.230_969_929_2 * s,
        -1.268_438_004_6 * l + 2.609_757_401_1 * m - 0.341_319_396_5 * s,
        -0.004_196_086_3 * l - 0.703_418_614_7 * m + 1.707_614_701_0 * s,
    ]
}

fn anchor_oklab(i: usize) -> [f64; 3] {
    linear_srgb_to_oklab(ANCHORS[i].map(|u| srgb_to_linear(u as f64 / 255.0)))
}

/// The colour at `t ∈ [0, 1]` (clamped) as sRGB bytes.
pub fn colormap(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (ANCHORS.len() - 1) as f64;
    let i = (x.floor() as usize).min(ANCHORS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (anchor_oklab(i), anchor_oklab(i + 1));
    let lab = [0, 1, 2].map(|k| a[k] + f * (b[k] - a[k]));
    oklab_to_linear_srgb(lab).map(|v| (linear_to_srgb(v) * 255.0 + 0.5) as u8)
}

/// A 256-entry lookup table of [`colormap`].
pub fn colormap_lut() -> Vec<[u8; 3]> {
    (0..256).map(|i| colormap(i as f64 / 255.0)).collect()
}

/// A shared log scale for several maps: from the 1st to the 99.5th percentile of their
/// pooled positive values (at most [`MAX_DECADES`] wide, at least a tenth of a decade).
pub fn scale_for_maps(maps: &[&[f32]]) -> ErrorMapScale {
    let total: usize = maps.iter().map(|m| m.len()).sum();
    // Deterministic subsample keeps the sort cheap on large images.
    let stride = (total / 2_000_000).max(1);
    let mut logs: Vec<f64> =
        maps.iter().flat_map(|m| m.iter()).step_by(stride).filter(|v| **v > 0.0 && v.is_finite()).map(|v| (*v as f64).log10()).collect();
    let (mut lo, mut hi) = if logs.is_empty() {
        (-4.0, 0.0)
    } else {
        logs.sort_by(|a, b| a.total_cmp(b));
        let q = |p: f64| logs[((logs.len() - 1) as f64 * p).round() as usize];
        (q(0.01), q(0.995))
    };
    lo = lo.max(hi - MAX_DECADES);
    if hi - lo < 0.1 {
        let mid = 0.5 * (hi + lo);
        lo = mid - 0.05;
        hi = mid + 0.05;
    }
    ErrorMapScale { log10_min: lo, log10_max: hi, colormap: COLORMAP_NAME.into() }
}

/// Maps per-pixel relMSE to sRGB bytes (zero and negative values get the darkest colour).
pub fn false_color_rgb8(map: &[f32], scale: &ErrorMapScale) -> Vec<u8> {
    let lut = colormap_lut();
    let span = scale.log10_max - scale.log10_min;
    map.iter()
        .flat_map(|v| {
            let t = if *v > 0.0 { ((*v as f64).log10() - scale.log10_min) / span } else { 0.0 };
            lut[(t.clamp(0.0, 1.0) * 255.0).round() as usize]
        })
        .collect()
}

/// Writes a false-colour PNG of a per-pixel relMSE map, atomically.
pub fn write_false_color_png(
    path: &Path,
    map: &[f32],
    width: usize,
    height: usize,
    scale: &ErrorMapScale,
    overwrite: bool,
) -> Result<(), EvalError> {
    if map.len() != width * height {
        return Err(EvalError::invalid(
            path.display().to_string(),
            format!("error map has {} values, expected {width}x{height}", map.len()),
        ));
    }
    let bytes = false_color_rgb8(map, scale);
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &bytes, overwrite)?;
    Ok(())
}

/// A horizontal colour bar (left = scale minimum) for legends.
pub fn write_colorbar_png(path: &Path, width: usize, height: usize, overwrite: bool) -> Result<(), EvalError> {
    let row: Vec<u8> = (0..width).flat_map(|x| colormap(x as f64 / (width.max(2) - 1) as f64)).collect();
    let bytes: Vec<u8> = (0..height).flat_map(|_| row.iter().copied()).collect();
    cvtrace_streams::preview::write_rgb8_png(path, width, height, &bytes, overwrite)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lightness(c: [u8; 3]) -> f64 {
        linear_srgb_to_oklab(c.map(|u| srgb_to_linear(u as f64 / 255.0)))[0]
    }

    #[test]
    fn ends_are_viridis_and_lightness_rises_evenly() {
        assert_eq!(colormap(0.0), ANCHORS[0]);
        assert_eq!(colormap(1.0), ANCHORS[4]);
        assert_eq!(colormap(0.5), ANCHORS[2]);
        let lut = colormap_lut();
        let l: Vec<f64> = lut.iter().map(|c| lightness(*c)).collect();
        for w in l.windows(2) {
            assert!(w[1] >= w[0] - 2e-3, "lightness must not fall: {w:?}");
        }
        // Even steps: no quarter of the map carries more than twice the lightness change of another.
        let q: Vec<f64> = (0..4).map(|k| l[(k + 1) * 255 / 4] - l[k * 255 / 4]).collect();
        let (mn, mx) = q.iter().fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
        assert!(mn > 0.0 && mx / mn < 2.0, "{q:?}");
    }

    #[test]
    fn oklab_round_trips() {
        for c in [[0.2, 0.5, 0.9], [1.0, 0.0, 0.0], [0.01, 0.02, 0.03]] {
            let back = oklab_to_linear_srgb(linear_srgb_to_oklab(c));
            for k in 0..3 {
                assert!((back[k] - c[k]).abs() < 1e-6, "{c:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn scale_covers_the_bulk_and_maps_ends_to_ends() {
        let a: Vec<f32> = (1..=1000).map(|i| 1e-4 * i as f32).collect(); // 1e-4 .. 1e-1
        let b: Vec<f32> = vec![0.0; 10];
        let s = scale_for_maps(&[&a, &b]);
        assert!((s.log10_min - (-4.0 + 1.0f64.log10() + (11.0f64).log10())).abs() < 0.05, "{s:?}");
        assert!((s.log10_max - (0.0995f64).log10()).abs() < 0.01, "{s:?}");
        let rgb = false_color_rgb8(&[0.0, 1e-9, 1.0, 10f32.powf(0.5 * (s.log10_min + s.log10_max) as f32)], &s);
        assert_eq!(&rgb[0..3], &ANCHORS[0]);
        assert_eq!(&rgb[3..6], &ANCHORS[0]);
        assert_eq!(&rgb[6..9], &ANCHORS[4]);
        assert!(lightness([rgb[9], rgb[10], rgb[11]]) > lightness(ANCHORS[0]));
        // Degenerate inputs still give a usable, finite scale.
        let flat = scale_for_maps(&[&[0.01f32; 5]]);
        assert!(flat.log10_max > flat.log10_min && flat.log10_min.is_finite());
        let wide: Vec<f32> = (0..100).map(|i| 10f32.powi(-i / 5)).collect();
        let w = scale_for_maps(&[&wide]);
        assert!(w.log10_max - w.log10_min <= MAX_DECADES + 1e-9);
    }

    #[test]
    fn png_has_the_map_colours() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("err.png");
        let scale = ErrorMapScale { log10_min: -3.0, log10_max: -1.0, colormap: COLORMAP_NAME.into() };
        write_false_color_png(&p, &[1e-4, 1e-2, 1.0, 1e-3, 1e-1, 0.0], 3, 2, &scale, false).unwrap();
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()));
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (3, 2));
        assert_eq!(&buf[0..3], &ANCHORS[0]);
        assert_eq!(&buf[3..6], &ANCHORS[2]);
        assert_eq!(&buf[6..9], &ANCHORS[4]);
        let err = write_false_color_png(&dir.path().join("bad.png"), &[0.0; 5], 3, 2, &scale, false).unwrap_err();
        assert!(err.to_string().contains("bad.png"), "{err}");
    }
}

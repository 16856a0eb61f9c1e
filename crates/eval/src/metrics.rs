//! Error metrics against a reference image, as the paper and IDUW's code define them.
//!
//! relMSE = mean over pixels and channels of `(x − r)² / (r̄² + ε)`, with `r̄` the mean of
//! the reference pixel's three channels and `ε = 0.01`. The denominator is per *pixel*,
//! not per channel, so a dark channel of a bright pixel is not blown up; `ε` keeps black
//! pixels from dominating.
use crate::EvalError;
use cvtrace_streams::Image;
use std::path::Path;

/// The `ε` of the relMSE denominator (IDUW's code and the paper's viewer use 1e-2).
pub const REL_MSE_EPSILON: f64 = 0.01;

/// A reference image with its relMSE weights `1 / (r̄² + ε)` computed once, and a label
/// (usually its file name) used in every error message.
#[derive(Clone, Debug)]
pub struct Reference {
    pub label: String,
    pub image: Image,
    weights: Vec<f64>,
}

impl Reference {
    /// Fails when the reference holds a non-finite value (it would poison every metric).
    pub fn new(image: Image, label: impl Into<String>) -> Result<Self, EvalError> {
        let label = label.into();
        ensure_finite(&image, &label)?;
        let weights = image.pixels.iter().map(|p| rel_mse_weight(*p)).collect();
        Ok(Reference { label, image, weights })
    }

    /// Why this reference cannot rank estimators, if it cannot: black everywhere (relMSE then
    /// measures each image's own brightness) or with negative pixels (relMSE's weights assume
    /// radiance, which is never negative).
    pub fn unusable_warning(&self) -> Option<String> {
        let pixels = &self.image.pixels;
        if pixels.iter().flatten().all(|&v| v == 0.0) {
            return Some(format!("{}: the reference is black everywhere, so relMSE does not measure error here", self.label));
        }
        let negative = pixels.iter().filter(|p| p.iter().any(|&v| v < 0.0)).count();
        (negative > 0).then(|| format!("{}: {negative} reference pixels are negative; relMSE assumes non-negative radiance", self.label))
    }

    /// Reads an RGB OpenEXR reference; errors name the file.
    pub fn read_exr(path: &Path) -> Result<Self, EvalError> {
        let image = cvtrace_streams::exr_io::read_rgb(path)?;
        Reference::new(image, path.display().to_string())
    }

    pub fn width(&self) -> usize {
        self.image.width
    }

    pub fn height(&self) -> usize {
        self.image.height
    }

    /// `1 / (r̄² + ε)` per pixel, row-major.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Errors (naming `label` and the reference) unless `x` has the reference's size and is finite.
    pub fn check(&self, x: &Image, label: &str) -> Result<(), EvalError> {
        ensure_same_size(x, label, &self.image, &self.label)?;
        ensure_finite(x, label)
    }

    /// relMSE of `x` (see the module docs).
    pub fn rel_mse(&self, x: &Image, label: &str) -> Result<f64, EvalError> {
        self.check(x, label)?;
        Ok(self.weighted_sq_error(x, true))
    }

    /// Plain mean squared error over pixels and channels.
    pub fn mse(&self, x: &Image, label: &str) -> Result<f64, EvalError> {
        self.check(x, label)?;
        Ok(self.weighted_sq_error(x, false))
    }

    /// Both metrics in one pass over the image.
    pub fn metrics(&self, x: &Image, label: &str) -> Result<Metrics, EvalError> {
        self.check(x, label)?;
        let (mut rel, mut abs) = (0.0f64, 0.0f64);
        for ((p, r), w) in x.pixels.iter().zip(&self.image.pixels).zip(&self.weights) {
            let e = sq_error(*p, *r);
            rel += e * w;
            abs += e;
        }
        let n = (3 * x.len()).max(1) as f64;
        Ok(Metrics { rel_mse: rel / n, mse: abs / n })
    }

    /// Per-pixel relMSE (mean over the three channels): the input of false-colour maps.
    /// Its mean over pixels equals [`Reference::rel_mse`].
    pub fn rel_mse_map(&self, x: &Image, label: &str) -> Result<Vec<f32>, EvalError> {
        self.check(x, label)?;
        Ok(x.pixels.iter().zip(&self.image.pixels).zip(&self.weights).map(|((p, r), w)| (sq_error(*p, *r) * w / 3.0) as f32).collect())
    }

    fn weighted_sq_error(&self, x: &Image, relative: bool) -> f64 {
        let mut sum = 0.0f64;
        for ((p, r), w) in x.pixels.iter().zip(&self.image.pixels).zip(&self.weights) {
            sum += sq_error(*p, *r) * if relative { *w } else { 1.0 };
        }
        sum / (3 * x.len()).max(1) as f64
    }
}

/// relMSE and MSE of one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    pub rel_mse: f64,
    pub mse: f64,
}

/// `1 / (r̄² + ε)` for one reference pixel.
#[inline]
pub fn rel_mse_weight(r: [f32; 3]) -> f64 {
    let mean = (r[0] as f64 + r[1] as f64 + r[2] as f64) / 3.0;
    1.0 / (mean * mean + REL_MSE_EPSILON)
}

/// Sum over channels of the squared difference, in f64.
#[inline]
fn sq_error(x: [f32; 3], r: [f32; 3]) -> f64 {
    (0..3).map(|c| (x[c] as f64 - r[c] as f64).powi(2)).sum()
}

/// relMSE of `x` against `reference` (errors call them "image" and "reference"; use
/// [`Reference`] to name files and to reuse the weights across many images).
pub fn rel_mse(x: &Image, reference: &Image) -> Result<f64, EvalError> {
    Reference::new(reference.clone(), "reference")?.rel_mse(x, "image")
}

/// Mean squared error over pixels and channels.
pub fn mse(x: &Image, reference: &Image) -> Result<f64, EvalError> {
    Reference::new(reference.clone(), "reference")?.mse(x, "image")
}

/// Per-pixel relMSE (mean over channels), row-major.
pub fn rel_mse_map(x: &Image, reference: &Image) -> Result<Vec<f32>, EvalError> {
    Reference::new(reference.clone(), "reference")?.rel_mse_map(x, "image")
}

/// Errors naming both labels unless `a` and `b` have the same size.
pub fn ensure_same_size(a: &Image, a_label: &str, b: &Image, b_label: &str) -> Result<(), EvalError> {
    if a.same_size(b) {
        Ok(())
    } else {
        Err(EvalError::SizeMismatch {
            a: a_label.to_string(),
            aw: a.width,
            ah: a.height,
            b: b_label.to_string(),
            bw: b.width,
            bh: b.height,
        })
    }
}

/// Errors naming `label` and the first pixel holding NaN or infinity.
pub fn ensure_finite(img: &Image, label: &str) -> Result<(), EvalError> {
    match img.find_non_finite() {
        None => Ok(()),
        Some((x, y, channel)) => Err(EvalError::NonFinite { label: label.to_string(), x, y, channel, value: img.get(x, y)[channel] }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> Image {
        Image::from_fn(w, h, f)
    }

    #[test]
    fn rel_mse_matches_the_definition_pixel_by_pixel() {
        // Two pixels with different reference brightness: the denominators differ.
        let r = img(2, 1, |x, _| if x == 0 { [1.0, 2.0, 3.0] } else { [0.0, 0.0, 0.3] });
        let x = img(2, 1, |x, _| if x == 0 { [1.5, 2.0, 2.0] } else { [0.1, 0.0, 0.3] });
        let d0 = 2.0f64 * 2.0 + 0.01; // r̄ = 2
        let d1 = 0.1f64 * 0.1 + 0.01; // r̄ = 0.1
        let expected = ((0.25 + 0.0 + 1.0) / d0 + (0.01 + 0.0 + 0.0) / d1) / 6.0;
        // Inputs are f32, so agreement is to f32 precision.
        assert!((rel_mse(&x, &r).unwrap() - expected).abs() < 1e-6 * expected);
        let expected_mse = (0.25 + 1.0 + 0.01) / 6.0;
        assert!((mse(&x, &r).unwrap() - expected_mse).abs() < 1e-6 * expected_mse);
    }

    #[test]
    fn identical_images_have_zero_error_and_error_grows_quadratically() {
        let r = img(8, 5, |x, y| [x as f32 * 0.1, y as f32 * 0.2, 0.5]);
        assert_eq!(rel_mse(&r, &r).unwrap(), 0.0);
        let shifted = |d: f32| img(8, 5, |x, y| [x as f32 * 0.1 + d, y as f32 * 0.2 + d, 0.5 + d]);
        let e1 = rel_mse(&shifted(0.01), &r).unwrap();
        let e2 = rel_mse(&shifted(0.02), &r).unwrap();
        assert!((e2 / e1 - 4.0).abs() < 1e-3, "doubling the error should quadruple relMSE: {e1} {e2}");
    }

    #[test]
    fn map_mean_equals_scalar_and_metrics_agree() {
        let r = img(7, 3, |x, y| [(x * y) as f32 * 0.05, 0.2, x as f32]);
        let x = img(7, 3, |x, y| [(x + y) as f32 * 0.03, 0.25, x as f32 * 0.9]);
        let reference = Reference::new(r.clone(), "ref.exr").unwrap();
        let map = reference.rel_mse_map(&x, "x.exr").unwrap();
        assert_eq!(map.len(), 21);
        let mean = map.iter().map(|v| *v as f64).sum::<f64>() / map.len() as f64;
        let scalar = reference.rel_mse(&x, "x.exr").unwrap();
        assert!((mean - scalar).abs() < 1e-6 * scalar);
        let m = reference.metrics(&x, "x.exr").unwrap();
        assert!((m.rel_mse - scalar).abs() < 1e-12 * scalar);
        assert!((m.mse - reference.mse(&x, "x.exr").unwrap()).abs() < 1e-15);
    }

    #[test]
    fn size_mismatch_names_both_labels() {
        let reference = Reference::new(Image::new(4, 4), "cbox.ref.exr").unwrap();
        let err = reference.rel_mse(&Image::new(4, 3), "out/ours.exr").unwrap_err().to_string();
        assert!(err.contains("cbox.ref.exr") && err.contains("out/ours.exr"), "{err}");
        assert!(err.contains("4x3") && err.contains("4x4"), "{err}");
    }

    #[test]
    fn non_finite_values_are_rejected_with_their_position() {
        let reference = Reference::new(Image::new(3, 2), "ref").unwrap();
        let mut x = Image::new(3, 2);
        x.pixels[4][2] = f32::NAN;
        let err = reference.rel_mse(&x, "iduw.exr").unwrap_err().to_string();
        assert!(err.contains("iduw.exr") && err.contains("(1, 1)") && err.contains("channel 2"), "{err}");
        let mut bad_ref = Image::new(2, 2);
        bad_ref.pixels[0][0] = f32::INFINITY;
        assert!(Reference::new(bad_ref, "bad.ref.exr").unwrap_err().to_string().contains("bad.ref.exr"));
    }

    #[test]
    fn unreadable_reference_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("garbage.exr");
        std::fs::write(&p, b"not an exr").unwrap();
        let err = Reference::read_exr(&p).unwrap_err().to_string();
        assert!(err.contains("garbage.exr"), "{err}");
        let missing = Reference::read_exr(&dir.path().join("missing.exr")).unwrap_err().to_string();
        assert!(missing.contains("missing.exr"), "{missing}");
    }
}

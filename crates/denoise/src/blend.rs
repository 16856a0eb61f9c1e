//! `blend`: `ours` and Intel Open Image Denoise combined by shrinkage, with `ours`'
//! predicted variance telling how far to trust the denoiser.
//!
//! 1. `ours` with its defaults: an unbiased image `U` and its predicted variance `v`.
//! 2. The denoiser's input `X = max(0, λ·h̄ + (1 − λ)·max(U, 0))`: mostly the PT mean, whose
//!    noise is independent per pixel as OIDN expects, with a share of `U`, whose lower but
//!    spatially correlated noise OIDN would take for detail on its own.
//! 3. `D` = OIDN(`X`), guided by the first-hit albedo and normal (prefiltered by default).
//! 4. Per pixel, over a `(2r + 1)²` window clipped at the image border, the mean squared
//!    difference `s_e = ⟨mean_c (U − D)²⟩` and the mean noise `s_v = ⟨κ · mean_c v⟩`; the weight
//!    `w = clamp(1 − s_v / s_e, 0, 1)` (James–Stein's positive part: where `U` and `D` differ by
//!    no more than `U`'s noise explains, trust `D`; where by more, `D` is biased there and `U`
//!    takes over), one weight for the three channels.
//! 5. `C = (1 − ω)·(D + w·(U − D)) + ω·U`: a fixed share `ω` of the unbiased image everywhere.
//!
//! Every constant was chosen on the bundled scenes (docs/estimators.md, "The denoiser and
//! `ours`"), the validation set measured with them untouched.
use crate::oidn::{aux, denoised, options, AUX, QUALITY};
use cvtrace_oidn::DenoiseOptions;
use cvtrace_reconstruct::{
    BatchNeed, Bounds, Diagnostics, Estimator, EstimatorSpec, Image, Input, Instance, Needs, Output, Overrides, ParamKind, ParamSpec,
    Params, ReconError, Samples, MAX_BATCHES,
};
use rayon::prelude::*;

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "blend",
    label: "Ours + OIDN (shrinkage)",
    short: "Blend",
    summary: "OIDN on the PT stream mixed with `ours`, shrunk per pixel towards `ours` (positive-part James–Stein) where they differ by more than ours' predicted variance explains.",
    colour: [0xf0, 0xc0, 0x4a],
    samples: Samples::BothStreams,
    params: &[
        ParamSpec {
            name: "pt_share",
            kind: ParamKind::Float(Bounds::between(0.0, 1.0)),
            default: "0.75",
            doc: "λ: the PT mean's share of the denoiser's input, the rest being ours' image.",
            alias: None,
        },
        ParamSpec {
            name: "radius",
            kind: ParamKind::Int { min: 0, max: 64 },
            default: "7",
            doc: "r: the shrinkage statistics are means over (2r + 1)² pixels, clipped at the image border.",
            alias: None,
        },
        ParamSpec {
            name: "noise_scale",
            kind: ParamKind::Float(Bounds::at_least(0.0)),
            default: "2",
            doc: "κ: the multiple of ours' predicted variance counted as noise in the difference of the two images.",
            alias: None,
        },
        ParamSpec {
            name: "unbiased_share",
            kind: ParamKind::Float(Bounds::between(0.0, 1.0)),
            default: "0.05",
            doc: "ω: the share of ours' image in every output pixel.",
            alias: None,
        },
        QUALITY,
        AUX,
    ],
    needs: |p| Needs {
        batches: BatchNeed::Range { min: 2, max: MAX_BATCHES },
        features: (p.choice::<String>("aux") != "none").then_some("with guides (aux other than none)"),
        reference: false,
        spp: false,
        pt2n: false,
        bounded_values: true,
    },
    build: |p| Ok(Box::new(Blend::from_params(p)?)),
    variants: &[],
};

/// The `blend` estimator.
pub struct Blend {
    ours: Instance,
    pt_share: f32,
    radius: usize,
    noise_scale: f64,
    unbiased_share: f32,
    options: DenoiseOptions,
}

impl Blend {
    pub fn from_params(p: &Params) -> Result<Self, ReconError> {
        Ok(Blend {
            ours: cvtrace_reconstruct::build("ours", &Overrides::default())?,
            pt_share: p.float("pt_share") as f32,
            radius: p.usize("radius"),
            noise_scale: p.float("noise_scale"),
            unbiased_share: p.float("unbiased_share") as f32,
            options: options(p),
        })
    }
}

impl Estimator for Blend {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let s = input.streams;
        let ours = self.ours.run(input)?;
        let variance =
            ours.aov("variance").ok_or(ReconError::Failed { method: SPEC.name, message: "ours gave no variance layer".into() })?;
        let unbiased = &ours.image;
        let lambda = self.pt_share;
        let mix = |h: f32, u: f32| (lambda * h + (1.0 - lambda) * u.max(0.0)).max(0.0);
        let x = Image {
            width: s.width,
            height: s.height,
            pixels: s.pt.mean.pixels.iter().zip(&unbiased.pixels).map(|(h, u)| std::array::from_fn(|c| mix(h[c], u[c]))).collect(),
        };
        let d = denoised(SPEC.name, &x, aux(input), &self.options)?;
        // Per-pixel means over the channels of the squared difference and of the noise.
        let e2: Vec<f64> = unbiased
            .pixels
            .iter()
            .zip(&d.pixels)
            .map(|(u, d)| (0..3).map(|c| (u[c] as f64 - d[c] as f64).powi(2)).sum::<f64>() / 3.0)
            .collect();
        let noise: Vec<f64> = variance
            .pixels
            .iter()
            .map(|v| self.noise_scale * v.iter().map(|&x| if x.is_finite() && x > 0.0 { x as f64 } else { 0.0 }).sum::<f64>() / 3.0)
            .collect();
        let (s_e, s_v) = (box_mean(&e2, s.width, s.height, self.radius), box_mean(&noise, s.width, s.height, self.radius));
        let weights: Vec<f32> = s_e
            .iter()
            .zip(&s_v)
            .map(|(&e, &v)| {
                let w = 1.0 - v / e;
                if e > 0.0 && w.is_finite() {
                    w.clamp(0.0, 1.0) as f32
                } else {
                    0.0
                }
            })
            .collect();
        let omega = self.unbiased_share;
        let pixels = d
            .pixels
            .par_iter()
            .zip(unbiased.pixels.par_iter())
            .zip(weights.par_iter())
            .map(|((d, u), &w)| std::array::from_fn(|c| (1.0 - omega) * (d[c] + w * (u[c] - d[c])) + omega * u[c]))
            .collect();
        let mut diagnostics = Diagnostics::default();
        diagnostics.float("ours_weight_mean", weights.iter().map(|&w| w as f64).sum::<f64>() / weights.len().max(1) as f64);
        diagnostics.float("ours_seconds", ours.diagnostics.seconds);
        Ok(Output::new(Image { width: s.width, height: s.height, pixels }, diagnostics))
    }
}

/// The mean of `values` (a `width × height` image, row-major) over the `(2r + 1)²` window of
/// each pixel, clipped at the border (divided by the pixels inside the image), from prefix sums.
fn box_mean(values: &[f64], width: usize, height: usize, r: usize) -> Vec<f64> {
    let stride = width + 1;
    let mut sums = vec![0.0f64; stride * (height + 1)];
    for y in 0..height {
        let mut row = 0.0;
        for x in 0..width {
            row += values[y * width + x];
            sums[(y + 1) * stride + x + 1] = sums[y * stride + x + 1] + row;
        }
    }
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(width));
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(height));
            let total = sums[y1 * stride + x1] - sums[y0 * stride + x1] - sums[y1 * stride + x0] + sums[y0 * stride + x0];
            total / ((x1 - x0) * (y1 - y0)) as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_mean_is_the_mean_of_the_clipped_window() {
        let (w, h) = (7, 5);
        let values: Vec<f64> = (0..w * h).map(|i| ((i * 37) % 11) as f64).collect();
        for r in [0, 1, 2, 9] {
            let fast = box_mean(&values, w, h, r);
            for y in 0..h {
                for x in 0..w {
                    let mut sum = 0.0;
                    let mut n = 0;
                    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                        for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                            sum += values[yy * w + xx];
                            n += 1;
                        }
                    }
                    assert!((fast[y * w + x] - sum / n as f64).abs() < 1e-9, "r {r} at ({x}, {y})");
                }
            }
        }
    }
}

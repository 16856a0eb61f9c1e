//! `ivw`: the inverse-variance blend of the two streams, an estimator written outside
//! `cvtrace-reconstruct` with its public building blocks, to show what a new estimator takes.
//!
//! Per pixel and channel the PT and CRN means are two independent unbiased estimates of the
//! same value; the blend with the least variance weights each by the other's variance:
//! `F̂ = h̄ + w·(ḡ − h̄)`, `w = v_h / (v_h + v_g)`. The variances of the means come from the
//! batches ([`blocks::variance_of_mean`]) and are smoothed by the cross-bilateral filter
//! guided by the CRN image ([`blocks::cross_bilateral`]), so that `w` depends on a
//! neighbourhood rather than on the pixel's own noise (which would bias the blend towards
//! whichever stream came out low). It uses the CRN stream only as a second sample of the
//! pixel, never its correlation with neighbours, so it is a baseline between `average`
//! (`w = ½`) and the control variates.
//!
//! Register it with `registry.register(&cvtrace_ivw::SPEC)` (cvtrace does in `src/lib.rs`).

// An estimator made of the public blocks needs no `unsafe` of its own.
#![forbid(unsafe_code)]
use cvtrace_reconstruct::blocks::{self, CbfOptions};
use cvtrace_reconstruct::{
    BatchNeed, Bounds, Diagnostics, Estimator, EstimatorSpec, Image, Input, Needs, Output, ParamKind, ParamSpec, Params, ReconError,
    Samples, MAX_BATCHES,
};
use rayon::prelude::*;

pub static SPEC: EstimatorSpec = EstimatorSpec {
    name: "ivw",
    label: "Inverse-variance blend",
    short: "IVW",
    summary: "Per pixel, PT and CRN weighted by the inverse of their filtered batch variances (an example estimator in its own crate).",
    colour: [0xff, 0x9d, 0xa7],
    samples: Samples::BothStreams,
    params: &[
        ParamSpec {
            name: "radius",
            kind: ParamKind::Int { min: 1, max: 15 },
            default: "3",
            doc: "Radius in pixels of the cross-bilateral filter of the batch variances.",
            alias: None,
        },
        ParamSpec {
            name: "sigma_colour",
            kind: ParamKind::Float(Bounds::positive()),
            default: "0.25",
            doc: "Tolerance of the filter's relative CRN colour difference.",
            alias: None,
        },
        ParamSpec {
            name: "max_weight",
            kind: ParamKind::Float(Bounds::between(0.0, 1.0)),
            default: "1",
            doc: "Largest weight of the CRN stream, w ≤ max_weight (0 gives PT alone).",
            alias: None,
        },
    ],
    needs: |_| Needs {
        batches: BatchNeed::Range { min: 2, max: MAX_BATCHES },
        features: None,
        reference: false,
        spp: false,
        pt2n: false,
        bounded_values: true,
    },
    build: |p| Ok(Box::new(Ivw::from_params(p))),
    variants: &[],
};

/// The `ivw` estimator.
#[derive(Clone, Debug)]
pub struct Ivw {
    filter: CbfOptions,
    max_weight: f64,
}

impl Ivw {
    pub fn from_params(p: &Params) -> Self {
        let filter = CbfOptions { radius: p.usize("radius"), sigma_colour: p.float("sigma_colour") as f32, ..CbfOptions::default() };
        Ivw { filter, max_weight: p.float("max_weight") }
    }
}

impl Estimator for Ivw {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let set = input.streams;
        let v_h = blocks::cross_bilateral(&blocks::variance_of_mean(&set.pt), set, &self.filter);
        let v_g = blocks::cross_bilateral(&blocks::variance_of_mean(&set.crn), set, &self.filter);
        let (h, g) = (&set.pt.mean.pixels, &set.crn.mean.pixels);
        let weights: Vec<[f64; 3]> = (0..h.len())
            .into_par_iter()
            .map(|i| {
                std::array::from_fn(|c| {
                    let (a, b) = (v_h[i][c] as f64, v_g[i][c] as f64);
                    // Both zero: the streams agree to within their noise, either will do.
                    let w = if a + b > 0.0 { a / (a + b) } else { 0.5 };
                    w.min(self.max_weight)
                })
            })
            .collect();
        let pixels = h
            .par_iter()
            .zip(g.par_iter())
            .zip(weights.par_iter())
            .map(|((h, g), w)| std::array::from_fn(|c| (h[c] as f64 + w[c] * (g[c] as f64 - h[c] as f64)) as f32))
            .collect();
        let mut d = Diagnostics::default();
        let mean_w = weights.iter().flatten().sum::<f64>() / (3 * weights.len()).max(1) as f64;
        d.float("crn_weight_mean", mean_w);
        Ok(Output::new(Image { width: set.width, height: set.height, pixels }, d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
    use cvtrace_reconstruct::{Overrides, Registry};

    fn registry() -> Registry {
        let mut r = Registry::builtin();
        r.register(&SPEC).unwrap();
        r
    }

    #[test]
    fn max_weight_zero_is_pt_and_the_blend_lies_between_the_streams() {
        let set = SoftShadowScene::default().render(&RenderSpec { width: 24, height: 20, spp: 16, batches: 8, seed: 3 }).unwrap();
        let r = registry();
        let pt_only = r.build("ivw", &Overrides::parse(["ivw.max_weight=0"]).unwrap()).unwrap().run(&Input::new(&set)).unwrap();
        assert_eq!(pt_only.image, set.pt.mean);
        let out = r.build("ivw", &Overrides::default()).unwrap().run(&Input::new(&set)).unwrap();
        for ((o, h), g) in out.image.pixels.iter().zip(&set.pt.mean.pixels).zip(&set.crn.mean.pixels) {
            for c in 0..3 {
                let (lo, hi) = (h[c].min(g[c]), h[c].max(g[c]));
                assert!(o[c] >= lo - 1e-6 * hi.abs() && o[c] <= hi + 1e-6 * hi.abs(), "{} outside [{lo}, {hi}]", o[c]);
            }
        }
        let w = out.diagnostics.get("crn_weight_mean").and_then(|v| v.as_f64()).unwrap();
        assert!(w > 0.0 && w < 1.0, "{w}");
    }

    #[test]
    fn it_has_less_error_than_pt_on_the_synthetic_scene() {
        // Over 6 seeds, relMSE of the blend against PT alone: with two independent estimates
        // of similar variance the blend should come close to halving it (average does exactly
        // that); required: below 0.8 of PT's, a bound far from both 0.5 and 1.
        let scene = SoftShadowScene::default();
        let reference = scene.reference(48, 48);
        let r = registry();
        let ivw = r.build("ivw", &Overrides::default()).unwrap();
        let (mut e_ivw, mut e_pt) = (0.0, 0.0);
        for seed in 0..6 {
            let set = scene.render(&RenderSpec { width: 48, height: 48, spp: 16, batches: 8, seed: 900 + seed }).unwrap();
            let out = ivw.run(&Input::new(&set)).unwrap();
            e_ivw += cvtrace_eval::metrics::rel_mse(&out.image, &reference).unwrap();
            e_pt += cvtrace_eval::metrics::rel_mse(&set.pt.mean, &reference).unwrap();
        }
        assert!(e_ivw < 0.8 * e_pt, "ivw {e_ivw:.4e} vs PT {e_pt:.4e}");
    }
}

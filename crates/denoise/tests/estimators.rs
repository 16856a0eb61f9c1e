//! The denoiser's estimators on the analytic soft-shadow scene: each improves on what it
//! denoises, the combination reduces to its parts at the ends of its parameters, and the
//! PT(2n) post-process says what it misses.
use cvtrace_eval::metrics::rel_mse;
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{Image, Input, Overrides, Registry};

fn registry() -> Registry {
    let mut r = Registry::builtin();
    for spec in cvtrace_denoise::SPECS {
        r.register(spec).unwrap();
    }
    r
}

fn build(r: &Registry, name: &str, params: &[&str]) -> cvtrace_reconstruct::Instance {
    r.build(name, &Overrides::parse(params).unwrap()).unwrap()
}

const SIDE: usize = 48;

#[test]
fn oidn_and_pt2n_oidn_have_less_error_than_the_images_they_denoise() {
    // Four seeds each, at 4 and 8 spp, where noise dominates the error. A denoiser has no
    // variance formula to derive a bound from: the bound, 0.8 of the noisy image's error, tells
    // a working filter (0.2–0.3 here) from one that passes the image through (1), with room for
    // the seeds' spread.
    let scene = SoftShadowScene::default();
    let reference = scene.reference(SIDE, SIDE);
    let r = registry();
    let (oidn, pt2n_oidn) = (build(&r, "oidn", &[]), build(&r, "pt2n-oidn", &[]));
    let (mut e_pt, mut e_oidn, mut e_pt2n, mut e_pt2n_oidn) = (0.0, 0.0, 0.0, 0.0);
    for seed in 0..4 {
        let spec = RenderSpec { width: SIDE, height: SIDE, spp: 4, batches: 4, seed: 70 + seed };
        let set = scene.render(&spec).unwrap();
        let pt2n = scene.render_pt(&RenderSpec { spp: 8, ..spec }, 9).unwrap().mean;
        let input = Input::new(&set).with_pt2n(&pt2n, "pt2n");
        e_pt += rel_mse(&set.pt.mean, &reference).unwrap();
        e_oidn += rel_mse(&oidn.run(&input).unwrap().image, &reference).unwrap();
        e_pt2n += rel_mse(&pt2n, &reference).unwrap();
        e_pt2n_oidn += rel_mse(&pt2n_oidn.run(&input).unwrap().image, &reference).unwrap();
    }
    eprintln!("PT {e_pt:.3e}, OIDN {e_oidn:.3e}, PT(2n) {e_pt2n:.3e}, PT(2n) + OIDN {e_pt2n_oidn:.3e}");
    assert!(e_oidn < 0.8 * e_pt, "OIDN {e_oidn:.3e} vs PT {e_pt:.3e}");
    assert!(e_pt2n_oidn < 0.8 * e_pt2n, "PT(2n) + OIDN {e_pt2n_oidn:.3e} vs PT(2n) {e_pt2n:.3e}");
}

#[test]
fn the_blend_is_ours_with_an_unbiased_share_of_one_and_between_its_parts_otherwise() {
    let scene = SoftShadowScene::default();
    let set = scene.render(&RenderSpec { width: SIDE, height: SIDE, spp: 16, batches: 8, seed: 5 }).unwrap();
    let input = Input::new(&set);
    let r = registry();
    let ours = build(&r, "ours", &[]).run(&input).unwrap().image;
    let all_ours = build(&r, "blend", &["blend.unbiased_share=1"]).run(&input).unwrap().image;
    assert_eq!(all_ours, ours, "ω = 1 gives ours' image");
    // With ω = 0 and no noise allowed (κ = 0), w = 1 wherever the images differ: ours again.
    let trusting_ours = build(&r, "blend", &["blend.unbiased_share=0", "blend.noise_scale=0"]).run(&input).unwrap().image;
    assert_eq!(trusting_ours, ours, "κ = 0 leaves no difference to the denoiser");
    // The default output lies between ours and the denoised image, pixel by pixel.
    let out = build(&r, "blend", &[]).run(&input).unwrap();
    let w = out.diagnostics.get("ours_weight_mean").and_then(|v| v.as_f64()).unwrap();
    assert!((0.0..=1.0).contains(&w), "{w}");
    let denoised_mix = build(&r, "blend", &["blend.unbiased_share=0", "blend.noise_scale=1e30"]).run(&input).unwrap().image;
    for ((o, u), d) in out.image.pixels.iter().zip(&ours.pixels).zip(&denoised_mix.pixels) {
        for c in 0..3 {
            let (lo, hi) = (u[c].min(d[c]), u[c].max(d[c]));
            assert!(o[c] >= lo - 1e-6 * hi.abs().max(1.0) && o[c] <= hi + 1e-6 * hi.abs().max(1.0), "{} outside [{lo}, {hi}]", o[c]);
        }
    }
}

#[test]
fn the_pt2n_post_process_without_its_image_says_how_to_give_one() {
    let scene = SoftShadowScene::default();
    let set = scene.render(&RenderSpec { width: 8, height: 8, spp: 4, batches: 4, seed: 1 }).unwrap();
    let est = build(&registry(), "pt2n-oidn", &[]);
    let e = est.run(&Input::new(&set)).unwrap_err().to_string();
    assert!(e.contains("pt2n-oidn") && e.contains("--pt2n"), "{e}");
    let small = Image::new(4, 4);
    let e = est.run(&Input::new(&set).with_pt2n(&small, "small.exr")).unwrap_err().to_string();
    assert!(e.contains("small.exr") && e.contains("4x4"), "{e}");
}

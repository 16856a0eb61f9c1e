//! Same input, same output, bit for bit, whatever the thread count; borders are handled.
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::*;
use cvtrace_streams::Image;

fn run_on(threads: usize, set: &cvtrace_streams::StreamSet) -> Vec<Image> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let runs: [(&str, &[&str]); 5] =
            [("ours", &[]), ("ours", &["ours.select=random"]), ("ours", &["ours.shared_coefficients=true"]), ("cv", &[]), ("iduw", &[])];
        runs.iter().map(|(m, o)| build(m, &Overrides::parse(o.iter()).unwrap()).unwrap().run(&Input::new(set)).unwrap().image).collect()
    })
}

#[test]
fn output_does_not_depend_on_thread_count() {
    let set = SoftShadowScene::default().render(&RenderSpec { width: 40, height: 33, spp: 16, batches: 8, seed: 3 }).unwrap();
    let one = run_on(1, &set);
    let three = run_on(3, &set);
    for (a, b) in one.iter().zip(&three) {
        assert!(a.pixels.iter().zip(&b.pixels).all(|(p, q)| p.map(f32::to_bits) == q.map(f32::to_bits)));
    }
}

#[test]
fn borders_are_reconstructed_not_copied() {
    // The 5-pixel border ring of ours must beat PT there, as the interior does.
    let scene = SoftShadowScene::default();
    let (w, h) = (64, 64);
    let set = scene.render(&RenderSpec { width: w, height: h, spp: 32, batches: 16, seed: 12 }).unwrap();
    let reference = scene.reference(w, h);
    let out = build("ours", &Overrides::default()).unwrap().run(&Input::new(&set)).unwrap().image;
    let ring = |im: &Image| {
        let px = (0..w * h).filter(|i| {
            let (x, y) = (i % w, i / w);
            x < 5 || y < 5 || x >= w - 5 || y >= h - 5
        });
        let pixels: Vec<[f32; 3]> = px.map(|i| im.pixels[i]).collect();
        Image { width: pixels.len(), height: 1, pixels }
    };
    let (e_ours, e_pt) = (rel_mse(&ring(&out), &ring(&reference)), rel_mse(&ring(&set.pt.mean), &ring(&reference)));
    assert!(out.pixels.iter().all(|p| p.iter().all(|v| v.is_finite())));
    assert!(e_ours < 0.6 * e_pt, "border ring: ours {e_ours:.3e}, PT {e_pt:.3e}");
}

/// relMSE as the evaluation layer defines it (one definition for the whole project).
fn rel_mse(x: &cvtrace_streams::Image, reference: &cvtrace_streams::Image) -> f64 {
    cvtrace_eval::metrics::rel_mse(x, reference).expect("images of one size")
}

//! Packets change how rays reach Embree, never what a render gives: the streams of bundled
//! scenes rendered with packets and with single rays are the same bit for bit.
use cvtrace_embree::{BuildOptions, Device};
use cvtrace_render::{render_streams, RenderSettings, Scene};
use cvtrace_streams::StreamSet;
use std::path::Path;

fn render(scene: &Scene, options: &BuildOptions) -> StreamSet {
    let tracer = Device::new().and_then(|d| d.build_scene(scene.positions(), scene.triangles(), options)).expect("Embree builds it");
    // 37×21 leaves partial tiles, so some wavefront chunks are partly filled.
    let settings = RenderSettings { width: 37, height: 21, spp: 8, batches: 2, seed: 5, max_depth: -1, rr_depth: 5 };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| render_streams(scene, &tracer, &settings, &|_| {}).unwrap())
}

/// Every value of both streams and the features, as bits (so that −0 and 0 differ).
fn bits(s: &StreamSet) -> Vec<u32> {
    let planes = [&s.pt.mean, &s.crn.mean].into_iter().chain(s.pt.batches.iter()).chain(s.crn.batches.iter());
    planes.flat_map(|i| i.pixels.iter().flatten().map(|v| v.to_bits())).collect()
}

fn same_streams(scene: &str, robust: bool) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(scene).join("scene.gltf");
    let scene_data = Scene::load(&path).expect("the bundled scene loads");
    let with = BuildOptions { robust, packets: true, ..BuildOptions::default() };
    let (a, b) = (render(&scene_data, &with), render(&scene_data, &BuildOptions { packets: false, ..with }));
    assert!(bits(&a) == bits(&b) && a == b, "{scene} (robust {robust}): packets change the streams");
    assert!(a.pt.mean.pixels.iter().filter(|p| p[0] > 0.0).count() > 37 * 21 / 4, "{scene}: the render is mostly black");
}

#[test]
fn packets_leave_the_cornell_box_streams_unchanged() {
    same_streams("cornell-box", false);
    same_streams("cornell-box", true);
}

/// Glossy materials and an environment: scalar vertices in the wavefront, and shadow rays
/// without an end.
#[test]
fn packets_leave_the_teapots_streams_unchanged() {
    same_streams("teapots", false);
}

//! How often fast traversal lets a ray through where robust traversal stops it, on real renders:
//! each scene is rendered (a reference pass at the scene's own size and depth, robust answers)
//! with every ray also traced through a fast BVH, and the disagreements are counted.
//!
//!     cargo run --release -p cvtrace-session --example traversal_leaks -- SPP scenes/*/scene.gltf
//!
//! Prints one Markdown row per scene: rays, passes per million rays of each kind.
use cvtrace_embree::set_flush_denormals;
use cvtrace_embree::traversal_check::TraversalComparison;
use cvtrace_render::{render_reference_pass, Scene};
use cvtrace_session::{image_size, resolve_settings, View};
use cvtrace_streams::reference::ReferenceAccum;
use std::path::Path;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let spp: u32 = args.next().ok_or_else(|| anyhow::anyhow!("usage: traversal_leaks SPP SCENE.gltf..."))?.parse()?;
    let pool = rayon::ThreadPoolBuilder::new().start_handler(|_| set_flush_denormals()).build()?;
    println!("| scene | size, spp | rays | fast lets through: nearest (on a shared edge) | shadow (on a shared edge) | per million rays | robust lets through: nearest, shadow |");
    println!("|---|---|---|---|---|---|---|");
    for path in args {
        let scene = Scene::load(Path::new(&path))?;
        let view = View { width: None, height: None, max_depth: None, rr_depth: None };
        let size = image_size(&view, scene.render_defaults(), scene.camera());
        let settings = resolve_settings(&view, Some(spp), 1, 1_000_003, true, scene.render_defaults(), size);
        let check = TraversalComparison::build(scene.positions(), scene.triangles(), scene.ray_epsilon())?;
        let mut accum = ReferenceAccum::new(&settings.reference());
        let start = Instant::now();
        pool.install(|| render_reference_pass(&scene, &check, &settings, &mut accum, 0..spp, &|_| {}))?;
        let c = check.counts();
        let per_million = (c.fast_nearest + c.fast_shadow) as f64 / c.rays() as f64 * 1e6;
        let name = Path::new(&path).parent().and_then(|p| p.file_name()).map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        println!(
            "| {name} | {}×{}, {spp} | {:.1} M | {} ({}) | {} ({}) | {per_million:.2} | {}, {} |",
            settings.width,
            settings.height,
            c.rays() as f64 / 1e6,
            c.fast_nearest,
            c.fast_nearest_shared_edge,
            c.fast_shadow,
            c.fast_shadow_shared_edge,
            c.robust_nearest,
            c.robust_shadow
        );
        eprintln!("{name}: {:.1} s", start.elapsed().as_secs_f64());
    }
    Ok(())
}

//! Embree against the render crate's brute-force Möller–Trumbore, ray by ray: a random
//! triangle soup (nearest hit and occlusion) and the camera rays of the shipped Cornell box.
use cvtrace_embree::{BuildOptions, Device, EmbreeScene};
use cvtrace_render::testing::BruteForce;
use cvtrace_render::{Hit, Intersector, Material, Ray, Scene, SceneParts};
use glam::Vec3A;
use std::path::Path;

/// SplitMix64: a tiny, fixed-seed generator so the test needs no extra dependency.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn in_cube(&mut self, half: f32) -> Vec3A {
        Vec3A::new(self.f32(), self.f32(), self.f32()) * (2.0 * half) - Vec3A::splat(half)
    }
}

fn soup(rng: &mut Rng, count: usize) -> Scene {
    let mut parts = SceneParts { materials: vec![Material::diffuse(Vec3A::splat(0.5))], ..Default::default() };
    for i in 0..count as u32 {
        // Triangles of random size and orientation around random centres, many overlapping.
        let c = rng.in_cube(1.0);
        let size = 0.05 + 0.3 * rng.f32();
        parts.positions.extend([c + rng.in_cube(size), c + rng.in_cube(size), c + rng.in_cube(size)]);
        parts.triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        parts.triangle_materials.push(0);
    }
    Scene::from_parts(parts).expect("soup is a valid scene")
}

/// Robust (watertight) traversal, the one whose edge handling Möller–Trumbore is compared with.
fn embree_for(scene: &Scene) -> EmbreeScene {
    let robust = BuildOptions { robust: true, ..BuildOptions::default() };
    Device::new().and_then(|d| d.build_scene(scene.positions(), scene.triangles(), &robust)).expect("Embree builds the scene")
}

/// Tallies how two intersectors disagree. Exact agreement is not expected everywhere:
/// Embree's watertight test and Möller–Trumbore round differently, so a ray grazing an
/// edge (within float precision) may hit in one and miss in the other, and two triangles
/// at the same distance (the soup's triangles cross each other) may be ordered differently.
#[derive(Default, Debug)]
struct Agreement {
    rays: usize,
    hits: usize,
    /// Hit in one, miss in the other, with the hit point within `edge_tol` of an edge.
    edge_grazes: usize,
    /// Different triangles, same distance within tolerance.
    ties: usize,
}

fn barycentric_edge_distance(h: &Hit) -> f32 {
    h.u.min(h.v).min(1.0 - h.u - h.v).abs()
}

fn compare(scene: &Scene, embree: &EmbreeScene, brute: &BruteForce, rays: &[Ray]) -> Agreement {
    let mut a = Agreement { rays: rays.len(), ..Default::default() };
    for (k, r) in rays.iter().enumerate() {
        let (e, b) = (embree.intersect(r), brute.intersect(r));
        match (e, b) {
            (Some(e), Some(b)) => {
                a.hits += 1;
                let tol = 2e-5 * e.t.abs().max(1.0);
                assert!(
                    (e.t - b.t).abs() <= tol,
                    "ray {k}: Embree t = {} (prim {}), brute force t = {} (prim {})",
                    e.t,
                    e.prim,
                    b.t,
                    b.prim
                );
                if e.prim == b.prim {
                    assert!((e.u - b.u).abs() < 1e-4 && (e.v - b.v).abs() < 1e-4, "ray {k}: (u, v) {e:?} vs {b:?}");
                    let p = r.origin + r.dir * e.t;
                    let q = scene.surface(e.prim, e.u, e.v).p;
                    assert!((p - q).length() < 1e-4 * (1.0 + p.length()), "ray {k}: barycentrics give {q}, the ray gives {p}");
                } else {
                    a.ties += 1;
                }
            }
            (Some(h), None) | (None, Some(h)) => {
                assert!(barycentric_edge_distance(&h) < 1e-5, "ray {k}: only one intersector hits, and not at an edge: {h:?}");
                a.edge_grazes += 1;
            }
            (None, None) => {}
        }
        // Occlusion over a random sub-interval must match the nearest-hit answer unless the
        // nearest hit sits right at the interval end.
        if let Some(b) = b {
            let tmax = b.t * 0.5;
            assert!(!embree.occluded(&Ray { tmax, ..*r }), "ray {k}: occluded before the nearest hit");
            assert!(!brute.occluded(&Ray { tmax, ..*r }));
            assert!(embree.occluded(&Ray { tmax: b.t * 1.01 + 1e-4, ..*r }) || e.is_none(), "ray {k}: not occluded past the nearest hit");
        } else if e.is_none() {
            assert!(!embree.occluded(r), "ray {k}: occluded but no hit");
        }
    }
    a
}

#[test]
fn random_soup_matches_brute_force_ray_by_ray() {
    let mut rng = Rng(0x5eed_cafe);
    let scene = soup(&mut rng, 400);
    let embree = embree_for(&scene);
    let brute = BruteForce::new(&scene);
    let rays: Vec<Ray> = (0..20_000)
        .map(|_| {
            let origin = rng.in_cube(1.5);
            let target = rng.in_cube(1.0);
            Ray { origin, dir: target - origin, tmin: 0.0, tmax: f32::INFINITY }
        })
        .collect();
    let a = compare(&scene, &embree, &brute, &rays);
    eprintln!("{a:?}");
    // A meaningful test needs plenty of hits, and disagreements must stay rare.
    assert!(a.hits > a.rays / 4, "{a:?}");
    assert!(a.edge_grazes + a.ties <= a.rays / 2000, "{a:?}");
}

#[test]
fn cornell_box_camera_rays_match_brute_force() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = Scene::load(&path).expect("the shipped Cornell box loads");
    let embree = embree_for(&scene);
    assert_eq!(embree.triangle_count(), scene.triangles().len());
    let brute = BruteForce::new(&scene);
    let frame = scene.camera().frame(48, 48);
    let mut rng = Rng(7);
    let rays: Vec<Ray> = (0..48 * 48 * 2)
        .map(|k| {
            let (x, y) = ((k / 2) % 48, (k / 2) / 48);
            frame.ray(x, y, glam::Vec2::new(rng.f32(), rng.f32()))
        })
        .collect();
    let a = compare(&scene, &embree, &brute, &rays);
    // The box is closed towards the camera's view except through the front: every camera ray
    // inside the frame hits something.
    assert!(a.hits >= a.rays * 9 / 10, "{a:?}");
    assert!(a.edge_grazes + a.ties <= 2, "{a:?}");
}

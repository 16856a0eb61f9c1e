//! Embree wrapper basics: exact hits on a single triangle, misses, ray-interval limits,
//! occlusion, and sharing one committed scene between threads.
use cvtrace_embree::{BuildOptions, BuildQuality, Device, EmbreeScene};
use cvtrace_render::{Hit, Intersector, Ray};
use glam::Vec3A;

/// The triangle (0,0,0), (1,0,0), (0,1,0) in the z = 0 plane: the barycentrics of
/// vertices 1 and 2 of a point (x, y, 0) are exactly (u, v) = (x, y).
fn unit_triangle() -> EmbreeScene {
    EmbreeScene::build(&[Vec3A::ZERO, Vec3A::X, Vec3A::Y], &[[0, 1, 2]]).expect("valid triangle")
}

fn ray(origin: Vec3A, dir: Vec3A) -> Ray {
    Ray { origin, dir, tmin: 0.0, tmax: f32::INFINITY }
}

/// `a` within a few float ulps of `b` (Embree computes (u, v) as ratios).
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 4.0 * f32::EPSILON * b.abs().max(1.0)
}

#[test]
fn single_triangle_hit_has_exact_distance_and_barycentrics() {
    let s = unit_triangle();
    assert_eq!(s.triangle_count(), 1);
    for (x, y, z) in [(0.25f32, 0.5f32, 1.0f32), (0.1, 0.1, 3.0), (0.6, 0.3, 0.5)] {
        let h = s.intersect(&ray(Vec3A::new(x, y, z), Vec3A::NEG_Z)).unwrap_or_else(|| panic!("ray at ({x}, {y}) must hit"));
        assert!(close(h.t, z), "t = {} for a ray starting {z} above the plane", h.t);
        assert!(close(h.u, x) && close(h.v, y), "(u, v) = ({}, {}) at ({x}, {y})", h.u, h.v);
        assert_eq!(h.prim, 0);
    }
    // From below: Embree does not cull back faces.
    let h = s.intersect(&ray(Vec3A::new(0.2, 0.3, -2.0), Vec3A::Z)).expect("back face hit");
    assert!(close(h.t, 2.0) && close(h.u, 0.2) && close(h.v, 0.3), "{h:?}");
    // Direction need not be normalised: t is in units of `dir`.
    let h = s.intersect(&ray(Vec3A::new(0.2, 0.3, 1.0), Vec3A::new(0.0, 0.0, -4.0))).expect("hit");
    assert!(close(h.t, 0.25), "t = {}", h.t);
    // An oblique ray.
    let o = Vec3A::new(1.0, 1.0, 2.0);
    let target = Vec3A::new(0.2, 0.4, 0.0);
    let h = s.intersect(&ray(o, target - o)).expect("oblique hit");
    assert!((h.t - 1.0).abs() < 1e-6 && (h.u - 0.2).abs() < 1e-6 && (h.v - 0.4).abs() < 1e-6, "{h:?}");
}

#[test]
fn misses_outside_the_triangle_behind_the_ray_and_outside_the_interval() {
    let s = unit_triangle();
    // Beyond the hypotenuse u + v = 1.
    assert!(s.intersect(&ray(Vec3A::new(0.6, 0.6, 1.0), Vec3A::NEG_Z)).is_none());
    // Outside the legs.
    assert!(s.intersect(&ray(Vec3A::new(-0.1, 0.5, 1.0), Vec3A::NEG_Z)).is_none());
    // Pointing away.
    assert!(s.intersect(&ray(Vec3A::new(0.2, 0.2, 1.0), Vec3A::Z)).is_none());
    // Parallel to the plane, above it.
    assert!(s.intersect(&ray(Vec3A::new(-1.0, 0.2, 0.5), Vec3A::X)).is_none());
    // The hit at t = 1 lies outside [tmin, tmax] in both of these.
    let r = ray(Vec3A::new(0.2, 0.2, 1.0), Vec3A::NEG_Z);
    assert!(s.intersect(&Ray { tmax: 0.999, ..r }).is_none());
    assert!(s.intersect(&Ray { tmin: 1.001, ..r }).is_none());
    assert!(s.intersect(&Ray { tmax: 1.001, ..r }).is_some());
}

#[test]
fn nearest_of_two_triangles_is_reported_with_its_index() {
    // Two parallel triangles at z = 0 (index 0) and z = -1 (index 1).
    let p = [Vec3A::ZERO, Vec3A::X, Vec3A::Y, Vec3A::new(0.0, 0.0, -1.0), Vec3A::new(1.0, 0.0, -1.0), Vec3A::new(0.0, 1.0, -1.0)];
    let s = EmbreeScene::build(&p, &[[3, 4, 5], [0, 1, 2]]).unwrap();
    let h = s.intersect(&ray(Vec3A::new(0.2, 0.2, 1.0), Vec3A::NEG_Z)).unwrap();
    assert_eq!(h.prim, 1, "the z = 0 triangle is listed second");
    assert!(close(h.t, 1.0));
    let h = s.intersect(&ray(Vec3A::new(0.2, 0.2, -3.0), Vec3A::Z)).unwrap();
    assert_eq!(h.prim, 0);
    assert!(close(h.t, 2.0));
}

#[test]
fn occlusion_respects_the_ray_interval() {
    let s = unit_triangle();
    let r = ray(Vec3A::new(0.2, 0.2, 1.0), Vec3A::NEG_Z);
    assert!(s.occluded(&Ray { tmax: 2.0, ..r }));
    assert!(s.occluded(&Ray { tmax: f32::INFINITY, ..r }));
    assert!(!s.occluded(&Ray { tmax: 0.99, ..r }), "blocker beyond tmax");
    assert!(!s.occluded(&Ray { tmin: 1.01, tmax: 5.0, ..r }), "blocker before tmin");
    assert!(!s.occluded(&ray(Vec3A::new(0.8, 0.8, 1.0), Vec3A::NEG_Z)), "passes beside the triangle");
}

#[test]
fn every_build_option_gives_the_same_answers() {
    let s0 = unit_triangle();
    let device = Device::new().unwrap();
    let r = ray(Vec3A::new(0.3, 0.1, 2.0), Vec3A::NEG_Z);
    let expected = s0.intersect(&r).unwrap();
    for quality in [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High] {
        for robust in [false, true] {
            for compact in [false, true] {
                for quads in [false, true] {
                    let options = BuildOptions { quality, robust, compact, quads, packets: true };
                    let s = device.build_scene(&[Vec3A::ZERO, Vec3A::X, Vec3A::Y], &[[0, 1, 2]], &options).unwrap();
                    assert_eq!(s.intersect(&r), Some(expected), "{options:?}");
                }
            }
        }
    }
}

#[test]
fn one_scene_serves_many_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<EmbreeScene>();

    // A 32x32 grid of triangles; each thread casts the same rays and must get the same hits.
    let n = 32;
    let mut p = Vec::new();
    let mut t = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let base = p.len() as u32;
            let (x, y) = (i as f32, j as f32);
            p.extend([Vec3A::new(x, y, 0.0), Vec3A::new(x + 1.0, y, 0.0), Vec3A::new(x, y + 1.0, 0.0)]);
            t.push([base, base + 1, base + 2]);
        }
    }
    let s = EmbreeScene::build(&p, &t).unwrap();
    let rays: Vec<Ray> = (0..4096)
        .map(|k| {
            let (i, j) = (k % n, (k / n) % n);
            ray(Vec3A::new(i as f32 + 0.25, j as f32 + 0.25 + (k / (n * n)) as f32 * 0.1, 5.0), Vec3A::NEG_Z)
        })
        .collect();
    let reference: Vec<_> = rays.iter().map(|r| s.intersect(r)).collect();
    for (k, h) in reference.iter().enumerate() {
        let h = h.unwrap_or_else(|| panic!("ray {k} must hit"));
        assert_eq!(h.prim as usize, (k / n % n) * n + k % n);
    }
    std::thread::scope(|scope| {
        let handles: Vec<_> =
            (0..4).map(|_| scope.spawn(|| rays.iter().map(|r| (s.intersect(r), s.occluded(r))).collect::<Vec<_>>())).collect();
        for h in handles {
            for (k, (hit, occ)) in h.join().unwrap().into_iter().enumerate() {
                assert_eq!(hit, reference[k], "ray {k}");
                assert!(occ);
            }
        }
    });
    // The scene can also move to another thread and be dropped there.
    std::thread::spawn(move || drop(s)).join().unwrap();
}

/// Rays from inside a closed box aimed exactly at its shared edges (face diagonals and box
/// edges): the case where a non-watertight triangle test lets rays slip between two triangles.
/// Returns how many of `n` such rays miss the box.
fn leaks_through_shared_edges(robust: bool, quads: bool, n: usize) -> usize {
    let (lo, hi) = (Vec3A::new(-0.7, -0.9, -0.3), Vec3A::new(1.3, 1.1, 1.7));
    let corner = |i: usize| Vec3A::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1]);
    let positions: Vec<Vec3A> = (0..8).map(corner).collect();
    let faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let triangles: Vec<[u32; 3]> = faces.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    let device = Device::new().unwrap();
    let scene = device.build_scene(&positions, &triangles, &BuildOptions { robust, quads, ..BuildOptions::default() }).unwrap();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut misses = 0;
    for _ in 0..n {
        let origin = lo + (hi - lo) * Vec3A::new(0.2 + 0.6 * next(), 0.2 + 0.6 * next(), 0.2 + 0.6 * next());
        let [a, b, c, _] = faces[(next() * 6.0) as usize % 6];
        let t = next();
        // Half the targets on the diagonal a–c shared by the face's two triangles, half on its
        // edge a–b shared with the neighbouring face.
        let target =
            if next() < 0.5 { corner(a as usize).lerp(corner(c as usize), t) } else { corner(a as usize).lerp(corner(b as usize), t) };
        if scene.intersect(&ray(origin, target - origin)).is_none() {
            misses += 1;
        }
    }
    misses
}

#[test]
fn robust_traversal_is_watertight_at_shared_edges() {
    let n = 200_000;
    for quads in [true, false] {
        let fast = leaks_through_shared_edges(false, quads, n);
        let robust = leaks_through_shared_edges(true, quads, n);
        eprintln!("rays aimed at shared edges of a closed box that miss it (quads {quads}): robust {robust}, fast {fast} of {n}");
        assert_eq!(robust, 0, "robust traversal (quads {quads}) let {robust} of {n} rays through shared edges (fast: {fast})");
        // The rays do hit shared edges exactly: fast traversal leaks there (docs/performance.md:
        // 966 as triangles, 1179 as quads), so a robust count of 0 means something.
        assert!(
            fast > n / 1000,
            "fast traversal (quads {quads}) let only {fast} of {n} rays through: the rays no longer aim at shared edges"
        );
    }
}

/// A bumpy height field written as split quads (consecutive triangle pairs, both diagonals),
/// followed by loose triangles in no particular order: what meshes from exporters look like.
fn bumpy_mesh() -> (Vec<Vec3A>, Vec<[u32; 3]>) {
    let n = 24u32;
    let height = |i: u32, j: u32| ((i as f32 * 0.7).sin() * (j as f32 * 0.45).cos()) * 0.8;
    let mut positions: Vec<Vec3A> = (0..=n).flat_map(|j| (0..=n).map(move |i| Vec3A::new(i as f32, height(i, j), j as f32))).collect();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[b, c, d], [d, a, b]]);
            }
        }
    }
    // Loose triangles floating above the field.
    let mut state = 5u64;
    for k in 0..200u32 {
        let base = positions.len() as u32;
        let centre = Vec3A::new((k % 20) as f32 * 1.2 + 0.3, 2.0 + (k / 20) as f32 * 0.3, (k * 7 % 23) as f32);
        for _ in 0..3 {
            positions.push(centre + Vec3A::new(splitmix(&mut state), splitmix(&mut state), splitmix(&mut state)) * 0.9);
        }
        triangles.push([base, base + 1, base + 2]);
    }
    (positions, triangles)
}

fn splitmix(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// Casts `rays` at `triangles` given to Embree as triangles and as quads, for both traversals,
/// and asserts the same answers: hit or miss, distance, point (from the triangle's
/// barycentrics), triangle (but for rare ties across an edge), and occlusion before and after
/// the hit. Returns the number of hits.
fn assert_quads_match_triangles(what: &str, positions: &[Vec3A], triangles: &[[u32; 3]], rays: &[Ray]) -> usize {
    let device = Device::new().unwrap();
    let point = |h: &Hit| {
        let t = triangles[h.prim as usize].map(|i| positions[i as usize]);
        t[0] * (1.0 - h.u - h.v) + t[1] * h.u + t[2] * h.v
    };
    let mut hits = 0;
    for robust in [true, false] {
        let tris = device.build_scene(positions, triangles, &BuildOptions { robust, quads: false, ..BuildOptions::default() }).unwrap();
        let quads = device.build_scene(positions, triangles, &BuildOptions { robust, quads: true, ..BuildOptions::default() }).unwrap();
        let (mut n_hits, mut other_prim) = (0, 0);
        for r in rays {
            let (a, b) = (tris.intersect(r), quads.intersect(r));
            assert_eq!(a.is_some(), b.is_some(), "{what}, robust {robust}: {r:?} hits {a:?} as triangles but {b:?} as quads");
            let (Some(a), Some(b)) = (a, b) else { continue };
            n_hits += 1;
            let scale = a.t.max(1.0) * r.dir.length().max(1.0) * (1.0 + point(&a).length());
            assert!((a.t - b.t).abs() <= 1e-5 * scale, "{what}, robust {robust}: distance {} vs {}", a.t, b.t);
            assert!(point(&a).distance(point(&b)) < 1e-5 * scale, "{what}, robust {robust}: point {} vs {}", point(&a), point(&b));
            assert!(b.u >= -1e-6 && b.v >= -1e-6 && b.u + b.v <= 1.0 + 1e-5, "{what}: barycentrics ({}, {}) off the triangle", b.u, b.v);
            // On a shared edge, or where two triangles overlap in one plane (the Cornell box's
            // floor holds the blocks' footprints), either is right; the point above is checked.
            if a.prim != b.prim {
                other_prim += 1;
            }
            for tmax in [a.t * 0.5, a.t * 1.01] {
                let segment = Ray { tmax, ..*r };
                assert_eq!(tris.occluded(&segment), quads.occluded(&segment), "{what}, robust {robust}: occlusion of {segment:?}");
            }
        }
        eprintln!("{what}, robust {robust}: {n_hits} of {} rays hit; {other_prim} named another triangle at the same point", rays.len());
        assert!(other_prim * 200 <= n_hits, "{what}: {other_prim} of {n_hits} hits name a different triangle");
        hits = n_hits;
    }
    hits
}

/// Handing Embree triangle pairs as quads must not change what a ray hits, from either side
/// of the surfaces.
#[test]
fn quads_give_the_same_hits_as_triangles() {
    let (positions, triangles) = bumpy_mesh();
    let mut state = 99u64;
    let mut next = || splitmix(&mut state);
    // From above and from below the field (front and back faces).
    let rays: Vec<Ray> = (0..100_000)
        .map(|k| {
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let origin = Vec3A::new(next() * 24.0, 6.0 * side, next() * 24.0);
            let target = Vec3A::new(next() * 24.0, -1.5 * side, next() * 24.0);
            ray(origin, target - origin)
        })
        .collect();
    let hits = assert_quads_match_triangles("bumpy field", &positions, &triangles, &rays);
    assert!(hits > rays.len() / 2, "the rays should mostly hit the field");
}

/// `count` rays from points inside the box `lo`..`hi` (2% in from its faces), in directions
/// uniform over the sphere, drawn from `next`.
fn rays_inside(lo: Vec3A, hi: Vec3A, count: usize, next: &mut impl FnMut() -> f32) -> Vec<Ray> {
    (0..count)
        .map(|_| {
            let origin = lo + (hi - lo) * Vec3A::new(0.02 + 0.96 * next(), 0.02 + 0.96 * next(), 0.02 + 0.96 * next());
            let z = 2.0 * next() - 1.0;
            let phi = std::f32::consts::TAU * next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            ray(origin, Vec3A::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}

/// The same on the shipped Cornell box with rays like a path tracer's: from points inside the
/// room in every direction, so they hit walls and boxes from all sides.
#[test]
fn quads_give_the_same_hits_as_triangles_in_the_cornell_box() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = cvtrace_render::Scene::load(&path).expect("the shipped Cornell box loads");
    let (lo, hi) = scene.bounds();
    let mut state = 7u64;
    let mut next = || splitmix(&mut state);
    let rays = rays_inside(lo, hi, 100_000, &mut next);
    let hits = assert_quads_match_triangles("Cornell box", scene.positions(), scene.triangles(), &rays);
    assert!(hits > rays.len() / 2, "rays from inside the room should mostly hit it");
}

/// Batches traced in Embree's coherent mode must hit what single rays hit, up to the last bit
/// of the distance: camera rays of the Cornell box, 16 jittered samples per pixel as the renderer
/// batches them, in batches that also straddle pixels and rows, plus incoherent rays from inside
/// the room.
#[test]
fn coherent_batches_give_the_same_hits_as_single_rays() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = cvtrace_render::Scene::load(&path).expect("the shipped Cornell box loads");
    let (w, h) = (48u32, 40u32);
    let frame = scene.camera().frame(w, h);
    let mut state = 11u64;
    let mut next = || splitmix(&mut state);
    let mut rays: Vec<Ray> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for _ in 0..16 {
                rays.push(frame.ray(x, y, glam::Vec2::new(next(), next())));
            }
        }
    }
    let (lo, hi) = scene.bounds();
    for _ in 0..5_000 {
        let origin = lo + (hi - lo) * Vec3A::new(next(), next(), next());
        rays.push(ray(origin, Vec3A::new(next() - 0.5, next() - 0.5, next() - 0.5)));
    }
    let device = Device::new().unwrap();
    for robust in [true, false] {
        for quads in [true, false] {
            let tracer = device
                .build_scene(scene.positions(), scene.triangles(), &BuildOptions { robust, quads, ..BuildOptions::default() })
                .unwrap();
            let single: Vec<Option<Hit>> = rays.iter().map(|r| tracer.intersect(r)).collect();
            for batch in [16usize, 40, 64, 100] {
                let mut coherent = vec![None; rays.len()];
                for (r, c) in rays.chunks(batch).zip(coherent.chunks_mut(batch)) {
                    tracer.intersect_coherent(r, c);
                }
                let hits = single.iter().filter(|h| h.is_some()).count();
                assert!(hits > rays.len() * 3 / 4, "most rays should hit the room ({hits} of {})", rays.len());
                let (mut ties, mut inexact) = (0, 0);
                for (i, (a, b)) in single.iter().zip(&coherent).enumerate() {
                    let what = || format!("robust {robust}, quads {quads}, batches of {batch}: ray {i} {:?}", rays[i]);
                    let (Some(a), Some(b)) = (a, b) else {
                        assert_eq!(a, b, "{}", what());
                        continue;
                    };
                    // Embree's stream code may round the distance differently in the last bit.
                    assert!((a.t - b.t).abs() <= 1e-6 * a.t, "{}: {a:?} vs {b:?}", what());
                    if a.prim == b.prim {
                        assert!((a.u - b.u).abs() <= 1e-5 && (a.v - b.v).abs() <= 1e-5, "{}: {a:?} vs {b:?}", what());
                    } else {
                        // Where two triangles overlap in one plane (the blocks' footprints lie
                        // on the floor) either is right, at the same point.
                        let p = |h: &Hit| {
                            let t = scene.triangles()[h.prim as usize].map(|k| scene.positions()[k as usize]);
                            t[0] * (1.0 - h.u - h.v) + t[1] * h.u + t[2] * h.v
                        };
                        assert!(p(a).distance(p(b)) < 1e-3, "{}: {a:?} vs {b:?}", what());
                        ties += 1;
                    }
                    inexact += (a != b) as usize;
                }
                if batch == 16 {
                    eprintln!(
                        "robust {robust}, quads {quads}: {inexact} of {hits} hits differ in the last bits or name a coplanar twin ({ties})"
                    );
                }
                assert!(
                    ties * 200 <= hits,
                    "robust {robust}, quads {quads}, batches of {batch}: {ties} of {hits} hits name a different triangle"
                );
            }
        }
    }
}

/// Packets (Embree's `rtcIntersect16`/`rtcOccluded16` on CPUs with AVX-512, two 8-wide calls
/// elsewhere) give the answers of single rays bit for bit, whatever the traversal and the
/// geometry (with fast traversal on quads, where Embree's packet kernel would round the
/// barycentrics differently, the nearest hits go one by one): rays from inside the Cornell box
/// in every direction, their segments up to before and past the hit for occlusion, in packets
/// with lanes left out at random.
#[test]
fn packets_give_the_hits_of_single_rays_bit_for_bit() {
    use cvtrace_render::{RayPacket, PACKET};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = cvtrace_render::Scene::load(&path).expect("the shipped Cornell box loads");
    let (lo, hi) = scene.bounds();
    let mut state = 23u64;
    let mut next = || splitmix(&mut state);
    let rays = rays_inside(lo, hi, PACKET * 2000, &mut next);
    let masks: Vec<u16> = (0..rays.len() / PACKET).map(|k| if k % 3 == 0 { u16::MAX } else { (next() * 65536.0) as u16 }).collect();
    let packet = |rays: &[Ray]| {
        let mut p = RayPacket { origin: [[0.0; PACKET]; 3], dir: [[0.0; PACKET]; 3], tmin: [0.0; PACKET], tmax: [0.0; PACKET] };
        for (l, r) in rays.iter().enumerate() {
            for a in 0..3 {
                (p.origin[a][l], p.dir[a][l]) = (r.origin[a], r.dir[a]);
            }
            (p.tmin[l], p.tmax[l]) = (r.tmin, r.tmax);
        }
        p
    };
    let device = Device::new().unwrap();
    for robust in [true, false] {
        for quads in [true, false] {
            let tracer = device
                .build_scene(scene.positions(), scene.triangles(), &BuildOptions { robust, quads, ..BuildOptions::default() })
                .unwrap();
            let mut occluded = 0;
            for (rays, &active) in rays.chunks(PACKET).zip(&masks) {
                let hits = tracer.intersect_packet(&packet(rays), active);
                let mut segments = [*rays.first().unwrap(); PACKET];
                for (l, r) in rays.iter().enumerate() {
                    let want = if active >> l & 1 != 0 { tracer.intersect(r) } else { None };
                    let got = hits.get(l);
                    let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()));
                    assert_eq!(bits(got), bits(want), "robust {robust}, quads {quads}: lane {l} of {r:?}");
                    let t = want.map_or(1e3, |h| h.t);
                    segments[l] = Ray { tmax: if l % 2 == 0 { t * 0.999 } else { t * 1.001 }, ..*r };
                }
                let got = tracer.occluded_packet(&packet(&segments), active);
                for (l, s) in segments.iter().enumerate() {
                    let want = active >> l & 1 != 0 && tracer.occluded(s);
                    assert_eq!(got >> l & 1 != 0, want, "robust {robust}, quads {quads}: occlusion of lane {l}, {s:?}");
                    occluded += usize::from(want);
                }
            }
            assert!(occluded > rays.len() / 8, "segments past their hit should often be occluded ({occluded})");
        }
    }
}

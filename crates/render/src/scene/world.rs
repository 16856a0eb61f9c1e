//! The render-ready scene: world-space triangles in flat arrays (positions, index triples,
//! per-vertex normals/UVs, per-triangle material id, normal and area), materials, textures,
//! the light distribution over every emitter (emissive triangles, punctual lights, the
//! environment), the camera and the render defaults of the scene's sidecar file.
//! `Hit.prim` indexes [`Scene::triangles`].
use crate::intersect::MAX_COORDINATE;
use crate::scene::camera::{default_camera, Camera};
use crate::scene::error::SceneError;
use crate::scene::fingerprint::Canonical;
use crate::scene::lights::{triangle_power, Environment, LightSet, Punctual};
use crate::scene::material::Material;
use crate::scene::texture::Texture;
use crate::settings::RenderDefaults;
use cvtrace_streams::exact::MAX_SAMPLE;
use glam::{Vec2, Vec3A};
use std::path::Path;

/// Everything needed to build a [`Scene`] in memory (tests, procedural scenes, other loaders).
#[derive(Clone, Debug, Default)]
pub struct SceneParts {
    pub positions: Vec<Vec3A>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex shading normals, or empty to use geometric normals. A zero normal means "none".
    pub normals: Vec<Vec3A>,
    /// Per-vertex `TEXCOORD_0`, or empty.
    pub uvs: Vec<Vec2>,
    /// Material id of each triangle.
    pub triangle_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    /// `None`: a default camera looking at the scene bounds.
    pub camera: Option<Camera>,
    /// Point, spot and directional lights (world space).
    pub lights: Vec<Punctual>,
    /// Light from infinitely far away, seen by rays that escape.
    pub environment: Option<Environment>,
    /// Defaults for the render (from the sidecar file), all optional.
    pub render_defaults: RenderDefaults,
}

/// A surface point reconstructed from a hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub p: Vec3A,
    /// Unit geometric normal from the winding (front face side).
    pub ng: Vec3A,
    /// Unit shading normal, on the same side as `ng`.
    pub ns: Vec3A,
    pub uv: Vec2,
    pub material: u32,
}

/// A scene ready to render.
#[derive(Clone, Debug)]
pub struct Scene {
    positions: Vec<Vec3A>,
    triangles: Vec<[u32; 3]>,
    normals: Vec<Vec3A>,
    uvs: Vec<Vec2>,
    tri_material: Vec<u32>,
    tri_normal: Vec<Vec3A>,
    tri_area: Vec<f32>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    lights: LightSet,
    camera: Camera,
    /// The camera is [`default_camera`]'s: the scene came without one.
    automatic_camera: bool,
    bounds: (Vec3A, Vec3A),
    ray_epsilon: f32,
    render_defaults: RenderDefaults,
}

const MEMORY: &str = "<memory>";

impl Scene {
    /// Builds a scene from flat arrays, checking every index.
    pub fn from_parts(parts: SceneParts) -> Result<Scene, SceneError> {
        Scene::from_parts_named(parts, Path::new(MEMORY))
    }

    /// As [`Scene::from_parts`], naming `origin` in errors.
    pub fn from_parts_named(parts: SceneParts, origin: &Path) -> Result<Scene, SceneError> {
        let SceneParts {
            positions,
            triangles,
            normals,
            uvs,
            triangle_materials,
            materials,
            textures,
            camera,
            lights: punctual,
            environment,
            render_defaults,
        } = parts;
        let bad = |m: String| Err(SceneError::invalid(origin, m));
        if triangles.is_empty() {
            return bad("the scene has no triangles".into());
        }
        if positions.len() > u32::MAX as usize || triangles.len() > u32::MAX as usize {
            return bad("the scene has more than 2^32 vertices or triangles".into());
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return bad(format!("vertex {i} has a non-finite position"));
        }
        if let Some(i) = positions.iter().position(|p| p.abs().max_element() > MAX_COORDINATE) {
            return bad(format!("vertex {i} at {} is farther than {MAX_COORDINATE:e} from the origin", positions[i]));
        }
        if let Some(i) = normals.iter().position(|n| !n.is_finite()) {
            return bad(format!("vertex {i} has a non-finite normal"));
        }
        if !normals.is_empty() && normals.len() != positions.len() {
            return bad(format!("{} normals for {} vertices", normals.len(), positions.len()));
        }
        if !uvs.is_empty() && uvs.len() != positions.len() {
            return bad(format!("{} texture coordinates for {} vertices", uvs.len(), positions.len()));
        }
        if triangle_materials.len() != triangles.len() {
            return bad(format!("{} material ids for {} triangles", triangle_materials.len(), triangles.len()));
        }
        let nv = positions.len() as u32;
        if let Some((i, t)) = triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&k| k >= nv)) {
            return bad(format!("triangle {i} {t:?} indexes past the {nv} vertices"));
        }
        if let Some((i, m)) = triangle_materials.iter().enumerate().find(|(_, &m)| m as usize >= materials.len()) {
            return bad(format!("triangle {i} uses material {m} but there are {}", materials.len()));
        }
        for m in &materials {
            for t in [m.base_color_texture, m.metallic_roughness_texture, m.emissive_texture].into_iter().flatten() {
                if t as usize >= textures.len() {
                    return bad(format!("material `{}` uses texture {t} but there are {}", m.name, textures.len()));
                }
            }
            if !(m.base_color.is_finite()
                && m.emission.is_finite()
                && m.metallic.is_finite()
                && m.roughness.is_finite()
                && m.ior.is_finite())
            {
                return bad(format!("material `{}` has a non-finite parameter", m.name));
            }
        }
        // A camera ray that hits an emitter records its radiance as the sample: beyond the
        // largest sample the exact sums hold it would be clamped, and every image of the scene
        // wrong (the stream file's means would not even agree with its batches).
        let mut used = vec![false; materials.len()];
        triangle_materials.iter().for_each(|&m| used[m as usize] = true);
        if let Some((i, m)) = materials.iter().enumerate().find(|(i, m)| used[*i] && m.emission.max_element() as f64 > MAX_SAMPLE) {
            return bad(format!(
                "material {i} ({:?}) emits radiance {:e} (emissiveFactor × emissiveStrength), beyond 1.4e14 (2^47), the \
                 largest sample a render's exact sums hold; scale the scene's emission down (relative errors stay the same)",
                m.name,
                m.emission.max_element()
            ));
        }

        let mut tri_normal = Vec::with_capacity(triangles.len());
        let mut tri_area = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let [p0, p1, p2] = t.map(|i| positions[i as usize]);
            let c = (p1 - p0).cross(p2 - p0);
            let len = c.length();
            tri_area.push(0.5 * len);
            tri_normal.push(if len > 0.0 { c / len } else { Vec3A::Z });
        }
        for (i, l) in punctual.iter().enumerate() {
            l.validate().map_err(|m| SceneError::invalid(origin, format!("punctual light {i}: {m}")))?;
        }
        render_defaults.validate().map_err(|m| SceneError::invalid(origin, format!("render defaults: {m}")))?;
        let (lo, hi) =
            positions.iter().fold((Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let mean_emission: Vec<Vec3A> = materials.iter().map(|m| m.mean_emission(&textures)).collect();
        let power: Vec<f64> =
            triangle_materials.iter().zip(&tri_area).map(|(&m, &a)| triangle_power(mean_emission[m as usize], a)).collect();
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let lights = LightSet::new(&power, &tri_area, punctual, environment, radius);

        let scale = lo.abs().max(hi.abs()).max_element().max((hi - lo).max_element()).max(1e-3);
        let automatic_camera = camera.is_none();
        let camera = match camera {
            Some(c) => c,
            None => default_camera(lo, hi),
        };
        camera.validate().map_err(|m| SceneError::invalid(origin, m))?;
        Ok(Scene {
            positions,
            triangles,
            normals,
            uvs,
            tri_material: triangle_materials,
            tri_normal,
            tri_area,
            materials,
            textures,
            lights,
            camera,
            automatic_camera,
            bounds: (lo, hi),
            ray_epsilon: 1e-5 * scale,
            render_defaults,
        })
    }

    /// All vertices, world space.
    pub fn positions(&self) -> &[Vec3A] {
        &self.positions
    }

    /// Index triples into [`Scene::positions`]; `Hit.prim` indexes this list.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn set_camera(&mut self, c: Camera) {
        self.camera = c;
        self.automatic_camera = false;
    }

    /// Whether the camera is the automatic one of a scene without its own ([`default_camera`]:
    /// it frames the scene's bounds from +Z), not one the scene or a caller gave.
    pub fn has_automatic_camera(&self) -> bool {
        self.automatic_camera
    }

    /// Marks the camera as the automatic one (a loader that filled it in itself).
    pub(crate) fn mark_automatic_camera(&mut self) {
        self.automatic_camera = true;
    }

    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    pub fn textures(&self) -> &[Texture] {
        &self.textures
    }

    /// Material id of each triangle.
    pub fn triangle_materials(&self) -> &[u32] {
        &self.tri_material
    }

    /// Every emitter and the selection distribution over them.
    pub fn lights(&self) -> &LightSet {
        &self.lights
    }

    /// Render settings the scene asks for (sidecar `[render]`, and the glTF's
    /// `asset.extras.defaultResolution` when the sidecar gives no size); command-line flags
    /// override them.
    pub fn render_defaults(&self) -> &RenderDefaults {
        &self.render_defaults
    }

    pub fn set_render_defaults(&mut self, d: RenderDefaults) {
        self.render_defaults = d;
    }

    /// Axis-aligned bounds `(min, max)` of all vertices.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        self.bounds
    }

    /// Distance by which secondary rays start off a surface, relative to the scene's size.
    pub fn ray_epsilon(&self) -> f32 {
        self.ray_epsilon
    }

    /// The vertex normals (empty if the scene has none).
    #[inline]
    pub(crate) fn vertex_normals(&self) -> &[Vec3A] {
        &self.normals
    }

    /// Whether the scene has vertex normals.
    #[inline]
    pub(crate) fn has_normals(&self) -> bool {
        !self.normals.is_empty()
    }

    #[inline]
    pub fn triangle_vertices(&self, prim: u32) -> [Vec3A; 3] {
        self.triangles[prim as usize].map(|i| self.positions[i as usize])
    }

    #[inline]
    pub fn triangle_area(&self, prim: u32) -> f32 {
        self.tri_area[prim as usize]
    }

    #[inline]
    pub fn geometric_normal(&self, prim: u32) -> Vec3A {
        self.tri_normal[prim as usize]
    }

    #[inline]
    pub fn material_of(&self, prim: u32) -> &Material {
        &self.materials[self.tri_material[prim as usize] as usize]
    }

    /// The surface at barycentrics `(u, v)` of triangle `prim` (Embree's convention).
    #[inline]
    pub fn surface(&self, prim: u32, u: f32, v: f32) -> SurfacePoint {
        let [i0, i1, i2] = self.triangles[prim as usize].map(|i| i as usize);
        let w = 1.0 - u - v;
        let p = self.positions[i0] * w + self.positions[i1] * u + self.positions[i2] * v;
        let ng = self.tri_normal[prim as usize];
        let mut ns = ng;
        if !self.normals.is_empty() {
            let n = self.normals[i0] * w + self.normals[i1] * u + self.normals[i2] * v;
            let len2 = n.length_squared();
            if len2 > 1e-12 && len2.is_finite() {
                ns = n / len2.sqrt();
                if ns.dot(ng) < 0.0 {
                    ns = -ns;
                }
            }
        }
        SurfacePoint { p, ng, ns, uv: self.uv(prim, u, v), material: self.tri_material[prim as usize] }
    }

    /// The texture coordinate at barycentrics `(u, v)` of triangle `prim` (zero without UVs),
    /// as [`Scene::surface`] gives it.
    #[inline]
    pub fn uv(&self, prim: u32, u: f32, v: f32) -> Vec2 {
        if self.uvs.is_empty() {
            return Vec2::ZERO;
        }
        let [i0, i1, i2] = self.triangles[prim as usize].map(|i| i as usize);
        let w = 1.0 - u - v;
        self.uvs[i0] * w + self.uvs[i1] * u + self.uvs[i2] * v
    }
}

/// The version of [`Scene::fingerprint`], written before its hex digits (`fp3:…`), so that a
/// file recorded with an earlier fingerprint is told apart from a file of another scene.
pub const FINGERPRINT_VERSION: &str = "fp3";

impl Scene {
    /// A fingerprint of everything the scene renders, bit for bit: geometry, materials,
    /// textures, lights and camera, but not its render defaults or material names (they change
    /// no image), so a checkpoint, `--extend` or a study can tell a render of the same scene
    /// from another. A canonical serialisation (each value's bit pattern, little-endian, arrays
    /// with their lengths, enums by a fixed tag) hashed with BLAKE3: no formatting of types,
    /// so a new glam or Rust cannot change it. It reads the arrays in place.
    pub fn fingerprint(&self) -> String {
        let mut h = Canonical::new();
        h.bytes(b"cvtrace scene fingerprint 3");
        h.array(self.positions.len(), |h| h.floats(self.positions.iter().flat_map(|p| p.to_array())));
        h.array(self.triangles.len(), |h| self.triangles.iter().flatten().for_each(|&i| h.word(i as u64)));
        h.array(self.normals.len(), |h| h.floats(self.normals.iter().flat_map(|n| n.to_array())));
        h.array(self.uvs.len(), |h| h.floats(self.uvs.iter().flat_map(|t| t.to_array())));
        h.array(self.tri_material.len(), |h| self.tri_material.iter().for_each(|&m| h.word(m as u64)));
        h.array(self.textures.len(), |h| {
            for t in &self.textures {
                h.word(t.width as u64);
                h.word(t.height as u64);
                h.array(t.texels.len(), |h| h.floats(t.texels.iter().flat_map(|c| c.to_array())));
            }
        });
        h.array(self.materials.len(), |h| {
            for m in &self.materials {
                h.vec(m.base_color);
                h.texture(m.base_color_texture);
                h.floats([m.metallic, m.roughness]);
                h.texture(m.metallic_roughness_texture);
                h.floats([m.specular]);
                h.vec(m.specular_color);
                h.floats([m.transmission, m.ior]);
                h.vec(m.emission);
                h.texture(m.emissive_texture);
            }
        });
        // Emitting triangles are derived from the geometry and materials above.
        h.array(self.lights.punctual().len(), |h| {
            for l in self.lights.punctual() {
                match *l {
                    Punctual::Point { position, intensity } => {
                        h.word(0);
                        h.vec(position);
                        h.vec(intensity);
                    }
                    Punctual::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                        h.word(1);
                        h.vec(position);
                        h.vec(direction);
                        h.vec(intensity);
                        h.floats([cos_inner, cos_outer]);
                    }
                    Punctual::Directional { direction, irradiance } => {
                        h.word(2);
                        h.vec(direction);
                        h.vec(irradiance);
                    }
                }
            }
        });
        match self.lights.environment() {
            None => h.word(0),
            Some(e) => {
                h.word(1);
                e.fingerprint_into(&mut h);
            }
        }
        let c = &self.camera;
        h.vec(c.eye);
        h.vec(c.target);
        h.vec(c.up);
        h.floats([c.vfov_deg]);
        h.word(c.width as u64);
        h.word(c.height as u64);
        let digest = h.finalize();
        let first: [u8; 8] = digest.as_bytes()[..8].try_into().expect("a BLAKE3 digest has 32 bytes");
        format!("{FINGERPRINT_VERSION}:{:016x}", u64::from_be_bytes(first))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fingerprint of [`quad`], as this version of the format computes it.
    const PINNED_QUAD_FINGERPRINT: &str = "fp3:431dd2f141525ad7";

    #[test]
    fn the_fingerprint_is_a_stable_canonical_serialisation() {
        // The value is the format: a change of it (a new glam, a reordered field) orphans every
        // checkpoint, study and reference recorded with it, so it is pinned here; a deliberate
        // change bumps FINGERPRINT_VERSION and this value together.
        let fp = Scene::from_parts(quad()).unwrap().fingerprint();
        assert_eq!(fp, PINNED_QUAD_FINGERPRINT);
        assert!(fp.starts_with(&format!("{FINGERPRINT_VERSION}:")) && fp.len() == FINGERPRINT_VERSION.len() + 17);
        // A material's name renders nothing.
        let mut renamed = quad();
        renamed.materials[0].name = "another name".into();
        assert_eq!(Scene::from_parts(renamed).unwrap().fingerprint(), fp);
    }

    #[test]
    fn the_fingerprint_sees_every_part_of_the_scene_but_not_its_render_defaults() {
        let parts = || {
            let mut p = quad();
            p.textures = vec![Texture::new(2, 1, vec![glam::Vec3::ZERO, glam::Vec3::ONE]).unwrap()];
            p.materials[0].base_color_texture = Some(0);
            p.uvs = vec![Vec2::ZERO; 4];
            p
        };
        let base = Scene::from_parts(parts()).unwrap().fingerprint();
        assert_eq!(base, Scene::from_parts(parts()).unwrap().fingerprint(), "not deterministic");
        let mut with_defaults = Scene::from_parts(parts()).unwrap();
        with_defaults.set_render_defaults(RenderDefaults { reference_spp: Some(64), ..Default::default() });
        assert_eq!(base, with_defaults.fingerprint());
        type Change = (&'static str, Box<dyn Fn(&mut SceneParts)>);
        let changes: Vec<Change> = vec![
            ("a position", Box::new(|p| p.positions[2].x = f32::from_bits(p.positions[2].x.to_bits() + 1))),
            ("a triangle's winding", Box::new(|p| p.triangles[0] = [0, 2, 1])),
            ("a triangle's material", Box::new(|p| p.triangle_materials.swap(0, 1))),
            ("a texel", Box::new(|p| p.textures[0].texels[1].y = 0.5)),
            ("a texture's shape", Box::new(|p| (p.textures[0].width, p.textures[0].height) = (1, 2))),
            ("a uv", Box::new(|p| p.uvs[3] = Vec2::new(0.0, 1.0))),
            ("a material", Box::new(|p| p.materials[0].roughness = 0.5)),
            ("the environment", Box::new(|p| p.environment = Some(Environment::constant(Vec3A::ONE).unwrap()))),
            ("the camera", Box::new(|p| p.camera = Some(Camera { vfov_deg: 30.0, ..Camera::default() }))),
        ];
        for (what, change) in changes {
            let mut p = parts();
            change(&mut p);
            assert_ne!(Scene::from_parts(p).unwrap().fingerprint(), base, "{what} changed, the fingerprint did not");
        }
    }

    fn quad() -> SceneParts {
        SceneParts {
            positions: vec![Vec3A::ZERO, Vec3A::X, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            triangle_materials: vec![0, 1],
            materials: vec![Material::diffuse(Vec3A::splat(0.5)), Material::emissive(Vec3A::ZERO, Vec3A::ONE)],
            ..Default::default()
        }
    }

    #[test]
    fn from_parts_precomputes_normals_areas_and_lights() {
        let s = Scene::from_parts(quad()).unwrap();
        assert_eq!(s.geometric_normal(0), Vec3A::Z);
        assert!((s.triangle_area(1) - 0.5).abs() < 1e-6);
        assert_eq!(s.lights().len(), 1);
        assert!((s.lights().pdf_area(1) - 2.0).abs() < 1e-6);
        let sp = s.surface(0, 0.25, 0.5);
        assert!((sp.p - Vec3A::new(0.75, 0.5, 0.0)).length() < 1e-6);
        // Default camera sees the whole quad from +Z.
        assert!(s.camera().eye.z > 1.0);
    }

    #[test]
    fn shading_normals_are_interpolated_and_oriented_with_the_winding() {
        let mut p = quad();
        // Vertex normals pointing *against* the winding normal (+z), tilted differently per vertex.
        p.normals = vec![Vec3A::new(0.0, 0.0, -1.0), Vec3A::new(0.6, 0.0, -0.8), Vec3A::new(0.0, 0.6, -0.8), Vec3A::new(0.0, 0.0, -1.0)];
        p.uvs = vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
        let s = Scene::from_parts(p).unwrap();
        let sp = s.surface(0, 1.0, 0.0); // at vertex 1
        assert!((sp.ns - Vec3A::new(-0.6, 0.0, 0.8)).length() < 1e-6, "{}", sp.ns);
        assert_eq!(sp.ng, Vec3A::Z);
        let mid = s.surface(0, 0.5, 0.5);
        assert!((mid.ns.length() - 1.0).abs() < 1e-6 && mid.ns.z > 0.0);
        assert!((mid.uv - Vec2::new(1.0, 0.5)).length() < 1e-6);
        // Zero normals fall back to the geometric normal.
        let mut p = quad();
        p.normals = vec![Vec3A::ZERO; 4];
        assert_eq!(Scene::from_parts(p).unwrap().surface(1, 0.2, 0.2).ns, Vec3A::Z);
    }

    #[test]
    fn from_parts_rejects_bad_indices() {
        let mut p = quad();
        p.triangles[1] = [0, 2, 9];
        let e = Scene::from_parts(p).unwrap_err().to_string();
        assert!(e.contains("triangle 1") && e.contains("<memory>"), "{e}");
        let mut p = quad();
        p.triangle_materials[0] = 5;
        assert!(Scene::from_parts(p).unwrap_err().to_string().contains("material 5"));
        let mut p = quad();
        p.normals = vec![Vec3A::Z];
        assert!(Scene::from_parts(p).is_err());
    }
}

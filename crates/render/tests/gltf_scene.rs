//! glTF loading: a tiny file written by the test (JSON + base64 or external buffer) loads with
//! the right geometry, instancing, camera and material; broken files give errors naming the file.
use cvtrace_render::{Scene, SceneError};
use glam::Vec3A;
use std::path::Path;

mod common;
use common::{quad_buffer, quad_buffer_json};

fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The document: the quad instanced twice under a scaled parent, a camera node, one material.
/// `extra` is spliced into the top-level object (e.g. `"extensionsRequired": [...]`).
fn gltf_json(buffer_uri: &str, extra: &str, material_extra: &str) -> String {
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
  {extra}
  "scene": 0,
  "scenes": [{{"nodes": [0, 3]}}],
  "nodes": [
    {{"children": [1, 2], "scale": [2, 2, 2]}},
    {{"mesh": 0}},
    {{"mesh": 0, "translation": [5, 0, 0]}},
    {{"camera": 0, "translation": [0, 1, 10]}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.5, "znear": 0.1, "aspectRatio": 2.0}}}}],
  "meshes": [{{"primitives": [
    {{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}},
    {{"attributes": {{"POSITION": 0}}, "mode": 1}}
  ]}}],
  "materials": [{{
    "name": "lamp",
    "pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.25, 1, 1], "metallicFactor": 0.0, "roughnessFactor": 0.3 {material_extra}}},
    "emissiveFactor": [1, 0.5, 0.25],
    "extensions": {{
      "KHR_materials_emissive_strength": {{"emissiveStrength": 4.0}},
      "KHR_materials_specular": {{"specularFactor": 0.0}}
    }}
  }}],
  {quad}
}}"#,
        quad = quad_buffer_json(buffer_uri)
    )
}

fn embedded_uri() -> String {
    format!("data:application/octet-stream;base64,{}", base64(&quad_buffer()))
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn tiny_gltf_loads_geometry_instances_camera_and_material() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "quad.gltf", &gltf_json(&embedded_uri(), "", ""));
    let scene = Scene::load(&path).unwrap();
    // Two instances of two triangles; the LINES primitive is skipped.
    assert_eq!(scene.triangles().len(), 4);
    assert_eq!(scene.positions().len(), 8);
    let (lo, hi) = scene.bounds();
    // Parent scale 2 applies after the child's translation: x spans [0, 2] and [10, 12].
    assert_eq!((lo, hi), (Vec3A::ZERO, Vec3A::new(12.0, 2.0, 0.0)));
    let cam = scene.camera();
    assert_eq!(cam.eye, Vec3A::new(0.0, 1.0, 10.0));
    assert!(((cam.target - cam.eye).normalize() - Vec3A::NEG_Z).length() < 1e-6);
    assert!((cam.vfov_deg - 0.5f32.to_degrees()).abs() < 1e-4);
    assert_eq!((cam.width, cam.height), (1024, 512));
    let m = &scene.materials()[scene.triangle_materials()[0] as usize];
    assert_eq!(m.name, "lamp");
    assert_eq!(m.base_color, Vec3A::new(0.5, 0.25, 1.0));
    assert_eq!((m.metallic, m.roughness, m.specular), (0.0, 0.3, 0.0));
    assert_eq!(m.emission, Vec3A::new(4.0, 2.0, 1.0));
    // Both instances emit, facing +z.
    assert_eq!(scene.lights().len(), 4);
    assert_eq!(scene.geometric_normal(3), Vec3A::Z);
}

#[test]
fn external_buffer_loads_and_its_absence_is_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("quad data.bin"), quad_buffer()).unwrap();
    let path = write(dir.path(), "ext.gltf", &gltf_json("quad%20data.bin", "", ""));
    assert_eq!(Scene::load(&path).unwrap().triangles().len(), 4);
    std::fs::remove_file(dir.path().join("quad data.bin")).unwrap();
    let e = Scene::load(&path).unwrap_err();
    assert!(matches!(e, SceneError::MissingFile { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(msg.contains("ext.gltf") && msg.contains("quad data.bin"), "{msg}");
}

#[test]
fn malformed_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = write(dir.path(), "broken.gltf", "{ \"asset\": { \"version\": ");
    let msg = Scene::load(&bad).unwrap_err().to_string();
    assert!(msg.contains("broken.gltf"), "{msg}");
    let missing = dir.path().join("nope.gltf");
    let msg = Scene::load(&missing).unwrap_err().to_string();
    assert!(msg.contains("nope.gltf"), "{msg}");
    // An accessor pointing past its buffer.
    let text =
        gltf_json(&embedded_uri(), "", "").replace("\"byteOffset\": 48, \"byteLength\": 12", "\"byteOffset\": 48, \"byteLength\": 120");
    let p = write(dir.path(), "overrun.gltf", &text);
    let msg = Scene::load(&p).unwrap_err().to_string();
    assert!(msg.contains("overrun.gltf"), "{msg}");
}

#[test]
fn out_of_range_indices_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let mut buf = quad_buffer();
    buf[48 + 10] = 7; // last index → vertex 7 of 4
    let text = gltf_json(&format!("data:application/octet-stream;base64,{}", base64(&buf)), "", "");
    let p = write(dir.path(), "idx.gltf", &text);
    let msg = Scene::load(&p).unwrap_err().to_string();
    assert!(msg.contains("idx.gltf") && msg.contains("vertex 7"), "{msg}");
}

#[test]
fn unsupported_required_extension_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = gltf_json(&embedded_uri(), r#""extensionsRequired": ["KHR_draco_mesh_compression"],"#, "");
    let p = write(dir.path(), "draco.gltf", &text);
    let e = Scene::load(&p).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, SceneError::UnsupportedExtension { .. }), "{e:?}");
    assert!(msg.contains("draco.gltf") && msg.contains("KHR_draco_mesh_compression"), "{msg}");
    // A required extension cvtrace does read is accepted.
    let text = gltf_json(&embedded_uri(), r#""extensionsRequired": ["KHR_materials_specular"],"#, "");
    let p = write(dir.path(), "spec.gltf", &text);
    assert!(Scene::load(&p).is_ok());
}

fn write_png(path: &Path, w: u32, h: u32, rgb: &[u8]) {
    let f = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(f, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header().unwrap().write_image_data(rgb).unwrap();
}

#[test]
fn base_colour_texture_is_decoded_from_srgb_and_a_missing_one_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("albedo.png"), 2, 1, &[255, 0, 0, 128, 128, 128]);
    let top = r#""images": [{"uri": "albedo.png"}], "textures": [{"source": 0}],"#;
    let text = gltf_json(&embedded_uri(), top, r#", "baseColorTexture": {"index": 0}"#);
    let p = write(dir.path(), "tex.gltf", &text);
    let scene = Scene::load(&p).unwrap();
    let m = &scene.materials()[0];
    let t = &scene.textures()[m.base_color_texture.expect("texture is used") as usize];
    assert_eq!((t.width, t.height), (2, 1));
    assert_eq!(t.texels[0], glam::Vec3::new(1.0, 0.0, 0.0));
    let g = cvtrace_render::scene::texture::srgb_to_linear(128.0 / 255.0);
    assert!((t.texels[1] - glam::Vec3::splat(g)).length() < 1e-6 && g < 0.25, "{}", t.texels[1]);
    std::fs::remove_file(dir.path().join("albedo.png")).unwrap();
    let msg = Scene::load(&p).unwrap_err().to_string();
    assert!(msg.contains("tex.gltf") && msg.contains("albedo.png"), "{msg}");
}

#[test]
fn default_resolution_hint_sets_the_camera_size() {
    let dir = tempfile::tempdir().unwrap();
    let text = gltf_json(&embedded_uri(), "", "")
        .replace(r#""asset": {"version": "2.0"}"#, r#""asset": {"version": "2.0", "extras": {"defaultResolution": [300, 200]}}"#);
    let p = write(dir.path(), "res.gltf", &text);
    let cam = Scene::load(&p).unwrap().camera().clone();
    assert_eq!((cam.width, cam.height), (300, 200));
}

#[test]
fn repository_cornell_box_loads() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.gltf");
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangles().len(), 36);
    // One quad light facing down, emitting (17, 12, 4).
    assert_eq!(scene.lights().len(), 2);
    let light = (0..36u32).find(|&i| scene.lights().pdf_area(i) > 0.0).unwrap();
    assert!((scene.material_of(light).emission - Vec3A::new(17.0, 12.0, 4.0)).length() < 1e-3);
    assert!(scene.geometric_normal(light).y < -0.99);
    let cam = scene.camera();
    assert_eq!((cam.width, cam.height), (256, 256));
    assert!((cam.eye - Vec3A::new(278.0, 273.0, -800.0)).length() < 1e-3);
    assert!((cam.target - cam.eye).normalize().z > 0.999);
}

#[test]
fn binary_glb_loads_from_its_bin_chunk() {
    // The same document with the buffer in the GLB's BIN chunk (no uri).
    let json = gltf_json("REMOVE", "", "").replace(r#", "uri": "REMOVE""#, "");
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin = quad_buffer(); // 60 bytes, already a multiple of 4
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("quad.glb");
    std::fs::write(&p, &glb).unwrap();
    let scene = Scene::load(&p).unwrap();
    assert_eq!(scene.triangles().len(), 4);
    // A truncated GLB is an error naming the file.
    let q = dir.path().join("cut.glb");
    std::fs::write(&q, &glb[..glb.len() - 30]).unwrap();
    let msg = Scene::load(&q).unwrap_err().to_string();
    assert!(msg.contains("cut.glb"), "{msg}");
}

//! glTF 2.0 → [`Scene`]: flattens every mesh instance of the default scene into world space,
//! converts materials and textures, and picks the camera.
//!
//! What is read: triangles (lists, strips and fans; points and lines are skipped with a
//! warning), `POSITION`, `NORMAL`, `TEXCOORD_0`; metallic-roughness materials with their
//! textures, `KHR_materials_specular`, `KHR_materials_transmission`, `KHR_materials_ior`,
//! `KHR_materials_emissive_strength`; `KHR_lights_punctual` lights on nodes (one light per node
//! instance, placed by the node's world transform, shining along its local −Z; `range` is
//! ignored); the perspective camera of the first node (depth-first from the scene roots) that
//! has one, with the resolution from `asset.extras.defaultResolution` if given, else 512 on the
//! long side of the camera's aspect ratio. Then the sidecar `<stem>.cvtrace.toml`, if present,
//! adds the environment light and the render defaults ([`crate::scene::sidecar`]). Unsupported
//! *required* extensions are an error; other unsupported extensions, alpha modes, normal and
//! occlusion textures are ignored with a warning. What the specification forbids is an error
//! rather than a guess: accessor types other than those above, factors outside their ranges,
//! an invalid camera, a node with two parents. Every error names the file (and the light,
//! camera or material).
use crate::scene::camera::{default_camera, Camera};
use crate::scene::error::SceneError;
use crate::scene::lights::Punctual;
use crate::scene::material::Material;
use crate::scene::sidecar::{check_define_keys, sidecar_path, Define, Sidecar};
use crate::scene::texture::{srgb_to_linear, Texture};
use crate::scene::world::{Scene, SceneParts};
use cvtrace_streams::input_file::{regular_file, NotAFile};
use glam::{Mat3, Mat4, Vec2, Vec3A};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Extensions cvtrace understands, so a file may list them in `extensionsRequired`.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_lights_punctual",
];

/// Node hierarchies deeper than this are treated as cyclic (the spec forbids cycles).
const MAX_NODE_DEPTH: usize = 1024;

// Loading is the importer's: the scene itself only checks and holds what it is given.
impl Scene {
    /// Loads a glTF 2.0 scene (`.gltf` with external or embedded buffers, or `.glb`).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        load(path, &[])
    }

    /// As [`Scene::load`], with `-D` overrides of the sidecar's settings.
    pub fn load_with(path: &Path, defines: &[Define]) -> Result<Scene, SceneError> {
        load(path, defines)
    }
}

/// Loads `path` (.gltf or .glb), its sidecar with `defines` applied.
pub fn load(path: &Path, defines: &[Define]) -> Result<Scene, SceneError> {
    check_define_keys(defines)?;
    require_regular_file(path, path)?;
    let bytes = std::fs::read(path).map_err(|e| SceneError::Io { path: path.to_path_buf(), error: e })?;
    let malformed = |e: gltf::Error| SceneError::Malformed { path: path.to_path_buf(), message: e.to_string() };
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(&bytes).map_err(malformed)?;
    check_index_widths(&bytes, path)?;
    let mut json = document.into_json();
    for ext in &json.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(SceneError::UnsupportedExtension { path: path.to_path_buf(), extension: ext.clone() });
        }
    }
    for ext in &json.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            tracing::warn!("{}: ignoring glTF extension {ext}", path.display());
        }
    }
    check_json(&json, path)?;
    let resolution = default_resolution(&json, path);
    // Checked above; gltf's own validator does not know every extension cvtrace reads.
    json.extensions_required.clear();
    let document = gltf::Document::from_json(json).map_err(malformed)?;

    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    check_external_files(&document, &base, path)?;
    let buffers = import_buffers(&document, &base, blob, path)?;
    check_accessors(&document, &buffers, path)?;
    let images = import_images(&document, &base, &buffers, path)?;

    // The accessor readers index buffers and unwrap directly; the checks above are meant to
    // leave them nothing to trip on, and this turns anything they missed into an error instead
    // of a crash (the panic message is still printed).
    let built = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| Builder::new(path, &document, &buffers, &images).build()));
    let (parts, automatic_camera) = match built {
        Ok(r) => r?,
        Err(_) => {
            return Err(SceneError::Malformed {
                path: path.to_path_buf(),
                message: "the glTF reader failed on an inconsistency cvtrace does not check (see the panic above)".into(),
            })
        }
    };
    let mut parts = parts;
    if let (Some((w, h)), Some(cam)) = (resolution, parts.camera.as_mut()) {
        (cam.width, cam.height) = (w, h);
    }
    let sidecar = match Sidecar::discover(path)? {
        None if defines.is_empty() => None,
        found => Some(found.unwrap_or_else(|| Sidecar { path: sidecar_path(path), ..Sidecar::default() }).with_defines(defines)?),
    };
    if let Some(sidecar) = sidecar {
        parts.environment = sidecar.environment()?;
        parts.render_defaults = sidecar.render;
    }
    // Precedence of the size: sidecar, then the glTF's hint (flags override both later).
    let d = &mut parts.render_defaults;
    if let (None, None, Some((w, h))) = (d.width, d.height, resolution) {
        (d.width, d.height) = (Some(w), Some(h));
    }
    let mut scene = Scene::from_parts_named(parts, path)?;
    if automatic_camera {
        scene.mark_automatic_camera();
    }
    Ok(scene)
}

/// What the `gltf` crate does not check before it indexes or unwraps (it would panic):
/// the major version, accessor references of mesh attributes, images with exactly one source
/// (and a MIME type when stored in a buffer view), cameras whose `type` has its projection
/// object, and accessors of at least one element (the specification's minimum).
fn check_json(json: &gltf::json::Root, path: &Path) -> Result<(), SceneError> {
    let err = |m: String| Err(SceneError::Malformed { path: path.to_path_buf(), message: m });
    if json.asset.version.split('.').next() != Some("2") {
        return err(format!("asset.version is {:?}; cvtrace reads glTF 2.x", json.asset.version));
    }
    let accessors = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= accessors {
                    let name = match semantic {
                        gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        gltf::json::validation::Checked::Invalid => "an attribute".into(),
                    };
                    return err(format!("mesh {m} primitive {p}: {name} refers to accessor {} but there are {accessors}", index.value()));
                }
            }
        }
    }
    for (i, image) in json.images.iter().enumerate() {
        match (&image.uri, &image.buffer_view) {
            (None, None) => return err(format!("image {i} has neither a uri nor a bufferView; glTF requires one")),
            (Some(_), Some(_)) => return err(format!("image {i} has both a uri and a bufferView; glTF allows only one")),
            (None, Some(_)) if image.mime_type.is_none() => {
                return err(format!("image {i} is stored in a buffer view and needs a mimeType"))
            }
            _ => {}
        }
    }
    for (i, c) in json.cameras.iter().enumerate() {
        use gltf::json::camera::Type;
        use gltf::json::validation::Checked;
        let (matching, key) = match c.type_ {
            Checked::Valid(Type::Perspective) => (c.perspective.is_some(), "perspective"),
            Checked::Valid(Type::Orthographic) => (c.orthographic.is_some(), "orthographic"),
            Checked::Invalid => (true, ""),
        };
        if !matching {
            return err(format!("camera {i} is of type {key} but has no `{key}` object"));
        }
    }
    for (i, a) in json.accessors.iter().enumerate() {
        if a.count.0 == 0 {
            return err(format!("accessor {i} has count 0; glTF requires at least 1"));
        }
    }
    Ok(())
}

/// Object keys whose values (or array elements) are indices into the document's arrays.
const INDEX_KEYS: &[&str] = &[
    "buffer",
    "bufferView",
    "camera",
    "children",
    "index",
    "indices",
    "input",
    "inverseBindMatrices",
    "joints",
    "light",
    "material",
    "mesh",
    "node",
    "nodes",
    "output",
    "sampler",
    "scene",
    "skeleton",
    "skin",
    "source",
];

/// The `gltf` crate reads every index as a u64 and keeps its low 32 bits, so that index 2^32
/// would silently refer to element 0: an index that does not fit in 32 bits is an error.
/// `bytes` is the whole .gltf or .glb file (already parsed once, so it is well-formed).
fn check_index_widths(bytes: &[u8], path: &Path) -> Result<(), SceneError> {
    use gltf::json::Value;
    let glb;
    let text: &[u8] = if bytes.starts_with(b"glTF") {
        glb =
            gltf::binary::Glb::from_slice(bytes).map_err(|e| SceneError::Malformed { path: path.to_path_buf(), message: e.to_string() })?;
        &glb.json
    } else {
        bytes
    };
    let Ok(root) = gltf::json::deserialize::from_slice::<Value>(text) else { return Ok(()) };
    // `holds` = the values here are indices: under an index key, in `attributes`, or in a
    // morph target. `extras` is the application's own and is not looked into.
    fn find(v: &Value, key: &str, holds: bool, at: &mut Vec<String>) -> Option<u64> {
        match v {
            Value::Number(n) if holds => n.as_u64().filter(|&i| i > u32::MAX as u64),
            Value::Array(items) => items.iter().enumerate().find_map(|(i, x)| {
                at.push(i.to_string());
                let r = find(x, key, holds, at);
                if r.is_none() {
                    at.pop();
                }
                r
            }),
            Value::Object(map) if key != "extras" => map.iter().find_map(|(k, x)| {
                at.push(k.clone());
                let r = find(x, k, INDEX_KEYS.contains(&k.as_str()) || key == "attributes" || key == "targets", at);
                if r.is_none() {
                    at.pop();
                }
                r
            }),
            _ => None,
        }
    }
    let mut at = Vec::new();
    match find(&root, "", false, &mut at) {
        Some(i) => Err(SceneError::Malformed {
            path: path.to_path_buf(),
            message: format!("/{}: index {i} does not fit in 32 bits", at.join("/")),
        }),
        None => Ok(()),
    }
}

/// `asset.extras.defaultResolution: [width, height]`, cvtrace's own hint for the render size
/// (glTF cameras only carry an aspect ratio). An unusable hint is ignored with a warning.
fn default_resolution(json: &gltf::json::Root, path: &Path) -> Option<(u32, u32)> {
    let raw = json.asset.extras.as_ref()?;
    let v: gltf::json::Value = gltf::json::deserialize::from_str(raw.get()).ok()?;
    let hint = v.get("defaultResolution")?;
    let side = |i: usize| hint.as_array()?.get(i)?.as_u64().filter(|&x| (1..=16384).contains(&x)).map(|x| x as u32);
    let size = side(0).zip(side(1));
    if size.is_none() || hint.as_array().is_some_and(|r| r.len() != 2) {
        tracing::warn!("{}: ignoring asset.extras.defaultResolution {hint}: expected [width, height], each 1 to 16384", path.display());
        return None;
    }
    size
}

/// Percent-decodes a relative URI (glTF URIs are RFC 3986 encoded) as the `gltf` crate does;
/// `None` if the bytes it stands for are not UTF-8 (the crate would panic on them).
fn decode_uri(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8(out).ok()
}

/// The file a buffer or image URI refers to, resolved as the `gltf` crate's importer resolves
/// it (it reads the images): `None` for a `data:` URI; `file:` URIs are taken as they are (the
/// crate does not percent-decode them), relative ones are decoded and joined to `base`; any
/// other scheme is an error.
fn external_path(base: &Path, uri: &str) -> Result<Option<PathBuf>, String> {
    if uri.contains(':') {
        if uri.starts_with("data:") {
            return Ok(None);
        }
        if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
            return Ok(Some(PathBuf::from(rest)));
        }
        return Err(format!("the URI {} has a scheme cvtrace does not read (only relative paths, file: and data:)", short_uri(uri)));
    }
    match decode_uri(uri) {
        Some(decoded) => Ok(Some(base.join(decoded))),
        None => Err(format!("the URI {} does not percent-decode to UTF-8", short_uri(uri))),
    }
}

/// A URI for a message: `data:` URIs are cut after their media type.
fn short_uri(uri: &str) -> String {
    if uri.starts_with("data:") {
        let head: String = uri.chars().take_while(|&c| c != ',').take(60).collect();
        format!("`{head},…`")
    } else if uri.chars().count() > 200 {
        format!("`{}…`", uri.chars().take(200).collect::<String>())
    } else {
        format!("`{uri}`")
    }
}

/// Largest image file read (the importer reads a file whole before decoding it; its decoder
/// allocates at most 512 MiB, so no usable image is larger).
const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;

/// Checks every buffer and image URI before anything is read: names the first missing or
/// unreadable file (the importer would only report a bare "No such file"), refuses devices,
/// FIFOs and directories (reading them would never end), URIs the importer cannot resolve, and
/// image files too large to be images.
fn check_external_files(doc: &gltf::Document, base: &Path, path: &Path) -> Result<(), SceneError> {
    let mut uris = Vec::new();
    for b in doc.buffers() {
        if let gltf::buffer::Source::Uri(uri) = b.source() {
            uris.push((format!("buffer {}", b.index()), uri, false));
        }
    }
    for im in doc.images() {
        if let gltf::image::Source::Uri { uri, .. } = im.source() {
            uris.push((format!("image {}", im.index()), uri, true));
        }
    }
    for (what, uri, image) in uris {
        let file = external_path(base, uri).map_err(|m| SceneError::invalid(path, format!("{what}: {m}")))?;
        if let Some(file) = file {
            require_regular_file(&file, path)?;
            let size = std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0);
            if image && size > MAX_IMAGE_FILE_BYTES {
                return Err(SceneError::MissingFile {
                    path: path.to_path_buf(),
                    file,
                    message: format!("{what} is {size} bytes; images larger than {MAX_IMAGE_FILE_BYTES} bytes are not read"),
                });
            }
        }
    }
    Ok(())
}

/// The buffers' bytes. External files are read only up to the buffer's `byteLength` (the
/// importer reads whole files, so a huge file behind a small buffer would be read entirely),
/// into memory reserved fallibly; a file shorter than `byteLength` is an error naming it.
fn import_buffers(
    doc: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
    path: &Path,
) -> Result<Vec<gltf::buffer::Data>, SceneError> {
    use std::io::Read;
    let malformed = |m: String| SceneError::Malformed { path: path.to_path_buf(), message: m };
    let mut buffers = Vec::with_capacity(doc.buffers().len());
    for b in doc.buffers() {
        let (i, len) = (b.index(), b.length());
        let mut data = match b.source() {
            gltf::buffer::Source::Bin => {
                blob.take().ok_or_else(|| malformed(format!("buffer {i} has no uri and there is no GLB binary chunk for it")))?
            }
            gltf::buffer::Source::Uri(uri) => match external_path(base, uri).map_err(|m| malformed(format!("buffer {i}: {m}")))? {
                None => gltf::buffer::Data::from_source(b.source(), Some(base)).map_err(|e| malformed(format!("buffer {i}: {e}")))?.0,
                Some(file) => {
                    let missing = |message: String| SceneError::MissingFile { path: path.to_path_buf(), file: file.clone(), message };
                    let f = std::fs::File::open(&file).map_err(|e| missing(e.to_string()))?;
                    let size = f.metadata().map_err(|e| missing(e.to_string()))?.len();
                    if size < len as u64 {
                        return Err(missing(format!("it has {size} bytes but buffer {i} has byteLength {len}")));
                    }
                    let mut data = Vec::new();
                    data.try_reserve_exact(len.saturating_add(3))
                        .map_err(|_| missing(format!("cannot allocate the {len} bytes of buffer {i}")))?;
                    f.take(len as u64).read_to_end(&mut data).map_err(|e| missing(e.to_string()))?;
                    data
                }
            },
        };
        if data.len() < len {
            return Err(malformed(format!("buffer {i} has byteLength {len} but holds {} bytes", data.len())));
        }
        while !data.len().is_multiple_of(4) {
            data.push(0);
        }
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
}

/// Decodes the images one by one, so that an error names the image and its file.
fn import_images(
    doc: &gltf::Document,
    base: &Path,
    buffers: &[gltf::buffer::Data],
    path: &Path,
) -> Result<Vec<gltf::image::Data>, SceneError> {
    let mut images = Vec::with_capacity(doc.images().len());
    for im in doc.images() {
        let data = gltf::image::Data::from_source(im.source(), Some(base), buffers).map_err(|e| {
            let source = match im.source() {
                gltf::image::Source::Uri { uri, .. } => match external_path(base, uri) {
                    Ok(Some(file)) => file.display().to_string(),
                    _ => short_uri(uri),
                },
                gltf::image::Source::View { view, .. } => format!("buffer view {}", view.index()),
            };
            SceneError::invalid(path, format!("cannot decode image {} ({source}): {e}", im.index()))
        })?;
        images.push(data);
    }
    Ok(images)
}

/// `file` (the scene `path` itself or a file it references) must be a readable regular file:
/// reading a device such as /dev/zero would never end.
fn require_regular_file(file: &Path, path: &Path) -> Result<(), SceneError> {
    match regular_file(file) {
        Ok(_) => Ok(()),
        Err(NotAFile::Io(e)) if file == path => Err(SceneError::Io { path: path.to_path_buf(), error: e }),
        Err(e) if file == path => Err(SceneError::invalid(path, e.to_string())),
        Err(e) => Err(SceneError::MissingFile { path: path.to_path_buf(), file: file.to_path_buf(), message: e.to_string() }),
    }
}

/// Checks that every buffer view lies inside its buffer and every accessor inside its view:
/// gltf's readers would otherwise silently truncate (or panic on) out-of-range data.
fn check_accessors(doc: &gltf::Document, buffers: &[gltf::buffer::Data], path: &Path) -> Result<(), SceneError> {
    let err = |m: String| Err(SceneError::Malformed { path: path.to_path_buf(), message: m });
    for v in doc.views() {
        let have = buffers.get(v.buffer().index()).map_or(0, |b| b.len());
        if v.offset().checked_add(v.length()).is_none_or(|end| end > have) {
            return err(format!(
                "buffer view {} spans bytes {}..{} of buffer {}, which has {have}",
                v.index(),
                v.offset(),
                v.offset().saturating_add(v.length()),
                v.buffer().index()
            ));
        }
    }
    // Bytes needed by `count` elements of `size` bytes at `offset` with `stride`.
    let span = |offset: usize, count: usize, size: usize, stride: usize| -> Option<usize> {
        if count == 0 {
            return Some(offset);
        }
        (count - 1).checked_mul(stride)?.checked_add(size)?.checked_add(offset)
    };
    for a in doc.accessors() {
        if let Some(v) = a.view() {
            // The readers step by the stride and assert that an element fits in it.
            if let Some(stride) = v.stride().filter(|&s| s < a.size()) {
                return err(format!(
                    "accessor {} has elements of {} bytes but its buffer view {} has byteStride {stride}",
                    a.index(),
                    a.size(),
                    v.index()
                ));
            }
            let stride = v.stride().unwrap_or(a.size());
            if span(a.offset(), a.count(), a.size(), stride).is_none_or(|end| end > v.length()) {
                return err(format!("accessor {} reads past the end of buffer view {}", a.index(), v.index()));
            }
        }
        if let Some(sp) = a.sparse() {
            // The checks below (and the readers' element size) assume tightly packed views.
            if sp.indices().view().stride().is_some() || sp.values().view().stride().is_some() {
                return err(format!("sparse accessor {}: its buffer views must not have a byteStride", a.index()));
            }
            let isz = match sp.indices().index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let (iv, vv) = (sp.indices().view(), sp.values().view());
            if span(sp.indices().offset(), sp.count(), isz, isz).is_none_or(|end| end > iv.length())
                || span(sp.values().offset(), sp.count(), a.size(), a.size()).is_none_or(|end| end > vv.length())
            {
                return err(format!("sparse accessor {} reads past the end of its buffer views", a.index()));
            }
            // The gltf crate applies whatever indices it finds: out of range they are dropped,
            // repeated or unsorted they overwrite each other, all silently.
            let bytes = &buffers[iv.buffer().index()][iv.offset() + sp.indices().offset()..];
            let mut previous: Option<usize> = None;
            for k in 0..sp.count() {
                let b = &bytes[k * isz..(k + 1) * isz];
                let i = match isz {
                    1 => b[0] as usize,
                    2 => u16::from_le_bytes([b[0], b[1]]) as usize,
                    _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
                };
                if i >= a.count() || previous.is_some_and(|p| i <= p) {
                    return err(format!(
                        "sparse accessor {}: index {i} at position {k}; sparse indices must increase strictly and stay below the count {}",
                        a.index(),
                        a.count()
                    ));
                }
                previous = Some(i);
            }
        }
    }
    Ok(())
}

struct Builder<'a> {
    path: &'a Path,
    doc: &'a gltf::Document,
    buffers: &'a [gltf::buffer::Data],
    images: &'a [gltf::image::Data],
    parts: SceneParts,
    /// (image index, sRGB?) → texture index.
    texture_ids: HashMap<(usize, bool), u32>,
    /// glTF material index → scene material id; `None` key is the default material.
    material_ids: HashMap<Option<usize>, u32>,
    camera: Option<Camera>,
    warned_texcoord: bool,
    /// Nodes already instanced: glTF gives every node at most one parent, and a file that
    /// breaks this could otherwise make the traversal exponential.
    visited: Vec<bool>,
    /// Material features cvtrace does not render, each reported once.
    warned: std::collections::BTreeSet<&'static str>,
}

impl<'a> Builder<'a> {
    fn new(path: &'a Path, doc: &'a gltf::Document, buffers: &'a [gltf::buffer::Data], images: &'a [gltf::image::Data]) -> Self {
        Builder {
            path,
            doc,
            buffers,
            images,
            parts: SceneParts::default(),
            texture_ids: HashMap::new(),
            material_ids: HashMap::new(),
            camera: None,
            warned_texcoord: false,
            visited: vec![false; doc.nodes().len()],
            warned: Default::default(),
        }
    }

    fn err(&self, message: impl Into<String>) -> SceneError {
        SceneError::invalid(self.path, message)
    }

    /// The scene's parts, and whether its camera is the automatic one (the glTF has none).
    fn build(mut self) -> Result<(SceneParts, bool), SceneError> {
        let roots: Vec<gltf::Node> = match self.doc.default_scene().or_else(|| self.doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                // No scene: every node that is nobody's child is a root.
                let mut is_child = vec![false; self.doc.nodes().len()];
                for n in self.doc.nodes() {
                    for c in n.children() {
                        is_child[c.index()] = true;
                    }
                }
                self.doc.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };
        for root in roots {
            self.visit(&root, Mat4::IDENTITY, 0)?;
        }
        if self.parts.triangles.is_empty() {
            return Err(self.err("the scene contains no triangles"));
        }
        let (lo, hi) = self
            .parts
            .positions
            .iter()
            .fold((Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let automatic_camera = self.camera.is_none();
        self.parts.camera = Some(self.camera.take().unwrap_or_else(|| default_camera(lo, hi)));
        if self.parts.normals.iter().all(|n| *n == Vec3A::ZERO) {
            self.parts.normals.clear();
        }
        if self.parts.uvs.iter().all(|n| *n == Vec2::ZERO) {
            self.parts.uvs.clear();
        }
        Ok((self.parts, automatic_camera))
    }

    fn visit(&mut self, node: &gltf::Node, parent: Mat4, depth: usize) -> Result<(), SceneError> {
        if depth > MAX_NODE_DEPTH {
            return Err(self.err("the node hierarchy is cyclic or deeper than 1024 levels"));
        }
        if std::mem::replace(&mut self.visited[node.index()], true) {
            return Err(self.err(format!(
                "node {} is reached twice from the scene (glTF allows one parent per node; instance a mesh from several nodes instead)",
                node.index()
            )));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if !world.is_finite() {
            return Err(self.err(format!("node {} has a non-finite transform", node.index())));
        }
        if self.camera.is_none() {
            if let Some(cam) = node.camera() {
                self.camera = self.convert_camera(&cam, world)?;
            }
        }
        if let Some(mesh) = node.mesh() {
            self.add_mesh(&mesh, world)?;
        }
        if let Some(light) = node.light() {
            self.add_light(&light, node.index(), world)?;
        }
        for child in node.children() {
            self.visit(&child, world, depth + 1)?;
        }
        Ok(())
    }

    /// One `KHR_lights_punctual` light at a node instance: position from the world transform,
    /// direction its local −Z (scale ignored), radiometric value `colour × intensity`.
    fn add_light(&mut self, light: &gltf::khr_lights_punctual::Light, node: usize, world: Mat4) -> Result<(), SceneError> {
        use gltf::khr_lights_punctual::Kind;
        let name = match light.name() {
            Some(n) => format!("light {} `{n}` (node {node})", light.index()),
            None => format!("light {} (node {node})", light.index()),
        };
        let intensity = light.intensity();
        if !(intensity.is_finite() && intensity >= 0.0) {
            return Err(self.err(format!("{name}: intensity {intensity} must be finite and non-negative")));
        }
        let value = Vec3A::from(light.color()) * intensity;
        let position = world.transform_point3a(Vec3A::ZERO);
        let direction = world.transform_vector3a(Vec3A::NEG_Z).normalize_or_zero();
        let l = match light.kind() {
            Kind::Point => Punctual::Point { position, intensity: value },
            Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                Punctual::spot(position, direction, value, inner_cone_angle, outer_cone_angle)
                    .map_err(|m| self.err(format!("{name}: {m}")))?
            }
            Kind::Directional => Punctual::Directional { direction, irradiance: value },
        };
        l.validate().map_err(|m| self.err(format!("{name}: {m}")))?;
        self.parts.lights.push(l);
        Ok(())
    }

    /// The camera of a node; an orthographic one is skipped with a warning, an invalid
    /// perspective one is an error (rendering some other view instead would be a silent wrong image).
    fn convert_camera(&self, cam: &gltf::Camera, world: Mat4) -> Result<Option<Camera>, SceneError> {
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let eye = world.transform_point3a(Vec3A::ZERO);
                let forward = world.transform_vector3a(Vec3A::NEG_Z).normalize_or_zero();
                let up = world.transform_vector3a(Vec3A::Y).normalize_or_zero();
                let (width, height) = match p.aspect_ratio() {
                    None => (512, 512),
                    Some(a) if a.is_finite() && a >= 1.0 => ((512.0 * a).round().min(16384.0) as u32, 512),
                    Some(a) if a.is_finite() && a > 0.0 => (512, (512.0 / a).round().min(16384.0) as u32),
                    Some(a) => return Err(self.err(format!("camera {}: aspectRatio {a} must be positive", cam.index()))),
                };
                let c = Camera { eye, target: eye + forward, up, vfov_deg: p.yfov().to_degrees(), width, height };
                c.validate().map_err(|m| self.err(format!("camera {}: {m} (yfov {} rad, node transform)", cam.index(), p.yfov())))?;
                Ok(Some(c))
            }
            gltf::camera::Projection::Orthographic(_) => {
                tracing::warn!("{}: orthographic camera {} is not supported; skipped", self.path.display(), cam.index());
                Ok(None)
            }
        }
    }

    fn add_mesh(&mut self, mesh: &gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        let flip = world.determinant() < 0.0;
        for prim in mesh.primitives() {
            use gltf::mesh::Mode;
            let mode = prim.mode();
            if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                tracing::warn!(
                    "{}: mesh {} has a {mode:?} primitive; only triangles are rendered, skipped",
                    self.path.display(),
                    mesh.index()
                );
                continue;
            }
            self.check_accessor_types(&prim, mesh.index())?;
            let reader = prim.reader(|b| self.buffers.get(b.index()).map(|d| &d.0[..]));
            let Some(pos) = reader.read_positions() else {
                return Err(self.err(format!("mesh {} has a primitive without POSITION", mesh.index())));
            };
            let positions: Vec<Vec3A> = pos.map(|p| world.transform_point3a(Vec3A::from(p))).collect();
            let n = positions.len();
            let raw_normals: Option<Vec<Vec3A>> = reader.read_normals().map(|it| it.map(Vec3A::from).collect());
            if let Some(i) = raw_normals.as_ref().and_then(|v| v.iter().position(|n| !n.is_finite())) {
                return Err(self.err(format!("mesh {}: NORMAL of vertex {i} is not finite", mesh.index())));
            }
            let normals: Option<Vec<Vec3A>> = raw_normals.map(|v| v.into_iter().map(|n| (normal_matrix * n).normalize_or_zero()).collect());
            let uvs: Option<Vec<Vec2>> = reader.read_tex_coords(0).map(|t| t.into_f32().map(Vec2::from).collect());
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..n as u32).collect(),
            };
            if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
                return Err(self.err(format!("mesh {} indexes vertex {bad} but has {n} vertices", mesh.index())));
            }
            if normals.as_ref().is_some_and(|v| v.len() != n) || uvs.as_ref().is_some_and(|v| v.len() != n) {
                return Err(self.err(format!("mesh {}: attribute counts differ from POSITION", mesh.index())));
            }
            if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
                return Err(self.err(format!("mesh {}: a triangle list of {} indices (not a multiple of 3)", mesh.index(), indices.len())));
            }
            if uvs.is_none() && prim.material().pbr_metallic_roughness().base_color_texture().is_some() {
                self.warn_once("a textured material on a mesh without TEXCOORD_0: its texture's first texel colours the whole mesh");
            }
            let tris = triangulate(mode, &indices);
            let material = self.material_id(prim.material())?;
            let offset = self.parts.positions.len() as u32;
            if (offset as usize + n) > u32::MAX as usize {
                return Err(self.err("the scene has more than 2^32 vertices"));
            }
            self.parts.positions.extend_from_slice(&positions);
            self.parts.normals.extend(normals.unwrap_or_else(|| vec![Vec3A::ZERO; n]));
            self.parts.uvs.extend(uvs.unwrap_or_else(|| vec![Vec2::ZERO; n]));
            for [a, b, c] in tris {
                let t = if flip { [a, c, b] } else { [a, b, c] };
                self.parts.triangles.push(t.map(|i| i + offset));
                self.parts.triangle_materials.push(material);
            }
        }
        Ok(())
    }

    /// The component types and shapes cvtrace reads; the `gltf` crate would otherwise reinterpret
    /// the bytes (or panic on indices of a float type).
    fn check_accessor_types(&self, prim: &gltf::Primitive, mesh: usize) -> Result<(), SceneError> {
        use gltf::accessor::{DataType, Dimensions};
        use gltf::mesh::Semantic;
        let float = |a: &gltf::Accessor| a.data_type() == DataType::F32;
        let unorm = |a: &gltf::Accessor| a.normalized() && matches!(a.data_type(), DataType::U8 | DataType::U16);
        let check = |what: &str, a: Option<gltf::Accessor>, dims: Dimensions, ok: &dyn Fn(&gltf::Accessor) -> bool, expected: &str| match a
        {
            Some(a) if a.dimensions() != dims || !ok(&a) => Err(self.err(format!(
                "mesh {mesh}: {what} accessor {} is {:?} {:?}{}; expected {expected}",
                a.index(),
                a.dimensions(),
                a.data_type(),
                if a.normalized() { " normalized" } else { "" }
            ))),
            _ => Ok(()),
        };
        let vec3 = "VEC3 of FLOAT (KHR_mesh_quantization is not supported)";
        check("POSITION", prim.get(&Semantic::Positions), Dimensions::Vec3, &float, vec3)?;
        check("NORMAL", prim.get(&Semantic::Normals), Dimensions::Vec3, &float, vec3)?;
        let uv_ok = |a: &gltf::Accessor| float(a) || unorm(a);
        check(
            "TEXCOORD_0",
            prim.get(&Semantic::TexCoords(0)),
            Dimensions::Vec2,
            &uv_ok,
            "VEC2 of FLOAT or normalized UNSIGNED_BYTE/SHORT",
        )?;
        let index_ok = |a: &gltf::Accessor| matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32) && !a.normalized();
        check("indices", prim.indices(), Dimensions::Scalar, &index_ok, "SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT")
    }

    fn warn_once(&mut self, what: &'static str) {
        if self.warned.insert(what) {
            tracing::warn!("{}: {what}", self.path.display());
        }
    }

    fn material_id(&mut self, m: gltf::Material) -> Result<u32, SceneError> {
        if let Some(&id) = self.material_ids.get(&m.index()) {
            return Ok(id);
        }
        let mat = if m.index().is_none() { Material::default() } else { self.convert_material(&m)? };
        let id = self.parts.materials.len() as u32;
        self.parts.materials.push(mat);
        self.material_ids.insert(m.index(), id);
        Ok(id)
    }

    fn convert_material(&mut self, m: &gltf::Material) -> Result<Material, SceneError> {
        let pbr = m.pbr_metallic_roughness();
        let bc = pbr.base_color_factor();
        let mut mat = Material {
            name: m.name().map(str::to_owned).unwrap_or_else(|| format!("material {}", m.index().unwrap_or(0))),
            base_color: Vec3A::new(bc[0], bc[1], bc[2]),
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            ..Material::default()
        };
        mat.base_color_texture = self.texture(pbr.base_color_texture(), true)?;
        mat.metallic_roughness_texture = self.texture(pbr.metallic_roughness_texture(), false)?;
        if let Some(s) = m.specular() {
            mat.specular = s.specular_factor();
            mat.specular_color = Vec3A::from(s.specular_color_factor());
        }
        if let Some(t) = m.transmission() {
            mat.transmission = t.transmission_factor();
        }
        if let Some(ior) = m.ior() {
            mat.ior = ior;
        }
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength >= 0.0 && strength.is_finite()) {
            return Err(self.err(format!("material `{}` has emissiveStrength {strength}; expected ≥ 0", mat.name)));
        }
        // The specification's ranges: out of them, a factor is not a darker or brighter
        // material but an energy-creating or meaningless one.
        let unit = |v: f32| (0.0..=1.0).contains(&v);
        let factors = [
            ("baseColorFactor", bc[..3].iter().all(|&v| unit(v))),
            ("metallicFactor", unit(mat.metallic)),
            ("roughnessFactor", unit(mat.roughness)),
            ("specularFactor", unit(mat.specular)),
            ("specularColorFactor", mat.specular_color.min_element() >= 0.0),
            ("transmissionFactor", unit(mat.transmission)),
            ("emissiveFactor", m.emissive_factor().iter().all(|&v| unit(v))),
        ];
        if let Some((name, _)) = factors.iter().find(|(_, ok)| !ok) {
            return Err(self.err(format!("material `{}`: {name} is outside the range glTF allows", mat.name)));
        }
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            self.warn_once("alphaMode MASK or BLEND is not rendered: surfaces are opaque");
        }
        if m.normal_texture().is_some() {
            self.warn_once("normalTexture is not rendered");
        }
        if m.occlusion_texture().is_some() {
            self.warn_once("occlusionTexture is not rendered");
        }
        mat.emission = Vec3A::from(m.emissive_factor()) * strength;
        if mat.emission.max_element() > 0.0 {
            mat.emissive_texture = self.texture(m.emissive_texture(), true)?;
        }
        if !(mat.ior >= 1.0 && mat.ior.is_finite()) {
            return Err(self.err(format!("material `{}` has ior {}; expected ≥ 1", mat.name, mat.ior)));
        }
        Ok(mat)
    }

    fn texture(&mut self, info: Option<gltf::texture::Info>, srgb: bool) -> Result<Option<u32>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        if info.tex_coord() != 0 && !self.warned_texcoord {
            tracing::warn!("{}: textures using TEXCOORD_{} are looked up with TEXCOORD_0", self.path.display(), info.tex_coord());
            self.warned_texcoord = true;
        }
        let image = info.texture().source().index();
        if let Some(&id) = self.texture_ids.get(&(image, srgb)) {
            return Ok(Some(id));
        }
        let data = self.images.get(image).ok_or_else(|| self.err(format!("texture refers to missing image {image}")))?;
        let tex = convert_image(data, srgb).map_err(|m| self.err(format!("image {image}: {m}")))?;
        let id = self.parts.textures.len() as u32;
        self.parts.textures.push(tex);
        self.texture_ids.insert((image, srgb), id);
        Ok(Some(id))
    }
}

/// Triangle index triples of a list, strip or fan.
fn triangulate(mode: gltf::mesh::Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    match mode {
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| if i % 2 == 0 { [idx[i], idx[i + 1], idx[i + 2]] } else { [idx[i + 1], idx[i], idx[i + 2]] })
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1)).map(|i| [idx[0], idx[i], idx[i + 1]]).collect(),
        _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

/// Most texels a texture may have: 2^27 (a 16384 × 8192 image), what the decoder's 512 MiB
/// allows an RGBA image. A texel takes 12 bytes once converted, so this bounds a texture at
/// 1.5 GiB; a larger grey image is an error instead of a multi-GiB allocation.
const MAX_TEXELS: usize = 1 << 27;

/// Decodes glTF's image data to linear RGB (sRGB-decoding colour textures).
fn convert_image(data: &gltf::image::Data, srgb: bool) -> Result<Texture, String> {
    use gltf::image::Format;
    let (channels, bytes_per) = match data.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        Format::R32G32B32FLOAT => (3, 4),
        Format::R32G32B32A32FLOAT => (4, 4),
    };
    let n = data.width as usize * data.height as usize;
    if n > MAX_TEXELS {
        return Err(format!("{}×{} texels is more than cvtrace's limit of {MAX_TEXELS}", data.width, data.height));
    }
    if data.pixels.len() < n * channels * bytes_per {
        return Err("the decoded pixels are fewer than its size says".into());
    }
    let value = |i: usize| -> f32 {
        let b = &data.pixels[i * bytes_per..(i + 1) * bytes_per];
        match bytes_per {
            1 => b[0] as f32 / 255.0,
            2 => u16::from_ne_bytes([b[0], b[1]]) as f32 / 65535.0,
            _ => f32::from_ne_bytes([b[0], b[1], b[2], b[3]]),
        }
    };
    let decode = |v: f32| if srgb && bytes_per < 4 { srgb_to_linear(v) } else { v };
    let mut texels = Vec::new();
    texels.try_reserve_exact(n).map_err(|_| format!("cannot allocate {n} texels"))?;
    texels.extend((0..n).map(|p| {
        let c = |k: usize| decode(value(p * channels + k));
        match channels {
            1 | 2 => glam::Vec3::splat(c(0)),
            _ => glam::Vec3::new(c(0), c(1), c(2)),
        }
    }));
    Texture::new(data.width, data.height, texels).ok_or_else(|| format!("{}×{} is not a usable size", data.width, data.height))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::RenderDefaults;

    fn base64(data: &[u8]) -> String {
        const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for c in data.chunks(3) {
            let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
            for k in 0..4 {
                out.push(if k <= c.len() { T[(n >> (18 - 6 * k) & 63) as usize] as char } else { '=' });
            }
        }
        out
    }

    /// A floor quad and three lights: the point light (light 0) on two nodes, one of them under
    /// a translated, scaled parent; a spot (light 1) turned to face down; a sun (light 2) turned
    /// to shine along −X, under a scale. `spot` and `point_intensity` are spliced in.
    fn lights_gltf(spot: &str, point_intensity: &str, extras: &str) -> String {
        let mut buf = Vec::new();
        for p in [[-1f32, 0., 1.], [1., 0., 1.], [1., 0., -1.], [-1., 0., -1.]] {
            for c in p {
                buf.extend_from_slice(&c.to_le_bytes());
            }
        }
        for i in [0u16, 1, 2, 0, 2, 3] {
            buf.extend_from_slice(&i.to_le_bytes());
        }
        let h = std::f32::consts::FRAC_1_SQRT_2;
        format!(
            r#"{{
  "asset": {{"version": "2.0"{extras}}},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensionsRequired": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [
    {{"type": "point", "name": "bulb", "color": [1, 0.5, 0.25], "intensity": {point_intensity}, "range": 3}},
    {{"type": "spot", "intensity": 3, "spot": {spot}}},
    {{"type": "directional", "color": [1, 1, 0.5], "intensity": 2}}
  ]}}}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1, 3, 4, 5]}}],
  "nodes": [
    {{"mesh": 0}},
    {{"translation": [1, 2, 3], "scale": [2, 2, 2], "children": [2]}},
    {{"translation": [0, 1, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
    {{"translation": [-4, 0, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
    {{"translation": [0, 5, 0], "rotation": [-{h}, 0, 0, {h}], "extensions": {{"KHR_lights_punctual": {{"light": 1}}}}}},
    {{"rotation": [0, {h}, 0, {h}], "scale": [3, 3, 3], "extensions": {{"KHR_lights_punctual": {{"light": 2}}}}}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, -1], "max": [1, 0, 1]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
            base64(&buf)
        )
    }

    #[test]
    fn punctual_lights_are_placed_by_their_node_instances() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lights.gltf");
        std::fs::write(&path, lights_gltf(r#"{"innerConeAngle": 0.2, "outerConeAngle": 0.5}"#, "8", "")).unwrap();
        let scene = Scene::load(&path).unwrap();
        let lights = scene.lights().punctual();
        assert_eq!(lights.len(), 4, "{lights:?}");
        let near = |a: Vec3A, b: Vec3A| (a - b).length() < 1e-5;
        let i = Vec3A::new(8.0, 4.0, 2.0);
        match &lights[0] {
            Punctual::Point { position, intensity } => {
                assert!(near(*position, Vec3A::new(1.0, 4.0, 3.0)) && *intensity == i, "{:?}", lights[0])
            }
            l => panic!("{l:?}"),
        }
        match &lights[1] {
            Punctual::Point { position, intensity } => assert!(near(*position, Vec3A::new(-4.0, 0.0, 0.0)) && *intensity == i),
            l => panic!("{l:?}"),
        }
        match &lights[2] {
            Punctual::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                assert!(near(*position, Vec3A::new(0.0, 5.0, 0.0)) && near(*direction, Vec3A::NEG_Y), "{:?}", lights[2]);
                assert_eq!(*intensity, Vec3A::splat(3.0));
                assert!((cos_inner - 0.2f32.cos()).abs() < 1e-6 && (cos_outer - 0.5f32.cos()).abs() < 1e-6);
            }
            l => panic!("{l:?}"),
        }
        match &lights[3] {
            Punctual::Directional { direction, irradiance } => {
                assert!(near(*direction, Vec3A::NEG_X), "{direction}");
                assert_eq!(*irradiance, Vec3A::new(2.0, 2.0, 1.0));
            }
            l => panic!("{l:?}"),
        }
        assert_eq!(scene.lights().len(), 4, "four lights, no emissive triangles");
        assert!(scene.lights().environment().is_none());
        assert_eq!(*scene.render_defaults(), RenderDefaults::default());
    }

    #[test]
    fn bad_lights_are_errors_naming_the_file_and_the_light() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.gltf");
        for (spot, intensity, needle) in [
            (r#"{"innerConeAngle": 0.6, "outerConeAngle": 0.5}"#, "8", "light 1"),
            (r#"{"innerConeAngle": 0.1, "outerConeAngle": 2.0}"#, "8", "light 1"),
            (r#"{"innerConeAngle": 0.1, "outerConeAngle": 0.5}"#, "-1", "light 0 `bulb`"),
        ] {
            std::fs::write(&path, lights_gltf(spot, intensity, "")).unwrap();
            let e = Scene::load(&path).unwrap_err().to_string();
            assert!(e.contains("bad.gltf") && e.contains(needle), "{e}");
        }
    }

    #[test]
    fn invalid_files_are_errors_naming_the_file_and_the_problem() {
        // Each case mutates the valid lights scene at JSON pointers. Before these checks the
        // first two panicked inside the gltf crate, the cycle hung, and the rest rendered a
        // silently wrong image.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.gltf");
        let spot = r#"{"innerConeAngle": 0.2, "outerConeAngle": 0.5}"#;
        let valid: gltf::json::Value = gltf::json::deserialize::from_str(&lights_gltf(spot, "8", "")).unwrap();
        let v = |s: &str| -> gltf::json::Value { gltf::json::deserialize::from_str(s).unwrap() };
        let cases: &[(&[(&str, &str)], &str)] = &[
            (&[("/meshes/0/primitives/0/attributes/POSITION", "99")], "POSITION refers to accessor 99 but there are 2"),
            (&[("/images", r#"[{"bufferView": 0}]"#)], "image 0 is stored in a buffer view and needs a mimeType"),
            (&[("/accessors/1/componentType", "5120")], "indices accessor 1 is Scalar I8"),
            (&[("/accessors/0/type", r#""VEC2""#)], "POSITION accessor 0 is Vec2 F32"),
            (&[("/accessors/1/count", "0")], "accessor 1 has count 0"),
            // Sparse indices 0, 1, 2, 0 (the index buffer read as sparse indices): not increasing.
            (
                &[(
                    "/accessors/0/sparse",
                    r#"{"count": 4, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 0}}"#,
                )],
                "sparse accessor 0: index 0 at position 3",
            ),
            (&[("/accessors/1/count", "5")], "5 indices (not a multiple of 3)"),
            (&[("/asset/version", r#""1.0""#)], "asset.version"),
            (&[("/nodes/0/children", "[1]")], "node 1 is reached twice"),
            (&[("/nodes/0/translation", "[1e20, 0, 0]")], "farther than 1e15"),
            (
                &[("/cameras", r#"[{"type": "perspective", "perspective": {"yfov": 0, "znear": 0.1}}]"#), ("/nodes/3/camera", "0")],
                "camera 0",
            ),
            (
                &[
                    ("/materials", r#"[{"pbrMetallicRoughness": {"baseColorFactor": [2, 1, 1, 1]}}]"#),
                    ("/meshes/0/primitives/0/material", "0"),
                ],
                "baseColorFactor is outside",
            ),
            (
                &[("/materials", r#"[{"emissiveFactor": [-1, 0, 0]}]"#), ("/meshes/0/primitives/0/material", "0")],
                "emissiveFactor is outside",
            ),
            // Found by fuzzing the scene input: the first panicked in the gltf crate (image.rs),
            // the next two tripped its assertions inside the loader's catch_unwind (which
            // printed a panic and blamed "an accessor or buffer view"), the last two silently
            // referred to node 1 and accessor 0 (the crate keeps an index's low 32 bits).
            (&[("/images", r#"[{"name": "no source"}]"#)], "image 0 has neither a uri nor a bufferView"),
            (&[("/bufferViews/0/byteStride", "4")], "accessor 0 has elements of 12 bytes but its buffer view 0 has byteStride 4"),
            (
                &[("/cameras", r#"[{"type": "orthographic", "perspective": {"yfov": 0.5, "znear": 0.1}}]"#), ("/nodes/3/camera", "0")],
                "camera 0 is of type orthographic but has no `orthographic` object",
            ),
            (&[("/scenes/0/nodes/1", "4294967297")], "/scenes/0/nodes/1: index 4294967297 does not fit in 32 bits"),
            (&[("/meshes/0/primitives/0/attributes/POSITION", "4294967296")], "index 4294967296 does not fit in 32 bits"),
        ];
        for (edits, needle) in cases {
            let mut json = valid.clone();
            for (pointer, value) in *edits {
                let (parent, key) = pointer.rsplit_once('/').unwrap();
                let target = json.pointer_mut(parent).unwrap_or_else(|| panic!("{parent}"));
                match target {
                    gltf::json::Value::Array(items) => items[key.parse::<usize>().unwrap()] = v(value),
                    _ => _ = target.as_object_mut().unwrap().insert(key.to_string(), v(value)),
                }
            }
            std::fs::write(&path, json.to_string()).unwrap();
            let e = Scene::load(&path).expect_err(needle).to_string();
            assert!(e.contains("bad.gltf") && e.contains(needle), "{edits:?}: {e}");
        }
        // The device guard: a scene path that is not a regular file fails at once.
        let e = Scene::load(dir.path()).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
    }

    #[test]
    fn the_sidecar_adds_the_environment_and_render_defaults() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.gltf");
        let spot = r#"{"innerConeAngle": 0.2, "outerConeAngle": 0.5}"#;
        // Without a sidecar, the glTF's size hint is the default size.
        std::fs::write(&path, lights_gltf(spot, "8", r#", "extras": {"defaultResolution": [300, 200]}"#)).unwrap();
        let s = Scene::load(&path).unwrap();
        assert_eq!((s.render_defaults().width, s.render_defaults().height), (Some(300), Some(200)));
        // The sidecar's size wins over the hint.
        let sidecar = dir.path().join("scene.cvtrace.toml");
        std::fs::write(
            &sidecar,
            "[render]
width = 320
height = 180
reference_spp = 512

[environment]
color = [0.5, 0.5, 1]
",
        )
        .unwrap();
        let s = Scene::load(&path).unwrap();
        let d = s.render_defaults();
        assert_eq!((d.width, d.height, d.reference_spp, d.spp), (Some(320), Some(180), Some(512), None));
        assert_eq!(s.lights().environment().unwrap().eval(Vec3A::Y), Vec3A::new(0.5, 0.5, 1.0));
        assert_eq!(s.lights().len(), 5);
        // A broken sidecar fails the load, naming itself.
        std::fs::write(
            &sidecar,
            "[render]
width = 320
[environment]
colour = [1, 1, 1]
",
        )
        .unwrap();
        let e = Scene::load(&path).unwrap_err().to_string();
        assert!(e.contains("scene.cvtrace.toml") && e.contains("colour") && e.contains("line 4"), "{e}");
    }

    #[test]
    fn textures_beyond_the_texel_limit_are_errors() {
        // A 20000² grey PNG (400 MB decoded, within the decoder's limit) became a 4.8 GB texel
        // array and aborted on allocation failure.
        let data = gltf::image::Data { pixels: vec![], format: gltf::image::Format::R8, width: 16384, height: 8193 };
        let e = convert_image(&data, true).unwrap_err();
        assert!(e.contains("16384×8193") && e.contains("limit"), "{e}");
        let data = gltf::image::Data { pixels: vec![0, 128, 255, 7], format: gltf::image::Format::R8G8, width: 2, height: 1 };
        assert_eq!(convert_image(&data, false).unwrap().texels, vec![glam::Vec3::ZERO, glam::Vec3::splat(1.0)]);
        let short = gltf::image::Data { pixels: vec![0; 3], format: gltf::image::Format::R8G8, width: 2, height: 1 };
        assert!(convert_image(&short, false).is_err());
    }

    #[test]
    fn uri_decoding_and_triangulation() {
        assert_eq!(decode_uri("my%20mesh.bin").as_deref(), Some("my mesh.bin"));
        assert_eq!(decode_uri("100%").as_deref(), Some("100%"));
        assert_eq!(decode_uri("%C3%A9%4G%").as_deref(), Some("é%4G%"));
        assert_eq!(decode_uri("scene%FF.bin"), None);
        assert_eq!(triangulate(gltf::mesh::Mode::TriangleStrip, &[0, 1, 2, 3]), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(triangulate(gltf::mesh::Mode::TriangleFan, &[0, 1, 2, 3]), vec![[0, 1, 2], [0, 2, 3]]);
    }
}

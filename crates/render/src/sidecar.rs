//! The scene sidecar file `<stem>.cvtrace.toml` next to `<stem>.gltf`/`.glb`: what glTF
//! cannot express (the environment light) and the scene's render defaults. The format is in
//! docs/scene-format.md. Every key is optional; unknown keys are errors (a misspelt key would
//! otherwise be silently ignored), and every error names the sidecar file — TOML syntax and
//! type errors also give the line.
use crate::lights::Environment;
use crate::render::MAX_IMAGE_SIDE;
use crate::scene::SceneError;
use cvtrace_streams::input_file::{regular_file, NotAFile};
use glam::Vec3A;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Render settings a scene asks for; command-line flags override them. `None` = not given.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDefaults {
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Samples per pixel of each stream of `cvtrace render`.
    pub spp: Option<u32>,
    /// Mitsuba's convention: −1 unlimited, else at least 1.
    pub max_depth: Option<i32>,
    pub rr_depth: Option<u32>,
    /// Samples per pixel of reference renders (`render --reference`, `study`).
    pub reference_spp: Option<u32>,
}

impl RenderDefaults {
    /// Checks ranges; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if let Some(v) = v {
                if v == 0 || v > MAX_IMAGE_SIDE {
                    return Err(format!("[render] {key} = {v}: must be between 1 and {MAX_IMAGE_SIDE}"));
                }
            }
        }
        for (key, v) in [("spp", self.spp), ("reference_spp", self.reference_spp)] {
            if v == Some(0) {
                return Err(format!("[render] {key} = 0: must be at least 1"));
            }
        }
        if let Some(d) = self.max_depth {
            if d < -1 || d == 0 {
                return Err(format!("[render] max_depth = {d}: must be -1 (unlimited) or at least 1"));
            }
        }
        Ok(())
    }
}

/// The `[environment]` table.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSpec {
    /// Constant radiance, linear RGB.
    pub color: Option<[f32; 3]>,
    /// A lat-long OpenEXR map, relative to the sidecar's folder.
    pub map: Option<PathBuf>,
    /// Multiplies `color` or `map` (default 1).
    pub strength: Option<f32>,
    /// Degrees about +Y (default 0).
    pub rotation: Option<f32>,
}

/// A parsed and checked sidecar file.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sidecar {
    #[serde(default)]
    pub render: RenderDefaults,
    pub environment: Option<EnvironmentSpec>,
    /// Where it was read from (map paths are relative to its folder).
    #[serde(skip)]
    pub path: PathBuf,
}

/// Largest sidecar file read.
pub const MAX_SIDECAR_BYTES: u64 = 1 << 20;

/// `dir/scene.gltf` → `dir/scene.cvtrace.toml`.
pub fn sidecar_path(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    scene.with_file_name(format!("{stem}.cvtrace.toml"))
}

impl Sidecar {
    /// Parses and checks `text` as the sidecar at `path` (used in errors and to resolve `map`).
    pub fn parse(text: &str, path: &Path) -> Result<Sidecar, SceneError> {
        let invalid = |m: String| SceneError::invalid(path, m);
        let mut s: Sidecar = toml::from_str(text).map_err(|e| invalid(e.to_string().trim_end().to_string()))?;
        s.path = path.to_path_buf();
        s.render.validate().map_err(invalid)?;
        if let Some(env) = &s.environment {
            match (env.color, &env.map) {
                (Some(_), Some(_)) => return Err(invalid("[environment] has both `color` and `map`; give one".into())),
                (None, None) => return Err(invalid("[environment] needs `color` or `map`".into())),
                _ => {}
            }
            if let Some(c) = env.color {
                if !c.iter().all(|v| v.is_finite() && *v >= 0.0) {
                    return Err(invalid(format!("[environment] color = {c:?}: components must be finite and non-negative")));
                }
            }
            if let Some(k) = env.strength {
                if !(k.is_finite() && k >= 0.0) {
                    return Err(invalid(format!("[environment] strength = {k}: must be finite and non-negative")));
                }
            }
            if let Some(r) = env.rotation {
                if !r.is_finite() {
                    return Err(invalid(format!("[environment] rotation = {r}: must be finite")));
                }
            }
            if let Some(file) = s.map_path() {
                // A FIFO would block the read forever, a device never end it.
                if let Err(e) = regular_file(&file) {
                    return Err(SceneError::MissingFile { path: path.to_path_buf(), file, message: e.to_string() });
                }
            }
        }
        Ok(s)
    }

    /// Reads and checks the sidecar at `path`, which must be a regular file of at most
    /// [`MAX_SIDECAR_BYTES`] (a FIFO would block the read forever, a device never end it).
    pub fn load(path: &Path) -> Result<Sidecar, SceneError> {
        use std::io::Read;
        let io = |e: std::io::Error| SceneError::Io { path: path.to_path_buf(), error: e };
        let len = regular_file(path).map_err(|e| match e {
            NotAFile::Io(e) => io(e),
            other => SceneError::invalid(path, other.to_string()),
        })?;
        if len > MAX_SIDECAR_BYTES {
            return Err(SceneError::invalid(path, format!("is {len} bytes; a sidecar may have at most {MAX_SIDECAR_BYTES}")));
        }
        let mut text = String::new();
        std::fs::File::open(path).and_then(|f| f.take(MAX_SIDECAR_BYTES + 1).read_to_string(&mut text)).map_err(io)?;
        Sidecar::parse(&text, path)
    }

    /// The sidecar of the scene file `scene`, if there is one.
    pub fn discover(scene: &Path) -> Result<Option<Sidecar>, SceneError> {
        let path = sidecar_path(scene);
        // A dangling symbolic link is a sidecar that cannot be read, not a missing one.
        if std::fs::symlink_metadata(&path).is_err() {
            return Ok(None);
        }
        tracing::info!("using sidecar {}", path.display());
        Sidecar::load(&path).map(Some)
    }

    /// The environment map's path, resolved against the sidecar's folder.
    pub fn map_path(&self) -> Option<PathBuf> {
        let map = self.environment.as_ref()?.map.as_ref()?;
        let dir = self.path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        Some(dir.join(map))
    }

    /// Builds the environment light (reading the map); `None` without an `[environment]`.
    pub fn environment(&self) -> Result<Option<Environment>, SceneError> {
        let Some(spec) = &self.environment else { return Ok(None) };
        let invalid = |m: String| SceneError::invalid(&self.path, m);
        let strength = spec.strength.unwrap_or(1.0);
        let env = match (spec.color, self.map_path()) {
            (Some(c), _) => Environment::constant(Vec3A::from_array(c) * strength).map_err(invalid)?,
            (None, Some(file)) => {
                let image = cvtrace_streams::exr_io::read_rgb(&file).map_err(|e| invalid(format!("environment map: {e}")))?;
                Environment::from_image(&image, strength).map_err(|m| invalid(format!("environment map {}: {m}", file.display())))?
            }
            (None, None) => return Err(invalid("[environment] needs `color` or `map`".into())),
        };
        env.rotated(spec.rotation.unwrap_or(0.0)).map(Some).map_err(invalid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Sidecar, String> {
        Sidecar::parse(text, Path::new("scenes/x/scene.cvtrace.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn a_full_file_parses() {
        let s = parse(
            "[render]\nwidth = 320\nheight = 180\nspp = 96\nmax_depth = -1\nrr_depth = 5\nreference_spp = 8192\n\n\
             [environment]\ncolor = [0.6, 0.7, 1.0]\nstrength = 2.0\nrotation = 30.0\n",
        )
        .unwrap();
        assert_eq!(
            s.render,
            RenderDefaults {
                width: Some(320),
                height: Some(180),
                spp: Some(96),
                max_depth: Some(-1),
                rr_depth: Some(5),
                reference_spp: Some(8192)
            }
        );
        let env = s.environment().unwrap().unwrap();
        assert!((env.eval(Vec3A::Y) - Vec3A::new(1.2, 1.4, 2.0)).length() < 1e-6);
        // Everything is optional.
        assert_eq!(parse("").unwrap().render, RenderDefaults::default());
        assert!(parse("[render]\nspp = 4\n").unwrap().environment.is_none());
        assert_eq!(sidecar_path(Path::new("a/b/scene.gltf")), Path::new("a/b/scene.cvtrace.toml"));
        assert_eq!(sidecar_path(Path::new("m.glb")), Path::new("m.cvtrace.toml"));
    }

    #[test]
    fn bad_files_give_clear_errors_naming_the_file() {
        let cases: [(&str, &[&str]); 10] = [
            ("[render]\nwidth = 320\nheight = = 4\n", &["scene.cvtrace.toml", "line 3"]),
            ("[render]\nwidht = 320\n", &["scene.cvtrace.toml", "widht", "line 2"]),
            ("[renderer]\nwidth = 320\n", &["renderer"]),
            ("[render]\nwidth = 0\n", &["width = 0", "between 1"]),
            ("[render]\nwidth = -5\n", &["line 2", "-5"]),
            ("[render]\nmax_depth = 0\n", &["max_depth = 0"]),
            ("[environment]\ncolor = [1, 1, 1]\nmap = \"sky.exr\"\n", &["both `color` and `map`"]),
            ("[environment]\ncolor = [1, -0.5, 1]\n", &["color", "non-negative"]),
            ("[environment]\ncolor = [1, 1, 1]\nstrength = -1\n", &["strength = -1"]),
            ("[environment]\nmap = \"no-such-sky.exr\"\n", &["scene.cvtrace.toml", "no-such-sky.exr"]),
        ];
        for (text, needles) in cases {
            let e = parse(text).expect_err(text);
            for n in needles {
                assert!(e.contains(n), "error for {text:?} lacks {n:?}: {e}");
            }
        }
        assert!(parse("[environment]\nstrength = 2\n").unwrap_err().contains("needs `color` or `map`"));
    }

    #[test]
    fn maps_load_relative_to_the_sidecar_and_bad_texels_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let img = cvtrace_streams::Image::from_fn(8, 4, |x, _| [x as f32, 1.0, 1.0]);
        cvtrace_streams::exr_io::write_rgb(&dir.path().join("sky.exr"), &img, &[], false).unwrap();
        let path = dir.path().join("scene.cvtrace.toml");
        std::fs::write(&path, "[environment]\nmap = \"sky.exr\"\nstrength = 0.5\n").unwrap();
        let s = Sidecar::discover(&dir.path().join("scene.gltf")).unwrap().unwrap();
        let env = s.environment().unwrap().unwrap();
        // Direction −Z is the centre column (u = 0.5 → x = 4).
        assert_eq!(env.eval(Vec3A::NEG_Z), Vec3A::new(2.0, 0.5, 0.5));
        let mut bad = img.clone();
        bad.pixels[5][2] = -3.0;
        cvtrace_streams::exr_io::write_rgb(&dir.path().join("sky.exr"), &bad, &[], true).unwrap();
        let e = Sidecar::load(&path).unwrap().environment().unwrap_err().to_string();
        assert!(e.contains("scene.cvtrace.toml") && e.contains("sky.exr") && e.contains("texel (5, 0)"), "{e}");
        std::fs::write(dir.path().join("sky.exr"), b"not an exr").unwrap();
        let e = Sidecar::load(&path).unwrap().environment().unwrap_err().to_string();
        assert!(e.contains("sky.exr"), "{e}");
        assert!(Sidecar::discover(&dir.path().join("other.gltf")).unwrap().is_none());
    }
}

//! The scene sidecar file `<stem>.cvtrace.toml` next to `<stem>.gltf`/`.glb`: what glTF
//! cannot express (the environment light) and the scene's render defaults. The format is in
//! docs/scene-format.md. Every key is optional; unknown keys are errors (a misspelt key would
//! otherwise be silently ignored), and every error names the sidecar file — TOML syntax and
//! type errors also give the line.
use crate::scene::error::SceneError;
use crate::scene::lights::Environment;
use crate::settings::{RenderDefaults, MAX_IMAGE_SIDE, MAX_RR_DEPTH, MAX_SPP};
use cvtrace_streams::input_file::{regular_file, NotAFile};
use glam::Vec3A;
use serde::Deserialize;
use std::path::{Path, PathBuf};

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

/// A `-D key=value` override of one sidecar setting, as `mitsuba -D spp=64`: it replaces the
/// sidecar's value (or stands in for a missing sidecar); command-line flags still win over it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Define {
    pub key: String,
    pub value: String,
}

/// The keys `-D` accepts: the sidecar's, `[render]` ones also without their table name.
pub const DEFINE_KEYS: [&str; 10] = [
    "width",
    "height",
    "spp",
    "max_depth",
    "rr_depth",
    "reference_spp",
    "environment.color",
    "environment.map",
    "environment.strength",
    "environment.rotation",
];

impl std::str::FromStr for Define {
    type Err = String;

    fn from_str(s: &str) -> Result<Define, String> {
        match s.split_once('=') {
            Some((key, value)) if !key.trim().is_empty() => Ok(Define { key: key.trim().to_string(), value: value.trim().to_string() }),
            _ => Err(format!("{s:?}: expected KEY=VALUE, e.g. -D max_depth=8 (keys: {})", DEFINE_KEYS.join(", "))),
        }
    }
}

impl std::fmt::Display for Define {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}={}", self.key, self.value)
    }
}

impl Define {
    /// The key as in [`DEFINE_KEYS`] (`render.width` → `width`), if it is one.
    pub fn canonical_key(&self) -> Option<&'static str> {
        let key = self.key.strip_prefix("render.").unwrap_or(&self.key);
        DEFINE_KEYS.iter().copied().find(|k| *k == key)
    }

    fn error(&self, message: impl Into<String>) -> SceneError {
        SceneError::Define { define: self.to_string(), message: message.into() }
    }

    fn number<T: std::str::FromStr>(&self, what: &str) -> Result<T, SceneError> {
        self.value.parse().map_err(|_| self.error(format!("{:?} is not {what}", self.value)))
    }

    /// A whole number in `lo..=hi`: one outside is out of range (whatever type would hold it),
    /// not "not a whole number".
    fn whole<T: TryFrom<i128>>(&self, what: &str, lo: i128, hi: i128) -> Result<T, SceneError> {
        let v: i128 = self.value.parse().map_err(|_| self.error(format!("{:?} is not {what}", self.value)))?;
        if !(lo..=hi).contains(&v) {
            let key = self.canonical_key().unwrap_or_default();
            return Err(self.error(format!("{v} is out of range: {key} must be between {lo} and {hi}")));
        }
        T::try_from(v).map_err(|_| self.error(format!("{v} is out of range")))
    }
}

/// Checks every define's key (before the scene is read, so a typo fails at once).
pub fn check_define_keys(defines: &[Define]) -> Result<(), SceneError> {
    for d in defines {
        if d.canonical_key().is_none() {
            return Err(d.error(format!("no such setting; the keys are {}", DEFINE_KEYS.join(", "))));
        }
    }
    Ok(())
}

impl Sidecar {
    /// The sidecar with `defines` applied in order and checked as a file's values are. Giving
    /// one side of the image only (`-D width=64`) takes the other from the camera's aspect, as
    /// `--width` alone does; a new `environment.color` replaces a map and the other way round.
    pub fn with_defines(mut self, defines: &[Define]) -> Result<Sidecar, SceneError> {
        check_define_keys(defines)?;
        let sides: Vec<&str> = defines.iter().filter_map(Define::canonical_key).filter(|k| matches!(*k, "width" | "height")).collect();
        if !sides.is_empty() {
            if !sides.contains(&"width") {
                self.render.width = None;
            }
            if !sides.contains(&"height") {
                self.render.height = None;
            }
        }
        for d in defines {
            let key = d.canonical_key().unwrap_or_default();
            let whole = "a whole number";
            let (side, spp) = (MAX_IMAGE_SIDE as i128, MAX_SPP as i128);
            let r = &mut self.render;
            match key {
                "width" => r.width = Some(d.whole(whole, 1, side)?),
                "height" => r.height = Some(d.whole(whole, 1, side)?),
                "spp" => r.spp = Some(d.whole(whole, 1, spp)?),
                "rr_depth" => r.rr_depth = Some(d.whole(whole, 0, MAX_RR_DEPTH as i128)?),
                "reference_spp" => r.reference_spp = Some(d.whole(whole, 1, spp)?),
                "max_depth" => r.max_depth = Some(d.whole("a whole number (-1 for unlimited)", -1, i32::MAX as i128)?),
                _ => {
                    let env = self.environment.get_or_insert_with(EnvironmentSpec::default);
                    match key {
                        "environment.color" => {
                            env.color = Some(parse_color(&d.value).ok_or_else(|| {
                                d.error("expected linear RGB as r,g,b (e.g. 0.6,0.7,1.0) or one grey value, finite and non-negative")
                            })?);
                            env.map = None;
                        }
                        "environment.map" => {
                            // Relative to where the command runs, not to the sidecar's folder.
                            let file = std::path::absolute(&d.value).map_err(|e| d.error(e.to_string()))?;
                            if let Err(e) = regular_file(&file) {
                                return Err(d.error(format!("cannot read {}: {e}", file.display())));
                            }
                            env.map = Some(file);
                            env.color = None;
                        }
                        "environment.strength" => {
                            let k: f32 = d.number("a number")?;
                            if !(k.is_finite() && k >= 0.0) {
                                return Err(d.error("must be finite and non-negative"));
                            }
                            env.strength = Some(k);
                        }
                        _ => {
                            let r: f32 = d.number("a number of degrees")?;
                            if !r.is_finite() {
                                return Err(d.error("must be finite"));
                            }
                            env.rotation = Some(r);
                        }
                    }
                }
            }
            self.render.validate().map_err(|m| d.error(m))?;
        }
        if let Some(env) = &self.environment {
            if env.color.is_none() && env.map.is_none() {
                let given: Vec<String> = defines.iter().filter(|d| d.key.starts_with("environment.")).map(Define::to_string).collect();
                return Err(SceneError::Define {
                    define: given.join(" -D "),
                    message: "the scene has no environment light to change; give -D environment.color=r,g,b or -D environment.map=FILE too"
                        .into(),
                });
            }
        }
        Ok(self)
    }
}

/// `r,g,b` (brackets allowed, as in the sidecar) or one grey value.
fn parse_color(text: &str) -> Option<[f32; 3]> {
    let inner = text.trim().trim_start_matches('[').trim_end_matches(']');
    let v: Vec<f32> = inner.split(',').map(|x| x.trim().parse::<f32>()).collect::<Result<_, _>>().ok()?;
    let c = match v[..] {
        [g] => [g; 3],
        [r, g, b] => [r, g, b],
        _ => return None,
    };
    c.iter().all(|x| x.is_finite() && *x >= 0.0).then_some(c)
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

    fn define(s: &str) -> Define {
        s.parse().unwrap()
    }

    #[test]
    fn defines_override_the_sidecar_and_bad_ones_name_the_key() {
        let base = parse("[render]\nwidth = 320\nheight = 180\nmax_depth = -1\n\n[environment]\ncolor = [1, 1, 1]\n").unwrap();
        let s = base
            .clone()
            .with_defines(&[
                define("max_depth=8"),
                define("render.spp=16"),
                define("environment.strength=2.5"),
                define("environment.color=0.5"),
            ])
            .unwrap();
        assert_eq!((s.render.width, s.render.height, s.render.max_depth, s.render.spp), (Some(320), Some(180), Some(8), Some(16)));
        let env = s.environment().unwrap().unwrap();
        assert!((env.eval(Vec3A::Y) - Vec3A::splat(1.25)).length() < 1e-6);
        // One side alone keeps the camera's aspect, as --width does.
        let s = base.clone().with_defines(&[define("width=64")]).unwrap();
        assert_eq!((s.render.width, s.render.height), (Some(64), None));
        // No sidecar: the defines stand alone.
        let s = Sidecar::default().with_defines(&[define("environment.color=0.1,0.2,0.3")]).unwrap();
        assert_eq!(s.environment.unwrap().color, Some([0.1, 0.2, 0.3]));
        let cases: [(&str, &[&str]); 11] = [
            ("widht=64", &["-D widht=64", "no such setting", "width"]),
            ("width=abc", &["-D width=abc", "not a whole number"]),
            // Whole numbers too large (or negative) for the setting are out of range.
            ("spp=99999999999", &["-D spp=99999999999", "out of range", "between 1 and 2147483647"]),
            ("rr_depth=-2", &["-D rr_depth=-2", "out of range", "between 0 and"]),
            ("width=0", &["-D width=0", "between 1"]),
            ("max_depth=0", &["-D max_depth=0", "-1 (unlimited)"]),
            ("max_depth=x", &["-D max_depth=x", "whole number"]),
            ("environment.strength=-1", &["-D environment.strength=-1", "non-negative"]),
            ("environment.color=1,2", &["-D environment.color=1,2", "r,g,b"]),
            ("environment.rotation=nan", &["-D environment.rotation=nan", "finite"]),
            ("environment.map=no-such-sky.exr", &["-D environment.map=no-such-sky.exr", "no-such-sky.exr"]),
        ];
        for (text, needles) in cases {
            let e = base.clone().with_defines(&[define(text)]).expect_err(text).to_string();
            for n in needles {
                assert!(e.contains(n), "error for {text:?} lacks {n:?}: {e}");
            }
        }
        let e = Sidecar::default().with_defines(&[define("environment.strength=2")]).unwrap_err().to_string();
        assert!(e.contains("environment.strength=2") && e.contains("no environment light"), "{e}");
        assert!("novalue".parse::<Define>().unwrap_err().contains("KEY=VALUE"));
        assert!("=3".parse::<Define>().is_err());
    }
}

//! Flags that several commands take: what is rendered (size, camera, path length, traversal,
//! `-D` overrides), sample counts, parts, and the default batch count.
use anyhow::{bail, Context, Result};
use cvtrace_render::Define;
use cvtrace_session::{CameraView, RenderSession, SessionError, SessionOptions, Traversal, View};
use cvtrace_streams::parts::PartSpec;
use glam::Vec3A;
use std::path::Path;

/// `--traversal`, clap's view of [`Traversal`].
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TraversalArg {
    Robust,
    #[default]
    Fast,
}

impl From<TraversalArg> for Traversal {
    fn from(t: TraversalArg) -> Traversal {
        match t {
            TraversalArg::Robust => Traversal::Robust,
            TraversalArg::Fast => Traversal::Fast,
        }
    }
}

/// What is rendered, shared by `render`, `study` and `farm`: image size, camera, path-length
/// limits. Unset values come from the scene's sidecar, then the glTF, then built-in defaults.
#[derive(clap::Args, Debug, Clone)]
pub struct ViewArgs {
    /// Image width [default: the scene's (sidecar, else the glTF's defaultResolution), else 256;
    /// with only --height given, from the camera's aspect ratio].
    #[arg(long, value_parser = side_parser(), allow_hyphen_values = true)]
    pub width: Option<u32>,
    /// Image height [default: the scene's, else from the width and the camera's aspect ratio].
    #[arg(long, value_parser = side_parser(), allow_hyphen_values = true)]
    pub height: Option<u32>,
    /// Longest path in segments from the camera (Mitsuba convention), -1 for unlimited
    /// [default: the sidecar's max_depth, else -1].
    #[arg(long, allow_negative_numbers = true)]
    pub max_depth: Option<i32>,
    /// Path depth at which Russian roulette starts [default: the sidecar's rr_depth, else 5].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=i32::MAX as i64), allow_hyphen_values = true)]
    pub rr_depth: Option<u32>,
    /// Override the scene camera: "ex,ey,ez:tx,ty,tz:vfov_degrees" (eye, target, vertical FOV; up stays).
    #[arg(long, value_name = "EYE:TARGET:FOV")]
    pub camera: Option<String>,
    /// Embree traversal: `robust` is watertight where triangles share an edge; `fast` (Embree's
    /// and Mitsuba 3's default) is quicker but lets rays that graze a shared edge through
    /// (docs/performance.md has both figures).
    #[arg(long, value_enum, default_value_t = TraversalArg::Fast)]
    pub traversal: TraversalArg,
    /// Override a setting of the scene's sidecar, as `mitsuba -D spp=64`; repeatable. Keys:
    /// width, height, spp, max_depth, rr_depth, reference_spp, environment.color (r,g,b),
    /// environment.map (an EXR, relative to the current folder), environment.strength,
    /// environment.rotation (degrees). A flag wins over -D of the same setting (--width over
    /// -D width).
    #[arg(short = 'D', value_name = "KEY=VALUE", value_parser = parse_define)]
    pub define: Vec<Define>,
}

impl ViewArgs {
    /// Size and path limits as a session job takes them.
    pub fn view(&self) -> View {
        View { width: self.width, height: self.height, max_depth: self.max_depth, rr_depth: self.rr_depth }
    }

    /// The value of the last `-D KEY=…` whose key is `key`, if it parses (a bad one is
    /// reported, naming it, when the scene loads).
    pub fn defined<T: std::str::FromStr>(&self, key: &str) -> Option<T> {
        self.define.iter().rev().find(|d| d.canonical_key() == Some(key)).and_then(|d| d.value.parse().ok())
    }

    /// The camera override, traversal and `-D` overrides, for a [`RenderSession`].
    pub fn session_options(&self) -> Result<SessionOptions> {
        cvtrace_render::scene::sidecar::check_define_keys(&self.define)?;
        Ok(SessionOptions {
            camera: self.camera.as_deref().map(parse_camera).transpose()?,
            traversal: self.traversal.into(),
            defines: self.define.clone(),
        })
    }

    /// A session on `scene` with these options, naming the flag when the camera override is
    /// unusable.
    pub fn open_session(&self, scene: &Path) -> Result<RenderSession> {
        RenderSession::new(scene, &self.session_options()?).map_err(|e| match e {
            SessionError::Camera(m) => anyhow::anyhow!("--camera: {m}"),
            e => e.into(),
        })
    }
}

/// The batch count when `--batches` is not given: the most of 16, 8, 4, 2, 1 that divides
/// every spp value ([`cvtrace_session::default_batches`]), logged when it is not the default.
pub fn default_batches(spps: &[u32]) -> u32 {
    let b = cvtrace_session::default_batches(spps);
    if b != cvtrace_session::DEFAULT_BATCHES {
        let list = spps.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
        tracing::info!("--batches not given: {b} batches, the most of 16, 8, 4, 2, 1 that divide --spp {list}");
    }
    b
}

fn parse_define(s: &str) -> Result<Define, String> {
    s.parse()
}

/// `--part I/N`.
pub fn parse_part(s: &str) -> Result<PartSpec, String> {
    s.parse()
}

/// Eye, target and vertical field of view from `--camera`. A value in the right format that
/// is no finite number is named as such.
fn parse_camera(s: &str) -> Result<CameraView> {
    let usage = "expected --camera \"ex,ey,ez:tx,ty,tz:vfov\", e.g. \"278,273,-800:278,273,0:37\"";
    let parts: Vec<&str> = s.split(':').collect();
    if parts.len() != 3 {
        bail!("--camera {s:?}: {usage}");
    }
    let number = |text: &str, what: &str| -> Result<f32> {
        let v: f32 = text.trim().parse().with_context(|| format!("--camera {s:?}: {usage}"))?;
        if !v.is_finite() {
            bail!("--camera {s:?}: the {what} {:?} is not a finite number", text.trim());
        }
        Ok(v)
    };
    let vec3 = |p: &str, what: &str| -> Result<Vec3A> {
        let texts: Vec<&str> = p.split(',').collect();
        if texts.len() != 3 {
            bail!("--camera {s:?}: {usage}");
        }
        let mut v = [0.0f32; 3];
        for ((c, text), axis) in v.iter_mut().zip(&texts).zip(["x", "y", "z"]) {
            *c = number(text, &format!("{what}'s {axis}"))?;
        }
        Ok(Vec3A::from_array(v))
    };
    let (eye, target) = (vec3(parts[0], "eye")?, vec3(parts[1], "target")?);
    Ok(CameraView { eye, target, vfov_deg: number(parts[2], "field of view")? })
}

/// Sample counts on the command line: 1 up to what a file records (an EXR `int`), with the
/// range in clap's own error, and `-8` taken as the (refused) value it is rather than a flag
/// (each such flag also allows hyphen values).
pub fn spp_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=cvtrace_render::settings::MAX_SPP as i64)
}

/// An image side: 1 to the largest the renderer takes.
pub fn side_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=cvtrace_render::settings::MAX_IMAGE_SIDE as i64)
}

/// A batch count: 1 to what the stream file numbers.
pub fn batches_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=cvtrace_render::settings::MAX_BATCHES as i64)
}

/// A count with no limit of its own but 1 (parts; the passes to stop after).
pub fn count_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=u32::MAX as i64)
}

/// A seed: any 64-bit unsigned number; a negative one is out of range in the words clap uses
/// for the other counts.
pub fn parse_seed(s: &str) -> Result<u64, String> {
    match (s.trim().parse::<u64>(), s.trim().parse::<i128>()) {
        (Ok(v), _) => Ok(v),
        (Err(_), Ok(_)) => Err(format!("{} is not in 0..={}", s.trim(), u64::MAX)),
        (Err(e), Err(_)) => Err(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_flag_parses_and_rejects_garbage() {
        let v = parse_camera("278,273,-800:278,273,0:37").unwrap();
        assert_eq!((v.eye, v.target, v.vfov_deg), (Vec3A::new(278.0, 273.0, -800.0), Vec3A::new(278.0, 273.0, 0.0), 37.0));
        for bad in ["1,2:3,4,5:6", "1,2,3:4,5,6", "a,b,c:1,2,3:4", "1,2,3:4,5,6:x", "1,2,3,4:5,6,7:8", "nan,0,0:1,1,1:30"] {
            assert!(parse_camera(bad).is_err(), "{bad}");
        }
        // The format is right: the value at fault is named, not the format repeated.
        let e = parse_camera("0,inf,0:1,1,1:30").unwrap_err().to_string();
        assert!(e.contains("eye's y \"inf\" is not a finite number") && !e.contains("expected"), "{e}");
        let e = parse_camera("0,0,0:1,1,1:NaN").unwrap_err().to_string();
        assert!(e.contains("field of view \"NaN\""), "{e}");
    }

    #[test]
    fn seeds_take_every_u64_and_name_the_range_of_negative_ones() {
        assert_eq!(parse_seed("18446744073709551615"), Ok(u64::MAX));
        assert_eq!(parse_seed("-1"), Err("-1 is not in 0..=18446744073709551615".into()));
        assert!(parse_seed("x").is_err() && parse_seed("18446744073709551616").is_err());
    }

    #[test]
    fn the_default_batch_count_divides_every_spp_value() {
        assert_eq!(default_batches(&[96]), 16);
        assert_eq!(default_batches(&[8, 12]), 4);
        assert_eq!(default_batches(&[7]), 1);
        assert_eq!(default_batches(&[]), 16);
    }
}

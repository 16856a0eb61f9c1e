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
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [default: the scene's, else from the width and the camera's aspect ratio].
    #[arg(long)]
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

/// Eye, target and vertical field of view from `--camera`.
fn parse_camera(s: &str) -> Result<CameraView> {
    let usage = "expected --camera \"ex,ey,ez:tx,ty,tz:vfov\", e.g. \"278,273,-800:278,273,0:37\"";
    let parts: Vec<&str> = s.split(':').collect();
    if parts.len() != 3 {
        bail!("--camera {s:?}: {usage}");
    }
    let vec3 = |p: &str| -> Result<Vec3A> {
        let v: Vec<f32> =
            p.split(',').map(|x| x.trim().parse::<f32>()).collect::<Result<_, _>>().with_context(|| format!("--camera {s:?}: {usage}"))?;
        match v[..] {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3A::new(x, y, z)),
            _ => bail!("--camera {s:?}: {usage}"),
        }
    };
    let vfov_deg: f32 = parts[2].trim().parse().with_context(|| format!("--camera {s:?}: {usage}"))?;
    Ok(CameraView { eye: vec3(parts[0])?, target: vec3(parts[1])?, vfov_deg })
}

/// Sample counts on the command line: 1 up to what a file records (an EXR `int`), with the
/// range in clap's own error, and `-8` taken as the (refused) value it is rather than a flag.
pub fn spp_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=cvtrace_render::settings::MAX_SPP as i64)
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
    }

    #[test]
    fn the_default_batch_count_divides_every_spp_value() {
        assert_eq!(default_batches(&[96]), 16);
        assert_eq!(default_batches(&[8, 12]), 4);
        assert_eq!(default_batches(&[7]), 1);
        assert_eq!(default_batches(&[]), 16);
    }
}

//! `cvtrace render`: a glTF scene → a PT/CRN stream file, or (`--reference`) a progressive,
//! resumable PT-only reference image.
//!
//! Everything that can be checked cheaply (flags, output path, scene) is checked before the
//! render starts, so a long render never fails at the end for a reason known at the start.
//! The render itself is a [`RenderSession`] job; this file parses the flags, shows progress
//! and reports.
//!
//! Settings not given as flags come from the scene's sidecar `<stem>.cvtrace.toml`
//! (`[render]`, docs/scene-format.md), then the glTF's `asset.extras.defaultResolution` (size
//! only), then the built-in defaults.
//! Outputs are written atomically: an error or interruption never leaves a partial file.
use anyhow::{bail, Context, Result};
use cvtrace::session::{
    self, CameraView, Job, Progress, ReferenceJob, ReferenceOutcome, RenderSession, SessionError, SessionOptions, StreamJob, View,
    DEFAULT_BATCHES, DEFAULT_WIDTH,
};
use cvtrace_render::{Define, RenderDefaults};
use cvtrace_streams::parts::PartSpec;
use glam::Vec3A;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::sync::OnceLock;

pub use cvtrace::session::Traversal;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// glTF 2.0 scene (.gltf with its buffers, or .glb).
    pub scene: PathBuf,
    /// Output: a stream file (e.g. cbox.streams.exr), or with --reference an RGB EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel of each stream (or of the reference) [default: the sidecar's `spp`, or
    /// `reference_spp` with --reference, else 64].
    #[arg(long, value_parser = spp_parser(), allow_hyphen_values = true)]
    pub spp: Option<u32>,
    /// Batches per stream (must divide --spp) [default: the most of 16, 8, 4, 2, 1 that divides
    /// --spp; 16 is the estimators' measured default, docs/estimators.md]. Not used with --reference.
    #[arg(long)]
    pub batches: Option<u32>,
    /// Random seed: the same seed and settings give bit-identical output.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Render a PT-only reference image, progressively, resumable from a checkpoint next to the output.
    #[arg(long)]
    pub reference: bool,
    /// With --reference: samples per pixel per pass; a checkpoint is saved after every pass.
    #[arg(long, default_value_t = 64, requires = "reference")]
    pub pass_spp: u32,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Also write an sRGB PNG preview of the image (the mean of both streams, or the reference).
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    /// With --reference: continue the finished reference at --output (same scene, seed and
    /// settings) up to --spp samples and replace it. The samples continue its sequence, so the
    /// result equals a one-shot render of --spp to f32 rounding (the file keeps means, not sums).
    #[arg(long, requires = "reference")]
    pub extend: bool,
    /// Render only part I of N (counted from 0) into a part file: a contiguous range of whole
    /// batches (or, with --reference, of whole passes of --pass-spp). `cvtrace merge` joins
    /// the N parts into exactly the file one render writes.
    #[arg(long, value_name = "I/N", value_parser = parse_part)]
    pub part: Option<PartSpec>,
    /// Testing aid: with --reference, stop (keeping the checkpoint) after this many passes.
    #[arg(long, hide = true, requires = "reference")]
    pub stop_after_passes: Option<u32>,
}

/// What is rendered, shared by `render` and `study`: image size, camera, path-length limits.
/// Unset values come from the scene (see the module doc).
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
    #[arg(long, value_enum, default_value_t = Traversal::Fast)]
    pub traversal: Traversal,
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
            traversal: self.traversal,
            defines: self.define.clone(),
        })
    }
}

/// A session on `scene` with `options`, naming the flag when the camera override is unusable.
pub fn open_session(scene: &std::path::Path, options: &SessionOptions) -> Result<RenderSession> {
    RenderSession::new(scene, options).map_err(|e| match e {
        SessionError::Camera(m) => anyhow::anyhow!("--camera: {m}"),
        e => e.into(),
    })
}

/// The batch count when `--batches` is not given: the largest of 16, 8, 4, 2, 1 that divides
/// `--spp` (16 where the count comes from the scene), so `render --spp 8` just works. A value
/// given that does not divide stays an error.
pub fn default_batches(spp: Option<u32>) -> u32 {
    let Some(n) = spp else { return DEFAULT_BATCHES };
    let b = [DEFAULT_BATCHES, 8, 4, 2, 1].into_iter().find(|b| n % b == 0).unwrap_or(1);
    if b != DEFAULT_BATCHES {
        tracing::info!("--batches not given: {b} batches, the most of 16, 8, 4, 2, 1 that divide --spp {n}");
    }
    b
}

pub fn run(args: RenderArgs) -> Result<()> {
    // Cheap checks first: flags, then whether the output can be written at all.
    let batches = match (args.reference, args.batches) {
        (true, Some(_)) => bail!("--batches does not apply to --reference renders (they have a single PT stream)"),
        (true, None) => 1,
        (false, Some(b)) => b,
        (false, None) => default_batches(args.spp.or(args.view.defined("spp"))),
    };
    if args.reference && args.pass_spp == 0 {
        bail!("--pass-spp must be at least 1");
    }
    if args.part.is_some() && args.preview.is_some() {
        bail!("--preview: a part has no finished image; preview the merged file");
    }
    if let Some(spec) = args.part {
        if !args.reference {
            // More parts than batches is refused before the scene loads.
            spec.range(batches, "batches")?;
        }
    }
    if args.stop_after_passes == Some(0) {
        bail!("--stop-after-passes 0: must be at least 1 (a reference stops after its last pass anyway)");
    }
    // The flags alone (scene defaults filled in after loading); a flag given is checked now.
    let view = args.view.view();
    let flag_size = (args.view.width.unwrap_or(DEFAULT_WIDTH), args.view.height.unwrap_or(DEFAULT_WIDTH));
    let mut provisional =
        session::resolve_settings(&view, args.spp, batches, args.seed, args.reference, &RenderDefaults::default(), flag_size);
    // Without --spp the count comes from the scene, so only --batches itself is checked here.
    provisional.spp = args.spp.unwrap_or(batches);
    provisional.validate()?;
    let options = args.view.session_options()?;
    let job = if args.reference {
        Job::Reference(ReferenceJob {
            output: args.output.clone(),
            view,
            spp: args.spp,
            seed: args.seed,
            pass_spp: args.pass_spp,
            overwrite: args.force,
            extend: args.extend,
            stop_after_passes: args.stop_after_passes,
            part: args.part,
            label: "a reference",
        })
    } else {
        Job::Streams(StreamJob {
            output: args.output.clone(),
            view,
            spp: args.spp,
            batches,
            seed: args.seed,
            overwrite: args.force,
            part: args.part,
        })
    };
    // Missing folders of the output are made, as `study` makes its own; taken back if the
    // render fails.
    if let Some(p) = &args.preview {
        cvtrace_streams::atomic::check_extension(p, "png")?;
        crate::cli::refuse_overwriting_inputs(p, &[&args.output, &args.scene])?;
    }
    let made = crate::cli::make_parent_folders(&args.output)?;
    let result = render_job(&args, &job, &options);
    if result.is_err() {
        crate::cli::remove_empty(&made);
    }
    result
}

fn render_job(args: &RenderArgs, job: &Job, options: &SessionOptions) -> Result<()> {
    job.check_outputs()?;
    if let Some(p) = &args.preview {
        cvtrace_streams::atomic::check_writable(p, args.force)?;
    }
    let session = open_session(&args.scene, options)?;
    let progress = TerminalProgress::default();
    match job {
        Job::Streams(j) => session.render_streams(j, &progress)?,
        Job::Reference(j) => {
            crate::cli::set_interrupt_note(format!(
                "the finished passes are kept in {}; run the same command again to resume",
                cvtrace_streams::checkpoint::checkpoint_path(&j.output).display()
            ));
            if let ReferenceOutcome::Stopped { passes, samples_done, spp } = session.render_reference(j, &progress)? {
                tracing::info!(
                    "stopped after {passes} passes as asked: {samples_done} of {spp} spp saved in {}",
                    cvtrace_streams::checkpoint::checkpoint_path(&j.output).display()
                );
                // No finished image to preview yet.
                return Ok(());
            }
        }
    }
    if let Some(p) = &args.preview {
        // The file's top-level R, G, B: a stream file's picture or the reference itself.
        let image = cvtrace_streams::exr_io::read_picture(job.output())?;
        cvtrace_streams::preview::write_png(p, &image, 0.0, args.force)?;
        tracing::info!("wrote {}", p.display());
    }
    Ok(())
}

/// A progress bar on stderr, drawn only when stderr is a terminal; one per render.
#[derive(Default)]
pub struct TerminalProgress {
    bar: OnceLock<ProgressBar>,
}

impl Progress for TerminalProgress {
    fn start(&self, total: u64, done: u64) {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        bar.set_style(progress_style_of(PROGRESS_TEMPLATE));
        bar.set_position(done);
        bar.reset_eta();
        let _ = self.bar.set(bar);
    }

    fn advance(&self, samples: u64) {
        if let Some(bar) = self.bar.get() {
            bar.inc(samples);
        }
    }

    fn suspend(&self, f: &mut dyn FnMut()) {
        match self.bar.get() {
            Some(bar) => bar.suspend(f),
            None => f(),
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.bar.get() {
            bar.finish_and_clear();
        }
    }
}

/// The render progress line: at most [`PROGRESS_COLUMNS`] wide whatever the numbers, with the
/// rate in millions of samples per second (what renderers quote).
pub const PROGRESS_TEMPLATE: &str = "{elapsed_precise} [{bar:24.cyan/blue}] {percent:>3}% {msamples} M, {rate} M samples/s, ETA {eta}";
#[cfg(test)]
pub const PROGRESS_COLUMNS: usize = 80;

/// `template` with the widest values its keys take: hours of elapsed time, a full bar, 100%,
/// 10^11 samples done at 10^11 samples/s, and a 4-character ETA (indicatif's "59m", "23h").
#[cfg(test)]
pub fn widest_progress_line(template: &str) -> String {
    let bar = regex_lite_bar(template);
    template
        .replace("{elapsed_precise}", "99:59:59")
        .replace(&bar.0, &"#".repeat(bar.1))
        .replace("{percent:>3}", "100")
        .replace("{msamples}", &millions(1e11))
        .replace("{rate}", &millions(1e11))
        .replace("{eta}", "999d")
}

/// The `{bar:N...}` key of `template` and its width N.
#[cfg(test)]
fn regex_lite_bar(template: &str) -> (String, usize) {
    let start = template.find("{bar:").expect("a bar");
    let end = start + template[start..].find('}').expect("a closed key") + 1;
    let key = &template[start..end];
    let width = key[5..].split('.').next().and_then(|w| w.parse().ok()).expect("a bar width");
    (key.to_string(), width)
}

/// `template` (with the keys `{msamples}`, done, and `{rate}`, both in millions) as a style.
pub fn progress_style_of(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .with_key("msamples", |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&millions(s.pos() as f64));
        })
        .with_key("rate", |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&millions(s.per_sec()));
        })
}

/// `x` in millions with 3 or 4 significant digits, at most 6 characters below 10^12.
fn millions(x: f64) -> String {
    let m = x / 1e6;
    if !m.is_finite() || m < 0.0 {
        "?".into()
    } else if m < 10.0 {
        format!("{m:.2}")
    } else if m < 1000.0 {
        format!("{m:.1}")
    } else {
        format!("{m:.0}")
    }
}

fn parse_define(s: &str) -> Result<Define, String> {
    s.parse()
}

fn parse_part(s: &str) -> Result<PartSpec, String> {
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
    fn the_progress_line_fits_80_columns_and_reads_in_millions() {
        assert_eq!(
            (millions(1.234e6), millions(45.67e6), millions(999.94e6), millions(123_456.0e6)),
            ("1.23".into(), "45.7".into(), "999.9".into(), "123456".into())
        );
        let widest = widest_progress_line(PROGRESS_TEMPLATE);
        assert!(!widest.contains('{'), "every key is replaced: {widest}");
        assert!(widest.contains("M samples/s"), "{widest}");
        assert!(widest.chars().count() <= PROGRESS_COLUMNS, "{} columns: {widest}", widest.chars().count());
        // The template is one indicatif accepts (else the plain bar would be drawn).
        assert!(ProgressStyle::with_template(PROGRESS_TEMPLATE).is_ok());
    }

    #[test]
    fn camera_flag_parses_and_rejects_garbage() {
        let v = parse_camera("278,273,-800:278,273,0:37").unwrap();
        assert_eq!((v.eye, v.target, v.vfov_deg), (Vec3A::new(278.0, 273.0, -800.0), Vec3A::new(278.0, 273.0, 0.0), 37.0));
        for bad in ["1,2:3,4,5:6", "1,2,3:4,5,6", "a,b,c:1,2,3:4", "1,2,3:4,5,6:x", "1,2,3,4:5,6,7:8", "nan,0,0:1,1,1:30"] {
            assert!(parse_camera(bad).is_err(), "{bad}");
        }
    }
}

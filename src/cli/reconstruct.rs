//! `cvtrace reconstruct`: run one or all estimators on a stream file (or IDUW's layout).
use anyhow::{bail, Context, Result};
use cvtrace_reconstruct::{
    build, ErrorEstimate, Estimator, FloorMode, FloorSource, Input, Method, MethodChoice, Options, Output, Penalty, Selection,
};
use cvtrace_streams::exr_io::{read_rgb, write_rgb, AttrValue};
use cvtrace_streams::iduw_layout::{parse_iduw_name, read_iduw};
use cvtrace_streams::preview::write_png;
use cvtrace_streams::{atomic, StreamSet};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ReconstructArgs {
    /// A cvtrace stream file, or IDUW's `<scene>_<spp>spp_randImg.exr` / `_corrImg.exr`.
    pub input: PathBuf,
    /// pt, crn, average, iduw, cv, ours, or all.
    #[arg(long, default_value = "ours")]
    pub method: MethodChoice,
    /// Output `.exr` for one method; a directory for `--method all` (`<dir>/<method>.exr` + `.png`).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Replace existing outputs.
    #[arg(long)]
    pub force: bool,
    /// Ground truth: needed by `--errors oracle`; when given, relMSE of each output is printed.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Also write an sRGB PNG preview next to a single-method output (always on for `all`).
    #[arg(long)]
    pub png: bool,
    /// Exposure of the PNG previews, in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    #[command(flatten)]
    pub options: EstimatorArgs,
}

/// The estimators' options; unset flags keep the library's measured defaults.
#[derive(clap::Args, Debug, Default)]
pub struct EstimatorArgs {
    /// ours/cv: how the control-variate pixels are chosen (knn, window, random, gbuffer).
    #[arg(long)]
    pub select: Option<Selection>,
    /// ours: pixels per set, centre included (cv uses k−1 neighbours).
    #[arg(long)]
    pub k: Option<usize>,
    /// ours/cv: side of the window the k pixels are chosen from (odd).
    #[arg(long)]
    pub search_window: Option<usize>,
    /// ours: PT error estimates (cbf, variance, cbf-residual, oracle — oracle needs --reference).
    #[arg(long)]
    pub errors: Option<ErrorEstimate>,
    /// ours: symmetric penalty on neighbours' error estimates (none, avg, max, residual).
    #[arg(long)]
    pub penalty: Option<Penalty>,
    /// ours: ridge, relative to the mean diagonal of the system.
    #[arg(long)]
    pub ridge: Option<f64>,
    /// ours/cv: one coefficient vector for all channels instead of one per channel.
    #[arg(long)]
    pub shared_coefficients: bool,
    /// ours: τ of the noise floor on the CRN covariance, as a fraction of the PT error estimate (0 = off; shape: --crn-floor-mode).
    #[arg(long)]
    pub crn_floor: Option<f64>,
    /// ours: shape of the floor: common (noise shared by the set) or independent (diagonal).
    #[arg(long)]
    pub crn_floor_mode: Option<FloorMode>,
    /// ours: the floor's variance ṽ: pt (the PT error estimates) or crn (filtered CRN variance).
    #[arg(long)]
    pub crn_floor_source: Option<FloorSource>,
    /// ours: estimate β on one half of the CRN batches and apply it to the other half (and vice versa).
    #[arg(long)]
    pub cross_fit: bool,
    /// ours, --errors cbf: radius in pixels of the cross-bilateral filter of the PT variances.
    #[arg(long)]
    pub cbf_radius: Option<usize>,
    /// ours, --errors cbf: tolerance of the filter's relative CRN colour difference.
    #[arg(long)]
    pub cbf_sigma_colour: Option<f32>,
    /// ours, --errors cbf: tolerance of the filter's albedo difference.
    #[arg(long)]
    pub cbf_sigma_albedo: Option<f32>,
    /// ours, --errors cbf: tolerance of the filter's shading-normal difference.
    #[arg(long)]
    pub cbf_sigma_normal: Option<f32>,
    /// ours, --errors cbf: leave a pixel's own variance out of its estimate (kept by default, so
    /// that a firefly pixel is not trusted; docs/estimators.md).
    #[arg(long)]
    pub cbf_exclude_centre: bool,
    /// cv: ridge, relative to the mean diagonal of V_g.
    #[arg(long)]
    pub cv_ridge: Option<f64>,
    /// iduw: window side (odd).
    #[arg(long)]
    pub iduw_window: Option<usize>,
    /// iduw: a fixed γ instead of choosing one from the published grid.
    #[arg(long)]
    pub iduw_gamma: Option<f32>,
}

impl EstimatorArgs {
    /// The library defaults with every given flag applied.
    pub fn to_options(&self) -> Options {
        let mut o = Options::default();
        if let Some(s) = self.select {
            o.ours.select = s;
            o.cv.select = s;
        }
        if let Some(k) = self.k {
            o.ours.k = k;
            o.cv.k = k.saturating_sub(1);
        }
        if let Some(w) = self.search_window {
            o.ours.search_window = w;
            o.cv.search_window = w;
        }
        if let Some(e) = self.errors {
            o.ours.errors = e;
        }
        if let Some(p) = self.penalty {
            o.ours.penalty = p;
        }
        if let Some(r) = self.ridge {
            o.ours.ridge = r;
        }
        if self.shared_coefficients {
            o.ours.shared_coefficients = true;
            o.cv.shared_coefficients = true;
        }
        if let Some(t) = self.crn_floor {
            o.ours.crn_floor = t;
        }
        if let Some(m) = self.crn_floor_mode {
            o.ours.crn_floor_mode = m;
        }
        if let Some(src) = self.crn_floor_source {
            o.ours.crn_floor_source = src;
        }
        if self.cross_fit {
            o.ours.cross_fit = true;
        }
        let cbf = &mut o.ours.cbf;
        if let Some(r) = self.cbf_radius {
            cbf.radius = r;
        }
        if let Some(v) = self.cbf_sigma_colour {
            cbf.sigma_colour = v;
        }
        if let Some(v) = self.cbf_sigma_albedo {
            cbf.sigma_albedo = v;
        }
        if let Some(v) = self.cbf_sigma_normal {
            cbf.sigma_normal = v;
        }
        if self.cbf_exclude_centre {
            cbf.exclude_centre = true;
        }
        if let Some(r) = self.cv_ridge {
            o.cv.ridge = r;
        }
        if let Some(w) = self.iduw_window {
            o.iduw.window = w;
        }
        if self.iduw_gamma.is_some() {
            o.iduw.gamma = self.iduw_gamma;
        }
        o
    }
}

/// Reads a stream file, or IDUW's input layout when the name follows it.
pub fn read_input(path: &Path) -> Result<StreamSet> {
    if let Some((dir, scene, spp)) = parse_iduw_name(path) {
        tracing::info!(scene = %scene, spp, "reading IDUW's input layout");
        return Ok(read_iduw(&dir, &scene, spp)?);
    }
    Ok(StreamSet::read(path)?)
}

/// Where each method's outputs go.
struct Target {
    method: Method,
    exr: PathBuf,
    png: Option<PathBuf>,
}

fn targets(args: &ReconstructArgs) -> Result<Vec<Target>> {
    match args.method {
        MethodChoice::One(m) => {
            if args.output.is_dir() {
                bail!("{}: is a directory; for one method give a file such as out/{m}.exr", args.output.display());
            }
            let png = args.png.then(|| args.output.with_extension("png"));
            Ok(vec![Target { method: m, exr: args.output.clone(), png }])
        }
        MethodChoice::All => {
            if args.output.extension().is_some_and(|e| e == "exr") {
                bail!("{}: --method all writes one file per method; give a directory", args.output.display());
            }
            if args.output.exists() && !args.output.is_dir() {
                bail!("{}: is a file; --method all writes one file per method into a directory", args.output.display());
            }
            Ok(Method::ALL
                .iter()
                .map(|&m| Target {
                    method: m,
                    exr: args.output.join(format!("{m}.exr")),
                    png: Some(args.output.join(format!("{m}.png"))),
                })
                .collect())
        }
    }
}

pub fn run(args: ReconstructArgs) -> Result<()> {
    check_exposure(args.exposure)?;
    let options = args.options.to_options();
    // Every option given is checked, also those of methods not run: `--method pt --k 0` is as
    // much a mistake as `--method ours --k 0`. `ours` first: it names `--k` as given (`cv`
    // counts the neighbours, k − 1).
    for m in [Method::Ours, Method::Cv, Method::Iduw] {
        build(m, &options)?;
    }
    // Build every estimator first: absurd options fail before any file is read.
    let estimators: Vec<(Target, Box<dyn Estimator>)> = targets(&args)?
        .into_iter()
        .map(|t| build(t.method, &options).map(|e| (t, e)))
        .collect::<Result<_, _>>()?;
    // `--method all` creates its directory, but only once the inputs have been read: a failed
    // command leaves nothing behind.
    let new_directory = matches!(args.method, MethodChoice::All) && !args.output.is_dir();
    if new_directory {
        atomic::check_writable(&args.output, false)?;
    }
    let inputs: Vec<&Path> = std::iter::once(args.input.as_path()).chain(args.reference.as_deref()).collect();
    for p in &inputs {
        crate::cli::check_input_file(p)?;
    }
    for (t, _) in &estimators {
        for out in std::iter::once(&t.exr).chain(&t.png) {
            crate::cli::refuse_overwriting_inputs(out, &inputs)?;
        }
        atomic::check_extension(&t.exr, "exr")?;
        if let Some(p) = &t.png {
            atomic::check_extension(p, "png")?;
        }
        if !new_directory {
            atomic::check_writable(&t.exr, args.force)?;
            if let Some(p) = &t.png {
                atomic::check_writable(p, args.force)?;
            }
        }
    }
    let started = std::time::Instant::now();
    let set = read_input(&args.input)?;
    if set.meta.non_finite_samples > 0 {
        tracing::warn!(
            "{}: the renderer replaced {} NaN or infinite samples by zero; every estimate from this file is biased by them",
            args.input.display(),
            set.meta.non_finite_samples
        );
    }
    let reference = args.reference.as_deref().map(read_rgb).transpose()?;
    tracing::info!(
        "read {} ({}x{}, {} spp per stream, {} batches) in {:.2} s",
        args.input.display(),
        set.width,
        set.height,
        set.meta.spp,
        set.batch_count(),
        started.elapsed().as_secs_f64()
    );
    let streams_name = args.input.display().to_string();
    let reference_name = args.reference.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    let mut input = Input::new(&set).named(&streams_name, &reference_name);
    if let Some(r) = &reference {
        if !r.same_size(&set.pt.mean) {
            bail!(
                "{}: reference is {}x{} but {} is {}x{}",
                reference_name, r.width, r.height, streams_name, set.width, set.height
            );
        }
        input = input.with_reference(r);
    }
    // Every method's requirements first, then every image, then the files: a method that
    // cannot run, or an image that is not finite, leaves no outputs of the others behind.
    for (_, estimator) in &estimators {
        input.check(estimator.name(), &estimator.needs())?;
    }
    let mut outputs = Vec::with_capacity(estimators.len());
    for (_, estimator) in &estimators {
        let out = estimator.reconstruct(&input)?;
        tracing::info!("{}: {:.3} s", estimator.name(), out.diagnostics.seconds);
        if let Some((x, y, c)) = out.image.find_non_finite() {
            bail!(
                "{streams_name}: `{}` produced a non-finite value at pixel ({x}, {y}), channel {}; the input holds values \
                 too large for f32 arithmetic (largest {:e})",
                estimator.name(),
                ["R", "G", "B"][c],
                set.pt.mean.pixels.iter().chain(&set.crn.mean.pixels).flatten().fold(0.0f32, |m, v| m.max(v.abs()))
            );
        }
        outputs.push(out);
    }
    // The images are one set: a run that fails or is interrupted half-way takes back what it
    // wrote, and the folder it made.
    let mut written = atomic::OutputSet::new();
    if new_directory {
        written.create_dir_all(&args.output).with_context(|| format!("{}: cannot create directory", args.output.display()))?;
    }
    let mut rows = Vec::new();
    for ((target, estimator), out) in estimators.iter().zip(outputs) {
        written.write(&target.exr, || write_output(&target.exr, &args, estimator.as_ref(), &out, set.meta.non_finite_samples))?;
        if let Some(png) = &target.png {
            written.write(png, || write_png(png, &out.image, args.exposure, args.force))?;
        }
        let rel = reference.as_ref().map(|r| cvtrace_eval::metrics::rel_mse(&out.image, r)).transpose()?;
        rows.push((estimator.name(), rel, out.diagnostics));
    }
    written.keep();
    print_summary(&rows);
    Ok(())
}

/// PNG exposure in stops: anything beyond ±64 turns every preview white or black.
pub fn check_exposure(stops: f32) -> Result<()> {
    if !(stops.is_finite() && stops.abs() <= 64.0) {
        bail!("--exposure {stops}: must be a number of stops between -64 and 64");
    }
    Ok(())
}

/// `non_finite_samples`: the input's count of replaced samples, carried into the output.
fn write_output(path: &Path, args: &ReconstructArgs, estimator: &dyn Estimator, out: &Output, non_finite_samples: u64) -> Result<()> {
    let mut attrs: Vec<(String, AttrValue)> = vec![
        ("cvtrace.method".into(), AttrValue::Text(estimator.name().into())),
        ("cvtrace.source".into(), AttrValue::Text(args.input.display().to_string())),
        ("cvtrace.nonFiniteSamples".into(), AttrValue::Text(non_finite_samples.to_string())),
        ("cvtrace.version".into(), AttrValue::Text(env!("CARGO_PKG_VERSION").into())),
        ("cvtrace.seconds".into(), AttrValue::Float(out.diagnostics.seconds as f32)),
    ];
    for (k, v) in estimator.settings() {
        attrs.push((format!("cvtrace.option.{k}"), AttrValue::Text(v)));
    }
    for (k, v) in &out.diagnostics.entries {
        attrs.push((format!("cvtrace.diag.{k}"), AttrValue::Text(v.to_string())));
    }
    let borrowed: Vec<(&str, AttrValue)> = attrs.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
    write_rgb(path, &out.image, &borrowed, args.force)?;
    tracing::info!("wrote {}", path.display());
    Ok(())
}

fn print_summary(rows: &[(&str, Option<f64>, cvtrace_reconstruct::Diagnostics)]) {
    println!("{:<8} {:>12} {:>9}  diagnostics", "method", "relMSE", "seconds");
    for (name, rel, diag) in rows {
        let rel = rel.map(|r| format!("{r:.6}")).unwrap_or_else(|| "-".into());
        let extra: Vec<String> = diag.entries.iter().map(|(k, v)| format!("{k}={v}")).collect();
        println!("{name:<8} {rel:>12} {:>9.3}  {}", diag.seconds, extra.join(" "));
    }
}

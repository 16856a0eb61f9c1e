//! `cvtrace reconstruct`: run one or all estimators on a stream file (or IDUW's layout).
use crate::cli::estimator_args::EstimatorArgs;
use crate::cli::registry;
use anyhow::{bail, Context, Result};
use cvtrace_reconstruct::{EstimatorSpec, Input, Instance, Output};
use cvtrace_streams::exr_io::{put_rgb, read_rgb, AttrValue, ExrChannels};
use cvtrace_streams::iduw_layout::{parse_iduw_name, read_iduw};
use cvtrace_streams::preview::write_png;
use cvtrace_streams::{atomic, StreamMeta, StreamSet};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ReconstructArgs {
    /// A cvtrace stream file, or IDUW's `<scene>_<spp>spp_randImg.exr` / `_corrImg.exr`.
    #[arg(required_unless_present_any = ["list", "help_method"])]
    pub input: Option<PathBuf>,
    /// An estimator (`--list` shows them), a comma-separated list of them, or all.
    #[arg(long, default_value = "ours")]
    pub method: String,
    /// Output `.exr` for one method; a directory for several (`<dir>/<method>.exr` + `.png`).
    #[arg(short, long, required_unless_present_any = ["list", "help_method"])]
    pub output: Option<PathBuf>,
    /// Replace existing outputs.
    #[arg(long)]
    pub force: bool,
    /// Ground truth: needed by `--errors oracle`; when given, relMSE of each output is printed.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// A plain PT render of the same view with the samples of both streams (2n spp, e.g.
    /// `cvtrace render --reference --spp 2n`), for the estimators that post-process one
    /// (`pt2n-oidn`); `--method all` leaves them out without it.
    #[arg(long, value_name = "EXR")]
    pub pt2n: Option<PathBuf>,
    /// Also write an sRGB PNG preview next to a single-method output (always on for several).
    #[arg(long)]
    pub png: bool,
    /// Exposure of the PNG previews, in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    /// List the registered estimators and exit.
    #[arg(long)]
    pub list: bool,
    /// Print an estimator's spec (summary, inputs, every parameter with default, range and doc) and exit.
    #[arg(long, value_name = "NAME")]
    pub help_method: Option<String>,
    #[command(flatten)]
    pub options: EstimatorArgs,
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
    spec: &'static EstimatorSpec,
    exr: PathBuf,
    png: Option<PathBuf>,
}

fn targets(args: &ReconstructArgs, output: &Path) -> Result<Vec<Target>> {
    let specs = registry().select(&args.method)?;
    if let [spec] = specs[..] {
        if !args.method.eq_ignore_ascii_case("all") {
            if output.is_dir() {
                bail!("{}: is a directory; for one method give a file such as out/{}.exr", output.display(), spec.name);
            }
            let png = args.png.then(|| output.with_extension("png"));
            return Ok(vec![Target { spec, exr: output.to_path_buf(), png }]);
        }
    }
    if output.extension().is_some_and(|e| e == "exr") {
        bail!("{}: --method {} writes one file per method; give a directory", output.display(), args.method);
    }
    if output.exists() && !output.is_dir() {
        bail!("{}: is a file; --method {} writes one file per method into a directory", output.display(), args.method);
    }
    Ok(specs
        .into_iter()
        .map(|spec| Target { spec, exr: output.join(format!("{}.exr", spec.name)), png: Some(output.join(format!("{}.png", spec.name))) })
        .collect())
}

/// `--list`: one line per registered estimator.
fn list() {
    crate::cli::say!("{:<10} {:<24} {:<6} {:<44} summary", "name", "label", "spp", "reads (defaults)");
    for spec in registry().specs() {
        let needs = (spec.needs)(&cvtrace_reconstruct::Params::defaults(spec));
        let spp = spec.samples.describe().split(' ').next().unwrap_or("");
        crate::cli::say!("{:<10} {:<24} {:<6} {:<44} {}", spec.name, spec.label, spp, needs.describe(), spec.summary);
    }
    crate::cli::say!("\n`cvtrace reconstruct --help-method NAME` lists an estimator's parameters; set them with --param NAME.PARAM=VALUE.");
}

pub fn run(args: ReconstructArgs) -> Result<()> {
    if args.list {
        list();
        return Ok(());
    }
    if let Some(name) = &args.help_method {
        crate::cli::say!("{}", registry().get(name)?.help().trim_end_matches('\n'));
        return Ok(());
    }
    let (Some(input_path), Some(output)) = (args.input.clone(), args.output.clone()) else {
        bail!("reconstruct needs an input stream file and -o");
    };
    // Missing folders above the output are made, and taken back if the command fails.
    let made = crate::cli::files::make_parent_folders(&output)?;
    let result = reconstruct(&args, input_path, output);
    if result.is_err() {
        crate::cli::files::remove_empty(&made);
    }
    result
}

fn reconstruct(args: &ReconstructArgs, input_path: PathBuf, output: PathBuf) -> Result<()> {
    check_exposure(args.exposure)?;
    // Every option given is checked, also those of methods not run: `--method pt --k 0` is as
    // much a mistake as `--method ours --k 0`.
    let overrides = args.options.checked()?;
    // Build every estimator first: absurd options fail before any file is read.
    let mut estimators: Vec<(Target, Instance)> =
        targets(args, &output)?.into_iter().map(|t| registry().build(t.spec.name, &overrides).map(|e| (t, e))).collect::<Result<_, _>>()?;
    if args.pt2n.is_none() && args.method.eq_ignore_ascii_case("all") {
        estimators.retain(|(_, e)| {
            if e.needs().pt2n {
                tracing::info!("{}: left out, it needs a PT(2n) render (--pt2n)", e.name());
            }
            !e.needs().pt2n
        });
    }
    // Several methods create their directory, but only once the inputs have been read: a
    // failed command leaves nothing behind.
    let new_directory = (estimators.len() > 1 || args.method.eq_ignore_ascii_case("all")) && !output.is_dir();
    if new_directory {
        atomic::check_writable(&output, false)?;
    }
    let inputs: Vec<&Path> = std::iter::once(input_path.as_path()).chain(args.reference.as_deref()).chain(args.pt2n.as_deref()).collect();
    for p in &inputs {
        crate::cli::files::check_input_file(p)?;
    }
    // A reference or PT(2n) render of another scene, camera or path length is of another image.
    if parse_iduw_name(&input_path).is_none() {
        for (other, what) in [(&args.reference, "reference"), (&args.pt2n, "PT(2n) render")] {
            if let Some(other) = other {
                cvtrace_streams::Provenance::check_same_image(other, what, &input_path)?;
            }
        }
    }
    for (t, _) in &estimators {
        for out in std::iter::once(&t.exr).chain(&t.png) {
            crate::cli::files::refuse_overwriting_inputs(out, &inputs)?;
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
    let set = read_input(&input_path)?;
    if set.meta.non_finite_samples > 0 {
        tracing::warn!(
            "{}: the renderer replaced {} NaN or infinite samples by zero; every estimate from this file is biased by them",
            input_path.display(),
            set.meta.non_finite_samples
        );
    }
    let reference = args.reference.as_deref().map(read_rgb).transpose()?;
    if let (Some(path), Some(image)) = (&args.reference, &reference) {
        // Black, or negative pixels: relMSE is no measure against it.
        if let Some(w) = cvtrace_eval::Reference::new(image.clone(), path.display().to_string())?.unusable_warning() {
            tracing::warn!("{w}");
        }
    }
    let pt2n = args.pt2n.as_deref().map(read_rgb).transpose()?;
    tracing::info!(
        "read {} ({}x{}, {} spp per stream, {} batches) in {:.2} s",
        input_path.display(),
        set.width,
        set.height,
        set.meta.spp,
        set.batch_count(),
        started.elapsed().as_secs_f64()
    );
    let streams_name = input_path.display().to_string();
    let reference_name = args.reference.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    let mut input = Input::new(&set).named(&streams_name, &reference_name);
    if let Some(r) = &reference {
        if !r.same_size(&set.pt.mean) {
            bail!("{}: reference is {}x{} but {} is {}x{}", reference_name, r.width, r.height, streams_name, set.width, set.height);
        }
        input = input.with_reference(r);
    }
    let pt2n_name = args.pt2n.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    if let Some(image) = &pt2n {
        input = input.with_pt2n(image, &pt2n_name);
    }
    // Every method's requirements first, then every image, then the files: a method that
    // cannot run, or an image that is not finite, leaves no outputs of the others behind.
    for (_, estimator) in &estimators {
        input.check(estimator.name(), &estimator.needs())?;
    }
    let mut outputs = Vec::with_capacity(estimators.len());
    for (_, estimator) in &estimators {
        let out = estimator.run(&input)?;
        tracing::info!("{}: {:.3} s", estimator.name(), out.diagnostics.seconds);
        input.check_output(estimator.name(), &out.image)?;
        outputs.push(out);
    }
    // The images are one set: a run that fails or is interrupted half-way takes back what it
    // wrote, and the folder it made.
    let mut written = atomic::OutputSet::new();
    if new_directory {
        written.create_dir_all(&output).with_context(|| format!("{}: cannot create directory", output.display()))?;
    }
    let mut rows = Vec::new();
    for ((target, estimator), out) in estimators.iter().zip(outputs) {
        written.write(&target.exr, || write_output(&target.exr, args, &input_path, estimator, &out, &set.meta))?;
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

/// `meta`: the input's; its spp, seed, scene and count of replaced samples go into the output.
fn write_output(path: &Path, args: &ReconstructArgs, source: &Path, estimator: &Instance, out: &Output, meta: &StreamMeta) -> Result<()> {
    let non_finite_samples = meta.non_finite_samples;
    let mut attrs: Vec<(String, AttrValue)> = vec![
        ("cvtrace.method".into(), AttrValue::Text(estimator.name().into())),
        ("cvtrace.source".into(), AttrValue::Text(source.display().to_string())),
        ("cvtrace.nonFiniteSamples".into(), AttrValue::Text(non_finite_samples.to_string())),
        // What the image stands for, so that `compare` and other tools see its samples and render.
        ("cvtrace.spp".into(), AttrValue::Int(i32::try_from(estimator.spec().samples.total(meta.spp)).unwrap_or(i32::MAX))),
        ("cvtrace.streamSpp".into(), AttrValue::Int(i32::try_from(meta.spp).unwrap_or(i32::MAX))),
        ("cvtrace.seed".into(), AttrValue::Text(meta.seed.to_string())),
        ("cvtrace.scene".into(), AttrValue::Text(meta.scene.clone())),
        ("cvtrace.version".into(), AttrValue::Text(env!("CARGO_PKG_VERSION").into())),
        ("cvtrace.seconds".into(), AttrValue::Float(out.diagnostics.seconds as f32)),
    ];
    for (k, v) in estimator.settings() {
        attrs.push((format!("cvtrace.option.{k}"), AttrValue::Text(v)));
    }
    for (k, v) in &out.diagnostics.entries {
        attrs.push((format!("cvtrace.diag.{k}"), AttrValue::Text(v.to_string())));
    }
    // The picture as the top-level R, G, B (what viewers show), each AOV as `<name>.R/G/B`.
    let mut ch = ExrChannels::new(out.image.width, out.image.height);
    put_rgb(&mut ch, "", &out.image);
    for (name, layer) in &out.aovs {
        put_rgb(&mut ch, &format!("{name}."), layer);
    }
    ch.attributes.extend(attrs);
    ch.write(path, args.force)?;
    tracing::info!("wrote {}", path.display());
    Ok(())
}

/// The terminal's table: numbers to 4 significant digits, which is what a reader compares (the
/// output files keep every digit).
fn print_summary(rows: &[(&str, Option<f64>, cvtrace_reconstruct::Diagnostics)]) {
    crate::cli::say!("{}", summary_table(rows).trim_end());
}

fn summary_table(rows: &[(&str, Option<f64>, cvtrace_reconstruct::Diagnostics)]) -> String {
    use cvtrace_eval::table::{fmt_num, fmt_seconds};
    let width = rows.iter().map(|(name, _, _)| name.len()).max().unwrap_or(0).max(8);
    let mut out = format!("{:<width$} {:>10} {:>9}  diagnostics\n", "method", "relMSE", "seconds");
    for (name, rel, diag) in rows {
        let rel = rel.map(fmt_num).unwrap_or_else(|| "-".into());
        let extra: Vec<String> = diag.entries.iter().map(|(k, v)| format!("{k}={}", diag_value(v))).collect();
        out += &format!("{name:<width$} {rel:>10} {:>9}  {}\n", fmt_seconds(diag.seconds), extra.join(" "));
    }
    out
}

/// A diagnostic for the terminal: a float to 4 significant digits, anything else as it is.
fn diag_value(v: &cvtrace_reconstruct::DiagValue) -> String {
    match v {
        cvtrace_reconstruct::DiagValue::Float(x) => cvtrace_eval::table::fmt_num(*x),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_prints_four_significant_digits() {
        let mut diag = cvtrace_reconstruct::Diagnostics { seconds: 0.123456, ..Default::default() };
        diag.float("gamma", 0.123456789).float("weight", 1234.56789).float("tiny", 1.23456e-7).int("k", 16).text("select", "knn");
        let table = summary_table(&[("ours", Some(0.0123456789), diag)]);
        let row = table.lines().nth(1).unwrap();
        for want in ["0.01235", "0.123 ", "gamma=0.1235", "weight=1235", "tiny=1.235e-7", "k=16", "select=knn"] {
            assert!(row.contains(want), "{want:?} missing from {row:?}");
        }
        assert!(!row.contains("0.123456"), "{row:?}");
    }
}

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
use crate::cli::args::{batches_parser, default_batches, parse_part, parse_seed, spp_parser, ViewArgs};
use crate::cli::files::{make_parent_folders, refuse_overwriting_inputs, remove_empty, set_interrupt_note};
use crate::cli::progress::TerminalProgress;
use anyhow::{bail, Result};
use cvtrace_render::RenderDefaults;
use cvtrace_session::{self as session, Job, ReferenceJob, ReferenceOutcome, StreamJob, DEFAULT_WIDTH};
use cvtrace_streams::parts::PartSpec;
use std::path::PathBuf;

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
    #[arg(long, value_parser = batches_parser(), allow_hyphen_values = true)]
    pub batches: Option<u32>,
    /// Random seed: the same seed and settings give bit-identical output.
    #[arg(long, default_value_t = 0, value_parser = parse_seed, allow_hyphen_values = true)]
    pub seed: u64,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Render a PT-only reference image, progressively, resumable from a checkpoint next to the output.
    #[arg(long)]
    pub reference: bool,
    /// With --reference: samples per pixel per pass; a checkpoint is saved after every pass.
    #[arg(long, default_value_t = 64, requires = "reference", value_parser = spp_parser(), allow_hyphen_values = true)]
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
    #[arg(long, hide = true, requires = "reference", value_parser = clap::value_parser!(u32).range(0..=u32::MAX as i64), allow_hyphen_values = true)]
    pub stop_after_passes: Option<u32>,
}

pub fn run(args: RenderArgs) -> Result<()> {
    // Cheap checks first: flags, then whether the output can be written at all.
    let batches = match (args.reference, args.batches) {
        (true, Some(_)) => bail!("--batches does not apply to --reference renders (they have a single PT stream)"),
        (true, None) => 1,
        (false, Some(b)) => b,
        (false, None) => default_batches(&args.spp.or(args.view.defined("spp")).into_iter().collect::<Vec<_>>()),
    };
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
    // The -D keys and --camera are checked before anything is made.
    args.view.session_options()?;
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
        refuse_overwriting_inputs(p, &[&args.output, &args.scene])?;
    }
    let made = make_parent_folders(&args.output)?;
    let result = render_job(&args, &job);
    if result.is_err() {
        remove_empty(&made);
    }
    result
}

fn render_job(args: &RenderArgs, job: &Job) -> Result<()> {
    job.check_outputs()?;
    if let Some(p) = &args.preview {
        cvtrace_streams::atomic::check_writable(p, args.force)?;
    }
    let session = args.view.open_session(&args.scene)?;
    let progress = TerminalProgress::default();
    match job {
        Job::Streams(j) => session.render_streams(j, &progress)?,
        Job::Reference(j) => {
            set_interrupt_note(format!(
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

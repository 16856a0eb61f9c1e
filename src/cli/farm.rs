//! `cvtrace farm`: a render as parts on a Slurm cluster (a job folder, its submission, its
//! status). The bookkeeping is `cvtrace-farm`'s; this file maps flags to a plan and prints.
use crate::cli::render::{default_batches, spp_parser, ViewArgs};
use anyhow::{bail, Context, Result};
use cvtrace_farm::{JobFolder, MergeState, PartState, Plan, Slurm};
use cvtrace_render::part::PartSpec;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct FarmArgs {
    #[command(subcommand)]
    pub command: FarmCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum FarmCommand {
    /// Write the job folder of a render in parts (and with --submit, submit it to Slurm).
    Render(FarmRenderArgs),
    /// Which parts of a job folder are done, queued, failed or missing, and the merge.
    Status(FarmStatusArgs),
}

#[derive(clap::Args, Debug)]
pub struct FarmRenderArgs {
    /// glTF 2.0 scene, as every part will be given it (paths relative to this folder).
    pub scene: PathBuf,
    /// The merged output: a stream file, or with --reference an RGB EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel of each stream (or of the reference).
    #[arg(long, value_parser = spp_parser(), allow_hyphen_values = true)]
    pub spp: u32,
    /// Batches per stream [default: the most of 16, 8, 4, 2, 1 that divide --spp].
    #[arg(long)]
    pub batches: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub view: ViewArgs,
    /// A reference: the parts are ranges of passes of --pass-spp samples.
    #[arg(long)]
    pub reference: bool,
    #[arg(long, default_value_t = 64, requires = "reference")]
    pub pass_spp: u32,
    /// Number of parts (array tasks): at most the number of batches (or passes).
    #[arg(long)]
    pub parts: u32,
    /// The job folder [default: the output's name with `.farm` for `.exr`].
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Submit with sbatch: the parts that are missing or failed, and the merge after them.
    #[arg(long)]
    pub submit: bool,
    /// An argument for sbatch (repeatable), e.g. --sbatch-arg=--partition=gpu.
    #[arg(long = "sbatch-arg", value_name = "ARG", allow_hyphen_values = true)]
    pub sbatch_args: Vec<String>,
    /// Let the merge replace an existing output.
    #[arg(long)]
    pub force: bool,
}

#[derive(clap::Args, Debug)]
pub struct FarmStatusArgs {
    /// A job folder written by `cvtrace farm render`.
    pub dir: PathBuf,
}

pub fn run(args: FarmArgs) -> Result<()> {
    match args.command {
        FarmCommand::Render(a) => render(a),
        FarmCommand::Status(a) => status(&a.dir),
    }
}

fn default_dir(output: &Path) -> PathBuf {
    let name = output.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    output.with_file_name(format!("{}.farm", name.strip_suffix(".exr").unwrap_or(&name)))
}

fn render(a: FarmRenderArgs) -> Result<()> {
    crate::cli::check_input_file(&a.scene)?;
    cvtrace_streams::atomic::check_extension(&a.output, "exr")?;
    if a.parts == 0 {
        bail!("--parts 0: there must be at least one part");
    }
    let mut render_args = vec!["--spp".to_string(), a.spp.to_string()];
    let (units, what, pass_spp) = if a.reference {
        if a.batches.is_some() {
            bail!("--batches does not apply to --reference renders (they have a single PT stream)");
        }
        if a.pass_spp == 0 {
            bail!("--pass-spp must be at least 1");
        }
        render_args.extend(["--reference".into(), "--pass-spp".into(), a.pass_spp.to_string()]);
        (a.spp.div_ceil(a.pass_spp), "passes", Some(a.pass_spp))
    } else {
        let b = a.batches.unwrap_or_else(|| default_batches(Some(a.spp)));
        let settings = cvtrace_render::RenderSettings { spp: a.spp, batches: b, width: 1, height: 1, ..Default::default() };
        settings.validate().context("--spp and --batches")?;
        render_args.extend(["--batches".into(), b.to_string()]);
        (b, "batches", None)
    };
    PartSpec { index: 0, count: a.parts }
        .range(units, what)
        .map_err(|e| anyhow::anyhow!("{}", e.to_string().replace("--part 0/", "--parts ")))?;
    render_args.extend(["--seed".into(), a.seed.to_string()]);
    let v = &a.view;
    for (flag, value) in [
        ("--width", v.width.map(|x| x.to_string())),
        ("--height", v.height.map(|x| x.to_string())),
        ("--max-depth", v.max_depth.map(|x| x.to_string())),
        ("--rr-depth", v.rr_depth.map(|x| x.to_string())),
        ("--camera", v.camera.clone()),
    ] {
        if let Some(value) = value {
            render_args.extend([flag.to_string(), value]);
        }
    }
    for d in &v.define {
        render_args.extend(["-D".into(), d.to_string()]);
    }
    // Checked now rather than on every node.
    v.session_options()?;
    render_args.extend(["--traversal".into(), v.traversal.name().into()]);

    let dir = a.dir.clone().unwrap_or_else(|| default_dir(&a.output));
    let plan = Plan {
        kind: if a.reference { "reference" } else { "streams" }.into(),
        cvtrace: std::env::current_exe().context("the path of this cvtrace binary")?,
        workdir: std::env::current_dir().context("the current folder")?,
        scene: a.scene.to_string_lossy().into_owned(),
        output: a.output.to_string_lossy().into_owned(),
        render_args,
        units,
        pass_spp,
        parts: a.parts,
        replace_output: a.force,
    };
    let new = !dir.join("manifest.json").exists();
    if new {
        let made = crate::cli::make_parent_folders(&a.output)?;
        if let Err(e) = cvtrace_streams::atomic::check_writable(&a.output, a.force) {
            crate::cli::remove_empty(&made);
            return Err(e.into());
        }
    }
    let folder = JobFolder::create(&dir, plan)?;
    if new {
        tracing::info!("wrote the job folder {} ({} parts of {units} {what})", folder.dir.display(), a.parts);
    }
    if !a.submit {
        say!("job folder {}: submit it with\n{}or run this command again with --submit", folder.dir.display(), folder.how_to_submit());
        return Ok(());
    }
    let s = folder.submit(&Slurm, &a.sbatch_args)?;
    match (&s.array, &s.merge, &s.waiting) {
        (_, _, Some(job)) => say!("nothing to submit: the parts not done are queued or running; merge job {job} waits for them"),
        (None, None, None) => say!("nothing to submit: every part is done and {} is merged", a.output.display()),
        (array, merge, None) => {
            if let Some(job) = array {
                let tasks = s.tasks.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
                say!("submitted parts {tasks} as array job {job}");
            }
            if let Some(job) = merge {
                say!("submitted the merge as job {job} (runs after the parts succeed): {}", a.output.display());
            }
        }
    }
    Ok(())
}

fn status(dir: &Path) -> Result<()> {
    let folder = JobFolder::open(dir)?;
    let st = folder.status(&Slurm)?;
    let m = &folder.manifest;
    let (mut done, mut failed) = (0, 0);
    for p in &st.parts {
        let range = m.describe(&p.part);
        let job = p.job.as_ref().map(|j| format!(" (job {j}_{})", p.part.index)).unwrap_or_default();
        let state = match &p.state {
            PartState::Done => {
                done += 1;
                "done".to_string()
            }
            PartState::Queued(s) => format!("{}{job}", s.to_lowercase()),
            PartState::Failed(why) => {
                failed += 1;
                format!("failed: {why}{job}, log {}", folder.dir.join("logs").join(format!("part-{}.out", p.part.index)).display())
            }
            PartState::Missing => "missing (not submitted)".to_string(),
        };
        say!("part {} ({range}): {state}", p.part.index);
    }
    let merge_job = st.merge_job.as_ref().map(|j| format!(" (job {j})")).unwrap_or_default();
    let merge = match &st.merge {
        MergeState::Done => format!("done: {}", st.output.display()),
        MergeState::Queued(s) => format!("{}{merge_job}", s.to_lowercase()),
        MergeState::Failed(why) => format!("{why}{merge_job}"),
        MergeState::NotSubmitted => "not submitted".to_string(),
    };
    say!("merge: {merge}");
    say!("{done} of {} parts done, {failed} failed", st.parts.len());
    if failed > 0 {
        say!("run the same `cvtrace farm render ... --submit` again to submit only the failed and missing parts");
    }
    Ok(())
}

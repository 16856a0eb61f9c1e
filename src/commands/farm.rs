//! `cvtrace farm`: a render as parts, or a study as cells, on a Slurm cluster (a job folder, its
//! submission, its status). The bookkeeping is `cvtrace-farm`'s; this file maps flags to a plan
//! and prints.
use crate::cli::args::{batches_parser, count_parser, default_batches, parse_seed, spp_parser, ViewArgs};
use crate::cli::say;
use crate::cli::study_setup::{prepare, StudyArgs};
use anyhow::{bail, Context, Result};
use cvtrace_farm::{JobFolder, MergeState, PartState, Plan, Slurm, StudyCells};
use cvtrace_streams::parts::PartSpec;
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
    /// Write the job folder of a study, a render per array task and the statistics after them
    /// (and with --submit, submit it). Takes the arguments of `cvtrace study`.
    Study(FarmStudyArgs),
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
    #[arg(long, value_parser = batches_parser(), allow_hyphen_values = true)]
    pub batches: Option<u32>,
    #[arg(long, default_value_t = 0, value_parser = parse_seed, allow_hyphen_values = true)]
    pub seed: u64,
    #[command(flatten)]
    pub view: ViewArgs,
    /// A reference: the parts are ranges of passes of --pass-spp samples.
    #[arg(long)]
    pub reference: bool,
    #[arg(long, default_value_t = 64, requires = "reference", value_parser = spp_parser(), allow_hyphen_values = true)]
    pub pass_spp: u32,
    /// Number of parts (array tasks): at most the number of batches (or passes).
    #[arg(long, value_parser = count_parser(), allow_hyphen_values = true)]
    pub parts: u32,
    #[command(flatten)]
    pub job: JobArgs,
    /// Let the merge replace an existing output.
    #[arg(long)]
    pub force: bool,
}

#[derive(clap::Args, Debug)]
pub struct FarmStudyArgs {
    #[command(flatten)]
    pub study: StudyArgs,
    #[command(flatten)]
    pub job: JobArgs,
}

/// The job folder and its submission, the same for every farm command.
#[derive(clap::Args, Debug)]
pub struct JobArgs {
    /// The job folder [default: the output's name (for `farm study`, the study folder's) with
    /// `.farm`].
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Submit with sbatch: the tasks (parts or study cells) that are missing or failed, and the
    /// job that then merges or summarises them.
    #[arg(long)]
    pub submit: bool,
    /// An argument for sbatch (repeatable), e.g. --sbatch-arg=--partition=gpu: kept in the job
    /// folder's scripts (`#SBATCH`) and given to every submission; a later run without any
    /// keeps them, one with others replaces them.
    #[arg(long = "sbatch-arg", value_name = "ARG", allow_hyphen_values = true)]
    pub sbatch_args: Vec<String>,
}

#[derive(clap::Args, Debug)]
pub struct FarmStatusArgs {
    /// A job folder written by `cvtrace farm render` or `cvtrace farm study`.
    pub dir: PathBuf,
}

pub fn run(args: FarmArgs) -> Result<()> {
    match args.command {
        FarmCommand::Render(a) => render(a),
        FarmCommand::Study(a) => study(a),
        FarmCommand::Status(a) => status(&a.dir),
    }
}

fn default_dir(output: &Path) -> PathBuf {
    let name = output.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    output.with_file_name(format!("{}.farm", name.strip_suffix(".exr").unwrap_or(&name)))
}

fn render(a: FarmRenderArgs) -> Result<()> {
    crate::cli::files::check_input_file(&a.scene)?;
    cvtrace_streams::atomic::check_extension(&a.output, "exr")?;
    let mut render_args = vec!["--spp".to_string(), a.spp.to_string()];
    let (units, what, pass_spp) = if a.reference {
        if a.batches.is_some() {
            bail!("--batches does not apply to --reference renders (they have a single PT stream)");
        }
        render_args.extend(["--reference".into(), "--pass-spp".into(), a.pass_spp.to_string()]);
        (a.spp.div_ceil(a.pass_spp), "passes", Some(a.pass_spp))
    } else {
        let b = a.batches.unwrap_or_else(|| default_batches(&[a.spp]));
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
    render_args.extend(["--traversal".into(), cvtrace_session::Traversal::from(v.traversal).name().into()]);

    let dir = a.job.dir.clone().unwrap_or_else(|| default_dir(&a.output));
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
        study: None,
    };
    let new = !dir.join("manifest.json").exists();
    if new {
        let made = crate::cli::files::make_parent_folders(&a.output)?;
        if let Err(e) = cvtrace_streams::atomic::check_writable(&a.output, a.force) {
            crate::cli::files::remove_empty(&made);
            return Err(e.into());
        }
    }
    let folder = JobFolder::create(&dir, plan, &a.job.sbatch_args)?;
    if new {
        tracing::info!("wrote the job folder {} ({} parts of {units} {what})", folder.dir.display(), a.parts);
    }
    if !a.job.submit {
        say!("job folder {}: submit it with\n{}or run this command again with --submit", folder.dir.display(), folder.how_to_submit());
        return Ok(());
    }
    submit(&folder)
}

/// Submits what `folder` still needs (with its sbatch arguments) and says what was submitted.
fn submit(folder: &JobFolder) -> Result<()> {
    let s = folder.submit(&Slurm, &folder.manifest.sbatch_args)?;
    let names = folder.manifest.scripts();
    let (task, last) = (names.task, names.last_name);
    let output = folder.manifest.final_output();
    match (&s.array, &s.merge, &s.waiting) {
        (_, _, Some(job)) => say!("nothing to submit: the {task}s not done are queued or running; {last} job {job} waits for them"),
        (None, None, None) => say!("nothing to submit: every {task} is done and {} is written", output.display()),
        (array, merge, None) => {
            if let Some(job) = array {
                let tasks = s.tasks.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
                say!("submitted {task}s {tasks} as array job {job}");
            }
            if let Some(job) = merge {
                say!("submitted the {last} as job {job} (runs after the {task}s succeed): {}", output.display());
            }
        }
    }
    Ok(())
}

/// Flags of `farm study` that are the farm's, not the study's: (flag, takes a value).
const FARM_STUDY_FLAGS: [(&str, bool); 3] = [("--submit", false), ("--dir", true), ("--sbatch-arg", true)];

/// The arguments of `cvtrace farm study` that are the study's, exactly as given (the scene and
/// `-o` among them): every cell and the final study run `cvtrace study` with them, so that they
/// are the study the user would have run, estimator options and all.
fn study_tokens(argv: &[String]) -> Result<Vec<String>> {
    // The subcommand words come after global options, some of which take a value.
    let mut words = Vec::new();
    let mut i = 1;
    while i < argv.len() && words.len() < 2 {
        let t = argv[i].as_str();
        if matches!(t, "-t" | "--threads" | "--log") {
            i += 1;
        } else if !t.starts_with('-') {
            words.push(t);
        }
        i += 1;
    }
    if words != ["farm", "study"] {
        bail!("cannot find `farm study` in the command line {argv:?}");
    }
    let mut out = Vec::new();
    let mut rest = argv[i..].iter();
    while let Some(t) = rest.next() {
        if t == "--" {
            out.push(t.clone());
            out.extend(rest.cloned());
            break;
        }
        match FARM_STUDY_FLAGS.iter().find(|(f, _)| t == f || (t.starts_with(f) && t[f.len()..].starts_with('='))) {
            Some((f, true)) if t == f => {
                rest.next();
            }
            Some(_) => {}
            None => out.push(t.clone()),
        }
    }
    Ok(out)
}

fn study(a: FarmStudyArgs) -> Result<()> {
    let s = &a.study;
    if let Some(cell) = s.cell {
        bail!("--cell {cell}: the farm gives every task its cell; give the study's arguments without --cell");
    }
    // The final job runs the study alone: a reference it had to render would take one node for
    // longer than every cell.
    if !s.reference.exists() {
        bail!(
            "{}: the reference does not exist; render it first (it can be a farm job too: cvtrace farm render SCENE --reference --spp N --parts P -o {})",
            s.reference.display(),
            s.reference.display()
        );
    }
    prepare(s)?;
    let argv: Vec<String> = std::env::args_os()
        .map(|a| a.into_string().map_err(|a| anyhow::anyhow!("{}: not UTF-8; a job script needs it as text", a.to_string_lossy())))
        .collect::<Result<_>>()?;
    let tokens = study_tokens(&argv)?;
    let mut spps = s.spp.clone();
    spps.sort_unstable();
    spps.dedup();
    let cells = 2 * spps.len() as u32 * s.seeds;
    let dir = a.job.dir.clone().unwrap_or_else(|| default_dir(&s.output));
    if crate::cli::files::same_output(&dir, &s.output) {
        bail!("{}: given as both --dir and -o; the job folder and the study folder must differ", dir.display());
    }
    let plan = Plan {
        kind: "study".into(),
        cvtrace: std::env::current_exe().context("the path of this cvtrace binary")?,
        workdir: std::env::current_dir().context("the current folder")?,
        scene: s.scene.to_string_lossy().into_owned(),
        output: s.output.to_string_lossy().into_owned(),
        render_args: tokens,
        units: cells,
        pass_spp: None,
        parts: cells,
        replace_output: true,
        study: Some(StudyCells { spps, seeds: s.seeds }),
    };
    let new = !dir.join("manifest.json").exists();
    let folder = JobFolder::create(&dir, plan, &a.job.sbatch_args)?;
    if new {
        tracing::info!("wrote the job folder {} ({cells} cells)", folder.dir.display());
    }
    if !a.job.submit {
        say!("job folder {}: submit it with\n{}or run this command again with --submit", folder.dir.display(), folder.how_to_submit());
        return Ok(());
    }
    submit(&folder)
}

fn status(dir: &Path) -> Result<()> {
    let folder = JobFolder::open(dir)?;
    let st = folder.status(&Slurm)?;
    let m = &folder.manifest;
    let names = m.scripts();
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
        say!("{} {} ({range}): {state}", names.task, p.part.index);
    }
    let merge_job = st.merge_job.as_ref().map(|j| format!(" (job {j})")).unwrap_or_default();
    let merge = match &st.merge {
        MergeState::Done => format!("done: {}", st.output.display()),
        MergeState::Queued(s) => format!("{}{merge_job}", s.to_lowercase()),
        MergeState::Failed(why) => format!("{why}{merge_job}"),
        MergeState::NotSubmitted => "not submitted".to_string(),
    };
    say!("{}: {merge}", names.last_name);
    say!("{done} of {} {}s done, {failed} failed", st.parts.len(), names.task);
    if failed > 0 {
        say!(
            "run the same `cvtrace farm {} ... --submit` again to submit only the failed and missing {}s",
            if m.plan.study.is_some() { "study" } else { "render" },
            names.task
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::study_tokens;

    fn tokens(line: &str) -> Result<String, String> {
        let argv: Vec<String> = line.split(' ').map(String::from).collect();
        study_tokens(&argv).map(|t| t.join(" ")).map_err(|e| e.to_string())
    }

    #[test]
    fn the_study_gets_its_own_arguments_as_given() {
        assert_eq!(
            tokens(
                "cvtrace --log warn -t 2 farm study s.gltf --spp 4,8 --submit --dir j --sbatch-arg --partition=x -o out --reference r.exr"
            ),
            Ok("s.gltf --spp 4,8 -o out --reference r.exr".into())
        );
        assert_eq!(
            tokens("cvtrace farm --log=warn study s.gltf --dir=j --sbatch-arg=-N1 --param ours.k=4 -o o -- x --submit"),
            Ok("s.gltf --param ours.k=4 -o o -- x --submit".into())
        );
        assert!(tokens("cvtrace farm render s.gltf").is_err());
    }
}

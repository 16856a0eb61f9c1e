//! `cvtrace report`: the static HTML comparison viewer from one or more study folders.
use anyhow::{bail, Context, Result};
use cvtrace_eval::report::{REPORT_FILES, REPORT_FOLDERS};
use cvtrace_eval::{write_report, ReportOptions, StudyResults};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Study folders (each holding results.json), or a folder whose sub-folders are studies.
    #[arg(required = true)]
    pub studies: Vec<PathBuf>,
    /// Output folder for index.html and its files.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Page title.
    #[arg(long, default_value = "cvtrace")]
    pub title: String,
    /// Also write the cross-scene Markdown summary (every method's relMSE per scene, the headline
    /// ratios with their geometric means, the ablations, then each scene's table) to this file.
    #[arg(long, value_name = "FILE")]
    pub markdown: Option<PathBuf>,
    /// Leave the ablations' images (and their pixel values) out of the viewer (their numbers
    /// stay): a lighter folder to publish.
    #[arg(long)]
    pub no_ablation_images: bool,
    /// Replace an existing report (and Markdown file).
    #[arg(long)]
    pub force: bool,
}

/// Refuses a `--markdown` path that the report itself writes (`-o rep --markdown
/// rep/index.html` would replace the page), or that is a file of one of the studies.
fn check_markdown_path(md: &Path, output: &Path, studies: &[PathBuf]) -> Result<()> {
    let md_abs = crate::cli::files::resolved(md);
    if let Ok(inside) = md_abs.strip_prefix(crate::cli::files::resolved(output)) {
        let first = inside.components().next().map(|c| c.as_os_str().to_string_lossy().into_owned()).unwrap_or_default();
        let own = inside.as_os_str().is_empty()
            || (inside.components().count() == 1 && REPORT_FILES.contains(&first.as_str()))
            || REPORT_FOLDERS.contains(&first.as_str());
        if own {
            bail!("--markdown {}: the report writes this path itself (in {}); write the summary elsewhere", md.display(), output.display());
        }
        // Its other files are the user's, also where the report folder sits in a study's.
        return Ok(());
    }
    for d in studies {
        if md.exists() && md_abs.starts_with(crate::cli::files::resolved(d)) {
            bail!("--markdown {}: is a file of the study {}; write the summary elsewhere", md.display(), d.display());
        }
    }
    Ok(())
}

/// The folders holding results.json among `paths` and their immediate sub-folders.
fn find_studies(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    for p in paths {
        if p.join("results.json").is_file() {
            found.push(p.clone());
            continue;
        }
        if !p.is_dir() {
            bail!("{}: not a study folder (no such directory)", p.display());
        }
        let mut subs: Vec<PathBuf> = std::fs::read_dir(p)
            .with_context(|| format!("{}: cannot list", p.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            // A report written next to the studies holds a results.json too; it is not a study.
            .filter(|d| d.join("results.json").is_file() && !d.join("viewer.js").is_file())
            .collect();
        if subs.is_empty() {
            bail!("{}: no results.json in it or its sub-folders (run `cvtrace study` first)", p.display());
        }
        subs.sort();
        found.extend(subs);
    }
    // One folder named twice (`study study/`, or a folder and its parent) would be one scene twice.
    for (i, d) in found.iter().enumerate() {
        if let Some(other) = found[..i].iter().find(|o| crate::cli::files::same_output(o, d)) {
            bail!("{} and {}: the same study folder is given twice", other.display(), d.display());
        }
    }
    Ok(found)
}

/// The deepest folder containing every path.
fn common_root(dirs: &[PathBuf]) -> PathBuf {
    let abs: Vec<PathBuf> = dirs.iter().map(|d| std::path::absolute(d).unwrap_or_else(|_| d.clone())).collect();
    let mut root = abs[0].clone();
    while !abs.iter().all(|d| d.starts_with(&root)) {
        if !root.pop() {
            break;
        }
    }
    root
}

fn rebase(p: &mut Option<String>, prefix: &Path) {
    if let Some(s) = p.as_mut() {
        *s = prefix.join(&*s).to_string_lossy().into_owned();
    }
}

pub fn run(args: ReportArgs) -> Result<()> {
    let dirs = find_studies(&args.studies)?;
    let root = common_root(&dirs);
    let mut scenes = Vec::new();
    for d in &dirs {
        let r = StudyResults::read_json(&d.join("results.json"))?;
        let abs = std::path::absolute(d).unwrap_or_else(|_| d.clone());
        let prefix = abs.strip_prefix(&root).unwrap_or(Path::new("")).to_path_buf();
        for mut s in r.scenes {
            rebase(&mut s.reference.image, &prefix);
            rebase(&mut s.reference.values, &prefix);
            for m in &mut s.methods {
                if args.no_ablation_images && m.ablation {
                    (m.image, m.error_map, m.difference_map, m.flip_map, m.values) = (None, None, None, None, None);
                }
                for p in [&mut m.image, &mut m.error_map, &mut m.difference_map, &mut m.flip_map, &mut m.values] {
                    rebase(p, &prefix);
                }
            }
            scenes.push(s);
        }
    }
    let results = StudyResults::new(scenes);
    // The viewer and the summary go next to the studies, never over them.
    let study_files: Vec<PathBuf> = dirs.iter().map(|d| d.join("results.json")).collect();
    let inputs: Vec<&Path> = dirs.iter().chain(&study_files).map(PathBuf::as_path).collect();
    crate::cli::files::refuse_overwriting_inputs(&args.output, &inputs)?;
    if let Some(md) = &args.markdown {
        crate::cli::files::refuse_overwriting_inputs(md, &inputs)?;
        check_markdown_path(md, &args.output, &dirs)?;
        cvtrace_streams::atomic::check_writable(md, args.force)?;
    }
    // The report claims its folder itself; its missing parents are made here, and taken back
    // if it fails.
    let made = crate::cli::files::make_parent_folders(&args.output)?;
    let written = write_report(&results, &root, &args.output, &ReportOptions { title: args.title.clone(), overwrite: args.force })
        .map(|index| crate::cli::say!("report: {}", index.display()));
    if let Err(e) = written {
        crate::cli::files::remove_empty(&made);
        return Err(e.into());
    }
    if let Some(md) = &args.markdown {
        let text = cvtrace_eval::table::markdown_summary(&results);
        cvtrace_streams::atomic::write_atomically(md, args.force, |tmp| std::fs::write(tmp, &text))?;
        crate::cli::say!("summary: {}", md.display());
    }
    Ok(())
}

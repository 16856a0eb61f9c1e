//! `cvtrace study`: the paper's protocol on one scene, in one command.
//!
//! For every requested spp `n` and seed, it renders the paired PT/CRN streams (`n` spp each)
//! and a real PT render with `2n` spp, reconstructs with every estimator, and scores each
//! against the reference: relMSE mean ± standard error, bias² and variance over seeds, time
//! per stage. A missing reference is rendered first. The folder is resumable: every render is
//! a file written atomically, so an interrupted study keeps its finished seeds and only
//! re-runs the (cheap) reconstructions. The protocol is `cvtrace_study`'s; the renders come
//! from `cvtrace_session::RenderSource`; the checks are `cli::study_setup`'s; this file runs
//! and prints.
use crate::cli::progress::{progress_style_of, TerminalProgress};
use crate::cli::say;
use crate::cli::study_setup::{prepare, read_reference, study_name, Prepared, StudyArgs};
use anyhow::{Context, Result};
use cvtrace_eval::results::ReferenceInfo;
use cvtrace_eval::{table, Reference};
use cvtrace_session::{Job, Progress, ReferenceJob, RenderSource};
use cvtrace_streams::Provenance;
use cvtrace_study::{SceneInfo, Study, REFERENCE_SEED};
use indicatif::{ProgressBar, ProgressDrawTarget};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub fn run(args: StudyArgs) -> Result<()> {
    let Prepared { spps, session, planned, pixels, columns, batches, headline, existing, reference_spp } = prepare(&args)?;
    let study = Study { columns: &columns, spps: spps.clone(), seeds: args.seeds, first_seed: args.seed, batches, headline };
    let overall = StudyProgress::default();
    // Each seed of n spp renders 2 streams of n and a PT image of 2n samples per pixel.
    overall.bar.set_length(pixels * args.seeds as u64 * spps.iter().map(|&n| 4 * n as u64).sum::<u64>());
    let shares = overall.clone();
    let probe = RenderSource::new(&session, args.output.clone(), args.view.view(), args.seed, Box::new(move || shares.share()));
    let args = &args;
    // The folders this run makes: if it fails before anything is written in them, they go again.
    let made: Vec<PathBuf> =
        args.output.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).map(Path::to_path_buf).collect();
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create the study folder", args.output.display()))?;
    if let Some(cell) = args.cell {
        // No claim of the folder: the farm renders its cells side by side, each into its own
        // file (written atomically), and the study that follows reuses them.
        let mut source = probe;
        let path = source.render_cell(cell, study.batches).map_err(|e| anyhow::anyhow!("{e}"))?;
        say!("cell {cell}: {}", path.display());
        return Ok(());
    }
    // Two studies in one folder would render the same files twice and race over them: the
    // claim comes before anything else is made in it, and a study that does not get it
    // removes only what it made itself.
    let claim = cvtrace_streams::output_lock::OutputLock::acquire(&args.output.join(".cvtrace-study.lock"), &args.output);
    let (result, made_spp_dirs) = match claim {
        Ok(_claim) => {
            let mut source = probe;
            let result = study_in_folder(args, &planned, &study, &mut source, &overall, existing, reference_spp);
            (result, source.made_folders().to_vec())
        }
        Err(e) => (Err(e.into()), Vec::new()),
    };
    if result.is_err() {
        // Only empty ones: a finished render or checkpoint stays for the next run.
        for dir in made_spp_dirs.into_iter().chain(made) {
            let _ = std::fs::remove_dir(dir);
        }
    }
    result
}

/// One progress line for all the renders of a study (streams and PT(2n) images, in pixel
/// samples), drawn on stderr when it is a terminal; a render found finished counts as done.
#[derive(Clone)]
struct StudyProgress {
    bar: ProgressBar,
}

/// The overall line: narrower than a render's, since it starts with "study".
const STUDY_PROGRESS_TEMPLATE: &str =
    "study {elapsed_precise} [{bar:16.cyan/blue}] {percent:>3}% {msamples} M, {rate} M samples/s, ETA {eta}";

impl Default for StudyProgress {
    fn default() -> Self {
        let bar = ProgressBar::hidden();
        bar.set_style(progress_style_of(STUDY_PROGRESS_TEMPLATE));
        StudyProgress { bar }
    }
}

impl StudyProgress {
    /// What one render reports to.
    fn share(&self) -> Box<dyn Progress> {
        Box::new(self.clone())
    }

    fn show(&self) {
        self.bar.set_draw_target(ProgressDrawTarget::stderr());
        self.bar.reset_eta();
    }
}

impl Progress for StudyProgress {
    fn start(&self, _total: u64, done: u64) {
        // Samples found done (a resumed or reused render) took no time now: they must not
        // enter the rate.
        if done > 0 {
            self.bar.inc(done);
            self.bar.reset_eta();
        }
    }

    fn advance(&self, samples: u64) {
        // Interrupted, the process is ending: a bar drawn now would land after the note.
        if !cvtrace_streams::atomic::interrupted() {
            self.bar.inc(samples);
        }
    }

    fn suspend(&self, f: &mut dyn FnMut()) {
        self.bar.suspend(f)
    }
}

/// The study in its folder, which exists and is this run's: the reference (`existing`, or
/// rendered with `reference_spp`), then every spp value and seed, then the tables and images.
fn study_in_folder(
    args: &StudyArgs,
    planned: &Provenance,
    study: &Study,
    source: &mut RenderSource,
    overall: &StudyProgress,
    existing: Option<(Reference, Option<u32>)>,
    reference_spp: u32,
) -> Result<()> {
    // The reference: reuse the file, or render it (resumable through render's checkpoint).
    let session = source.session;
    let (reference, reference_spp) = match existing {
        Some(r) => r,
        None => {
            tracing::info!("{} does not exist: rendering a {reference_spp} spp reference first", args.reference.display());
            let job = ReferenceJob::replacing(args.reference.clone(), args.view.view(), reference_spp, REFERENCE_SEED);
            // Its missing folders are made, as `render` makes them, and taken back if it fails.
            let made = crate::cli::files::make_parent_folders(&args.reference)?;
            if let Err(e) = session.render(&Job::Reference(job), &TerminalProgress::default()) {
                crate::cli::files::remove_empty(&made);
                return Err(e.into());
            }
            read_reference(args)?
        }
    };
    let scene = SceneInfo {
        name: study_name(args),
        reference: ReferenceInfo {
            path: ReferenceInfo::path_of(&args.reference),
            spp: reference_spp,
            image: None,
            noise: None,
            values: None,
        },
        // The seed differs between the renders; it is in each file.
        render: planned.fields().into_iter().filter(|(k, _)| *k != "seed").map(|(k, v)| (k.to_string(), v)).collect(),
    };
    overall.show();
    let start = Instant::now();
    let results = study.run(source, &reference, scene, &args.output);
    overall.bar.finish_and_clear();
    let results = results?;
    say!("{}", table::terminal_report(&results).trim_end_matches('\n'));
    say!(
        "study written to {} in {} (make a viewer with: cvtrace report {} -o report/)",
        args.output.display(),
        wall_time(start.elapsed().as_secs_f64()),
        args.output.display()
    );
    Ok(())
}

/// Wall-clock time as "42.0 s", "3 min 05 s" or "2 h 07 min".
fn wall_time(secs: f64) -> String {
    let whole = secs.round() as u64;
    if secs < 60.0 {
        format!("{secs:.1} s")
    } else if whole < 3600 {
        format!("{} min {:02} s", whole / 60, whole % 60)
    } else {
        format!("{} h {:02} min", whole / 3600, whole % 3600 / 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_progress_counts_every_render_and_fits_80_columns() {
        let overall = StudyProgress::default();
        overall.bar.set_length(100);
        // A render from scratch, one resumed at 10 of 30, one found finished.
        let a = overall.share();
        a.start(40, 0);
        a.advance(25);
        a.advance(15);
        a.finish();
        let b = overall.share();
        b.start(30, 10);
        b.advance(20);
        let c = overall.share();
        c.start(30, 30);
        c.finish();
        assert_eq!(overall.bar.position(), overall.bar.length().unwrap());
        let widest = crate::cli::progress::widest_progress_line(STUDY_PROGRESS_TEMPLATE);
        assert!(!widest.contains('{') && widest.starts_with("study "), "{widest}");
        assert!(widest.chars().count() <= crate::cli::progress::PROGRESS_COLUMNS, "{} columns: {widest}", widest.chars().count());
    }

    #[test]
    fn wall_times_read_at_a_glance() {
        assert_eq!(wall_time(4.04), "4.0 s");
        assert_eq!(wall_time(185.2), "3 min 05 s");
        assert_eq!(wall_time(7620.0), "2 h 07 min");
    }
}

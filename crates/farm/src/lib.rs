//! cvtrace on a Slurm cluster. A render is split into parts (`cvtrace render --part I/N`), run
//! as one sbatch job array, and joined by a merge job that depends on the parts (`afterok`):
//! Slurm schedules, places and retries; this crate writes the job folder, submits it, and tells
//! which parts are done, failed or missing. Nothing here renders or needs Embree.
//!
//! A job folder is self-contained: `manifest.json` (the plan), `commands.txt` (the exact
//! command of every part and of the merge), `parts.sbatch` (the array, one part per task),
//! `merge.sbatch`, and what running it leaves: `parts/part-NNN.exr`, `logs/`, `status/` (each
//! task's exit code, written by the script itself, since clusters without accounting forget
//! finished jobs) and `submissions.json` (the job ids).
//!
//! A study (`kind` `study`) is the same folder with cells for parts: each array task renders
//! one cell (`cvtrace study ... --cell KIND:SPP:SEED_INDEX`: a stream pair or its PT(2n) image)
//! straight into the study folder, under the name the study gives it (`cvtrace_study::files`),
//! and the final job, in place of the merge, is the plain `cvtrace study` with the same
//! arguments, which finds every render finished and only reconstructs and scores. The scripts
//! are `cells.sbatch` and `study.sbatch` then.
#![forbid(unsafe_code)]

use cvtrace_streams::atomic::{create_dir_all, write_atomically};
use cvtrace_streams::parts::PartHeader;
use cvtrace_study::files::{cell_file, cells, timing_file, Cell};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The layout of `manifest.json` this crate writes and reads.
pub const FORMAT: &str = "cvtrace-farm-v1";

#[derive(Debug, thiserror::Error)]
pub enum FarmError {
    #[error("{path}: {message}")]
    Folder { path: PathBuf, message: String },
    #[error(transparent)]
    File(#[from] cvtrace_streams::StreamError),
    #[error("{command}: {message}")]
    Slurm { command: String, message: String },
}

fn folder_error(path: &Path, message: impl Into<String>) -> FarmError {
    FarmError::Folder { path: path.to_path_buf(), message: message.into() }
}

/// What a farm job renders: everything that goes into the parts' commands.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Plan {
    /// `streams`, `reference` or `study`.
    pub kind: String,
    /// The cvtrace binary every task runs (absolute).
    pub cvtrace: PathBuf,
    /// The folder the commands run in (absolute): the scene and output are as the user gave
    /// them, so the merged file records the same scene path as a one-shot render there.
    pub workdir: PathBuf,
    pub scene: String,
    /// The merged file, or a study's folder.
    pub output: String,
    /// The flags of every part's render (samples, batches or pass size, seed, view), exact; of a
    /// study, all its arguments as the user gave them (the scene and `-o` among them).
    pub render_args: Vec<String>,
    /// Batches (stream renders) or passes (references), and the parts they are split into.
    pub units: u32,
    /// Samples per pass of a reference (its parts record sample ranges).
    pub pass_spp: Option<u32>,
    pub parts: u32,
    /// Whether the merge may replace an existing output.
    pub replace_output: bool,
    /// A study's spp values and seeds, whose cells are the parts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub study: Option<StudyCells>,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StudyCells {
    /// Samples per stream, ascending.
    pub spps: Vec<u32>,
    pub seeds: u32,
}

/// One part: its range of units, its file and its exact command.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PartEntry {
    pub index: u32,
    /// The units `first..end` (of a study cell: its seed index `first`).
    pub first: u32,
    pub end: u32,
    pub file: PathBuf,
    pub command: Vec<String>,
    /// A study cell, `KIND:SPP:SEED_INDEX`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub plan: Plan,
    pub parts: Vec<PartEntry>,
    pub merge: Vec<String>,
    /// Arguments for sbatch (`--sbatch-arg`): in both scripts' `#SBATCH` lines, so that a
    /// submission by hand gets them too, and on every submission's command line.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sbatch_args: Vec<String>,
}

/// The job ids of the folder's submissions, oldest first.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Submissions {
    pub arrays: Vec<ArraySubmission>,
    pub merges: Vec<String>,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ArraySubmission {
    pub job: String,
    pub tasks: Vec<u32>,
}

/// A job folder on disk.
#[derive(Clone, Debug)]
pub struct JobFolder {
    pub dir: PathBuf,
    pub manifest: Manifest,
}

impl Manifest {
    /// The manifest of `plan` with its parts in `dir` (absolute).
    pub fn new(plan: Plan, dir: &Path) -> Manifest {
        if let Some(study) = &plan.study {
            return Manifest::study(plan.clone(), study.clone());
        }
        let unit_flag = "--part";
        let parts = (0..plan.parts)
            .map(|i| {
                let at = |i: u32| (i as u64 * plan.units as u64 / plan.parts as u64) as u32;
                let file = dir.join("parts").join(format!("part-{i:03}.exr"));
                let mut command = vec![plan.cvtrace.to_string_lossy().into_owned(), "render".into(), plan.scene.clone()];
                command.extend(plan.render_args.iter().cloned());
                command.extend([unit_flag.into(), format!("{i}/{}", plan.parts), "-o".into(), file.to_string_lossy().into_owned()]);
                // A part's file belongs to the farm: a rerun replaces what an earlier run left.
                command.push("--force".into());
                PartEntry { index: i, first: at(i), end: at(i + 1), file, command, cell: None }
            })
            .collect::<Vec<_>>();
        let mut merge = vec![plan.cvtrace.to_string_lossy().into_owned(), "merge".into()];
        merge.extend(parts.iter().map(|p| p.file.to_string_lossy().into_owned()));
        merge.extend(["-o".into(), plan.output.clone()]);
        if plan.replace_output {
            merge.push("--force".into());
        }
        Manifest { format: FORMAT.into(), plan, parts, merge, sbatch_args: Vec::new() }
    }

    /// The cells of a study, in the folder its commands write (`output` from `workdir`).
    fn study(plan: Plan, study: StudyCells) -> Manifest {
        let folder = plan.workdir.join(&plan.output);
        let cvtrace = plan.cvtrace.to_string_lossy().into_owned();
        let study_command = |cell: Option<Cell>| {
            let mut c = vec![cvtrace.clone(), "study".into()];
            c.extend(plan.render_args.iter().cloned());
            if let Some(cell) = cell {
                c.extend(["--cell".into(), cell.to_string()]);
            }
            c
        };
        let parts = cells(&study.spps, study.seeds)
            .into_iter()
            .enumerate()
            .map(|(i, cell)| PartEntry {
                index: i as u32,
                first: cell.index,
                end: cell.index + 1,
                file: cell_file(&folder, cell),
                command: study_command(Some(cell)),
                cell: Some(cell.to_string()),
            })
            .collect();
        let merge = study_command(None);
        Manifest { format: FORMAT.into(), plan, parts, merge, sbatch_args: Vec::new() }
    }

    fn is_study(&self) -> bool {
        self.plan.study.is_some()
    }

    /// The array's and the final job's scripts, and what the tasks and the final job are called.
    pub fn scripts(&self) -> Scripts {
        if self.is_study() {
            Scripts { array: "cells.sbatch", last: "study.sbatch", task: "cell", last_name: "study" }
        } else {
            Scripts { array: "parts.sbatch", last: "merge.sbatch", task: "part", last_name: "merge" }
        }
    }

    /// What the final job writes: the merged file, or the study's `results.json`.
    pub fn final_output(&self) -> PathBuf {
        let out = self.plan.workdir.join(&self.plan.output);
        if self.is_study() {
            out.join("results.json")
        } else {
            out
        }
    }

    /// "batches 2..4", "passes 2..4", or a cell's "streams, 32 spp, seed index 0".
    pub fn describe(&self, p: &PartEntry) -> String {
        if let Some(cell) = p.cell.as_deref().and_then(|c| c.parse::<Cell>().ok()) {
            return format!("{}, {} spp, seed index {}", cell.kind.name(), cell.spp, cell.index);
        }
        let unit = if self.plan.kind == "streams" { "batches" } else { "passes" };
        format!("{unit} {}..{}", p.first, p.end)
    }
}

/// The file names and words of a job folder's two jobs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scripts {
    pub array: &'static str,
    pub last: &'static str,
    /// `part` or `cell`.
    pub task: &'static str,
    /// `merge` or `study`.
    pub last_name: &'static str,
}

/// Quotes `s` for bash when it holds anything but plain path characters.
pub fn quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

fn command_line(args: &[String]) -> String {
    args.iter().map(|a| quote(a)).collect::<Vec<_>>().join(" ")
}

/// Quotes `s` for an `#SBATCH` line, which sbatch splits itself: at whitespace outside quotes,
/// with a backslash escaping the next character and an unquoted `#` ending the line. Double
/// quotes with `\`, `"` and `#` escaped read back the same in every Slurm version (older ones
/// know no single quotes and end the line at any `#`).
pub fn quote_for_sbatch(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
        return s.to_string();
    }
    let mut out = String::from("\"");
    for c in s.chars() {
        if matches!(c, '\\' | '"' | '#') {
            out.push('\\');
        }
        out.push(c);
    }
    out.push('"');
    out
}

/// A path in sbatch's `--output` pattern: `%` doubled, so that only the pattern's own `%a` and
/// `%j` are replaced.
fn output_pattern(dir: &str, file: &str) -> String {
    format!("{}/{file}", dir.replace('%', "%%"))
}

fn write_text(path: &Path, text: &str) -> Result<(), FarmError> {
    write_atomically(path, true, |tmp| std::fs::write(tmp, text))?;
    Ok(())
}

impl JobFolder {
    /// Writes the job folder of `plan` at `dir` with the arguments for sbatch, or opens the one
    /// there if it was written for the same plan; a folder of another plan is an error
    /// (nothing is changed). Arguments given replace the folder's (its scripts are written
    /// again); none given keeps them.
    pub fn create(dir: &Path, plan: Plan, sbatch_args: &[String]) -> Result<JobFolder, FarmError> {
        let dir = std::path::absolute(dir).map_err(|e| folder_error(dir, e.to_string()))?;
        // sbatch reads its options line by line.
        if dir.to_string_lossy().contains(['\n', '\r']) || sbatch_args.iter().any(|a| a.contains(['\n', '\r'])) {
            return Err(folder_error(&dir, "a line break in the job folder's path or an --sbatch-arg cannot go into an sbatch script"));
        }
        let mut manifest = Manifest::new(plan, &dir);
        manifest.sbatch_args = sbatch_args.to_vec();
        if dir.join("manifest.json").exists() {
            let mut existing = JobFolder::open(&dir)?;
            // The job is its plan and commands; the sbatch arguments are how it is submitted.
            let recorded = std::mem::take(&mut existing.manifest.sbatch_args);
            if existing.manifest != (Manifest { sbatch_args: Vec::new(), ..manifest.clone() }) {
                let (a, b) = (&existing.manifest.plan, &manifest.plan);
                let what = if a.scene != b.scene || a.kind != b.kind {
                    "another scene or kind of render"
                } else if a.render_args != b.render_args || a.study != b.study {
                    "other render settings"
                } else if a.parts != b.parts {
                    "another number of parts"
                } else {
                    "another output, binary or folder"
                };
                return Err(folder_error(
                    &dir,
                    format!(
                        "holds a farm job of {what} ({}); give another --dir, or remove the folder to start over",
                        command_line(&existing.manifest.parts[0].command)
                    ),
                ));
            }
            if sbatch_args.is_empty() || sbatch_args == recorded {
                existing.manifest.sbatch_args = recorded;
            } else {
                existing.manifest.sbatch_args = manifest.sbatch_args;
                existing.write_scripts()?;
                existing.write_manifest()?;
            }
            return Ok(existing);
        }
        if dir.exists() && std::fs::read_dir(&dir).map(|mut d| d.next().is_some()).unwrap_or(true) {
            return Err(folder_error(&dir, "exists and is not a farm job folder (no manifest.json); give an empty or new --dir"));
        }
        for sub in ["", "parts", "logs", "status"] {
            create_dir_all(&dir.join(sub))?;
        }
        let folder = JobFolder { dir, manifest };
        folder.write_scripts()?;
        folder.write_manifest()?;
        Ok(folder)
    }

    fn write_manifest(&self) -> Result<(), FarmError> {
        let json = serde_json::to_string_pretty(&self.manifest).expect("a manifest serialises");
        write_text(&self.dir.join("manifest.json"), &(json + "\n"))
    }

    /// Opens the job folder at `dir`.
    pub fn open(dir: &Path) -> Result<JobFolder, FarmError> {
        let dir = std::path::absolute(dir).map_err(|e| folder_error(dir, e.to_string()))?;
        let path = dir.join("manifest.json");
        let text = std::fs::read_to_string(&path).map_err(|e| folder_error(&path, format!("not a farm job folder: {e}")))?;
        let manifest: Manifest = serde_json::from_str(&text).map_err(|e| folder_error(&path, format!("not a farm manifest: {e}")))?;
        if manifest.format != FORMAT {
            return Err(folder_error(&path, format!("manifest format {:?}, this cvtrace reads {FORMAT:?}", manifest.format)));
        }
        Ok(JobFolder { dir, manifest })
    }

    fn status_file(&self, what: &str) -> PathBuf {
        self.dir.join("status").join(format!("{what}.exit"))
    }

    fn write_scripts(&self) -> Result<(), FarmError> {
        let m = &self.manifest;
        let d = self.dir.to_string_lossy();
        let workdir = quote(&m.plan.workdir.to_string_lossy());
        let mut cases = String::new();
        for p in &m.parts {
            cases += &format!("    {}) {} ;;\n", p.index, command_line(&p.command));
        }
        let names = m.scripts();
        // sbatch reads these lines itself: paths and arguments quoted for it, not for bash.
        let sbatch = |log: &str| {
            let mut line = format!("#SBATCH {}\n", quote_for_sbatch(&format!("--output={}", output_pattern(&d, log))));
            if !m.sbatch_args.is_empty() {
                line += &format!("#SBATCH {}\n", m.sbatch_args.iter().map(|a| quote_for_sbatch(a)).collect::<Vec<_>>().join(" "));
            }
            line
        };
        let what = if m.is_study() { "One cell of the study (a render)" } else { "One part of the render" };
        let parts = format!(
            "#!/bin/bash\n\
             #SBATCH --job-name=cvtrace-{task}\n\
             {options}\
             # {what} per array task: sbatch --array=0-{last} {d}/{array}\n\
             # (commands.txt lists the same commands). The task's exit code goes to status/, which\n\
             # `cvtrace farm status` reads: a cluster without accounting forgets finished jobs.\n\
             set -euo pipefail\n\
             task=${{SLURM_ARRAY_TASK_ID:?submit this script with sbatch --array}}\n\
             status=$(printf '%s/status/part-%03d.exit' {dq} \"$task\")\n\
             rm -f \"$status\"\n\
             trap 'echo $? > \"$status\"' EXIT\n\
             cd {workdir}\n\
             case \"$task\" in\n\
             {cases}    *) echo \"no part $task in this job\" >&2; exit 2 ;;\n\
             esac\n",
            last = m.parts.len() - 1,
            dq = quote(&d),
            task = names.task,
            array = names.array,
            options = sbatch("logs/part-%a.out"),
        );
        let what = if m.is_study() {
            "The study: reconstructions and statistics on the cells' renders"
        } else {
            "The merge of every part into the output"
        };
        let merge = format!(
            "#!/bin/bash\n\
             #SBATCH --job-name=cvtrace-{last_name}\n\
             {options}\
             # {what}; submitted with --dependency=afterok on the array.\n\
             set -euo pipefail\n\
             status={status}\n\
             rm -f \"$status\"\n\
             trap 'echo $? > \"$status\"' EXIT\n\
             cd {workdir}\n\
             {merge}\n",
            status = quote(&self.status_file("merge").to_string_lossy()),
            merge = command_line(&m.merge),
            last_name = names.last_name,
            options = sbatch(&format!("logs/{}-%j.out", names.last_name)),
        );
        let mut commands = format!("# cd {workdir}\n");
        for p in &m.parts {
            commands += &(command_line(&p.command) + "\n");
        }
        commands += &(command_line(&m.merge) + "\n");
        write_text(&self.dir.join(names.array), &parts)?;
        write_text(&self.dir.join(names.last), &merge)?;
        write_text(&self.dir.join("commands.txt"), &commands)?;
        Ok(())
    }

    pub fn submissions(&self) -> Result<Submissions, FarmError> {
        let path = self.dir.join("submissions.json");
        match std::fs::read_to_string(&path) {
            Ok(t) => serde_json::from_str(&t).map_err(|e| folder_error(&path, format!("not a submissions record: {e}"))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Submissions::default()),
            Err(e) => Err(folder_error(&path, e.to_string())),
        }
    }

    fn save_submissions(&self, s: &Submissions) -> Result<(), FarmError> {
        write_text(&self.dir.join("submissions.json"), &(serde_json::to_string_pretty(s).expect("serialises") + "\n"))
    }

    /// The exit code a finished task wrote for `what` (`part-003`, `merge`).
    fn exit_code(&self, what: &str) -> Option<i32> {
        std::fs::read_to_string(self.status_file(what)).ok()?.trim().parse().ok()
    }

    /// Whether part `p`'s file is there and is that part (its header reads and holds its range);
    /// a study cell, whether its render and the timing written after it are there (the study
    /// checks the render's provenance when it reuses it).
    fn part_done(&self, p: &PartEntry) -> bool {
        if p.cell.is_some() {
            return p.file.is_file() && timing_file(&p.file).is_file();
        }
        let Ok(h) = PartHeader::read(&p.file) else { return false };
        match self.manifest.plan.pass_spp {
            None => h.range == (p.first..p.end),
            // A reference part records its samples: whole passes, the last one maybe short.
            Some(pass) => {
                let spp = h.provenance.spp.unwrap_or(0);
                h.range == (p.first * pass..(p.end * pass).min(spp))
            }
        }
    }

    /// The state of every part and of the merge, from the files and from `slurm`.
    pub fn status(&self, slurm: &dyn Scheduler) -> Result<Status, FarmError> {
        let subs = self.submissions()?;
        // The newest submission of each task, and what Slurm says of it (nothing once the job
        // has aged out of the controller).
        let mut latest: Vec<Option<(String, Option<String>)>> = vec![None; self.manifest.parts.len()];
        for a in &subs.arrays {
            let states = slurm.states(&a.job).unwrap_or_default();
            for &t in &a.tasks {
                let state = states.iter().find(|(task, _)| *task == Some(t)).map(|(_, s)| s.clone());
                if let Some(slot) = latest.get_mut(t as usize) {
                    *slot = Some((a.job.clone(), state));
                }
            }
        }
        let parts = self
            .manifest
            .parts
            .iter()
            .map(|p| {
                let submitted = latest[p.index as usize].clone();
                let slurm_state = submitted.as_ref().and_then(|(_, s)| s.clone());
                let state = if self.part_done(p) {
                    PartState::Done
                } else if let Some(s) = slurm_state.as_deref().filter(|s| is_active(s)) {
                    PartState::Queued(s.to_string())
                } else if let Some(code) = self.exit_code(&format!("part-{:03}", p.index)).filter(|c| *c != 0) {
                    PartState::Failed(format!("exit code {code}"))
                } else if let Some(s) = slurm_state.filter(|s| s != "COMPLETED") {
                    PartState::Failed(s.to_lowercase())
                } else if self.exit_code(&format!("part-{:03}", p.index)) == Some(0) {
                    PartState::Failed("exited 0 but its file is missing or not this part".into())
                } else {
                    PartState::Missing
                };
                PartReport { part: p.clone(), job: submitted.map(|(j, _)| j), state }
            })
            .collect();
        let merge_job = subs.merges.last().cloned();
        let merge_slurm = merge_job.as_ref().and_then(|j| slurm.states(j).ok()).and_then(|s| s.first().map(|(_, s)| s.clone()));
        let output = self.manifest.final_output();
        let merge = match (self.exit_code("merge"), merge_slurm) {
            (_, Some(s)) if is_active(&s) => MergeState::Queued(s),
            (Some(0), _) if output.is_file() => MergeState::Done,
            (Some(code), _) if code != 0 => MergeState::Failed(format!("exit code {code}")),
            (_, Some(s)) if s != "COMPLETED" => MergeState::Failed(s.to_lowercase()),
            _ if merge_job.is_some() => MergeState::Failed("not run".into()),
            _ => MergeState::NotSubmitted,
        };
        Ok(Status { parts, merge, merge_job, output })
    }

    /// Submits what is left: the parts that are missing or failed (one array), and a merge that
    /// depends on every part not yet done. Parts still queued or running are left alone.
    pub fn submit(&self, slurm: &dyn Scheduler, sbatch_args: &[String]) -> Result<Submitted, FarmError> {
        let status = self.status(slurm)?;
        if status.merge == MergeState::Done && status.parts.iter().all(|p| p.state == PartState::Done) {
            return Ok(Submitted::default());
        }
        let todo: Vec<u32> =
            status.parts.iter().filter(|p| matches!(p.state, PartState::Missing | PartState::Failed(_))).map(|p| p.part.index).collect();
        if todo.is_empty() && matches!(status.merge, MergeState::Queued(_)) {
            return Ok(Submitted { waiting: status.merge_job, ..Submitted::default() });
        }
        let mut subs = self.submissions()?;
        // A merge still waiting on the earlier parts would run too: one merge is enough.
        if let (Some(job), MergeState::Queued(_)) = (&status.merge_job, &status.merge) {
            slurm.cancel(job)?;
        }
        let mut deps: Vec<String> = status
            .parts
            .iter()
            .filter_map(|p| match (&p.state, &p.job) {
                (PartState::Queued(_), Some(job)) => Some(format!("{job}_{}", p.part.index)),
                _ => None,
            })
            .collect();
        let mut array = None;
        if !todo.is_empty() {
            for &i in &todo {
                let _ = std::fs::remove_file(self.status_file(&format!("part-{i:03}")));
            }
            let list = todo.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
            let mut args = sbatch_args.to_vec();
            args.extend([format!("--array={list}"), self.dir.join(self.manifest.scripts().array).to_string_lossy().into_owned()]);
            let job = slurm.submit(&args)?;
            deps.insert(0, job.clone());
            subs.arrays.push(ArraySubmission { job: job.clone(), tasks: todo.clone() });
            self.save_submissions(&subs)?;
            array = Some(job);
        }
        let _ = std::fs::remove_file(self.status_file("merge"));
        let mut args = sbatch_args.to_vec();
        if !deps.is_empty() {
            // Without --kill-on-invalid-dep a merge after a failed part would wait forever on
            // clusters that do not set DependencyParameters=kill_invalid_depend.
            args.extend([format!("--dependency=afterok:{}", deps.join(":")), "--kill-on-invalid-dep=yes".into()]);
        }
        args.push(self.dir.join(self.manifest.scripts().last).to_string_lossy().into_owned());
        let merge = slurm.submit(&args)?;
        subs.merges.push(merge.clone());
        self.save_submissions(&subs)?;
        Ok(Submitted { array, tasks: todo, merge: Some(merge), waiting: None })
    }

    /// How to submit the folder by hand.
    pub fn how_to_submit(&self) -> String {
        let d = quote(&self.dir.to_string_lossy());
        let names = self.manifest.scripts();
        // The scripts carry the sbatch arguments too; given here, they show what is submitted.
        let args: String = self.manifest.sbatch_args.iter().map(|a| format!("{} ", quote(a))).collect();
        format!(
            "array=$(sbatch --parsable --array=0-{} {args}{d}/{})\n\
             sbatch --dependency=afterok:$array --kill-on-invalid-dep=yes {args}{d}/{}\n",
            self.manifest.parts.len() - 1,
            names.array,
            names.last
        )
    }
}

/// Slurm states in which a job may still run.
fn is_active(state: &str) -> bool {
    matches!(
        state,
        "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING" | "REQUEUED" | "RESIZING" | "SUSPENDED" | "REQUEUE_HOLD" | "REQUEUE_FED"
    )
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PartState {
    /// The part's file is there and is that part.
    Done,
    /// Submitted and pending or running (the Slurm state).
    Queued(String),
    /// Ran and failed (the exit code or the Slurm state).
    Failed(String),
    /// Never submitted, or gone from the cluster without a trace.
    Missing,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MergeState {
    Done,
    Queued(String),
    Failed(String),
    NotSubmitted,
}

#[derive(Clone, Debug)]
pub struct PartReport {
    pub part: PartEntry,
    /// The job of the part's latest submission.
    pub job: Option<String>,
    pub state: PartState,
}

#[derive(Clone, Debug)]
pub struct Status {
    pub parts: Vec<PartReport>,
    pub merge: MergeState,
    pub merge_job: Option<String>,
    pub output: PathBuf,
}

/// What [`JobFolder::submit`] did: nothing (all done), or the array of parts and the merge.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Submitted {
    pub array: Option<String>,
    pub tasks: Vec<u32>,
    pub merge: Option<String>,
    /// Nothing submitted: this merge job still waits on parts that are queued or running.
    pub waiting: Option<String>,
}

/// The cluster, behind a trait so the bookkeeping is tested without one.
pub trait Scheduler {
    /// `sbatch --parsable ARGS`: the job id.
    fn submit(&self, args: &[String]) -> Result<String, FarmError>;
    /// The state of every task of `job` (`None` for a job that is no array).
    fn states(&self, job: &str) -> Result<Vec<(Option<u32>, String)>, FarmError>;
    fn cancel(&self, job: &str) -> Result<(), FarmError>;
}

/// The real Slurm commands on the PATH (with the environment's `SLURM_CONF`).
pub struct Slurm;

fn run(program: &str, args: &[String]) -> Result<String, FarmError> {
    let line = format!("{program} {}", command_line(args));
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| FarmError::Slurm { command: line.clone(), message: format!("could not run {program}: {e} (is Slurm installed?)") })?;
    if !out.status.success() {
        return Err(FarmError::Slurm { command: line, message: String::from_utf8_lossy(&out.stderr).trim().to_string() });
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

impl Scheduler for Slurm {
    fn submit(&self, args: &[String]) -> Result<String, FarmError> {
        let mut all = vec!["--parsable".to_string()];
        all.extend(args.iter().cloned());
        let out = run("sbatch", &all)?;
        // `--parsable` prints `id` or `id;cluster`.
        let id = out.trim().split(';').next().unwrap_or("").to_string();
        if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
            return Err(FarmError::Slurm { command: "sbatch".into(), message: format!("unexpected output {out:?}") });
        }
        Ok(id)
    }

    fn states(&self, job: &str) -> Result<Vec<(Option<u32>, String)>, FarmError> {
        let out = run(
            "squeue",
            &["-h".into(), "-t".into(), "all".into(), "--array".into(), "-j".into(), job.into(), "-o".into(), "%K %T".into()],
        )?;
        Ok(parse_states(&out))
    }

    fn cancel(&self, job: &str) -> Result<(), FarmError> {
        run("scancel", &[job.to_string()]).map(|_| ())
    }
}

/// `squeue -o "%K %T"` lines: the array task (`N/A` for a job that is no array) and the state.
pub fn parse_states(out: &str) -> Vec<(Option<u32>, String)> {
    out.lines()
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            let (task, state) = (it.next()?, it.next()?);
            Some((task.parse().ok(), state.to_string()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    /// A cluster that records submissions and reports the states it is told.
    #[derive(Default)]
    struct Fake {
        submitted: RefCell<Vec<Vec<String>>>,
        states: RefCell<Vec<(String, Option<u32>, String)>>,
        cancelled: RefCell<Vec<String>>,
    }

    impl Scheduler for Fake {
        fn submit(&self, args: &[String]) -> Result<String, FarmError> {
            self.submitted.borrow_mut().push(args.to_vec());
            Ok((100 + self.submitted.borrow().len()).to_string())
        }
        fn states(&self, job: &str) -> Result<Vec<(Option<u32>, String)>, FarmError> {
            Ok(self.states.borrow().iter().filter(|(j, _, _)| j == job).map(|(_, t, s)| (*t, s.clone())).collect())
        }
        fn cancel(&self, job: &str) -> Result<(), FarmError> {
            self.cancelled.borrow_mut().push(job.into());
            Ok(())
        }
    }

    fn plan(dir: &Path) -> Plan {
        Plan {
            kind: "streams".into(),
            cvtrace: "/opt/cvtrace".into(),
            workdir: dir.to_path_buf(),
            scene: "scene dir/cbox.gltf".into(),
            output: "cbox.streams.exr".into(),
            render_args: vec!["--spp".into(), "16".into(), "--batches".into(), "8".into()],
            units: 8,
            pass_spp: None,
            parts: 3,
            replace_output: false,
            study: None,
        }
    }

    #[test]
    fn folder_holds_every_command_and_refuses_another_plan() {
        let tmp = tempfile::tempdir().unwrap();
        let f = JobFolder::create(&tmp.path().join("job"), plan(tmp.path()), &[]).unwrap();
        let ranges: Vec<_> = f.manifest.parts.iter().map(|p| (p.first, p.end)).collect();
        assert_eq!(ranges, [(0, 2), (2, 5), (5, 8)]);
        let script = std::fs::read_to_string(f.dir.join("parts.sbatch")).unwrap();
        assert!(script.starts_with("#!/bin/bash\n") && script.contains("\nset -euo pipefail\n"), "{script}");
        assert!(script.contains("1) /opt/cvtrace render 'scene dir/cbox.gltf' --spp 16 --batches 8 --part 1/3 -o "), "{script}");
        let commands = std::fs::read_to_string(f.dir.join("commands.txt")).unwrap();
        assert_eq!(commands.lines().filter(|l| l.contains(" render ")).count(), 3);
        assert!(commands.lines().last().unwrap().contains(" merge ") && commands.contains("-o cbox.streams.exr"));
        // The same plan opens the folder; another is refused.
        JobFolder::create(&f.dir, plan(tmp.path()), &[]).unwrap();
        let e = JobFolder::create(&f.dir, Plan { parts: 4, ..plan(tmp.path()) }, &[]).unwrap_err().to_string();
        assert!(e.contains("another number of parts"), "{e}");
    }

    #[test]
    fn only_missing_and_failed_parts_are_resubmitted() {
        let tmp = tempfile::tempdir().unwrap();
        let f = JobFolder::create(&tmp.path().join("job"), plan(tmp.path()), &[]).unwrap();
        let slurm = Fake::default();
        let s = f.submit(&slurm, &["--partition=x".into()]).unwrap();
        assert_eq!((s.array.as_deref(), s.tasks.as_slice(), s.merge.as_deref()), (Some("101"), &[0, 1, 2][..], Some("102")));
        let sub = slurm.submitted.borrow().clone();
        assert!(sub[0].contains(&"--array=0,1,2".to_string()) && sub[0][0] == "--partition=x");
        assert!(sub[1].contains(&"--dependency=afterok:101".to_string()), "{:?}", sub[1]);

        // Part 0 failed, part 1 still runs, part 2 pends; the merge was cancelled.
        std::fs::write(f.dir.join("status/part-000.exit"), "1\n").unwrap();
        *slurm.states.borrow_mut() = vec![
            ("101".into(), Some(0), "FAILED".into()),
            ("101".into(), Some(1), "RUNNING".into()),
            ("101".into(), Some(2), "PENDING".into()),
            ("102".into(), None, "CANCELLED".into()),
        ];
        let st = f.status(&slurm).unwrap();
        let states: Vec<_> = st.parts.iter().map(|p| p.state.clone()).collect();
        assert_eq!(
            states,
            [PartState::Failed("exit code 1".into()), PartState::Queued("RUNNING".into()), PartState::Queued("PENDING".into())]
        );
        assert_eq!(st.merge, MergeState::Failed("cancelled".into()));
        let s = f.submit(&slurm, &[]).unwrap();
        assert_eq!(s.tasks, [0]);
        let sub = slurm.submitted.borrow().clone();
        assert!(sub[2].contains(&"--array=0".to_string()), "{:?}", sub[2]);
        assert!(sub[3].contains(&"--dependency=afterok:103:101_1:101_2".to_string()), "{:?}", sub[3]);
        assert!(slurm.cancelled.borrow().is_empty());
    }

    #[test]
    fn a_study_folder_has_a_cell_per_task_and_the_study_after_them() {
        let tmp = tempfile::tempdir().unwrap();
        let study = Plan {
            kind: "study".into(),
            output: "out/study".into(),
            render_args: ["scene dir/cbox.gltf", "--spp", "8,16", "--seeds", "2", "-o", "out/study"].map(String::from).to_vec(),
            units: 8,
            parts: 8,
            study: Some(StudyCells { spps: vec![8, 16], seeds: 2 }),
            ..plan(tmp.path())
        };
        let f = JobFolder::create(&tmp.path().join("job"), study, &[]).unwrap();
        let m = &f.manifest;
        assert_eq!(m.parts.len(), 8);
        let p = &m.parts[3];
        assert_eq!(p.file, tmp.path().join("out/study/spp00008/seed-001.pt2n.exr"));
        assert_eq!(m.describe(p), "pt2n, 8 spp, seed index 1");
        assert_eq!(p.command[1..].join(" "), "study scene dir/cbox.gltf --spp 8,16 --seeds 2 -o out/study --cell pt2n:8:1");
        assert_eq!(m.merge[1..].join(" "), "study scene dir/cbox.gltf --spp 8,16 --seeds 2 -o out/study");
        assert_eq!(m.final_output(), tmp.path().join("out/study/results.json"));
        let script = std::fs::read_to_string(f.dir.join("cells.sbatch")).unwrap();
        assert!(script.contains("    3) /opt/cvtrace study 'scene dir/cbox.gltf' --spp 8,16 --seeds 2 -o out/study --cell pt2n:8:1 ;;"));
        assert!(std::fs::read_to_string(f.dir.join("study.sbatch")).unwrap().contains("\n/opt/cvtrace study 'scene dir/cbox.gltf'"));

        // A cell is done once its render and its timing are there.
        let slurm = Fake::default();
        std::fs::create_dir_all(p.file.parent().unwrap()).unwrap();
        std::fs::write(&p.file, "exr").unwrap();
        assert_eq!(f.status(&slurm).unwrap().parts[3].state, PartState::Missing);
        std::fs::write(p.file.with_extension("seconds"), "1.0\n").unwrap();
        assert_eq!(f.status(&slurm).unwrap().parts[3].state, PartState::Done);
        let s = f.submit(&slurm, &[]).unwrap();
        assert_eq!(s.tasks, [0, 1, 2, 4, 5, 6, 7]);
        let sub = slurm.submitted.borrow().clone();
        assert!(sub[0].last().unwrap().ends_with("job/cells.sbatch") && sub[1].last().unwrap().ends_with("job/study.sbatch"), "{sub:?}");
    }

    #[test]
    fn sbatch_arguments_and_odd_paths_reach_the_scripts() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("job dir #1 50%");
        let args = vec!["--partition=gpu".to_string(), "--comment=a \"b\"".to_string()];
        let f = JobFolder::create(&dir, plan(tmp.path()), &args).unwrap();
        let script = std::fs::read_to_string(f.dir.join("parts.sbatch")).unwrap();
        let d = f.dir.to_string_lossy().replace('#', "\\#").replace('%', "%%");
        assert!(script.contains(&format!("\n#SBATCH \"--output={d}/logs/part-%a.out\"\n")), "{script}");
        assert!(script.contains("\n#SBATCH --partition=gpu \"--comment=a \\\"b\\\"\"\n"), "{script}");
        assert!(std::fs::read_to_string(f.dir.join("merge.sbatch")).unwrap().contains("\n#SBATCH --partition=gpu "));
        assert!(f.how_to_submit().contains("--array=0-2 --partition=gpu '--comment=a \"b\"' "), "{}", f.how_to_submit());
        // Opened again without arguments, the folder keeps its own; with others, they replace them.
        assert_eq!(JobFolder::create(&dir, plan(tmp.path()), &[]).unwrap().manifest.sbatch_args, args);
        let f = JobFolder::create(&dir, plan(tmp.path()), &["-N1".into()]).unwrap();
        assert_eq!(JobFolder::open(&dir).unwrap().manifest.sbatch_args, ["-N1"]);
        assert!(std::fs::read_to_string(f.dir.join("parts.sbatch")).unwrap().contains("\n#SBATCH -N1\n"));
        assert_eq!(quote_for_sbatch("a b#c\\"), r#""a b\#c\\""#);
    }

    #[test]
    fn squeue_lines_parse() {
        assert_eq!(parse_states("3 FAILED\nN/A PENDING\n\n"), [(Some(3), "FAILED".to_string()), (None, "PENDING".to_string())]);
        assert_eq!(quote("a b'c"), r"'a b'\''c'");
        assert_eq!(quote("--spp=3"), "--spp=3");
    }
}

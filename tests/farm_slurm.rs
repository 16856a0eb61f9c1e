//! `cvtrace farm` against a real Slurm cluster: `scripts/slurm_local.sh` brings up munged, a
//! slurmctld and two slurmd on free ports in a scratch folder; the Cornell box is rendered in 4
//! parts as a job array with a dependent merge, and the merged files must be the bytes of a
//! one-shot render. A part made to fail leaves the merge cancelled, `farm status` names it, and
//! submitting again runs only that part and then the merge. A tiny study run as a farm job (a
//! render per task, the statistics after them) gives the numbers of `cvtrace study` itself.
//!
//! Needs root and Debian's slurm-wlm and munge (scripts/setup.sh); skipped without them unless
//! CVTRACE_REQUIRE_TOOLS is set (as `make test` does), then it fails.
mod common;

use common::{cvtrace, ok, scene, stderr, stdout, SMALL};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// The cluster of one test, taken down when dropped (also when the test fails).
struct Cluster {
    dir: PathBuf,
    conf: String,
}

impl Cluster {
    fn up(dir: &Path) -> Cluster {
        // Made first, so that a half-started cluster is taken down too.
        let mut cluster = Cluster { dir: dir.to_path_buf(), conf: String::new() };
        let out = Command::new("bash").arg(script()).args(["up", dir.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "slurm_local.sh up failed:\n{}", String::from_utf8_lossy(&out.stderr));
        let conf = stdout(&out).lines().find_map(|l| l.strip_prefix("export SLURM_CONF=")).map(str::to_string);
        cluster.conf = conf.expect("up prints SLURM_CONF");
        cluster
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash").arg(script()).args(["down", self.dir.to_str().unwrap()]).output();
    }
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/slurm_local.sh")
}

fn available() -> bool {
    let root = rustix::process::geteuid().is_root();
    let tools = ["munged", "slurmctld", "slurmd", "sbatch", "squeue"]
        .iter()
        .all(|t| Command::new("which").arg(t).output().is_ok_and(|o| o.status.success()));
    let required = std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_some();
    assert!(
        (root && tools) || !required,
        "CVTRACE_REQUIRE_TOOLS is set, but this test needs root and slurm-wlm + munge (scripts/setup.sh)"
    );
    if !(root && tools) {
        eprintln!("skipped: needs root and slurm-wlm + munge (scripts/setup.sh)");
    }
    root && tools
}

fn farm(dir: &Path, conf: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cvtrace")).env("SLURM_CONF", conf).args(args).current_dir(dir).output().unwrap()
}

/// Polls `farm status` until its merge (or study) line starts with one of `ends` and no part is
/// still queued or running (a failed part cancels the merge while others still run); returns
/// the last report.
fn wait_for(dir: &Path, conf: &str, folder: &str, ends: &[&str]) -> String {
    let start = Instant::now();
    loop {
        let out = farm(dir, conf, &["--log", "warn", "farm", "status", folder]);
        ok(&out);
        let report = stdout(&out);
        let merge = report.lines().find_map(|l| l.strip_prefix("merge: ").or_else(|| l.strip_prefix("study: "))).unwrap_or("").to_string();
        let busy = ["pending", "running", "configuring", "completing"].iter().any(|s| report.contains(&format!(": {s}")));
        if ends.iter().any(|e| merge.starts_with(e)) && !busy {
            return report;
        }
        assert!(start.elapsed() < Duration::from_secs(180), "the farm job did not end in time:\n{report}");
        std::thread::sleep(Duration::from_millis(300));
    }
}

fn same_bytes(a: &Path, b: &Path) {
    assert!(std::fs::read(a).unwrap() == std::fs::read(b).unwrap(), "{} and {} differ", a.display(), b.display());
}

#[test]
fn farm_renders_on_a_real_slurm_cluster_merge_exactly_and_rerun_only_failed_parts() {
    if !available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cluster = Cluster::up(&tmp.path().join("slurm"));
    let conf = cluster.conf.clone();
    // `up` again finds the running cluster.
    let out = Command::new("bash").arg(script()).args(["up", cluster.dir.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stderr).contains("already up"), "{out:?}");
    assert!(stdout(&out).contains(&conf), "{out:?}");
    let work = tmp.path().join("work");
    std::fs::create_dir(&work).unwrap();
    let d = work.as_path();
    let s = scene();
    let sp = s.to_str().unwrap();

    // A stream file in 4 parts of 8 batches, against the one-shot render.
    let streams = [&["--spp", "16", "--batches", "8", "--seed", "3"][..], SMALL].concat();
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "-o", "one.streams.exr"][..], &streams].concat()));
    let out = farm(
        d,
        &conf,
        &[&["--log", "warn", "farm", "render", sp, "--parts", "4", "-o", "cbox.streams.exr", "--submit"][..], &streams].concat(),
    );
    ok(&out);
    assert!(stdout(&out).contains("submitted parts 0,1,2,3 as array job"), "{}", stdout(&out));
    let report = wait_for(d, &conf, "cbox.streams.farm", &["done", "failed", "cancelled"]);
    assert!(report.contains("4 of 4 parts done"), "{report}");
    same_bytes(&d.join("one.streams.exr"), &d.join("cbox.streams.exr"));
    for name in ["parts.sbatch", "merge.sbatch", "commands.txt", "manifest.json"] {
        assert!(d.join("cbox.streams.farm").join(name).is_file(), "{name}");
    }

    // A reference in 4 ranges of passes (6 passes of 4 samples, the last of 2).
    let reference = [&["--reference", "--spp", "22", "--pass-spp", "4", "--seed", "1"][..], SMALL].concat();
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "-o", "one.ref.exr"][..], &reference].concat()));
    ok(&farm(
        d,
        &conf,
        &[&["--log", "warn", "farm", "render", sp, "--parts", "4", "-o", "cbox.ref.exr", "--submit"][..], &reference].concat(),
    ));
    let report = wait_for(d, &conf, "cbox.ref.farm", &["done", "failed", "cancelled"]);
    assert!(report.contains("4 of 4 parts done"), "{report}");
    same_bytes(&d.join("one.ref.exr"), &d.join("cbox.ref.exr"));

    // A part that fails: a folder where part 2 must write its file.
    let other = [&["--spp", "8", "--batches", "4", "--seed", "9"][..], SMALL].concat();
    ok(&cvtrace(d, &[&["--log", "warn", "render", sp, "-o", "one9.streams.exr"][..], &other].concat()));
    let submit = [&["--log", "warn", "farm", "render", sp, "--parts", "4", "-o", "nine.streams.exr"][..], &other].concat();
    let out = farm(d, &conf, &submit);
    ok(&out);
    assert!(stdout(&out).contains("sbatch --parsable --array=0-3"), "without --submit it says how: {}", stdout(&out));
    std::fs::create_dir(d.join("nine.streams.farm/parts/part-002.exr")).unwrap();
    let submit: Vec<&str> = [&submit[..], &["--submit"]].concat();
    ok(&farm(d, &conf, &submit));
    let report = wait_for(d, &conf, "nine.streams.farm", &["done", "failed", "cancelled"]);
    assert!(report.lines().any(|l| l.starts_with("part 2 (batches 2..3): failed")), "{report}");
    assert!(report.contains("merge: cancelled") && report.contains("3 of 4 parts done, 1 failed"), "{report}");
    assert!(!d.join("nine.streams.exr").exists());

    std::fs::remove_dir(d.join("nine.streams.farm/parts/part-002.exr")).unwrap();
    let out = farm(d, &conf, &submit);
    ok(&out);
    assert!(stdout(&out).contains("submitted parts 2 as array job"), "only the failed part is submitted again: {}", stdout(&out));
    let report = wait_for(d, &conf, "nine.streams.farm", &["done", "failed", "cancelled"]);
    assert!(report.contains("merge: done") && report.contains("4 of 4 parts done"), "{report}");
    same_bytes(&d.join("one9.streams.exr"), &d.join("nine.streams.exr"));
    let out = farm(d, &conf, &submit);
    assert!(stdout(&out).contains("nothing to submit"), "{}", stdout(&out));

    farm_study_matches_the_study(d, &conf);
    an_output_with_a_space_and_sbatch_arguments(d, &conf, &streams);

    // `down` ends what `up` started, and again is harmless.
    let slurm_dir = cluster.dir.clone();
    drop(cluster);
    let out = Command::new("bash").arg(script()).args(["down", slurm_dir.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(processes_using(&slurm_dir), Vec::<String>::new(), "processes of the cluster are left");
}

/// The stream file of `streams` again, into a folder whose name has a space and a `#` (which
/// sbatch reads as a comment outside quotes), with an argument for sbatch: the logs land in the
/// job folder, and the merge is the one-shot file.
fn an_output_with_a_space_and_sbatch_arguments(d: &Path, conf: &str, streams: &[&str]) {
    let folder = "spaced out #1";
    std::fs::create_dir(d.join(folder)).unwrap();
    let sp = scene();
    let args = [
        &["--log", "warn", "farm", "render", sp.to_str().unwrap(), "--parts", "2", "-o", "spaced out #1/s.streams.exr"][..],
        &["--sbatch-arg=--partition=local", "--submit"],
        streams,
    ]
    .concat();
    ok(&farm(d, conf, &args));
    let job = "spaced out #1/s.streams.farm";
    let report = wait_for(d, conf, job, &["done", "failed", "cancelled"]);
    assert!(report.contains("merge: done") && report.contains("2 of 2 parts done"), "{report}");
    same_bytes(&d.join("one.streams.exr"), &d.join(folder).join("s.streams.exr"));
    let logs = common::files_in(&d.join(job).join("logs"));
    assert!(logs.contains(&"part-0.out".to_string()) && logs.iter().any(|l| l.starts_with("merge-")), "{logs:?}");
    assert!(!d.join("spaced").exists(), "sbatch cut the log path at the space");
}

/// The command lines of running processes that name `dir`.
fn processes_using(dir: &Path) -> Vec<String> {
    let needle = format!("{}/", dir.display());
    std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| std::fs::read(e.ok()?.path().join("cmdline")).ok())
        .map(|c| String::from_utf8_lossy(&c).replace('\0', " "))
        .filter(|c| c.contains(&needle))
        .collect()
}

/// A tiny study: 2 spp values × 2 seeds, each with its streams and its PT(2n) image.
const STUDY: &[&str] = &["--spp", "4,8", "--batches", "4", "--seeds", "2", "--width", "32", "--height", "32", "--max-depth", "6"];

/// [`STUDY`] with `flag` set to `value` instead.
fn study_with(flag: &str, value: &'static str) -> Vec<&'static str> {
    let mut v = STUDY.to_vec();
    let at = v.iter().position(|a| *a == flag).expect("a flag of STUDY") + 1;
    v[at] = value;
    v
}

/// The reference of the tiny study (a seed none of its renders use).
fn study_reference(d: &Path) {
    let sp = scene();
    let args =
        [&["--log", "warn", "render", sp.to_str().unwrap(), "--reference", "--spp", "64", "--seed", "77", "-o", "ref.exr"][..], SMALL];
    ok(&cvtrace(d, &args.concat()));
}

/// The numbers of a results.json: every method's relMSE statistics and the convergence points.
fn numbers(results: &Path) -> Vec<String> {
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(results).unwrap()).unwrap();
    let scene = &v["scenes"][0];
    let mut out = Vec::new();
    for m in scene["methods"].as_array().unwrap() {
        let f = |k: &str| m[k].to_string();
        out.push(format!("{} {} relmse {} se {} bias2 {}", f("name"), f("spp_total"), f("relmse_mean"), f("relmse_se"), f("bias2")));
    }
    for p in scene["convergence"].as_array().unwrap() {
        out.push(format!("{} {} relmse {}", p["method"], p["spp_total"], p["relmse"]));
    }
    out
}

/// `farm study --submit` on the cluster, against `cvtrace study` with the same arguments.
fn farm_study_matches_the_study(d: &Path, conf: &str) {
    study_reference(d);
    let sp = scene();
    let sp = sp.to_str().unwrap();
    let args = |out: &'static str| [&[sp][..], STUDY, &["--reference", "ref.exr", "-o", out]].concat();
    let out = farm(d, conf, &[&["--log", "warn", "farm", "study"][..], &args("farmed"), &["--submit"]].concat());
    ok(&out);
    assert!(stdout(&out).contains("submitted cells 0,1,2,3,4,5,6,7 as array job"), "{}", stdout(&out));
    let report = wait_for(d, conf, "farmed.farm", &["done", "failed", "cancelled"]);
    assert!(report.contains("study: done") && report.contains("8 of 8 cells done"), "{report}");
    assert!(report.contains("cell 3 (pt2n, 4 spp, seed index 1): done"), "{report}");
    // The final job rendered nothing: it found every cell's file to be the study's own.
    let logs = common::files_in(&d.join("farmed.farm/logs"));
    let study_log = logs.iter().find(|l| l.starts_with("study-")).expect("the study job's log");
    let log = std::fs::read_to_string(d.join("farmed.farm/logs").join(study_log)).unwrap();
    assert_eq!(log.matches("reusing").count(), 8, "{log}");

    ok(&cvtrace(d, &[&["--log", "warn", "study"][..], &args("direct")].concat()));
    let (farmed, direct) = (numbers(&d.join("farmed/results.json")), numbers(&d.join("direct/results.json")));
    assert!(farmed.len() > 10, "{farmed:?}");
    assert_eq!(farmed, direct);

    // Everything is done: a rerun submits nothing; one lost cell is all a rerun submits.
    let again = [&["--log", "warn", "farm", "study"][..], &args("farmed"), &["--submit"]].concat();
    let out = farm(d, conf, &again);
    assert!(stdout(&out).contains("nothing to submit"), "{}", stdout(&out));
    std::fs::remove_file(d.join("farmed/spp00008/seed-000.streams.exr")).unwrap();
    let out = farm(d, conf, &again);
    ok(&out);
    assert!(stdout(&out).contains("submitted cells 4 as array job"), "{}", stdout(&out));
    let report = wait_for(d, conf, "farmed.farm", &["done", "failed", "cancelled"]);
    assert!(report.contains("study: done") && report.contains("8 of 8 cells done"), "{report}");
    assert_eq!(numbers(&d.join("farmed/results.json")), direct);
}

/// Bad `farm study` input is a clear error and writes nothing (no cluster needed: without
/// --submit nothing is submitted).
#[test]
fn farm_study_refuses_bad_input_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    study_reference(d);
    let sp = scene();
    let sp = sp.to_str().unwrap();
    let farm_study = ["--log", "warn", "farm", "study", sp];
    let base = [&farm_study[..], STUDY].concat();
    let before = common::files_in(d);
    let fails = |extra: &[&str], says: &str| {
        let args = if extra.first().is_some_and(|a| *a != "--reference") {
            [&farm_study[..], extra].concat()
        } else {
            [&base[..], extra].concat()
        };
        let out = cvtrace(d, &args);
        assert!(!out.status.success(), "{extra:?} was accepted");
        assert!(stderr(&out).contains(says), "{extra:?}: {}", stderr(&out));
        assert_eq!(common::files_in(d), before, "{extra:?} wrote something");
    };
    fails(&["--reference", "missing.exr", "-o", "s"], "missing.exr: the reference does not exist; render it first");
    fails(&["--reference", "ref.exr", "-o", "s", "--cell", "streams:4:0"], "--cell streams:4:0: the farm gives every task its cell");
    fails(&[&study_with("--batches", "3")[..], &["--reference", "ref.exr", "-o", "s"]].concat(), "--batches 3 does not divide --spp 4");
    fails(
        &[&study_with("--width", "16")[..], &["--reference", "ref.exr", "-o", "s"]].concat(),
        "ref.exr: not a reference of this study's image",
    );
    fails(&["--reference", "ref.exr", "-o", "s", "--dir", "s"], "given as both --dir and -o");
    fails(&["--reference", "ref.exr", "-o", "s", "--param", "ours.nope=1"], "nope");
    std::fs::write(d.join("notes.txt"), "x").unwrap();
    let before = common::files_in(d);
    let out = cvtrace(d, &[&base[..], &["--reference", "ref.exr", "-o", "s", "--dir", "notes.txt"]].concat());
    assert!(!out.status.success() && stderr(&out).contains("notes.txt"), "{}", stderr(&out));
    assert_eq!(common::files_in(d), before);

    // Without --submit: the job folder, and how to submit it; the study folder is the cells' to make.
    let out = cvtrace(d, &[&base[..], &["--reference", "ref.exr", "-o", "s"]].concat());
    ok(&out);
    assert!(stdout(&out).contains("cells.sbatch") && stdout(&out).contains("study.sbatch"), "{}", stdout(&out));
    assert!(!d.join("s").exists());
    let commands = std::fs::read_to_string(d.join("s.farm/commands.txt")).unwrap();
    assert_eq!(commands.lines().filter(|l| l.contains(" --cell ")).count(), 8, "{commands}");
    assert!(commands.contains(" study ") && !commands.contains("--submit"), "{commands}");
    let status = cvtrace(d, &["farm", "status", "s.farm"]);
    ok(&status);
    assert!(stdout(&status).contains("cell 0 (streams, 4 spp, seed index 0): missing") && stdout(&status).contains("study: not submitted"));
    // The folder of another study is refused and left as it was.
    let manifest = std::fs::read(d.join("s.farm/manifest.json")).unwrap();
    let out = cvtrace(d, &[&farm_study[..], &study_with("--seeds", "3"), &["--reference", "ref.exr", "-o", "s"]].concat());
    assert!(!out.status.success() && stderr(&out).contains("holds a farm job of other render settings"), "{}", stderr(&out));
    assert_eq!(std::fs::read(d.join("s.farm/manifest.json")).unwrap(), manifest);
    // A cell the study does not have.
    let out = cvtrace(d, &[&["study", sp][..], STUDY, &["--reference", "ref.exr", "-o", "s", "--cell", "streams:16:0"]].concat());
    assert!(!out.status.success() && stderr(&out).contains("--cell streams:16:0: not a cell of this study"), "{}", stderr(&out));
    assert!(!d.join("s").exists());
}

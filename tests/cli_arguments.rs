//! Absurd command-line arguments, found by fuzzing the command line (render, reconstruct,
//! compare, study, report): each must be an error that names the argument, given before any
//! work and leaving no file behind — never a panic, an abort, a hang, a wrapped value or a
//! file written over another one.
mod common;

use common::{cvtrace, files_in, ok, scene, stderr, stream_and_reference, SMALL};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs `program args` in `dir`, killing it after 60 s (a FIFO input used to wait forever).
fn run_within(dir: &Path, program: &str, args: &[&str]) -> Output {
    let (out, err) = (dir.join(".stdout"), dir.join(".stderr"));
    let mut child = Command::new(program)
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("{args:?} still runs after 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let output = Output { status, stdout: std::fs::read(&out).unwrap(), stderr: std::fs::read(&err).unwrap() };
    std::fs::remove_file(out).unwrap();
    std::fs::remove_file(err).unwrap();
    output
}

/// `args` fails, its error names every needle, nothing panics, and no file appears in `dir`.
fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    refused_by(dir, env!("CARGO_BIN_EXE_cvtrace"), args, needles);
}

fn refused_by(dir: &Path, program: &str, args: &[&str], needles: &[&str]) {
    let before = files_in(dir);
    let out = run_within(dir, program, args);
    let e = stderr(&out);
    assert!(!out.status.success(), "{args:?} succeeded:\n{e}");
    assert!(matches!(out.status.code(), Some(1 | 2)), "{args:?} ended by {}:\n{e}", out.status);
    for n in needles {
        assert!(e.contains(n), "{args:?}: the error should name {n:?}:\n{e}");
    }
    assert!(!e.contains("panicked") && !e.contains("memory allocation"), "{args:?}:\n{e}");
    assert_eq!(files_in(dir), before, "{args:?} left files behind");
}

fn render_args<'a>(sp: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    [&["render", sp][..], SMALL, extra].concat()
}

#[test]
fn render_refuses_counts_its_files_cannot_record() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    // 65 536 batches used to allocate them all (and 2^32 − 1 to abort); the stream file numbers
    // batches with two digits.
    refused(d, &render_args(sp, &["--spp", "101", "--batches", "101", "-o", "x.streams.exr"]), &["--batches", "101", "1..=100"]);
    refused(
        d,
        &render_args(sp, &["--spp", "4294967295", "--batches", "4294967295", "-o", "x.streams.exr"]),
        &["--spp", "4294967295", "1..=2147483647"],
    );
    // EXR `int` attributes (cvtrace.spp, cvtrace.rrDepth) would wrap to negative values.
    refused(d, &render_args(sp, &["--spp", "2147483648", "--batches", "1", "-o", "x.streams.exr"]), &["--spp", "2147483648", "2147483647"]);
    // A negative count is the value it is, not a flag (clap's tip was `-- -8`).
    refused(d, &render_args(sp, &["--spp", "-8", "-o", "x.streams.exr"]), &["--spp", "-8", "1..=2147483647"]);
    refused(d, &render_args(sp, &["--reference", "--spp", "4294967295", "-o", "x.ref.exr"]), &["--spp", "4294967295"]);
    refused(
        d,
        &render_args(sp, &["--reference", "--rr-depth", "4294967295", "-o", "x.ref.exr"]),
        &["--rr-depth", "4294967295", "0..=2147483647"],
    );
    // The largest values that fit still render.
    ok(&cvtrace(
        d,
        &[&["--log", "warn"][..], &render_args(sp, &["--spp", "2", "--batches", "2", "--rr-depth", "2147483647", "-o", "y.streams.exr"])]
            .concat(),
    ));
}

#[test]
fn render_too_large_for_memory_fails_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    // A stream render goes into its file band by band: at 16384 pixels wide and 100 batches,
    // its bands take about 9 GiB, which `ulimit -v` (3 GB) does not leave.
    let bin = env!("CARGO_BIN_EXE_cvtrace");
    let start = Instant::now();
    refused_by(
        d,
        "sh",
        &[
            "-c",
            "ulimit -v 3000000 && exec \"$0\" \"$@\"",
            bin,
            "render",
            sp,
            "--width",
            "16384",
            "--height",
            "16384",
            "--spp",
            "100",
            "--batches",
            "100",
            "-o",
            "x.streams.exr",
        ],
        &["--width 16384 --height 16384 --batches 100", "GiB of memory"],
    );
    assert!(start.elapsed() < Duration::from_secs(20), "refused only after {:?}", start.elapsed());
    // Under `ulimit -v` (3 GB) a 4.4 GiB reference is refused the same way instead of aborting.
    refused_by(
        d,
        "sh",
        &[
            "-c",
            "ulimit -v 3000000 && exec \"$0\" \"$@\"",
            bin,
            "render",
            sp,
            "--reference",
            "--width",
            "8192",
            "--height",
            "8192",
            "--spp",
            "1",
            "-o",
            "x.ref.exr",
        ],
        &["--width 8192 --height 8192", "GiB of memory"],
    );
}

#[test]
fn reference_only_flags_and_narrow_cameras_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    // Ignored without --reference, they were accepted silently.
    refused(d, &render_args(sp, &["--spp", "8", "--batches", "4", "--pass-spp", "3", "-o", "x.streams.exr"]), &["--reference"]);
    refused(d, &render_args(sp, &["--spp", "8", "--batches", "4", "--stop-after-passes", "1", "-o", "x.streams.exr"]), &["--reference"]);
    // 0 passes stopped after one pass and left a checkpoint, no reference.
    refused(
        d,
        &render_args(sp, &["--reference", "--spp", "8", "--pass-spp", "2", "--stop-after-passes", "0", "-o", "x.ref.exr"]),
        &["--stop-after-passes 0"],
    );
    // A field of view so narrow that every ray is the viewing direction rendered a flat image
    // (a denormal one reads as 0 once the render flushes denormals).
    for (fov, why) in [("1e-30", "too narrow"), ("0.000001", "too narrow"), ("1e-45", "outside (0, 180)")] {
        let camera = format!("278,273,-800:278,273,0:{fov}");
        refused(d, &render_args(sp, &["--spp", "8", "--batches", "4", "--camera", &camera, "-o", "x.streams.exr"]), &["--camera", why]);
    }
}

#[test]
fn fifo_and_device_inputs_are_refused_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    assert!(Command::new("mkfifo").arg(d.join("fifo.exr")).status().unwrap().success());
    let s = scene();
    let sp = s.to_str().unwrap();
    let fifo = ["fifo.exr", "not a regular file"];
    refused(d, &["reconstruct", "fifo.exr", "-o", "x.exr"], &fifo);
    refused(d, &["reconstruct", "s.streams.exr", "--reference", "fifo.exr", "-o", "x.exr"], &fifo);
    refused(d, &["reconstruct", "/dev/zero", "-o", "x.exr"], &["/dev/zero", "not a regular file"]);
    refused(d, &["compare", "--reference", "fifo.exr", "ref.exr"], &fifo);
    refused(d, &["compare", "--reference", "ref.exr", "fifo.exr", "--csv", "t.csv"], &fifo);
    let study = [&["study", sp, "--reference", "fifo.exr", "--spp", "8", "--batches", "4", "--seeds", "1", "-o", "st"][..], SMALL].concat();
    refused(d, &study, &fifo);
}

#[test]
fn reconstruct_checks_every_option_given() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    let run = |extra: &[&'static str]| [&["reconstruct", "s.streams.exr", "-o", "x.exr"][..], extra].concat();
    // Options of a method that does not run were not checked at all.
    refused(d, &run(&["--method", "pt", "--k", "0"]), &["--k 0"]);
    refused(d, &run(&["--method", "average", "--cv-ridge", "inf"]), &["--cv-ridge inf"]);
    refused(d, &run(&["--method", "crn", "--iduw-window", "4"]), &["--iduw-window 4"]);
    refused(d, &run(&["--method", "ours", "--iduw-gamma=-1"]), &["--iduw-gamma -1"]);
    // `cv` counts neighbours (k − 1): its error named `--k 1` for `--k 0`.
    refused(d, &run(&["--method", "cv", "--k", "0"]), &["--k 0"]);
    ok(&cvtrace(
        d,
        &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "pt", "--k", "9", "--search-window", "3", "-o", "x.exr"],
    ));
}

#[test]
fn compare_refuses_one_file_as_both_csv_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "pt", "-o", "pt.exr"]));
    // With --force the JSON replaced the CSV, and the command succeeded.
    for json in ["./t.csv", "sub/../t.csv"] {
        std::fs::create_dir_all(d.join("sub")).unwrap();
        refused(d, &["compare", "--reference", "ref.exr", "pt.exr", "--csv", "t.csv", "--json", json, "--force"], &["same file"]);
    }
}

#[test]
fn study_arguments_that_would_wrap_or_fail_late_are_refused_first() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    std::fs::write(d.join("bad.exr"), b"not an EXR").unwrap();
    let s = scene();
    let sp = s.to_str().unwrap();
    // The study's arguments with the flags of `changes` (flag, value pairs) replaced or added.
    let study = |changes: &[&'static str]| -> Vec<String> {
        let mut args: Vec<String> = ["study", sp, "--reference", "ref.exr", "--spp", "8", "--batches", "4", "--seeds", "1", "-o", "st"]
            .iter()
            .chain(SMALL)
            .map(|a| a.to_string())
            .collect();
        for pair in changes.chunks(2) {
            match args.iter().position(|a| a == pair[0]) {
                Some(i) => args[i + 1] = pair[1].to_string(),
                None => args.extend([pair[0].to_string(), pair[1].to_string()]),
            }
        }
        args
    };
    let check = |changes: &[&'static str], needles: &[&str]| {
        let args = study(changes);
        refused(d, &args.iter().map(String::as_str).collect::<Vec<_>>(), needles);
    };
    // Seeds past 2^64 − 1 wrapped to 0 (and the PT(2n) renders' seeds with them).
    check(&["--seed", "18446744073709551615", "--seeds", "2"], &["--seed 18446744073709551615"]);
    // 2n of 2^31 wrapped to 0 spp, after the streams' render.
    check(&["--spp", "2147483648", "--batches", "4"], &["--spp", "2147483648", "1..=2147483647"]);
    // These failed after the study folder was made (and --name after every render).
    check(&["--reference", "new.exr", "--reference-spp", "0"], &["--reference-spp", "'0'", "1..=2147483647"]);
    check(&["--name", ""], &["--name"]);
    check(&["--name", " \t"], &["--name"]);
    check(&["--reference", "bad.exr"], &["bad.exr"]);
    check(&["--reference", "st"], &["st", "--reference and -o"]);
    check(&["--seed", "99"], &["seed 99"]);
    // A first render that fails left the study and spp folders (here the study folder's path
    // is 4070 bytes long: its lock fits in PATH_MAX, the first render's temporary does not).
    let mut deep = vec!["p".repeat(250); 16].join("/");
    deep = format!("{deep}/{}", "q".repeat(4070 - deep.len() - 1));
    let args = study(&[]);
    let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
    *args.iter_mut().find(|a| **a == "st").unwrap() = &deep;
    refused(d, &args, &["spp00008/seed-000.streams.exr", "File name too long"]);
}

#[test]
fn report_markdown_never_replaces_the_reports_or_the_studys_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    let s = scene();
    let sp = s.to_str().unwrap();
    ok(&cvtrace(
        d,
        &[&["--log", "warn", "study", sp, "--reference", "ref.exr", "--spp", "8", "--batches", "4", "--seeds", "1", "-o", "st"][..], SMALL]
            .concat(),
    ));
    ok(&cvtrace(d, &["--log", "warn", "report", "st", "-o", "rep"]));
    let page = std::fs::read(d.join("rep/index.html")).unwrap();
    let csv = std::fs::read(d.join("st/results.csv")).unwrap();
    // With --force the summary replaced the page (or the report's manifest, or the study's table).
    for md in ["rep/index.html", "./rep/results.json", "rep/.cvtrace-report", "rep/images/x.md", "rep"] {
        refused(d, &["report", "st", "-o", "rep", "--force", "--markdown", md], &["--markdown", "the report writes this path"]);
    }
    refused(d, &["report", "st", "-o", "rep", "--force", "--markdown", "st/results.csv"], &["st/results.csv", "is a file of the study"]);
    assert_eq!(std::fs::read(d.join("rep/index.html")).unwrap(), page);
    assert_eq!(std::fs::read(d.join("st/results.csv")).unwrap(), csv);
    // The summary as the new report folder itself: the report was written, then the summary failed.
    refused(d, &["report", "st", "-o", "rep2", "--markdown", "rep2"], &["--markdown rep2"]);
    // One study named twice was one scene twice, and the error named neither folder.
    refused(d, &["report", "st", "st/", "-o", "rep3"], &["st", "given twice"]);
    ok(&cvtrace(d, &["--log", "warn", "report", "st", "-o", "rep", "--force", "--markdown", "rep/summary.md"]));
}

#[test]
fn threads_that_cannot_start_and_unparsable_log_filters_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    // 1024 thread stacks do not fit in 1 GB of address space: the pool's error was a panic.
    // (Both are refused before any thread starts now.)
    let bin = env!("CARGO_BIN_EXE_cvtrace");
    refused_by(
        d,
        "sh",
        &["-c", "ulimit -v 1000000 && exec \"$0\" \"$@\"", bin, "--threads", "1024", "reconstruct", "s.streams.exr", "-o", "x.exr"],
        &["--threads 1024", "cannot start"],
    );
    // A render starts a second pool as large: in 4 GB, 961 threads each started, and the process
    // aborted when one of them could not get its signal stack.
    let s = scene();
    let sp = s.to_str().unwrap();
    refused_by(
        d,
        "sh",
        &[
            &["-c", "ulimit -v 4000000 && exec \"$0\" \"$@\"", bin, "--threads", "961"][..],
            &render_args(sp, &["--spp", "8", "--batches", "4", "-o", "x.streams.exr"]),
        ]
        .concat(),
        &["--threads 961", "cannot start 1922 worker threads"],
    );
    // An unparsable filter was dropped with a note, and the run went on without any log.
    refused(d, &["--log", "[", "reconstruct", "s.streams.exr", "-o", "x.exr"], &["--log \"[\""]);
}

#[test]
fn negative_numbers_are_values_out_of_range_not_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let sp = s.to_str().unwrap();
    let streams = |flag: &'static str, value: &'static str| render_args(sp, &["--spp", "8", flag, value, "-o", "x.streams.exr"]);
    let study = |flag: &'static str, value: &'static str| -> Vec<&str> {
        [&["study", sp, "--reference", "r.exr", "--spp", "8", "-o", "st", flag, value][..], SMALL].concat()
    };
    let farm = |flag: &'static str, value: &'static str| -> Vec<&str> {
        [&["farm", "render", sp, "--spp", "8", "-o", "f.streams.exr", flag, value][..], SMALL].concat()
    };
    let cases: Vec<(Vec<&str>, &[&str])> = vec![
        // A value with a leading hyphen is the flag's value, out of range, and no flag of its own.
        (["render", sp, "--width", "-16", "-o", "x.exr"].to_vec(), &["--width", "-16", "1..=16384"]),
        (["render", sp, "--height", "-16", "-o", "x.exr"].to_vec(), &["--height", "-16", "1..=16384"]),
        (streams("--seed", "-1"), &["--seed", "-1", "0..=18446744073709551615"]),
        (streams("--batches", "-4"), &["--batches", "-4", "1..=100"]),
        (render_args(sp, &["--reference", "--pass-spp", "-2", "-o", "x.exr"]), &["--pass-spp", "-2", "1..=2147483647"]),
        (["-t", "-1", "reconstruct", "--list"].to_vec(), &["--threads", "-1", "1..=1024"]),
        (study("--seeds", "-1"), &["--seeds", "-1", "1..=10000"]),
        (study("--seed", "-3"), &["--seed", "-3", "0..=18446744073709551615"]),
        (study("--reference-spp", "-5"), &["--reference-spp", "-5", "1..=2147483647"]),
        (farm("--parts", "-2"), &["--parts", "-2", "1..="]),
        (farm("--batches", "-8"), &["--batches", "-8", "1..=100"]),
    ];
    for (args, needles) in cases {
        refused(d, &args, needles);
        let e = stderr(&cvtrace(d, &args));
        assert!(!e.contains("'-- -") && !e.contains("unexpected argument"), "{args:?}: read as a flag:\n{e}");
    }
}

#[test]
fn errors_say_what_is_wrong_not_something_near_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    let s = scene();
    let sp = s.to_str().unwrap();
    let not = |args: &[&str], wrong: &str| {
        let e = stderr(&cvtrace(d, args));
        assert!(!e.contains(wrong), "{args:?}: the error is about {wrong:?}:\n{e}");
    };
    // A whole number too large for the setting is out of range, not "not a whole number".
    let big = render_args(sp, &["-D", "spp=99999999999", "-o", "x.streams.exr"]);
    refused(d, &big, &["-D spp=99999999999", "out of range", "2147483647"]);
    not(&big, "not a whole number");
    // The format is right; a coordinate is not a number to render with.
    let nan = render_args(sp, &["--spp", "8", "--camera", "nan,0,0:0,0,1:40", "-o", "x.streams.exr"]);
    refused(d, &nan, &["--camera", "nan", "not a finite number"]);
    not(&nan, "expected --camera");
    // A file where the output's folder should be.
    std::fs::write(d.join("file.exr"), b"a file").unwrap();
    let under_a_file = render_args(sp, &["--spp", "8", "-o", "file.exr/sub.exr"]);
    refused(d, &under_a_file, &["file.exr", "is a file, not a folder"]);
    not(&under_a_file, "does not exist");
    refused(d, &["reconstruct", "s.streams.exr", "--method", "pt", "-o", "file.exr/a/pt.exr"], &["file.exr", "is a file, not a folder"]);
    // Extending a stream file (another seed, too): that it is no reference is what matters.
    let extend = render_args(sp, &["--reference", "--extend", "--spp", "32", "--seed", "5", "-o", "s.streams.exr"]);
    refused(d, &extend, &["s.streams.exr", "stream file", "--extend"]);
    not(&extend, "seed");
}

//! The first hour of a new user: the README's PNG export, `compare`'s table and CSV, a method the
//! README names, what `--k` sets, outputs into folders that do not exist yet, and log lines and
//! an interrupt on a 100-column terminal.
mod common;

use common::{cvtrace, ok, scene, stderr, stdout, stream_and_reference, SMALL};
use std::io::{Read, Write};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn tool_missing(tool: &str) -> bool {
    let have = Command::new("which").arg(tool).output().is_ok_and(|o| o.status.success());
    assert!(have || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "{tool} is missing and CVTRACE_REQUIRE_TOOLS is set");
    if !have {
        eprintln!("skipped: needs {tool}");
    }
    !have
}

#[test]
fn the_readmes_png_export_is_the_srgb_preview() {
    if tool_missing("oiiotool") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    ok(&cvtrace(
        d,
        &[&["--log", "warn", "render", s.to_str().unwrap(), "--spp", "8", "-o", "s.streams.exr", "--preview", "s.png"][..], SMALL].concat(),
    ));
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let commands: Vec<&str> = readme
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|c| c.starts_with("oiiotool") && c.contains("x.streams.exr") && c.ends_with(".png"))
        .collect();
    assert!(!commands.is_empty(), "the README names no oiiotool command that writes a PNG");
    for command in commands {
        let line = command.replace("x.streams.exr", "s.streams.exr").replace("x.png", "o.png");
        let out = Command::new("sh").args(["-c", &line]).current_dir(d).output().unwrap();
        assert!(out.status.success(), "{line}: {}", String::from_utf8_lossy(&out.stderr));
        // Within one 8-bit step of `render --preview` (which rounds the same sRGB values).
        let diff = Command::new("oiiotool")
            .args(["o.png", "--ch", "R,G,B", "s.png", "--fail", "0.0045", "--warn", "0.0045", "--diff"])
            .current_dir(d)
            .output()
            .unwrap();
        assert!(diff.status.success(), "the README's `{command}` is not the sRGB preview:\n{}", String::from_utf8_lossy(&diff.stdout));
    }
}

#[test]
fn compare_shows_only_what_it_measures_and_its_csv_agrees() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    ok(&cvtrace(d, &["--log", "warn", "reconstruct", "s.streams.exr", "--method", "all", "-o", "out"]));
    // Into folders that do not exist yet, as every other output.
    let out = cvtrace(
        d,
        &[
            "--log",
            "warn",
            "compare",
            "--reference",
            "ref.exr",
            "out/pt.exr",
            "out/ours.exr",
            "--csv",
            "tables/t.csv",
            "--json",
            "more/t.json",
        ],
    );
    ok(&out);
    let table = stdout(&out);
    let header = table.lines().find(|l| l.starts_with("method")).unwrap_or_else(|| panic!("no table:\n{table}"));
    for column in ["relMSE", "MSE", "spp", "FLIP", "recon s"] {
        assert!(header.contains(column), "{column:?} missing: {header}");
    }
    // Columns of a study over seeds, always `–` or 0 for single images.
    for column in ["± se", "/PT(2n)", "bias²", "variance", "render s"] {
        assert!(!header.contains(column), "{column:?} in compare's table: {header}");
    }
    let csv = std::fs::read_to_string(d.join("tables/t.csv")).unwrap();
    let columns: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let at = |name: &str| columns.iter().position(|c| *c == name).unwrap();
    for row in csv.lines().skip(1) {
        let cells: Vec<&str> = row.split(',').collect();
        // The streams had 8 spp each; pt stands for 8 samples, ours for 16.
        assert_eq!(cells[at("spp_per_stream")], "8", "{row}");
        let total = if cells[at("method")] == "pt" { "8" } else { "16" };
        assert_eq!(cells[at("spp_total")], total, "{row}");
        assert!(table.lines().any(|l| l.contains(cells[at("method")]) && l.contains(&format!(" {total} "))), "{row} vs\n{table}");
    }
    assert!(d.join("more/t.json").is_file());
}

#[test]
fn a_variant_is_named_as_one_and_shared_flags_name_every_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    stream_and_reference(d);
    // The README's `cv-classic` is an ablation variant, run by `study --ablations`.
    let out = cvtrace(d, &["reconstruct", "s.streams.exr", "--method", "cv-classic", "-o", "x.exr"]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("cv-classic") && e.contains("variant") && e.contains("study --ablations"), "{e}");
    // `--k` sets `ours.k` and `cv.k`: its help and its errors name both.
    let help = stdout(&cvtrace(d, &["reconstruct", "--help"]));
    let k = help.lines().find(|l| l.trim_start().starts_with("--k ")).unwrap_or_else(|| panic!("no --k in\n{help}"));
    assert!(k.contains("ours.k") && k.contains("cv.k"), "{k}");
    for value in ["1", "1000"] {
        let out = cvtrace(d, &["reconstruct", "s.streams.exr", "--method", "pt", "--k", value, "-o", "x.exr"]);
        let e = stderr(&out);
        assert!(!out.status.success(), "--k {value}");
        assert!(e.contains(&format!("--k {value}")) && e.contains("ours.k") && e.contains("cv.k"), "--k {value}: {e}");
    }
}

#[test]
fn a_study_makes_the_folders_of_the_reference_it_renders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let study = [
        &["--log", "warn", "study", s.to_str().unwrap(), "--spp", "4", "--seeds", "1", "--batches", "4"][..],
        &["--reference", "refs/new/ref.exr", "--reference-spp", "8", "-o", "st"],
        SMALL,
    ]
    .concat();
    ok(&cvtrace(d, &study));
    assert!(d.join("refs/new/ref.exr").is_file() && d.join("st/results.json").is_file());
}

/// Bytes as a terminal shows them: each line's last overwrite (after its last `\r`), without
/// colour and erase codes.
fn screen_lines(bytes: &[u8]) -> Vec<String> {
    let text = String::from_utf8_lossy(bytes);
    text.split('\n')
        .map(|line| {
            let line = line.trim_end_matches('\r');
            let shown = line.rsplit('\r').next().unwrap_or("");
            let mut out = String::new();
            let mut chars = shown.chars();
            while let Some(c) = chars.next() {
                if c == '\u{1b}' {
                    // CSI: ESC [ parameters final-byte.
                    if chars.next() == Some('[') {
                        for f in chars.by_ref() {
                            if ('@'..='~').contains(&f) {
                                break;
                            }
                        }
                    }
                } else {
                    out.push(c);
                }
            }
            out
        })
        .collect()
}

/// `cvtrace args` on a pseudo-terminal (`script`), in `dir`; with `interrupt`, Ctrl-C is typed
/// once its progress bar shows. Returns what the terminal received.
fn on_a_terminal(dir: &Path, args: &[&str], interrupt: bool) -> Vec<u8> {
    let line = std::iter::once(env!("CARGO_BIN_EXE_cvtrace").to_string())
        .chain(args.iter().map(|a| format!("'{a}'")))
        .collect::<Vec<_>>()
        .join(" ");
    let mut child = Command::new("script")
        .args(["-qefc", &line, "/dev/null"])
        .current_dir(dir)
        .env("TERM", "xterm")
        .env("COLUMNS", "100")
        .env_remove("RUST_LOG")
        .env_remove("NO_COLOR")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut all = Vec::new();
        let _ = stdout.read_to_end(&mut all);
        all
    });
    if interrupt {
        // The bar is drawn a moment after the render starts; Ctrl-C goes through the terminal.
        std::thread::sleep(Duration::from_secs(3));
        stdin.write_all(b"\x03").unwrap();
        stdin.flush().unwrap();
    }
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed() < Duration::from_secs(120), "{args:?} did not end");
        std::thread::sleep(Duration::from_millis(50));
    }
    drop(stdin);
    reader.join().unwrap()
}

#[test]
fn log_lines_fit_100_columns_and_an_interrupt_gets_its_own_line() {
    if tool_missing("script") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // An absolute scene path, as a user's shell completion gives it.
    let s = scene();
    let sp = s.to_str().unwrap();
    let screen = screen_lines(&on_a_terminal(
        d,
        &[&["--log", "info", "render", sp, "--spp", "8", "-o", "a.streams.exr"][..], SMALL].concat(),
        false,
    ));
    assert!(screen.iter().any(|l| l.contains("INFO")), "no log on the terminal: {screen:#?}");
    for l in &screen {
        assert!(l.chars().count() <= 100, "{} columns: {l}", l.chars().count());
    }
    // A render long enough to be interrupted while its bar is drawn.
    let long = ["--log", "warn", "render", sp, "--spp", "65536", "--width", "128", "--height", "128", "-o", "big.streams.exr"];
    let screen = screen_lines(&on_a_terminal(d, &long, true));
    let line = screen.iter().find(|l| l.contains("interrupted")).unwrap_or_else(|| panic!("no interrupt: {screen:#?}"));
    assert!(line.starts_with("interrupted"), "the interrupt shares the progress bar's line: {line:?}");
    assert!(!d.join("big.streams.exr").exists());
}

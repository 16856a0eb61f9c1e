//! What `cvtrace farm render` writes before anything is submitted (no cluster needed): the
//! `--sbatch-arg` arguments reach the printed commands and the job folder's scripts, and paths
//! with spaces or `#` in the scripts' `#SBATCH` lines read back as they are.
mod common;

use common::{cvtrace, ok, scene, stdout, SMALL};

/// The arguments of a `#SBATCH` line as sbatch reads them: whitespace separates them; single or
/// double quotes group, a backslash escapes the next character, and an unquoted `#` ends the line.
fn sbatch_arguments(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut chars = line.chars().peekable();
    loop {
        while chars.peek().is_some_and(|c| c.is_whitespace()) {
            chars.next();
        }
        if chars.peek().is_none() {
            return out;
        }
        let (mut arg, mut quote, mut escaped) = (String::new(), None, false);
        while let Some(&c) = chars.peek() {
            if quote.is_none() && c.is_whitespace() && !escaped {
                break;
            }
            chars.next();
            if escaped {
                escaped = false;
                arg.push(c);
            } else if c == '\\' {
                escaped = true;
            } else if let Some(q) = quote {
                if c == q {
                    quote = None;
                } else {
                    arg.push(c);
                }
            } else if c == '"' || c == '\'' {
                quote = Some(c);
            } else if c == '#' {
                out.push(arg);
                return out;
            } else {
                arg.push(c);
            }
        }
        out.push(arg);
    }
}

#[test]
fn sbatch_arguments_and_odd_paths_reach_the_job_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let folder = "out dir #2";
    std::fs::create_dir(d.join(folder)).unwrap();
    let args = [
        &["--log", "warn", "farm", "render", s.to_str().unwrap(), "--spp", "8", "--batches", "4", "--parts", "2"][..],
        &["-o", "out dir #2/x.streams.exr", "--sbatch-arg=--partition=gpu", "--sbatch-arg", "--comment=a b"],
        SMALL,
    ]
    .concat();
    let out = cvtrace(d, &args);
    ok(&out);
    let printed = stdout(&out);
    // Printed: what to run by hand, with the arguments given.
    assert!(printed.contains("--partition=gpu") && printed.contains("'--comment=a b'"), "{printed}");
    let job = d.join(folder).canonicalize().unwrap().join("x.streams.farm");
    for script in ["parts.sbatch", "merge.sbatch"] {
        let text = std::fs::read_to_string(job.join(script)).unwrap();
        let options: Vec<String> = text.lines().filter_map(|l| l.strip_prefix("#SBATCH")).flat_map(sbatch_arguments).collect();
        assert!(
            options.contains(&"--partition=gpu".to_string()) && options.contains(&"--comment=a b".to_string()),
            "{script}: {options:?}"
        );
        let log =
            options.iter().find_map(|o| o.strip_prefix("--output=")).unwrap_or_else(|| panic!("{script}: no --output in {options:?}"));
        assert!(log.starts_with(&format!("{}/logs/", job.display())), "{script}: sbatch reads --output={log}");
    }
    // Run again, to submit, the folder is the same job: the arguments are part of it.
    ok(&cvtrace(d, &args));
}

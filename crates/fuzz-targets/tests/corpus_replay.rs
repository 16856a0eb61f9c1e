//! Replays every committed fuzz corpus file (`fuzz/corpus/<target>/`) and every crash
//! regression (`fuzz/regressions/<target>/`) through every fuzz target: a panic fails the test.
//! Inputs of one format are fed to the other targets too, as cheap extra coverage of the
//! readers' error paths. This is what `make fuzz-smoke` and CI run; it needs no nightly.
use cvtrace_fuzz_targets::TARGETS;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

/// The files of `dir`, sorted (empty if it does not exist).
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(entries) => entries.map(|e| e.expect("reading a corpus folder").path()).filter(|p| p.is_file()).collect(),
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

#[test]
fn every_target_has_a_committed_corpus_and_a_fuzz_target() {
    for (name, _) in TARGETS {
        let corpus = fuzz_dir().join("corpus").join(name);
        assert!(!files(&corpus).is_empty(), "no corpus files in {}", corpus.display());
        let target = fuzz_dir().join("fuzz_targets").join(format!("{name}.rs"));
        assert!(target.is_file(), "{} is missing", target.display());
    }
}

#[test]
fn committed_corpora_and_regressions_replay_through_every_target_without_panicking() {
    // The scene importer turns a panic of the glTF accessor readers into an error, so a panic
    // is seen by a hook rather than by unwinding to here (the fuzz targets abort on it).
    let panics = Arc::new(Mutex::new(Vec::<String>::new()));
    let seen = Arc::clone(&panics);
    std::panic::set_hook(Box::new(move |info| seen.lock().unwrap_or_else(|e| e.into_inner()).push(info.to_string())));
    let mut inputs = Vec::new();
    for (name, _) in TARGETS {
        inputs.extend(files(&fuzz_dir().join("corpus").join(name)));
        inputs.extend(files(&fuzz_dir().join("regressions").join(name)));
    }
    assert!(!inputs.is_empty());
    let mut failures = Vec::new();
    for input in &inputs {
        let data = std::fs::read(input).expect("reading a corpus file");
        for (name, target) in TARGETS {
            let unwound = std::panic::catch_unwind(|| target(&data)).is_err();
            let messages: Vec<String> = std::mem::take(&mut *panics.lock().unwrap_or_else(|e| e.into_inner()));
            if unwound || !messages.is_empty() {
                failures.push(format!("{name} <- {}: {}", input.display(), messages.join("; ")));
            }
        }
    }
    let _ = std::panic::take_hook();
    assert!(failures.is_empty(), "{} of {} runs panicked:\n{}", failures.len(), inputs.len() * TARGETS.len(), failures.join("\n"));
}

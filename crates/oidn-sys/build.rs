//! Finds Intel Open Image Denoise 2 where the `oidn` crate links it from, `OIDN_DIR` (which
//! `.cargo/config.toml` points at `.deps/oidn`, where `scripts/setup.sh` installs it from the
//! PyPI wheel `pyoidn`; a user's own `OIDN_DIR` wins), and fails the build with what to do
//! when it is not there: the `oidn` crate itself would only fail later, at the link.
//!
//! Its folder goes to dependents as `DEP_CVTRACE_OIDN_LIB_DIR`, for their binaries' rpath, so
//! that nothing needs LD_LIBRARY_PATH.
use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    let Some(dir) = std::env::var_os("OIDN_DIR").filter(|d| !d.is_empty()).map(PathBuf::from) else {
        fail("OIDN_DIR is not set (the project's .cargo/config.toml sets it to .deps/oidn; is this build outside the project?)")
    };
    let lib = dir.join("lib");
    println!("cargo:rerun-if-changed={}", lib.display());
    let missing: Vec<&str> = ["libOpenImageDenoise.so.2", "libOpenImageDenoise_device_cpu.so"]
        .into_iter()
        .filter(|prefix| !has_file_starting(&lib, prefix))
        .collect();
    if !missing.is_empty() {
        fail(&format!(
            "Intel Open Image Denoise 2 is not in {} (missing: {}).\n\
             Run `bash scripts/setup.sh`: it installs OIDN 2.5.1 there from the PyPI wheel pyoidn.\n\
             Or point OIDN_DIR at an OIDN 2.x install prefix (the folder holding lib/libOpenImageDenoise.so.2\n\
             and its CPU device module).",
            lib.display(),
            missing.join(", ")
        ));
    }
    if !lib.join("libOpenImageDenoise.so").exists() {
        fail(&format!("{}: libOpenImageDenoise.so.2 is there but not the link name libOpenImageDenoise.so", lib.display()));
    }
    println!("cargo:lib_dir={}", lib.display());
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
}

fn has_file_starting(dir: &Path, prefix: &str) -> bool {
    std::fs::read_dir(dir).map(|entries| entries.flatten().any(|e| e.file_name().to_string_lossy().starts_with(prefix))).unwrap_or(false)
}

fn fail(message: &str) -> ! {
    eprintln!("\nerror: {message}\n");
    std::process::exit(1);
}

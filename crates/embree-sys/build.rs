//! Finds the installed Embree (3 or 4), makes its Rust bindings and tells Cargo how to link it.
//!
//! Search order, the first that fits wins:
//! 1. `EMBREE_DIR`, an install prefix: with `include/embreeN/rtcore.h` the bindings come from
//!    bindgen on those headers; without headers (the Embree 4 library of the PyPI wheel
//!    `embreex`, which `scripts/setup.sh` lays out as `.deps/embree4/lib`) they are the
//!    committed `src/bindings/embree4.rs`, generated from Embree 4's headers for the
//!    configuration of Intel's release build;
//! 2. pkg-config `embree4`, then `embree3`;
//! 3. the system include folders (Debian 12's libembree-dev 3.13 ships no pkg-config file).
//!
//! What it found goes to the crates that depend on this one as `DEP_EMBREE_MAJOR`,
//! `DEP_EMBREE_ORIGIN` and, for a library outside the linker's default folders,
//! `DEP_EMBREE_LIB_DIR` (which their build scripts put into their binaries' rpath).
use std::env;
use std::path::{Path, PathBuf};

/// Where Embree was found and how to build against it.
struct Embree {
    major: u32,
    /// The folder holding `embree{major}/rtcore.h`, or `None` for a library without headers.
    include_dir: Option<PathBuf>,
    /// The library's folder when it is not one the linker searches anyway.
    lib_dir: Option<PathBuf>,
    /// How it was found, for the build log and `cvtrace --version`-style diagnostics.
    origin: String,
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/bindings/embree4.rs");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo:rerun-if-env-changed=CVTRACE_EMBREE_SAVE_BINDINGS");
    println!("cargo::rustc-check-cfg=cfg(embree_major, values(\"3\", \"4\"))");
    println!("cargo::rustc-check-cfg=cfg(embree_pregenerated)");

    let embree = find_embree().unwrap_or_else(|tried| missing_embree(&tried));
    println!("cargo:rustc-cfg=embree_major=\"{}\"", embree.major);
    println!("cargo:rustc-env=CVTRACE_EMBREE_ORIGIN={}", embree.origin);
    println!("cargo:major={}", embree.major);
    println!("cargo:origin={}", embree.origin);
    if let Some(dir) = &embree.lib_dir {
        println!("cargo:lib_dir={}", dir.display());
        // This crate's own tests load the library without LD_LIBRARY_PATH.
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", dir.display());
    }
    match &embree.include_dir {
        Some(include) => generate_bindings(embree.major, include),
        None => println!("cargo:rustc-cfg=embree_pregenerated"),
    }
}

/// Tries each source in order; on failure returns what was tried, for the error message.
fn find_embree() -> Result<Embree, Vec<String>> {
    let mut tried = Vec::new();

    if let Some(dir) = env::var_os("EMBREE_DIR").filter(|d| !d.is_empty()) {
        return Ok(from_prefix(&PathBuf::from(dir)));
    }
    tried.push("EMBREE_DIR (not set)".to_string());

    for (major, name) in [(4, "embree4"), (3, "embree3")] {
        match pkg_config::Config::new().cargo_metadata(true).probe(name) {
            Ok(lib) => {
                let mut dirs = lib.include_paths.clone();
                dirs.extend(["/usr/include", "/usr/local/include"].map(PathBuf::from));
                if let Some(inc) = dirs.into_iter().find(|d| d.join(name).join("rtcore.h").is_file()) {
                    let lib_dir = lib.link_paths.first().filter(|d| !is_default_lib_dir(d)).cloned();
                    return Ok(Embree { major, include_dir: Some(inc), lib_dir, origin: format!("pkg-config {name}") });
                }
                tried.push(format!("pkg-config {name} (found, but no {name}/rtcore.h under its include paths)"));
            }
            Err(_) => tried.push(format!("pkg-config {name} (not found)")),
        }
    }

    for prefix in ["/usr", "/usr/local"] {
        let include = Path::new(prefix).join("include");
        if let Some(major) = header_major(&include) {
            for lib in ["lib/x86_64-linux-gnu", "lib/aarch64-linux-gnu", "lib64", "lib"] {
                let lib_dir = Path::new(prefix).join(lib);
                if lib_dir.is_dir() {
                    println!("cargo:rustc-link-search=native={}", lib_dir.display());
                }
            }
            println!("cargo:rustc-link-lib=dylib=embree{major}");
            return Ok(Embree { major, include_dir: Some(include), lib_dir: None, origin: format!("{prefix}/include/embree{major}") });
        }
        tried.push(format!("{prefix}/include/embree{{4,3}}/rtcore.h (absent)"));
    }
    Err(tried)
}

/// An explicit `EMBREE_DIR`: headers and library, or a library alone (Embree 4 only, whose
/// bindings are committed). A prefix that holds neither is an error, not something to skip.
fn from_prefix(dir: &Path) -> Embree {
    let lib_dirs = ["lib", "lib64", "lib/x86_64-linux-gnu", "lib/aarch64-linux-gnu"].map(|l| dir.join(l));
    let include = dir.join("include");
    let origin = format!("EMBREE_DIR={}", dir.display());
    let headers = header_major(&include);
    let library = |major: u32| lib_dirs.iter().find_map(|d| library_file(d, major).map(|f| (d.clone(), f)));
    // Without headers only Embree 4 will do: its bindings are the committed ones.
    let wanted = headers.unwrap_or(4);
    let found = library(wanted).map(|l| (wanted, l));
    let Some((major, (lib_dir, file))) = found else {
        fail(&format!(
            "EMBREE_DIR={} holds no Embree library: expected lib/libembree4.so (or lib/libembree3.so) there, \
             with include/embree4/rtcore.h or include/embree3/rtcore.h beside it unless it is Embree 4.\n\
             `bash scripts/setup.sh` lays out Embree 4 from the PyPI wheel embreex in .deps/embree4.",
            dir.display()
        ))
    };
    println!("cargo:rustc-link-search=native={}", lib_dir.display());
    if file == format!("libembree{major}.so") {
        println!("cargo:rustc-link-lib=dylib=embree{major}");
    } else {
        // A library known only by its versioned name (the wheel's is `libembree4-<hash>.so.4`).
        println!("cargo:rustc-link-lib=dylib:+verbatim={file}");
    }
    Embree { major, include_dir: headers.map(|_| include), lib_dir: Some(lib_dir), origin }
}

/// The name of `libembree{major}` in `dir`: the unversioned link name if there is one, else
/// the first versioned file (`libembree4.so.4`, `libembree4-<hash>.so.4`).
fn library_file(dir: &Path, major: u32) -> Option<String> {
    let prefix = format!("libembree{major}");
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix) && n.contains(".so"))
        .collect();
    names.sort();
    let plain = format!("{prefix}.so");
    if names.contains(&plain) {
        return Some(plain);
    }
    names.into_iter().next()
}

fn is_default_lib_dir(dir: &Path) -> bool {
    ["/usr/lib", "/usr/lib64", "/lib", "/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu"].iter().any(|d| dir == Path::new(d))
}

/// The newest Embree major whose headers are under `include`.
fn header_major(include: &Path) -> Option<u32> {
    [4, 3].into_iter().find(|m| include.join(format!("embree{m}")).join("rtcore.h").is_file())
}

fn fail(message: &str) -> ! {
    eprintln!("\nerror: {message}\n");
    std::process::exit(1);
}

fn missing_embree(tried: &[String]) -> ! {
    fail(&format!(
        "could not find Embree 3 or 4, which cvtrace needs for ray casting.\n\
         \n\
         Looked at:\n{}\n\
         \n\
         Install it with `bash scripts/setup.sh` (Debian/Ubuntu: it installs libembree-dev), or\n\
         point EMBREE_DIR at an Embree install prefix (the folder holding lib/ and, for\n\
         Embree 3, include/embree3/rtcore.h).",
        tried.iter().map(|t| format!("  - {t}")).collect::<Vec<_>>().join("\n")
    ))
}

fn generate_bindings(major: u32, include: &Path) {
    let header = include.join(format!("embree{major}")).join("rtcore.h");
    println!("cargo:rerun-if-changed={}", header.display());
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR")).join("embree_bindings.rs");
    let bindings = bindgen::Builder::default()
        .header(header.to_string_lossy())
        .clang_arg(format!("-I{}", include.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        // Typed integers instead of Rust enums: a value Embree adds later must not be UB.
        .default_enum_style(bindgen::EnumVariation::NewType { is_bitfield: false, is_global: false })
        .bitfield_enum("RTC.*Flags")
        .derive_default(true)
        .layout_tests(false)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()))
        .generate()
        .unwrap_or_else(|e| {
            fail(&format!(
                "bindgen could not process {}: {e}\n(is libclang installed? `bash scripts/setup.sh` installs it)",
                header.display()
            ))
        });
    bindings.write_to_file(&out).unwrap_or_else(|e| fail(&format!("could not write {}: {e}", out.display())));
    // How src/bindings/embree4.rs is made again from a newer Embree 4's headers.
    if let Some(copy) = env::var_os("CVTRACE_EMBREE_SAVE_BINDINGS").filter(|c| !c.is_empty()) {
        std::fs::copy(&out, &copy).unwrap_or_else(|e| fail(&format!("could not copy the bindings to {}: {e}", Path::new(&copy).display())));
    }
}

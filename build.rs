//! Finds the installed Embree (3 or 4), generates its Rust bindings with bindgen and
//! compiles the small C shim that hides the API differences between the two majors.
//!
//! Search order: `EMBREE_DIR` (a prefix with `include/embreeN/rtcore.h` and `lib/`),
//! then pkg-config `embree4` / `embree3`, then the system include directories
//! (Debian 12's libembree-dev 3.13.5 ships no pkg-config file).
use std::env;
use std::path::{Path, PathBuf};

/// Where Embree was found and how to build against it.
struct Embree {
    major: u32,
    /// Directory that contains `embree{major}/rtcore.h`.
    include_dir: PathBuf,
    /// How it was found, for the build log.
    origin: String,
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/embree/shim.c");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");

    let embree = find_embree().unwrap_or_else(|tried| missing_embree(&tried));
    // Logged at run time next to the BVH build, so a user can tell which Embree they got.
    println!("cargo:rustc-env=CVTRACE_EMBREE_ORIGIN={}", embree.origin);
    let header = embree.include_dir.join(format!("embree{}", embree.major)).join("rtcore.h");
    println!("cargo:rerun-if-changed={}", header.display());

    generate_bindings(&embree, &header);
    compile_shim(&embree);
}

/// Tries each source in order; on failure returns what was tried, for the error message.
fn find_embree() -> Result<Embree, Vec<String>> {
    let mut tried = Vec::new();

    if let Some(dir) = env::var_os("EMBREE_DIR") {
        let dir = PathBuf::from(dir);
        let include = dir.join("include");
        match header_major(&include) {
            Some(major) => {
                let lib_dir = ["lib", "lib64", "lib/x86_64-linux-gnu", "lib/aarch64-linux-gnu"]
                    .iter()
                    .map(|l| dir.join(l))
                    .find(|l| has_library(l, major))
                    .unwrap_or_else(|| dir.join("lib"));
                println!("cargo:rustc-link-search=native={}", lib_dir.display());
                println!("cargo:rustc-link-lib=dylib=embree{major}");
                // Tests and the binary run from target/ without LD_LIBRARY_PATH.
                println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib_dir.display());
                return Ok(Embree { major, include_dir: include, origin: format!("EMBREE_DIR={}", dir.display()) });
            }
            None => {
                // An explicit EMBREE_DIR that is wrong is an error, not something to silently skip.
                eprintln!("error: EMBREE_DIR={} has neither include/embree4/rtcore.h nor include/embree3/rtcore.h", dir.display());
                std::process::exit(1);
            }
        }
    }
    tried.push("EMBREE_DIR (not set)".to_string());

    for (major, name) in [(4, "embree4"), (3, "embree3")] {
        match pkg_config::Config::new().cargo_metadata(true).probe(name) {
            Ok(lib) => {
                let mut dirs = lib.include_paths.clone();
                dirs.extend(["/usr/include", "/usr/local/include"].map(PathBuf::from));
                if let Some(inc) = dirs.into_iter().find(|d| d.join(name).join("rtcore.h").is_file()) {
                    return Ok(Embree { major, include_dir: inc, origin: format!("pkg-config {name}") });
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
            return Ok(Embree { major, include_dir: include, origin: format!("{prefix}/include/embree{major}") });
        }
        tried.push(format!("{prefix}/include/embree{{4,3}}/rtcore.h (absent)"));
    }
    Err(tried)
}

/// Whether `dir` holds `libembree{major}` in any form (.so, .so.N, .a, .dylib).
fn has_library(dir: &Path, major: u32) -> bool {
    let prefix = format!("libembree{major}");
    std::fs::read_dir(dir).map(|entries| entries.flatten().any(|e| e.file_name().to_string_lossy().starts_with(&prefix))).unwrap_or(false)
}

/// The newest Embree major whose headers are under `include`.
fn header_major(include: &Path) -> Option<u32> {
    [4, 3].into_iter().find(|m| include.join(format!("embree{m}")).join("rtcore.h").is_file())
}

fn missing_embree(tried: &[String]) -> ! {
    eprintln!(
        "\n\
         error: could not find Embree 3 or 4, which cvtrace needs for ray casting.\n\
         \n\
         Looked at:\n{}\n\
         \n\
         Install it with your package manager, e.g. on Debian/Ubuntu:\n\
         \x20   apt-get install libembree-dev      (or run scripts/setup.sh)\n\
         or point EMBREE_DIR at an Embree install prefix (the directory holding\n\
         include/embree4/rtcore.h or include/embree3/rtcore.h, and lib/).\n",
        tried.iter().map(|t| format!("  - {t}")).collect::<Vec<_>>().join("\n")
    );
    std::process::exit(1);
}

fn generate_bindings(embree: &Embree, header: &Path) {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR")).join("embree_bindings.rs");
    let bindings = bindgen::Builder::default()
        .header(header.to_string_lossy())
        .clang_arg(format!("-I{}", embree.include_dir.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        // Typed integers instead of Rust enums: a value Embree adds later must not be UB.
        .default_enum_style(bindgen::EnumVariation::NewType { is_bitfield: false, is_global: false })
        .bitfield_enum("RTC.*Flags")
        .derive_default(true)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()))
        .generate()
        .unwrap_or_else(|e| {
            eprintln!("error: bindgen could not process {}: {e}\n(is libclang installed? apt-get install libclang-dev)", header.display());
            std::process::exit(1);
        });
    bindings.write_to_file(&out).unwrap_or_else(|e| {
        eprintln!("error: could not write {}: {e}", out.display());
        std::process::exit(1);
    });
}

fn compile_shim(embree: &Embree) {
    cc::Build::new()
        .file("src/embree/shim.c")
        .include(&embree.include_dir)
        .define("CVT_EMBREE_MAJOR", embree.major.to_string().as_str())
        .opt_level(2)
        .warnings(true)
        .compile("cvtrace_embree_shim");
}

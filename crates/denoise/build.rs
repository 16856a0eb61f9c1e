//! The Open Image Denoise folder (`DEP_CVTRACE_OIDN_LIB_DIR`) into the rpath of this crate's
//! tests, so they run without LD_LIBRARY_PATH.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_CVTRACE_OIDN_LIB_DIR");
    if let Ok(dir) = std::env::var("DEP_CVTRACE_OIDN_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}

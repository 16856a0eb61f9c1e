//! The binary and the tests find Intel Open Image Denoise, which `scripts/setup.sh` installs
//! outside the system's library folders, through their rpath: no LD_LIBRARY_PATH needed.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_CVTRACE_OIDN_LIB_DIR");
    if let Ok(dir) = std::env::var("DEP_CVTRACE_OIDN_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}

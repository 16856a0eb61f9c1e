//! The extension module finds Intel Open Image Denoise, which `scripts/setup.sh` installs outside
//! the system's library folders, through its rpath, as the `cvtrace` binary does. A cdylib's link
//! arguments come from its own build script only, hence this one. In the wheel, the repair step
//! (`make python`) bundles the libraries and rewrites the rpath to the bundled copies.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_CVTRACE_OIDN_LIB_DIR");
    if let Ok(dir) = std::env::var("DEP_CVTRACE_OIDN_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}

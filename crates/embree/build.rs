//! Puts the folder of the Embree library `cvtrace-embree-sys` linked into the rpath of this
//! crate's tests, benches and examples, so they run without LD_LIBRARY_PATH when it is not a
//! system folder (the Embree 4 of `.deps/embree4`).
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_EMBREE_LIB_DIR");
    if let Ok(dir) = std::env::var("DEP_EMBREE_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}

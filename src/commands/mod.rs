//! One file per subcommand: its flags, and the glue from them to the library crates.
pub mod compare;
pub mod farm;
pub mod merge;
pub mod reconstruct;
pub mod render;
pub mod report;
pub mod study;

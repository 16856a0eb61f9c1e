//! One file per subcommand.
pub mod compare;
pub mod reconstruct;
pub mod render;
pub mod report;
pub mod study;
pub mod throughput;

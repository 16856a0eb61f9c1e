//! One file per subcommand.
pub mod reconstruct;
pub mod render;

//! `cvtrace reconstruct` (work in progress).
#[derive(clap::Args)]
pub struct ReconstructArgs {}

pub fn run(_args: ReconstructArgs) -> anyhow::Result<()> {
    anyhow::bail!("reconstruct is not implemented yet")
}

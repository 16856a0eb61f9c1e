//! `cvtrace render` (work in progress).
#[derive(clap::Args)]
pub struct RenderArgs {}

pub fn run(_args: RenderArgs) -> anyhow::Result<()> {
    anyhow::bail!("render is not implemented yet")
}

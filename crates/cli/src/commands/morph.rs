//! TODO(helper): implement this subcommand.

use crate::context::Context;

#[derive(clap::Args)]
pub struct Args {
    /// Input file.
    pub input: std::path::PathBuf,
}

pub fn run(_args: Args, _ctx: &Context) -> anyhow::Result<()> {
    anyhow::bail!("not implemented yet")
}

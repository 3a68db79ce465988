//! `asbuilt info`.

use std::process::ExitCode;

#[derive(clap::Args)]
pub struct InfoArgs {}

pub fn run(_args: InfoArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`asbuilt info` is not built yet")
}

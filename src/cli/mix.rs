//! `harmonid mix` (being built).

/// Arguments of `harmonid mix`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid mix` is not available yet"))
}

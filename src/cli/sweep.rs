//! `harmonid sweep` (being built).

/// Arguments of `harmonid sweep`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid sweep` is not available yet"))
}

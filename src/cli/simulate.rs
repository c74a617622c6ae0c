//! `harmonid simulate` (being built).

/// Arguments of `harmonid simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid simulate` is not available yet"))
}

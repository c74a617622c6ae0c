//! `harmonid check` (being built).

/// Arguments of `harmonid check`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid check` is not available yet"))
}

//! `harmonid identify` (being built).

/// Arguments of `harmonid identify`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid identify` is not available yet"))
}

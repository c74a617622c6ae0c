//! `harmonid noise-study` (being built).

/// Arguments of `harmonid noise-study`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`harmonid noise-study` is not available yet"))
}

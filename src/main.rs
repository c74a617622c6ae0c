//! The `harmonid` command line: one subcommand per capability, each in `src/cli/<name>.rs`.

mod cli;

use clap::{Parser, Subcommand};

/// harmonid: nonlinear multimode resonator models from multi-tone sideband spectra.
#[derive(Debug, Parser)]
#[command(name = "harmonid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Parse and validate a model file and print its equations of motion.
    Check(cli::check::Args),
    /// Print the combination frequencies each term generates under a set of drive tones.
    Mix(cli::mix::Args),
    /// Import instrument files (lock-in exports, tables, MATLAB files) into a dataset folder.
    Import(cli::import::Args),
    /// Pool datasets of one device (rounds of the lab loop) into one dataset folder.
    Merge(cli::merge::Args),
    /// Identify the model's coefficients from a measured dataset.
    Identify(cli::identify::Args),
    /// Fit one dataset by several models: which one the data support, and does it fit?
    Compare(cli::compare::Args),
    /// Which candidate terms (a library of monomials) do the data support? Writes the model.
    Discover(cli::discover::Args),
    /// Simulate measurements and write a dataset folder.
    Simulate(cli::simulate::Args),
    /// Compute a frequency-response curve with continuation through folds.
    Sweep(cli::sweep::Args),
    /// Every steady state at one drive and pump, with stability (homotopy continuation).
    States(cli::states::Args),
    /// Count the stable and unstable steady states over a grid of two parameters.
    PhaseDiagram(cli::phase_diagram::Args),
    /// The linear response to a weak probe tone about a steady state, its idler, and noise spectra.
    Response(cli::response::Args),
    /// Design a drive-tone plan, or score one, by the Cramér–Rao bounds of the unknowns.
    Plan(cli::plan::Args),
    /// Robustness of the identification to measurement noise (Supplementary Note V).
    NoiseStudy(cli::noise_study::Args),
    /// Write an HTML report with every figure of an identification.
    Report(cli::report::Args),
}

fn main() -> miette::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Check(args) => cli::check::run(args),
        Command::Mix(args) => cli::mix::run(args),
        Command::Import(args) => cli::import::run(args),
        Command::Merge(args) => cli::merge::run(args),
        Command::Identify(args) => cli::identify::run(args),
        Command::Compare(args) => cli::compare::run(args),
        Command::Discover(args) => cli::discover::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Sweep(args) => cli::sweep::run(args),
        Command::States(args) => cli::states::run(args),
        Command::PhaseDiagram(args) => cli::phase_diagram::run(args),
        Command::Response(args) => cli::response::run(args),
        Command::NoiseStudy(args) => cli::noise_study::run(args),
        Command::Report(args) => cli::report::run(args),
        Command::Plan(args) => cli::plan::run(args),
    }
}

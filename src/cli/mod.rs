//! Subcommands of the `harmonid` binary. Each module has an `Args` (clap) and a `run`.

pub mod check;
pub mod common;
pub mod compare;
pub mod discover;
pub mod figure;
pub mod identify;
pub mod import;
pub mod limit_cycles;
pub mod merge;
pub mod mix;
pub mod noise_study;
pub mod phase_diagram;
pub mod plan;
pub mod progress;
pub mod report;
pub mod response;
pub mod simulate;
pub mod states;
pub mod sweep;
pub mod sweep_args;
pub mod sweep_pumped;

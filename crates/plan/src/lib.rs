//! Drive-tone planning: scores a measurement plan by the Cramér–Rao bounds of the model's
//! unknowns ([`evaluate`]) and designs one ([`design`]).
//!
//! Both simulate each planned measurement noise-free by harmonic balance
//! (`harmonid_experiment::Plan::simulate_numeric`), predict its lines with the forward model of
//! `harmonid_ident::forward` and add up the Fisher information of the measurements
//! (`harmonid_ident::fisher`): per measurement, its actuator gains (one complex gain per mode
//! and measurement, `F = G V e^{iφ}`) are profiled out by a Schur complement, so the
//! information of the shared unknowns (`ω²`, `γ`, parameters) adds up over measurements.
//! Noise: per-quadrature `σ` (m) on every measured amplitude of every shot, independent; `N`
//! shots of each measurement.

#![warn(missing_docs)]

mod coupled;
mod design;
mod evaluate;
mod info;
mod level;

pub use design::{design, design_with_progress, DesignSettings, DesignStep};
pub use evaluate::{evaluate, Evaluation, Finding};

use harmonid_experiment::ExperimentError;
use harmonid_ident::{FisherError, ForwardError};

/// What can go wrong while planning.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The plan or the simulation of a measurement failed (boxed: it is large and rare).
    #[error(transparent)]
    Experiment(Box<ExperimentError>),
    /// The forward model failed (names the measurement or the unknown).
    #[error(transparent)]
    Forward(#[from] ForwardError),
    /// The Fisher information could not be formed (noise, shots).
    #[error(transparent)]
    Fisher(#[from] FisherError),
    /// The simulation crate refused the values.
    #[error(transparent)]
    Sim(#[from] harmonid_sim::SimError),
    /// A measurement's drive passes a fold: the steady state jumps while the drive ramps up.
    #[error("measurement \"{measurement}\": the drive passes a fold at {percent:.1} % of its level (the response jumps while the drive ramps up); lower its forces below that level or move its tones")]
    Fold {
        /// Measurement name.
        measurement: String,
        /// Where the jump happens, percent of the planned drive.
        percent: f64,
    },
    /// A parameter no drive within the limits reveals.
    #[error("{parameter} cannot be identified with drives within the limits ({limits}): {reason}")]
    Unidentifiable {
        /// The unknown.
        parameter: String,
        /// Why.
        reason: String,
        /// The limits in force.
        limits: String,
    },
    /// More measurements are needed than allowed.
    #[error("{needed} measurements are needed ({list}), but --max-measurements is {limit}; raise it or fix some parameters in the model")]
    Budget {
        /// Measurements the design needs.
        needed: usize,
        /// The limit.
        limit: usize,
        /// Their names and purposes.
        list: String,
    },
    /// Bad settings or values.
    #[error("{0}")]
    Input(String),
}

impl From<ExperimentError> for PlanError {
    fn from(e: ExperimentError) -> Self {
        PlanError::Experiment(Box::new(e))
    }
}

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
mod devices;
mod draws;
mod evaluate;
mod info;
mod instrument;
mod level;
mod range;
mod terms;

pub use design::{
    default_ladder, design, design_with_progress, DesignSettings, DesignStep, DEFAULT_DRAWS,
    DEFAULT_LADDER,
};
pub use evaluate::{evaluate, robustness, Evaluation, Finding, Robustness};
pub use instrument::{
    attenuation, bandwidth_3db_hz, choose_filter, design_for_instrument, lockin_lines, lockin_plan,
    lockin_time_s, nearest_hz, nebw_hz, settle_time, InstrumentSettings, LockIn, Profile, LOCKINS,
    REJECTION, SETTLE_ACCURACY,
};
pub use range::{
    GuessRange, RangeEntry, DEFAULT_F_LINEWIDTHS, DEFAULT_PARAM_FACTOR, DEFAULT_Q_REL,
};

use harmonid_experiment::ExperimentError;
use harmonid_ident::{FisherError, ForwardError};

/// What can go wrong while planning. Every variant is a diagnostic with a stable code and,
/// where there is one thing to try, a help line.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum PlanError {
    /// The plan or the simulation of a measurement failed (boxed: it is large and rare).
    #[error(transparent)]
    #[diagnostic(transparent)]
    Experiment(Box<ExperimentError>),
    /// The forward model failed (names the measurement or the unknown).
    #[error(transparent)]
    #[diagnostic(
        code(harmonid::plan::forward),
        help("the guess could not be simulated as planned: check the --values and the plan's drive levels")
    )]
    Forward(#[from] ForwardError),
    /// The Fisher information could not be formed (noise, shots).
    #[error(transparent)]
    #[diagnostic(code(harmonid::plan::fisher))]
    Fisher(#[from] FisherError),
    /// The simulation crate refused the values.
    #[error(transparent)]
    #[diagnostic(
        code(harmonid::plan::values),
        help("the --values must give every mode's f_hz and Q and every parameter of the model")
    )]
    Sim(#[from] harmonid_sim::SimError),
    /// A model with pump terms: the designer chooses drive tones, not pumps.
    #[error(
        "{model}: the model has pump terms ({terms}), and plan designs drive tones only, not pumps"
    )]
    #[diagnostic(
        code(harmonid::plan::pump),
        help("write the pumped measurements by hand (a plan's `pumps_hz`, `pump_levels`, `pump_phases_rad`) and check them with `harmonid simulate` and `harmonid noise-study`; or plan the drives with a copy of the model without the pump terms")
    )]
    PumpTerms {
        /// The model's source.
        model: String,
        /// The pump terms.
        terms: String,
    },
    /// A measurement's drive passes a fold: the steady state jumps while the drive ramps up.
    #[error("measurement \"{measurement}\": the drive passes a fold at {percent:.1} % of its level (the response jumps while the drive ramps up); lower its forces below that level or move its tones")]
    #[diagnostic(code(harmonid::plan::fold))]
    Fold {
        /// Measurement name.
        measurement: String,
        /// Where the jump happens, percent of the planned drive.
        percent: f64,
    },
    /// A parameter no drive within the limits reveals.
    #[error("{parameter} cannot be identified with drives within the limits ({limits}): {reason}")]
    #[diagnostic(
        code(harmonid::plan::unidentifiable),
        help("relax the limits (--max-force, --max-frequencies, --bandwidth), or fix the parameter in the model")
    )]
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
    #[diagnostic(code(harmonid::plan::budget))]
    Budget {
        /// Measurements the design needs.
        needed: usize,
        /// The limit.
        limit: usize,
        /// Their names and purposes.
        list: String,
    },
    /// A design setting out of its range.
    #[error("{what} must be {expected} (got {found})")]
    #[diagnostic(code(harmonid::plan::setting))]
    Setting {
        /// The setting (`the noise σ`, `shots`, ...).
        what: &'static str,
        /// The value given, as written in the message (with its unit).
        found: String,
        /// What it must be.
        expected: &'static str,
    },
    /// An instrument setting that cannot be used (gains, voltage, grid).
    #[error("{message}")]
    #[diagnostic(
        code(harmonid::plan::instrument),
        help("the instrument's limits: --grid-hz (every tone a multiple), --gain MODE=N/kg per V with --max-voltage, --max-frequencies")
    )]
    Instrument {
        /// What is wrong, the limit and what to relax.
        message: String,
    },
    /// An uncertainty of the guess that cannot be used.
    #[error("{quantity}: {message}")]
    #[diagnostic(
        code(harmonid::plan::range),
        help("a guess's uncertainty is written with its value: `beta1 = {{ value = 6e23, factor = 2 }}`, `Q = {{ value = 4.5e5, rel = 0.3 }}`, `f_hz = {{ value = 207600, abs_hz = 3 }}`")
    )]
    Range {
        /// The quantity (`Q:q1`, `beta1`).
        quantity: String,
        /// What is wrong and what to relax.
        message: String,
    },
    /// A plan with no measurement to score.
    #[error("the plan has no measurement")]
    #[diagnostic(
        code(harmonid::plan::empty),
        help("a plan needs at least one [[measurement]] with drives_hz and force")
    )]
    EmptyPlan,
    /// The gains could not be profiled out of the information (a numeric failure).
    #[error("profiling the gains out: {reason}")]
    #[diagnostic(code(harmonid::plan::profile))]
    Profile {
        /// What the linear algebra said.
        reason: String,
    },
}

/// The most devices a plan's bounds are drawn over: each draw simulates the whole plan on one
/// device (10,000 draws are already hours of work), so more is refused before any work.
pub const MAX_DRAWS: usize = 10_000;

/// Refuses more than [`MAX_DRAWS`] draws, saying the bound and why.
pub fn check_draws(draws: usize) -> Result<(), PlanError> {
    if draws > MAX_DRAWS {
        return Err(PlanError::Setting {
            what: "the devices drawn from the range (--draws)",
            found: draws.to_string(),
            expected: "at most 10000: each draw simulates the whole plan on one device, and the \
                       worst case of 100 draws is already well resolved",
        });
    }
    Ok(())
}

impl From<ExperimentError> for PlanError {
    fn from(e: ExperimentError) -> Self {
        PlanError::Experiment(Box::new(e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use miette::Diagnostic;

    #[test]
    fn every_error_reaches_the_user_as_a_coded_diagnostic() {
        let cases = [
            (PlanError::EmptyPlan, "harmonid::plan::empty"),
            (
                PlanError::Setting {
                    what: "shots",
                    found: "0".into(),
                    expected: "at least 1",
                },
                "harmonid::plan::setting",
            ),
            (
                PlanError::Fold {
                    measurement: "single_q1".into(),
                    percent: 42.0,
                },
                "harmonid::plan::fold",
            ),
            (
                PlanError::Budget {
                    needed: 4,
                    limit: 3,
                    list: "a, b, c, d".into(),
                },
                "harmonid::plan::budget",
            ),
        ];
        for (e, code) in cases {
            assert_eq!(
                e.code().map(|c| c.to_string()).as_deref(),
                Some(code),
                "{e}"
            );
        }
        let e = PlanError::Setting {
            what: "shots",
            found: "0".into(),
            expected: "at least 1",
        };
        assert_eq!(e.to_string(), "shots must be at least 1 (got 0)");
        assert!(PlanError::Unidentifiable {
            parameter: "g12".into(),
            reason: "no coupled drive".into(),
            limits: "--max-force 1".into(),
        }
        .help()
        .is_some());
    }
}

//! Forward simulation of nonlinear multimode resonators.
//!
//! Every mode `n` obeys (mass-normalised, SI, `DATA_FORMAT.md` conventions)
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q, q̇) = Σ_d Re[F_d^(n) e^{i 2π f_d t}],
//! ```
//!
//! and a complex amplitude `X` at `f` means `Re[X e^{i 2π f t}]` (peak). This crate computes:
//!
//! - time-domain responses with an exact-linear-part (Lawson) Dormand–Prince integrator and
//!   lock-in demodulation over windows holding whole periods of every frequency
//!   ([`simulate_lockin`]);
//! - multi-tone harmonic-balance steady states on an automatic lattice with a drive ramp
//!   ([`steady_state`], [`HbSolver`], [`convergence_report`]);
//! - sensitivities of steady states to modal data, model parameters and drive forces by
//!   implicit differentiation of the harmonic-balance equations ([`sensitivity`]);
//! - single-tone response curves through folds with stability, jumps and backbones ([`sweep`],
//!   [`backbone`]).

#![warn(missing_docs)]
// Numeric kernels index several parallel arrays with one loop variable; iterator chains would
// obscure the math.
#![allow(clippy::needless_range_loop)]

mod error;
mod excitation;
mod lattice;
mod linalg;
mod noise;
mod numeric;
mod response;
mod rough;
pub mod sensitivity;
mod steady;

mod time_domain;

pub use error::SimError;
pub use excitation::{common_grid, linear_response, Excitation, PumpTone};
pub use lattice::{choose_lattice, measured_lines, LatticeSettings, LINE_TOL_HZ};
pub use noise::{lockin_noise_sigma, NoiseGen};
pub use numeric::{
    parse_monomial, parse_rough_monomial, ModeValues, ModelValues, NumericModel, Term,
};
pub use response::{
    probe_response, LinearResponse, ProbeResponse, MAX_PROBES, MAX_RESPONSE_HARMONIC,
    MAX_RESPONSE_UNKNOWNS, RESPONSE_DEPTH,
};
pub use rough::RoughTerm;
pub use sensitivity::{Observation, ReducedSensitivity, SensParam, Sensitivity};
pub use steady::{
    backbone, check_stability, convergence_report, limit_cycle, quasi_periodic_branch,
    steady_state, steady_state_from, stepped_sweep, sweep, sweep_two_tone, ActiveModes, BranchEnd,
    ConvergenceReport, Fold, HbSettings, HbSolver, HbStatus, Hopf, LimitCycle, ModeLine,
    QuasiPeriodicBranch, QuasiPeriodicPoint, QuasiPeriodicSettings, ReducedSolver, Stability,
    SteadyState, SweepPoint, SweepResult, SweepSettings, TwoToneCurve, TwoToneJump, TwoTonePoint,
    TwoToneSettings, TwoToneStatus, TwoToneSweep, CONDENSE_SEPARATION, MAX_MODES,
    MAX_SWEEP_HARMONICS, MAX_SWEEP_HZ, MAX_SWEEP_POINTS,
};
pub use steady::{Grid, GridSampler};
pub use time_domain::{simulate_lockin, LockinResult, Start, TdSettings};

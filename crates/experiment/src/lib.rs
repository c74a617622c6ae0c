//! harmonid-experiment: the virtual experiment.
//!
//! A measurement [`Plan`] (the TOML file `harmonid simulate --plan` reads) lists measurement
//! points, drive configurations and the lock-in noise; [`Plan::simulate`] turns it, with a model
//! and its parameter values, into the [`Dataset`](harmonid_data::Dataset) a lab would record:
//! every mode `n` obeys
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = Σ_d Re[F_d^(n) e^{i2πf_d t}],
//! ```
//!
//! solved by harmonic balance (or integrated in time and demodulated), each steady state checked
//! for stability (Hill) and for truncation of its spectrum, and Gaussian noise of the given
//! per-quadrature σ added to every complex amplitude of every shot.
//!
//! ```
//! use harmonid_experiment::{values_from_toml, Plan, Settings};
//! let model = harmonid_model::parse_str(
//!     "mode q1 at 1 kHz\nparam beta1\npotential: beta1/4*q1^4\n",
//!     "duffing.hb",
//! )
//! .expect("a valid model");
//! let plan = Plan::from_toml(r#"
//!     [[measurement]]
//!     name = "two_tones"
//!     drives_hz = [999.0, 1001.0]
//!     force = { q1 = [1.0, 1.0] }
//! "#, "plan.toml").expect("a valid plan");
//! let values = values_from_toml(
//!     "[modes.q1]\nf_hz = 1000.0\nQ = 200.0\n[parameters]\nbeta1 = 1e10\n",
//!     "values.toml",
//! )
//! .expect("values");
//! let sim = plan.simulate(&model, &values, &Settings::default()).expect("simulates");
//! let m = &sim.dataset.measurements[0];
//! assert!(m.freqs_hz.iter().any(|&f| (f - 997.0).abs() < 1e-6)); // a sideband
//! assert!(sim.reports[0].stability.as_ref().is_some_and(|s| s.stable));
//! ```

#![warn(missing_docs)]
// Errors carry the plan's text and span for miette; they are built once, on the way out, never
// in a loop: their size does not matter.
#![allow(clippy::result_large_err)]

mod error;
mod lockin;
mod noise;
mod params_from_eom;
mod plan;
mod run;
mod values;

pub use error::{ExperimentError, PlanError};
pub use lockin::{LockinLevel, PlanInstrument};
pub use noise::{sigma_from_asd, sigma_from_time_rms, NoiseLevel};
pub use params_from_eom::{parameters_from_eom, DerivedParameters};
pub use plan::{Plan, PlanMeasurement, PlanNoise, MAX_LEVELS, MAX_MEASURED, MAX_SHOTS, MAX_TONES};
pub use run::{
    add_noise, Engine, LostLevel, MeasurementReport, Settings, Simulation, TimeDomain, Truncation,
    MAX_ORDER, MAX_TD_RUNS,
};
pub use values::{
    guess_from_report, guess_from_reports, guess_from_toml, read_guess, read_result, read_values,
    values_from_json, values_from_report, values_from_toml, Guess, Spread, RESULT_SPREAD_STDERR,
};

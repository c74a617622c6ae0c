//! harmonid-ident: identification of nonlinear multimode resonator models from the complex
//! amplitudes of multi-tone sideband spectra (the method of Wattjes et al., generalised).
//!
//! Per mode `n` and measured frequency `Ω_r` attributed to it (conventions of `DATA_FORMAT.md`:
//! a complex amplitude `X` at `f` is the signal `Re[X e^{i2πft}]`):
//!
//! ```text
//! (ω_n² − Ω_r² + iΩ_r ω_n/Q_n) q̂_n(Ω_r) + Σ_m b_m^(n) ĝ_m(Ω_r) = F̂_n(Ω_r)
//! ```
//!
//! where `ĝ_m` is the complex amplitude of monomial `m(q)` at `Ω_r`, computed exactly from the
//! measured spectra. Real and imaginary parts give two linear equations in the unknowns
//! (`ω_n²`, `ω_n/Q_n`, the model's parameters, forces or actuator gains), solved stage by
//! stage ([`problem`]) by equilibrated least squares ([`solve`]); [`report`] turns per-shot
//! estimates into the result file.
//!
//! ```no_run
//! use harmonid_ident::{identify, Dataset, Settings};
//! let model = harmonid_model::load("examples/nanostring_2mode/model.hb".as_ref()).expect("model");
//! let ds = Dataset::load("path/to/dataset").expect("dataset");
//! let report = identify(&model, &ds, &Settings::default()).expect("identify");
//! println!("{}", report.summary(ds.truth.as_ref()));
//! ```

#![warn(missing_docs)]

pub mod consistency;
pub mod dataset;
pub mod drift;
pub mod estimator;
pub mod fisher;
pub mod forward;
pub mod layout;
pub mod ml;
pub mod pool;
pub mod problem;
pub mod report;
pub mod solve;

pub use dataset::{
    Dataset, DatasetError, Manifest, Measurement, MeasurementSpec, Point, Truth, TruthForce,
    TruthMode, TruthNoise,
};
pub use estimator::{identify, MAX_REL_STDERR};
pub use fisher::{crlb, Bounds, FisherError, Noise};
pub use forward::{ForwardError, ForwardModel, ForwardSettings};
pub use layout::{Quantity, UnknownTable};
pub use problem::{
    Estimator, ForceModel, IdentError, Problem, Settings, Unknown, UnknownEstimator,
};
pub use report::{Estimate, Report};

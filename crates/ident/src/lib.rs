//! harmonid-ident: identification of nonlinear multimode resonator models from the complex
//! amplitudes of multi-tone sideband spectra (the method of Wattjes et al., generalised).
//!
//! **The estimate** is output-error maximum likelihood: the coefficients whose harmonic-balance
//! steady states ([`ForwardModel`]) best reproduce every measured line of the pooled shots,
//! each line weighted by its noise from the scatter of the shots. Its standard errors come
//! from the Fisher information at the estimate, inflated by `√(χ²/dof)` over a correct model's
//! expectation when the model misses the data, and are checked by a jackknife, a drift test
//! and the agreement of the measurements that see one quantity.
//!
//! **Its start** is the method's linear fit (equation error): per mode `n` and measured
//! frequency `Ω_r` attributed to it (conventions of `docs/data-format.md`: a complex amplitude
//! `X` at `f` is the signal `Re[X e^{i2πft}]`)
//!
//! ```text
//! (ω_n² − Ω_r² + iΩ_r ω_n/Q_n) q̂_n(Ω_r) + Σ_m b_m^(n) ĝ_m(Ω_r) = F̂_n(Ω_r)
//! ```
//!
//! where `ĝ_m` is the complex amplitude of monomial `m(q)` at `Ω_r`, computed exactly from the
//! measured spectra: two real equations per line, linear in the unknowns (`ω_n²`, `ω_n/Q_n`,
//! the model's parameters, forces or actuator gains), solved stage by stage ([`Problem`]) by
//! equilibrated least squares, per shot (the spread the paper's histograms show) and on the
//! pooled shots (the start).
//!
//! The modules follow that order: `identify` → `finalize` (the result, built once) →
//! `output_error` (starts and the fit) → `uncertainty` (Fisher bounds, jackknife, drift,
//! consistency) → `forward` (the dataset-shaped harmonic balance both use) → `shots` (pooling,
//! robust statistics) → `problem` (the linear fit) → `layout` (the one table of unknowns,
//! [`UnknownTable`]); the dataset reader is `harmonid_data`.
//!
//! ```
//! use harmonid_data::Dataset;
//! use harmonid_ident::{identify, Estimator, Settings};
//! use std::path::Path;
//! let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/nanostring_2mode");
//! let model = harmonid_model::load(&dir.join("model.hb")).expect("model");
//! let ds = Dataset::load(dir.join("data")).expect("dataset");
//! let report = identify(&model, &ds, &Settings::default()).expect("identify");
//! assert_eq!(report.estimator, Estimator::Ml.name());
//! let f1 = &report.modes["q1"].f_hz;
//! assert!((f1.value - 207_582.0).abs() < 5.0 * f1.stderr.max(1.0));
//! println!("{}", report.summary(ds.truth.as_ref()));
//! ```

#![warn(missing_docs)]

pub mod background;
mod background_terms;
mod compare;
mod discover;
pub mod finalize;
mod forward;
mod holdout;
mod identify;
mod layout;
mod output_error;
mod problem;
mod settings;
mod shots;
mod solve;
mod uncertainty;

pub use background_terms::{Background, BackgroundTerm, BadBackground};
pub use compare::{
    compare, compare_with_holdout, CompareError, ModelComparison, ModelFit, NestedTest,
    NotDetermined,
};
pub use discover::{
    discover, DiscoverError, DiscoverSettings, Discovery, DiscoveryStep, Library, LibraryForm,
    MAX_CANDIDATES,
};
pub use finalize::{
    report_from_shots, Estimate, FitReport, ForceResult, GainResult, ModeResult, Report,
    JACKKNIFE_TOL, MAX_REL_STDERR, RESULT_FORMAT,
};
pub use forward::{ForwardError, ForwardModel, ForwardSettings, Widened};
pub use holdout::{identify_with_holdout, HeldOut};
pub use identify::{identify, LADDER_ALPHA, MAX_MEASUREMENTS, MAX_SHOT_FITS};
pub use layout::{Quantity, Unknown, UnknownTable};
pub use output_error::ml::{refine, MlFit, MlSettings};
pub use problem::{
    DatasetShape, Fit, FitGroup, GroupDiagnostics, IdentError, NotIdentifiable, Problem,
};
pub use settings::{Estimator, ForceModel, Settings, UnknownEstimator, UnknownForceModel};
pub use shots::{disturbed_shots, pool, shot_stats, Pooled, ShotStats, REJECTION_ALPHA};
pub use solve::{solve_ls, LsSolution};
pub use uncertainty::consistency::{
    threshold as consistency_threshold, Compared, Comparison, FAMILY_ALPHA,
};
pub use uncertainty::{
    bounds_from_information, crlb, crlb_from_jacobian, drift_check, information, Bound, Bounds,
    Drift, FisherError, GoodnessOfFit, LineResidual, MeasurementFit, Noise, Unidentifiable,
    P_DOES_NOT_FIT,
};

//! harmonid-ident: identification of nonlinear multimode resonator models from the complex
//! amplitudes of multi-tone sideband spectra.
//!
//! Per mode `n` and measured frequency `Ω_r` attributed to it (conventions of `DATA_FORMAT.md`):
//!
//! ```text
//! (ω_n² − Ω_r² + iΩ_r ω_n/Q_n) q̂_n(Ω_r) + Σ_m b_m^(n) ĝ_m(Ω_r) = F̂_n(Ω_r)
//! ```
//!
//! where `ĝ_m` is the complex amplitude of monomial `m(q)` at `Ω_r`.

#![warn(missing_docs)]

pub mod dataset;
pub mod problem;
pub mod solve;

pub use dataset::{
    Dataset, DatasetError, Manifest, Measurement, MeasurementSpec, Point, Truth, TruthForce,
    TruthMode, TruthNoise,
};

//! Harmonic-balance algebra for multi-tone driven resonators.
//!
//! When the modes of
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = Σ_d F_d^(n) cos(2π f_d t + φ_d^(n))
//! ```
//!
//! move at several frequencies, every monomial `m(q)` responds at integer combinations of them.
//! This crate computes those responses exactly:
//!
//! - [`ProductPlan`] / [`monomial_amplitudes`]: numeric complex amplitudes of a monomial's
//!   product signal at chosen frequencies, from measured or simulated modal spectra
//!   (`x(t) = Σ_r Re[X_r e^{i2π f_r t}]`, peak amplitudes, DATA_FORMAT conventions), with
//!   Jacobians ([`ProductPlan::eval_jacobian`], [`monomial_jacobian`]).
#![warn(missing_docs)]

mod error;
mod product;

pub use error::SpectralError;
pub use product::{
    monomial_amplitudes, monomial_jacobian, ProductPlan, ProductScratch, FREQ_TOLERANCE_HZ,
    MAX_PRODUCT_DEGREE,
};

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
//! - [`ToneSet`], [`Combination`]: combination frequencies `Σ k_d f_d` as exact lattice points,
//!   printed `f1 + 2·f3 − f2`, with [`ToneSet::lattice`] to enumerate them up to an
//!   intermodulation order and [`nearest_mode`] to attribute them to a resonance;
//! - [`mixing_table`]: the symbolic expansion of a monomial under a [`ToneAssignment`], every line
//!   with an exact rational coefficient polynomial in the real tone amplitudes `X_d`
//!   (Supplementary Note II of the method's paper);
//! - [`ProductPlan`] / [`monomial_amplitudes`]: numeric complex amplitudes of a monomial's
//!   product signal at chosen frequencies, from measured or simulated modal spectra
//!   (`x(t) = Σ_r Re[X_r e^{i2π f_r t}]`, peak amplitudes, DATA_FORMAT conventions), with
//!   Jacobians ([`ProductPlan::eval_jacobian`], [`monomial_jacobian`]);
//! - [`SystemPlan`]: the forces `Σ c·m(x)` of a whole polynomial system and their Jacobian in
//!   one pass, sharing partial products between monomials and equations (what a
//!   harmonic-balance residual evaluates at every Newton step).
//!
//! Eq. S1 of the paper, `q1³` under tones `ω1 ± δ`:
//!
//! ```
//! use harmonid_poly::PowerProduct;
//! use harmonid_spectral::{mixing_table, ToneAssignment, Window};
//! let drives = vec![("q1".to_string(), vec![207592.0, 207572.0])];
//! let a = ToneAssignment::from_drives(&["q1"], &drives)?;
//! let t = mixing_table(&PowerProduct::from_exponents(&[3]), &a, &[Some(207582.0)], Window::default())?;
//! let names = a.symbols();
//! let at = |k: &[i32]| {
//!     let c = a.tones().combination(k).unwrap();
//!     t.line(&c).unwrap().coefficient.to_string_with(&names)
//! };
//! assert_eq!(t.lines.len(), 8);
//! assert_eq!(at(&[1, 0]), "3/4*X1^3 + 3/2*X1*X2^2");   // ω1 + δ
//! assert_eq!(at(&[2, -1]), "3/4*X1^2*X2");             // ω1 + 3δ
//! assert_eq!(at(&[3, 0]), "1/4*X1^3");                 // 3ω1 + 3δ
//! # Ok::<(), harmonid_spectral::SpectralError>(())
//! ```
#![warn(missing_docs)]

mod error;
mod lattice;
mod mixing;
mod product;
mod system;
#[cfg(test)]
mod test_rng;
mod velocity;

pub use error::SpectralError;
pub use lattice::{
    nearest_mode, nearest_of, Combination, LatticePoint, ToneSet, MAX_LATTICE_POINTS, MAX_TONES,
};
pub use mixing::{
    mixing_table, Component, ComponentKind, Line, MixingTable, ToneAssignment, Window,
    MAX_EXPANSION_TERMS,
};
pub use product::{
    monomial_amplitudes, monomial_jacobian, ProductPlan, ProductScratch, FREQ_TOLERANCE_HZ,
    MAX_PRODUCT_DEGREE,
};
pub use system::{SystemPlan, SystemScratch};
pub use velocity::{velocity_spectrum, velocity_to_amplitude};

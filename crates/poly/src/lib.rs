//! Exact polynomial algebra for equations of motion.
//!
//! The nonlinear part of a mass-normalised equation of motion,
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = F_n(t),
//! ```
//!
//! is a polynomial in the modal coordinates `q` whose coefficients `b_m^(n)` are themselves
//! polynomials (usually affine forms) in the model's parameters. This crate holds both levels
//! exactly, with rational numbers:
//!
//! - [`PowerProduct`]: a sparse product of variables with exponents, `q1*q2^2`;
//! - [`Coeff`]: a polynomial in the parameters, `3/4*beta1 + g12`, with [`Coeff::affine`] for the
//!   linear-in-parameters form that identification needs;
//! - [`Poly`]: a polynomial in the modal coordinates with [`Coeff`] coefficients, with
//!   differentiation ([`Poly::derivative`]) to turn a potential into equation terms.
//!
//! Arithmetic is checked: an overflow of the 128-bit rationals is an error, never a panic, so a
//! hostile model file cannot crash the program.
//!
//! ```
//! use harmonid_poly::{Coeff, Poly, Rational, VarId};
//! // U = 1/2 * g12 * q1^2 * q2^2, with modes q1 = 0, q2 = 1 and parameter g12 = 0.
//! let g12 = Poly::constant(Coeff::param(VarId(0)));
//! let q1 = Poly::var(VarId(0));
//! let q2 = Poly::var(VarId(1));
//! let u = g12
//!     .checked_mul(&q1.checked_pow(2)?)?
//!     .checked_mul(&q2.checked_pow(2)?)?
//!     .checked_scale(&Coeff::constant(Rational::new(1, 2)))?;
//! let dq1 = u.derivative(VarId(0))?;
//! let names = ["q1", "q2"];
//! assert_eq!(dq1.terms().next().map(|(m, _)| m.name(&names)), Some("q1*q2^2".to_string()));
//! let (_, c) = dq1.terms().next().unwrap();
//! assert_eq!(c.to_string_with(&["g12"]), "g12");
//! # Ok::<(), harmonid_poly::Overflow>(())
//! ```

mod coeff;
mod poly;
mod power_product;
mod rational;
mod ring;
mod sparse;

pub use coeff::{AffineForm, Coeff};
pub use poly::Poly;
pub use power_product::{PowerProduct, VarId};
pub use rational::{parse_decimal, rational_latex, rational_to_f64, Rational};
pub use ring::{Overflow, Ring};
pub use sparse::{PolyBuilder, SparsePoly};

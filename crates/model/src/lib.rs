//! The harmonid model language.
//!
//! A model file (`*.hb`) declares the modes of a resonator, its parameters, and its nonlinear
//! terms, written directly in an equation or as an interaction potential `U(q)` whose derivative
//! `∂U/∂q_n` enters the equation of mode `n`. This crate parses it (pest grammar in
//! `grammar/model.pest`), checks it, and lowers it to a [`Model`].

mod model;

pub use model::{Bounds, Linear, Mode, Model, NonAffineTerm, ParamKind, Parameter};

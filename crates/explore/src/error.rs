//! Errors of the exploration: bad requests refused before any work, and the simulation
//! crate's errors passed up.

use harmonid_sim::SimError;

/// What stopped an exploration, with the numbers and what to try.
#[derive(Debug, Clone, PartialEq, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum ExploreError {
    /// The excitation has no single frequency for the single-harmonic system.
    #[error("{what}: the single-harmonic system needs one response frequency")]
    #[diagnostic(
        code(explore::tone),
        help("give one drive tone, or one pump (the response at half its frequency), or both with the pump at twice the tone")
    )]
    NoSingleTone {
        /// What the excitation holds.
        what: String,
    },
    /// A request too large to run.
    #[error("{what} is beyond the limit ({limit})")]
    #[diagnostic(
        code(explore::too_large),
        help("ask for less: a coarser grid, fewer modes, lower-degree terms")
    )]
    TooComplex {
        /// What was asked.
        what: String,
        /// The limit.
        limit: &'static str,
    },
    /// Non-smooth terms (`abs`, `sign`, `tanh`): the single-harmonic system is a polynomial
    /// system only for polynomial terms, so the homotopy cannot promise every state of them.
    #[error("the model's non-smooth terms ({terms}) are not polynomial: `states` and `phase-diagram` find every steady state of polynomial models only")]
    #[diagnostic(
        code(explore::nonsmooth),
        help("follow the branches with `harmonid sweep` (harmonic balance by alternating frequency-time handles these terms), or replace the terms by polynomials to explore")
    )]
    NonSmooth {
        /// The non-smooth terms, by monomial name.
        terms: String,
    },
    /// A model other than the one a system was expanded for.
    #[error("the model's terms differ from those the single-harmonic system was expanded for")]
    #[diagnostic(code(explore::other_model))]
    OtherModel,
    /// A bad axis or grid.
    #[error("{what}: {why}")]
    #[diagnostic(code(explore::axis), help("{help}"))]
    BadAxis {
        /// The option or axis.
        what: String,
        /// What is wrong.
        why: String,
        /// What to do instead.
        help: String,
    },
    /// A value out of its range.
    #[error("{what} = {value} is not allowed: {why}")]
    #[diagnostic(code(explore::value))]
    BadValue {
        /// The quantity.
        what: String,
        /// The value.
        value: f64,
        /// The rule.
        why: &'static str,
    },
    /// From the simulation crate.
    #[error(transparent)]
    #[diagnostic(code(explore::sim))]
    Sim(#[from] SimError),
}

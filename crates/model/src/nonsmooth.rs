//! Non-smooth factors of equation terms: `abs(x)`, `sign(x)`, `tanh(x/c)` of one mode or one
//! velocity (issue 36).
//!
//! They are not polynomials, so they live beside the polynomial equations: a model keeps
//! them in `Model::nonsmooth[n]`, a polynomial per equation whose variables are the usual
//! ones (modes, velocities, pump) plus one variable per distinct factor, `VarId(2N + 1 + k)` for
//! `nonsmooth_factors[k]` (N modes). Every term of `nonsmooth[n]` holds at least one such
//! factor; its coefficient is a polynomial in the parameters like any other (an unknown that
//! enters linearly, for identification). The polynomial equations `eom[n]` never hold one.
//!
//! Canonical monomial names put the non-smooth factors first, in factor order, then the
//! polynomial part in variable order: `abs(q1)*q1`, `abs(d(q1))*d(q1)`, `sign(d(q1))`,
//! `tanh(d(q1)/0.001)*q2^2` (the scale `c` written by [`format_scale`]).

use harmonid_poly::VarId;

/// A non-smooth function of one mode `q_m` (variable `VarId(m)`) or one velocity `q̇_m`
/// (variable `VarId(N + m)`), in the variable numbering of [`Model`](crate::Model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NonSmooth {
    /// `abs(x) = |x|`.
    Abs(VarId),
    /// `sign(x)`: −1, 0, 1 (Coulomb friction when `x` is a velocity).
    Sign(VarId),
    /// `tanh(x / c)` with the scale `c > 0` in the unit of `x` (m, or m/s for a velocity; a
    /// smooth Coulomb friction for small `c`).
    Tanh(VarId, f64),
}

impl NonSmooth {
    /// The variable the function is applied to (a mode or a velocity).
    pub fn var(&self) -> VarId {
        match *self {
            NonSmooth::Abs(v) | NonSmooth::Sign(v) | NonSmooth::Tanh(v, _) => v,
        }
    }

    /// The function's value at `x`.
    #[inline]
    pub fn value(&self, x: f64) -> f64 {
        match *self {
            NonSmooth::Abs(_) => x.abs(),
            NonSmooth::Sign(_) => sign(x),
            NonSmooth::Tanh(_, c) => (x / c).tanh(),
        }
    }

    /// The pointwise derivative at `x`: `sign x` for `|x|`, 0 for `sign` (almost everywhere:
    /// its jump is not seen pointwise, see the harmonic-balance Jacobian), `sech²(x/c)/c` for
    /// `tanh(x/c)`.
    #[inline]
    pub fn derivative(&self, x: f64) -> f64 {
        match *self {
            NonSmooth::Abs(_) => sign(x),
            NonSmooth::Sign(_) => 0.0,
            NonSmooth::Tanh(_, c) => {
                let t = (x / c).tanh();
                (1.0 - t * t) / c
            }
        }
    }

    /// Whether the pointwise derivative misses a jump (`sign`): a Jacobian in harmonic
    /// coefficients must then be taken by differences, not sampled pointwise.
    pub fn has_jump(&self) -> bool {
        matches!(self, NonSmooth::Sign(_))
    }

    /// The function's name in the language (`abs`, `sign`, `tanh`).
    pub fn function(&self) -> &'static str {
        match self {
            NonSmooth::Abs(_) => "abs",
            NonSmooth::Sign(_) => "sign",
            NonSmooth::Tanh(..) => "tanh",
        }
    }

    /// Canonical name, given the names of the variables (`q1`, `d(q1)`): `abs(q1)`,
    /// `sign(d(q1))`, `tanh(d(q1)/0.001)`.
    pub fn name(&self, vars: &[impl AsRef<str>]) -> String {
        let x = vars.get(self.var().index()).map_or("?", |s| s.as_ref());
        match *self {
            NonSmooth::Tanh(_, c) => format!("tanh({x}/{})", format_scale(c)),
            _ => format!("{}({x})", self.function()),
        }
    }

    /// LaTeX, given the LaTeX names of the variables: `|q_{1}|`, `\operatorname{sign}(\dot{q}_{1})`,
    /// `\tanh(\dot{q}_{1}/10^{-3})`.
    pub fn latex(&self, vars: &[impl AsRef<str>]) -> String {
        let x = vars.get(self.var().index()).map_or("?", |s| s.as_ref());
        match *self {
            NonSmooth::Abs(_) => format!("\\left|{x}\\right|"),
            NonSmooth::Sign(_) => format!("\\operatorname{{sign}}({x})"),
            NonSmooth::Tanh(_, c) => format!("\\tanh({x}/{})", format_scale(c)),
        }
    }
}

/// `sign(x)`: −1, 0 or 1 (0 at 0, unlike `f64::signum`).
#[inline]
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The scale `c` of `tanh(x/c)` as monomial names write it: Rust's shortest round-trip form,
/// plain between 1e-4 and 1e6 (`0.001`, `2.5`), otherwise with an exponent (`1e-6`).
pub fn format_scale(c: f64) -> String {
    if (1e-4..1e6).contains(&c.abs()) {
        format!("{c}")
    } else {
        format!("{c:e}")
    }
}

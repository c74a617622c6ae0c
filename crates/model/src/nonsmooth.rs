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

    /// The average of the function over a sample's cell, the variable linear from the
    /// midpoint `(prev + x)/2` with the previous sample through `x` to the midpoint with the
    /// next: the value a time-sampled harmonic balance uses for a jump (`sign`) or a near-jump
    /// (`tanh` of a small scale), so that the harmonic coefficients move continuously with
    /// the amplitudes (Newton converges) and the error falls like the square of the cell
    /// width. `abs` is its midpoint value (no jump: sampled pointwise).
    pub fn cell_average(&self, prev: f64, x: f64, next: f64) -> f64 {
        let a = 0.5 * (prev + x);
        let b = 0.5 * (x + next);
        0.5 * (self.segment_average(a, x) + self.segment_average(x, b))
    }

    /// The average of the function over a variable that runs linearly from `a` to `b`.
    pub fn segment_average(&self, a: f64, b: f64) -> f64 {
        let d = b - a;
        let tiny = 1e-12 * (a.abs() + b.abs());
        if d.abs() <= tiny {
            return self.value(0.5 * (a + b));
        }
        match *self {
            // ∫ sign = |u|.
            NonSmooth::Sign(_) => (b.abs() - a.abs()) / d,
            // Across a small part of the scale: the midpoint value and its curvature term (the
            // difference of logarithms below would cancel).
            NonSmooth::Tanh(_, c) if d.abs() < 1e-2 * c => {
                let t = (0.5 * (a + b) / c).tanh();
                t - d * d / 12.0 * t * (1.0 - t * t) / (c * c)
            }
            // ∫ tanh(u/c) du = c ln cosh(u/c).
            NonSmooth::Tanh(_, c) => c * (log_cosh(b / c) - log_cosh(a / c)) / d,
            NonSmooth::Abs(_) => self.value(0.5 * (a + b)),
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

/// `ln cosh y` without overflow (`|y| + ln(1 + e^{−2|y|}) − ln 2`) or cancellation near 0
/// (`ln(1 + 2 sinh²(y/2))`).
fn log_cosh(y: f64) -> f64 {
    let a = y.abs();
    if a < 1.0 {
        let s = (0.5 * a).sinh();
        (2.0 * s * s).ln_1p()
    } else {
        a + (-2.0 * a).exp().ln_1p() - std::f64::consts::LN_2
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_averages_of_jumps() {
        let s = NonSmooth::Sign(VarId(0));
        // First half from 1.5 to 1: +1; second half from 1 to −1, crossing at its middle: 0.
        assert!((s.cell_average(2.0, 1.0, -3.0) - 0.5).abs() < 1e-15);
        assert_eq!(s.cell_average(1.0, 2.0, 3.0), 1.0);
        // tanh of a scale far below the cell's excursion is sign; far above, linear.
        let t = NonSmooth::Tanh(VarId(0), 1e-3);
        assert!((t.cell_average(2.0, 1.0, -3.0) - 0.5).abs() < 1e-3);
        let t = NonSmooth::Tanh(VarId(0), 1e3);
        let v = t.cell_average(0.2, 0.3, 0.5);
        // Nearly linear in u: the cell's mean variable, (0.25 + 0.3 + 0.3 + 0.4)/4 / c, less
        // the cubic term (u/c)³/3 ≈ 1e-11.
        assert!((v - 0.3125e-3).abs() < 2e-11, "{v}");
        assert!((log_cosh(800.0) - (800.0 - std::f64::consts::LN_2)).abs() < 1e-12);
        assert!(
            (log_cosh(1e-5) - 0.5e-10).abs() < 1e-20,
            "no cancellation near 0"
        );
    }

    #[test]
    fn segment_average_of_tanh_is_its_integral_over_the_segment() {
        // Midpoint rule with 200 000 panels against the closed form, across the scale.
        let c = 0.3;
        let t = NonSmooth::Tanh(VarId(0), c);
        for (a, b) in [(-1.0, 0.7), (0.1, 0.1 + 1e-4), (2.0, -0.05)] {
            let n = 200_000;
            let h = (b - a) / n as f64;
            let sum: f64 = (0..n)
                .map(|i| ((a + (i as f64 + 0.5) * h) / c).tanh())
                .sum();
            let want = sum / n as f64;
            let got = t.segment_average(a, b);
            assert!((got - want).abs() < 1e-9, "({a}, {b}): {got} vs {want}");
        }
    }
}

//! Equation terms with non-smooth factors (`kappa1*abs(q1)*q1`, `mu1*sign(d(q1))`,
//! `tanh(d(q1)/c)`; issue 36), evaluated pointwise.
//!
//! They are not polynomials, so the exact spectral products of harmonic balance cannot take
//! them: the lattice solver evaluates them by alternating frequency–time (sampling one common
//! period, see `steady/rough_aft.rs`), and the time domain calls them at every stage like the
//! polynomial forces.

use harmonid_model::NonSmooth;

/// One term `coef · Π x_var^exp · Π f_k(x_{v_k})^{e_k}` of an equation: a polynomial part over
/// the variables of [`crate::NumericModel`] (modes, velocities, pump) times non-smooth
/// functions of one mode or velocity each.
#[derive(Debug, Clone, PartialEq)]
pub struct RoughTerm {
    /// Mode whose equation holds the term.
    pub eq: usize,
    /// Coefficient, SI units of the equation.
    pub coef: f64,
    /// Polynomial `(variable, exponent)` factors, sorted, exponents ≥ 1 (may be empty:
    /// `mu1*sign(d(q1))`).
    pub factors: Vec<(usize, u32)>,
    /// The non-smooth factors with their exponents (the function's variable is in the
    /// numbering of the model's variables: `VarId(m)` a mode, `VarId(N + m)` its velocity).
    pub nonsmooth: Vec<(NonSmooth, u32)>,
    /// Canonical monomial name (`abs(q1)*q1`), for messages and tables.
    pub name: String,
}

impl RoughTerm {
    /// The term's value at the variables `x` (modes, then velocities, then the pump).
    #[inline]
    pub fn value(&self, x: &[f64]) -> f64 {
        let mut v = self.coef;
        for &(m, k) in &self.factors {
            v *= x[m].powi(k as i32);
        }
        for &(f, k) in &self.nonsmooth {
            v *= f.value(x[f.var().index()]).powi(k as i32);
        }
        v
    }

    /// Adds `∂(term)/∂x_j` to `row[j]` for every variable `j` the term holds, at `x`: the
    /// pointwise derivative (`d|x|/dx = sign x`, `d sign/dx = 0`, `d tanh(x/c)/dx =
    /// sech²(x/c)/c`).
    pub fn add_gradient(&self, x: &[f64], row: &mut [f64]) {
        let np = self.factors.len();
        let count = np + self.nonsmooth.len();
        for i in 0..count {
            // The derivative of factor i times every other factor's value.
            let (var, d) = if i < np {
                let (m, k) = self.factors[i];
                (m, k as f64 * x[m].powi(k as i32 - 1))
            } else {
                let (f, k) = self.nonsmooth[i - np];
                let xv = x[f.var().index()];
                (
                    f.var().index(),
                    k as f64 * f.value(xv).powi(k as i32 - 1) * f.derivative(xv),
                )
            };
            let mut v = self.coef * d;
            for (l, &(m, k)) in self.factors.iter().enumerate() {
                if l != i {
                    v *= x[m].powi(k as i32);
                }
            }
            for (l, &(f, k)) in self.nonsmooth.iter().enumerate() {
                if l + np != i {
                    v *= f.value(x[f.var().index()]).powi(k as i32);
                }
            }
            row[var] += v;
        }
    }

    /// Whether the term is odd under `x → −x` of every variable: it then makes only odd
    /// harmonics of a symmetric drive (`abs` is even, `sign` and `tanh` odd).
    pub fn is_odd(&self, pump: usize) -> bool {
        let poly: u32 = self
            .factors
            .iter()
            .filter(|&&(m, _)| m != pump)
            .map(|&(_, k)| k)
            .sum();
        let odd_fns: u32 = self
            .nonsmooth
            .iter()
            .filter(|(f, _)| !matches!(f, NonSmooth::Abs(_)))
            .map(|&(_, k)| k)
            .sum();
        (poly + odd_fns) % 2 == 1
    }

    /// A degree for choosing harmonics: the polynomial degree plus two per non-smooth factor
    /// (`abs(q1)*q1` counts as a cubic; its spectrum does not end, but decays like that of a
    /// cubic's neighbours).
    pub fn effective_degree(&self) -> u32 {
        self.factors.iter().map(|&(_, k)| k).sum::<u32>()
            + 2 * self.nonsmooth.iter().map(|&(_, k)| k).sum::<u32>()
    }

    /// Whether a factor jumps (`sign`) or nearly does (`tanh` of a scale): the harmonic-balance
    /// Jacobian of such a term must come from differences of its harmonic coefficients.
    pub fn has_jump(&self) -> bool {
        self.nonsmooth
            .iter()
            .any(|(f, _)| matches!(f, NonSmooth::Sign(_) | NonSmooth::Tanh(..)))
    }
}

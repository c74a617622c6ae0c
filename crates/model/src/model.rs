//! The checked, lowered model: what every numeric crate consumes.
//!
//! A [`Model`] is the result of parsing and validating a model file. Potentials are already
//! differentiated into equation terms, index families expanded, and every name resolved to an
//! index. Equation `n` reads (mass-normalised, SI, `DATA_FORMAT.md` conventions)
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + eom[n](q) = F_n(t),    ω_n = 2π f_n,
//! ```
//!
//! where `eom[n]` is a [`Poly`] in the modal coordinates (variable `VarId(m)` is `modes[m]`) whose
//! coefficients are polynomials in the parameters (variable `VarId(p)` is `params[p]`).

use crate::nonsmooth::NonSmooth;
use harmonid_poly::{Poly, PowerProduct, VarId};

/// A linear modal quantity (resonance frequency or quality factor): identified, or given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Linear {
    /// To be identified from data.
    Unknown,
    /// Given in the model file (Hz for frequencies, dimensionless for Q).
    Fixed(f64),
}

/// One mode of the resonator.
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// Name as written in the model file, e.g. `q1`.
    pub name: String,
    /// Nominal resonance frequency in Hz, if the model gives one (used to attribute measured
    /// frequencies to modes and as a starting point; a dataset's `nominal_hz` wins over it).
    pub nominal_hz: Option<f64>,
    /// Linear resonance frequency `f_n = ω_n / 2π` in Hz.
    pub f_hz: Linear,
    /// Quality factor `Q_n`.
    pub q_factor: Linear,
}

/// Whether a parameter is identified or given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamKind {
    /// To be identified from data.
    Unknown,
    /// Given in the model file, in the SI units of the terms it multiplies.
    Fixed(f64),
}

/// Optional bounds on a parameter's value, as written in the model (`g12 >= 0`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Bounds {
    /// Lower bound, if any.
    pub lower: Option<f64>,
    /// Upper bound, if any.
    pub upper: Option<f64>,
}

/// A named coefficient of the model.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Name as written (after index-family expansion, e.g. `g[1,2]` becomes `g12` or the name
    /// the language documents).
    pub name: String,
    /// Unknown or fixed.
    pub kind: ParamKind,
    /// Bounds for constrained identification.
    pub bounds: Bounds,
}

/// A term whose coefficient is not affine in the parameters, so linear least squares cannot
/// identify it (it is still fine for simulation).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the coefficient of {monomial} in the equation of {mode} is {coefficient}, which is not linear in the parameters; identification needs every coefficient to be a sum of parameters times numbers (rewrite it with a new parameter, or fix the parameters it multiplies)")]
pub struct NonAffineTerm {
    /// Mode whose equation holds the term.
    pub mode: String,
    /// Monomial name (`DATA_FORMAT.md` convention).
    pub monomial: String,
    /// The coefficient, printed.
    pub coefficient: String,
}

/// A checked model: modes, parameters and the lowered equations of motion.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Where the model came from (file path or a label), for messages and result files.
    pub source: String,
    /// Modes in declaration order; `VarId(m)` in a [`Poly`] is `modes[m]`,
    /// `VarId(modes.len() + m)` its velocity `d(q_m)`, and `VarId(2 · modes.len())` the pump
    /// signal `pump` (see [`PUMP_NAME`]).
    pub modes: Vec<Mode>,
    /// Parameters in declaration order; `VarId(p)` in a coefficient is `params[p]`.
    pub params: Vec<Parameter>,
    /// `eom[n]`: the terms on the left-hand side of mode `n`'s equation beyond the linear part,
    /// including those derived from potentials (`∂U/∂q_n`).
    pub eom: Vec<Poly>,
    /// The total interaction potential `U(q)` written in the file, if any (zero otherwise).
    pub potential: Poly,
    /// The total dissipation function `D(q, q̇)` written in the file, if any (zero otherwise);
    /// its derivatives `∂D/∂q̇_n` are in `eom` already.
    pub dissipation: Poly,
    /// `nonsmooth[n]`: the terms of mode `n`'s equation that hold a non-smooth factor
    /// (`kappa1*abs(q1)*q1`), beside the polynomial `eom[n]` (which never holds one). Variables
    /// as in `eom`, plus `VarId(2N + 1 + k)` for `nonsmooth_factors[k]` (see
    /// [`Model::nonsmooth_var`], [`Model::split_nonsmooth`]); coefficients are polynomials in
    /// the parameters as in `eom`. Empty polynomials when the model has none.
    pub nonsmooth: Vec<Poly>,
    /// The distinct non-smooth factors of the model (`abs(q1)`, `sign(d(q1))`,
    /// `tanh(d(q1)/0.001)`), in order of first appearance in the file.
    pub nonsmooth_factors: Vec<NonSmooth>,
}

impl Model {
    /// Mode names in declaration order.
    pub fn mode_names(&self) -> Vec<&str> {
        self.modes.iter().map(|m| m.name.as_str()).collect()
    }

    /// Parameter names in declaration order.
    pub fn param_names(&self) -> Vec<&str> {
        self.params.iter().map(|p| p.name.as_str()).collect()
    }

    /// Index of the mode called `name`.
    pub fn mode_index(&self, name: &str) -> Option<usize> {
        self.modes.iter().position(|m| m.name == name)
    }

    /// Index of the parameter called `name`.
    pub fn param_index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }

    /// The names of the variables of the equations: the modes, their velocities, then the
    /// pump (`q1, q2, d(q1), d(q2), pump`), as monomial names spell them.
    pub fn variable_names(&self) -> Vec<String> {
        let modes = self.modes.iter().map(|m| m.name.clone());
        let velocities = self.modes.iter().map(|m| velocity_name(&m.name));
        modes
            .chain(velocities)
            .chain(std::iter::once(PUMP_NAME.to_string()))
            .collect()
    }

    /// The variable of the pump signal: after every mode and velocity.
    pub fn pump_var(&self) -> VarId {
        VarId(2 * self.modes.len() as u32)
    }

    /// Whether any equation term holds a velocity `d(q)` (nonlinear damping, velocity
    /// couplings).
    pub fn has_velocity_terms(&self) -> bool {
        let nm = self.modes.len();
        self.any_factor(|v| (nm..2 * nm).contains(&v.index()))
    }

    /// Whether any equation term holds the pump signal (parametric pumping: `lambda*pump*q1`
    /// modulates a stiffness), so that every measurement must declare its pump tones.
    pub fn has_pump_terms(&self) -> bool {
        let pump = self.pump_var();
        self.any_factor(|v| v == pump)
    }

    /// The terms that hold the pump, as `monomial in the equation of mode` (for messages).
    pub fn pump_term_names(&self) -> Vec<String> {
        let pump = self.pump_var();
        let mut out = Vec::new();
        for (n, eq) in self.eom.iter().enumerate() {
            for (m, _) in eq.terms() {
                if m.exponent(pump) > 0 {
                    out.push(format!(
                        "{} in the equation of {}",
                        self.monomial_name(m),
                        self.modes[n].name
                    ));
                }
            }
        }
        out
    }

    /// Whether a factor of any term satisfies `pred`; a non-smooth factor counts as the
    /// variable it is applied to (`sign(d(q1))` holds the velocity `d(q1)`).
    fn any_factor(&self, pred: impl Fn(VarId) -> bool) -> bool {
        let first = 2 * self.modes.len() + 1;
        let resolve = |v: VarId| match v.index().checked_sub(first) {
            Some(k) => self.nonsmooth_factors.get(k).map_or(v, NonSmooth::var),
            None => v,
        };
        self.eom.iter().chain(&self.nonsmooth).any(|eq| {
            eq.terms()
                .any(|(m, _)| m.factors().iter().any(|&(v, _)| pred(resolve(v))))
        })
    }

    /// The canonical name (`DATA_FORMAT.md`) of a monomial in the modal coordinates and
    /// velocities (`q1^2*d(q1)`); a monomial of `nonsmooth` puts its non-smooth factors first
    /// (`abs(q1)*q1`, `tanh(d(q1)/0.001)`).
    pub fn monomial_name(&self, m: &PowerProduct) -> String {
        let first = 2 * self.modes.len() + 1;
        if m.factors().iter().any(|&(v, _)| v.index() >= first) {
            let (pp, names) = self.display_order(m, false);
            return pp.name(&names);
        }
        m.name(&self.variable_names())
    }

    /// Every equation term with its equation: the polynomial terms of `eom`, then those of
    /// `nonsmooth` (`(n, monomial, coefficient)`).
    pub fn all_terms(&self) -> impl Iterator<Item = (usize, &PowerProduct, &harmonid_poly::Coeff)> {
        let poly = self
            .eom
            .iter()
            .enumerate()
            .flat_map(|(n, eq)| eq.terms().map(move |(m, c)| (n, m, c)));
        let ns = self
            .nonsmooth
            .iter()
            .enumerate()
            .flat_map(|(n, eq)| eq.terms().map(move |(m, c)| (n, m, c)));
        poly.chain(ns)
    }

    /// Every term whose coefficient is not affine in the parameters; empty when the model can
    /// be identified by linear least squares.
    pub fn non_affine_terms(&self) -> Vec<NonAffineTerm> {
        let modes = self.mode_names();
        let params = self.param_names();
        let mut out = Vec::new();
        for (n, m, c) in self.all_terms() {
            if c.affine().is_none() {
                out.push(NonAffineTerm {
                    mode: modes[n].to_string(),
                    monomial: self.monomial_name(m),
                    coefficient: c.to_string_with(&params),
                });
            }
        }
        out
    }

    /// Checks that the model can be identified by linear least squares (every coefficient
    /// affine in the parameters); the error names the first offending term.
    pub fn check_identifiable(&self) -> Result<(), NonAffineTerm> {
        match self.non_affine_terms().into_iter().next() {
            Some(t) => Err(t),
            None => Ok(()),
        }
    }

    /// The value of each parameter: fixed ones from the model, unknown ones from `unknown`
    /// (looked up by name). Returns the name of the first unknown parameter with no value.
    pub fn param_values(
        &self,
        mut unknown: impl FnMut(&str) -> Option<f64>,
    ) -> Result<Vec<f64>, String> {
        self.params
            .iter()
            .map(|p| match p.kind {
                ParamKind::Fixed(v) => Ok(v),
                ParamKind::Unknown => unknown(&p.name).ok_or_else(|| p.name.clone()),
            })
            .collect()
    }

    /// Largest total degree of any polynomial equation term (0 for a linear model; the terms
    /// of `nonsmooth` are not polynomials and not counted).
    pub fn max_degree(&self) -> u32 {
        self.eom.iter().map(Poly::degree).max().unwrap_or(0)
    }

    /// The parameters that appear in the equation of mode `n`.
    pub fn params_in_equation(&self, n: usize) -> Vec<VarId> {
        let ns = self.nonsmooth.get(n).into_iter().flat_map(|p| p.terms());
        let mut v: Vec<VarId> = self.eom[n]
            .terms()
            .chain(ns)
            .flat_map(|(_, c)| c.variables())
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// The built-in name of the pump signal, `pump(t) = Σ_k Re[P_k e^{i2πf_k t}]` over the pump
/// tones a measurement declares (`pumps_hz`, `pump_levels`, `pump_phases_rad`): a factor of
/// equation terms (`lambda*pump*q1` modulates the stiffness of q1), in the unit of the
/// measurement's pump levels.
pub const PUMP_NAME: &str = "pump";

/// The name of the velocity of mode `mode` in the language and in monomial names: `d(q1)`.
pub fn velocity_name(mode: &str) -> String {
    format!("d({mode})")
}

/// Non-smooth terms (issue 36): see [`NonSmooth`] for the numbering of their variables.
impl Model {
    /// The variable that stands for `nonsmooth_factors[k]` in `nonsmooth[n]`: after the modes,
    /// velocities and pump.
    pub fn nonsmooth_var(&self, k: usize) -> VarId {
        VarId((2 * self.modes.len() + 1 + k) as u32)
    }

    /// Whether any equation holds a non-smooth factor.
    pub fn has_nonsmooth(&self) -> bool {
        self.nonsmooth.iter().any(|p| !p.is_zero())
    }

    /// A monomial of `nonsmooth[n]` split into its polynomial part (modes, velocities, pump)
    /// and its non-smooth factors `(k, exponent)` (`k` indexes `nonsmooth_factors`).
    pub fn split_nonsmooth(&self, m: &PowerProduct) -> (PowerProduct, Vec<(usize, u32)>) {
        let first = 2 * self.modes.len() + 1;
        let mut poly = Vec::new();
        let mut factors = Vec::new();
        for &(v, k) in m.factors() {
            match v.index().checked_sub(first) {
                Some(f) => factors.push((f, k)),
                None => poly.push((v, k)),
            }
        }
        // The factors come sorted from a valid monomial; a failure cannot happen.
        let poly = PowerProduct::from_factors(poly).unwrap_or_else(|_| PowerProduct::one());
        (poly, factors)
    }

    /// The terms with a non-smooth factor, as `monomial in the equation of mode` (for messages
    /// of the places that cannot handle them yet).
    pub fn nonsmooth_term_names(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (n, eq) in self.nonsmooth.iter().enumerate() {
            for (m, _) in eq.terms() {
                out.push(format!(
                    "{} in the equation of {}",
                    self.monomial_name(m),
                    self.modes[n].name
                ));
            }
        }
        out
    }

    /// The monomial with its variables renumbered so that the non-smooth factors come first
    /// (their canonical place in names), and the names in that numbering.
    pub(crate) fn display_order(
        &self,
        m: &PowerProduct,
        latex: bool,
    ) -> (PowerProduct, Vec<String>) {
        let first = 2 * self.modes.len() + 1;
        let k = self.nonsmooth_factors.len();
        let vars = if latex {
            self.variable_latex_names()
        } else {
            self.variable_names()
        };
        let mut names: Vec<String> = self
            .nonsmooth_factors
            .iter()
            .map(|f| if latex { f.latex(&vars) } else { f.name(&vars) })
            .collect();
        names.extend(vars);
        let pairs: Vec<(VarId, u32)> = m
            .factors()
            .iter()
            .map(|&(v, e)| match v.index().checked_sub(first) {
                Some(f) => (VarId(f as u32), e),
                None => (VarId((v.index() + k) as u32), e),
            })
            .collect();
        let mut sorted = pairs;
        sorted.sort_by_key(|&(v, _)| v);
        let pp = PowerProduct::from_factors(sorted).unwrap_or_else(|_| PowerProduct::one());
        (pp, names)
    }

    /// `nonsmooth[n]` renumbered as [`Model::display_order`] does, with its names, for text.
    pub(crate) fn nonsmooth_display(&self, n: usize, latex: bool) -> Option<(Poly, Vec<String>)> {
        let eq = self.nonsmooth.get(n).filter(|p| !p.is_zero())?;
        let mut b = harmonid_poly::PolyBuilder::new();
        let mut names = Vec::new();
        for (m, c) in eq.terms() {
            let (pp, nm) = self.display_order(m, latex);
            names = nm;
            b.push(pp, c.clone());
        }
        b.finish().ok().map(|p| (p, names))
    }
}

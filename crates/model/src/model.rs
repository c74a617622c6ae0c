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

    fn any_factor(&self, pred: impl Fn(VarId) -> bool) -> bool {
        self.eom.iter().any(|eq| {
            eq.terms()
                .any(|(m, _)| m.factors().iter().any(|&(v, _)| pred(v)))
        })
    }

    /// The canonical name (`DATA_FORMAT.md`) of a monomial in the modal coordinates and
    /// velocities (`q1^2*d(q1)`).
    pub fn monomial_name(&self, m: &PowerProduct) -> String {
        m.name(&self.variable_names())
    }

    /// Every term whose coefficient is not affine in the parameters; empty when the model can
    /// be identified by linear least squares.
    pub fn non_affine_terms(&self) -> Vec<NonAffineTerm> {
        let modes = self.mode_names();
        let vars = self.variable_names();
        let params = self.param_names();
        let mut out = Vec::new();
        for (n, eq) in self.eom.iter().enumerate() {
            for m in eq.non_affine_terms() {
                let coefficient = eq
                    .coeff(m)
                    .map(|c| c.to_string_with(&params))
                    .unwrap_or_default();
                out.push(NonAffineTerm {
                    mode: modes[n].to_string(),
                    monomial: m.name(&vars),
                    coefficient,
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

    /// Largest total degree of any equation term (0 for a linear model).
    pub fn max_degree(&self) -> u32 {
        self.eom.iter().map(Poly::degree).max().unwrap_or(0)
    }

    /// The parameters that appear in the equation of mode `n`.
    pub fn params_in_equation(&self, n: usize) -> Vec<VarId> {
        let mut v: Vec<VarId> = self.eom[n]
            .terms()
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

//! The numeric form of a model: evaluated coefficients in a flat layout for fast evaluation of
//! the nonlinear forces `Σ_m b_m^(n) m(q)` and their derivatives.

use crate::rough::RoughTerm;
use crate::SimError;
use harmonid_model::{Linear, Model};
use harmonid_poly::PowerProduct;
use std::collections::BTreeMap;

/// One term `coef · Π x_var^exp` of an equation, in flat storage. The variables are the
/// modes `q_0..q_{N−1}`, then their velocities (variable `N + m` is `q̇_m`, `d(q_m)` in the
/// model language), then the pump signal (variable `2N`, `pump`).
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Mode whose equation holds the term.
    pub eq: usize,
    /// Coefficient `b` in SI units of the equation (N/kg per m^degree, times s per velocity
    /// factor).
    pub coef: f64,
    /// `(variable, exponent)` factors, sorted by variable, exponents ≥ 1.
    pub factors: Vec<(usize, u32)>,
}

impl Term {
    /// Total degree.
    pub fn degree(&self) -> u32 {
        self.factors.iter().map(|&(_, k)| k).sum()
    }
}

/// A model with numbers: linear modal data and the nonlinear terms of each equation,
///
/// ```text
/// q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = F_n(t),   ω_n = 2π f_n.
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct NumericModel {
    /// Mode names in declaration order.
    pub mode_names: Vec<String>,
    /// Linear resonance frequencies `f_n`, Hz.
    pub f_hz: Vec<f64>,
    /// Quality factors `Q_n`.
    pub q_factor: Vec<f64>,
    /// Nonlinear terms, grouped by equation (`terms[eq_start[n]..eq_start[n+1]]`).
    terms: Vec<Term>,
    /// Per term (same order as `terms`): `(p, ∂coef/∂θ_p)` for every model parameter `p` the
    /// coefficient depends on, at the values it was built with (empty for numbers given
    /// directly). What sensitivities with respect to model parameters need.
    param_grad: Vec<Vec<(usize, f64)>>,
    eq_start: Vec<usize>,
    /// Highest exponent of each variable in any term (as many entries as variables in use).
    max_pow: Vec<u32>,
    /// A term holds a velocity.
    velocities: bool,
    /// The terms compiled for [`NumericModel::forces`]: term `t` is
    /// `coef[t] · Π pows[pow_idx[fac_start[t]..fac_start[t+1]]]` (indices into the power table).
    flat: FlatTerms,
    /// Terms with a non-smooth factor (`abs`, `sign`, `tanh`), beside the polynomial `terms`.
    rough: Vec<RoughTerm>,
    /// Per rough term: `(p, ∂coef/∂θ_p)`, as `param_grad`.
    rough_grad: Vec<Vec<(usize, f64)>>,
}

/// Terms as flat arrays (no per-term heap pointer to chase in the time-domain hot loop).
#[derive(Debug, Clone, PartialEq, Default)]
struct FlatTerms {
    coef: Vec<f64>,
    fac_start: Vec<u32>,
    pow_idx: Vec<u32>,
    /// Row length of the power table: highest exponent + 1.
    stride: usize,
}

/// Values that turn a [`Model`] into a [`NumericModel`]: modal data and parameters by name.
#[derive(Debug, Clone, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelValues {
    /// Per mode: `f_hz` and `Q` (used when the model leaves them unknown, and winning over the
    /// model's fixed values when given).
    #[serde(default)]
    pub modes: BTreeMap<String, ModeValues>,
    /// Parameter values by name (SI units of the terms they multiply).
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
    /// Optional: equation coefficients by monomial name (`[eom.q1] "q1^3" = 2.68e22`), as in
    /// `truth.toml`. When given for a mode, they replace that mode's equation terms from the
    /// model entirely.
    #[serde(default)]
    pub eom: BTreeMap<String, BTreeMap<String, f64>>,
}

/// Linear data of one mode.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct ModeValues {
    /// Linear resonance frequency, Hz.
    pub f_hz: Option<f64>,
    /// Quality factor.
    #[serde(rename = "Q")]
    pub q: Option<f64>,
}

fn check_positive(what: &str, v: f64, min: f64) -> Result<f64, SimError> {
    if v.is_finite() && v > min {
        Ok(v)
    } else {
        Err(SimError::BadValue {
            what: what.to_string(),
            value: v,
            why: format!("it must be a finite number above {min}"),
        })
    }
}

/// Parses a monomial name (`q1*q2^2`, `q1^2*d(q1)`, `q1*pump`) against mode names into sorted
/// `(variable, exponent)` pairs (the velocity `d(q_m)` is variable `N + m`, the pump `2N`).
pub fn parse_monomial(name: &str, modes: &[String]) -> Result<Vec<(usize, u32)>, SimError> {
    let bad = |why: String| SimError::BadMonomial {
        name: name.to_string(),
        why,
        modes: modes.join(", "),
    };
    let mut exps = vec![0u32; 2 * modes.len() + 1];
    for part in name.split('*') {
        let part = part.trim();
        let (var, k) = match part.split_once('^') {
            Some((v, k)) => (
                v.trim(),
                k.trim()
                    .parse::<u32>()
                    .map_err(|_| bad(format!("`{k}` is not a whole exponent")))?,
            ),
            None => (part, 1),
        };
        if k == 0 || k > 16 {
            return Err(bad(format!("exponent {k} is outside 1..=16")));
        }
        if var == harmonid_model::PUMP_NAME {
            exps[2 * modes.len()] += k;
            continue;
        }
        let (mode, velocity) = match var.strip_prefix("d(").and_then(|v| v.strip_suffix(')')) {
            Some(v) => (v.trim(), true),
            None => (var, false),
        };
        let m = modes
            .iter()
            .position(|n| n == mode)
            .ok_or_else(|| bad(format!("`{mode}` is not a mode")))?;
        exps[if velocity { modes.len() + m } else { m }] += k;
    }
    Ok(exps
        .iter()
        .enumerate()
        .filter(|(_, &k)| k > 0)
        .map(|(m, &k)| (m, k))
        .collect())
}

/// A monomial name with non-smooth factors (`abs(q1)*q1`, `sign(d(q1))`,
/// `tanh(d(q1)/0.001)*q2^2`: the names [`harmonid_model::Model::monomial_name`] writes) as a
/// term of equation `eq` with coefficient `coef`; `None` for a name without one.
pub fn parse_rough_monomial(
    name: &str,
    modes: &[String],
    eq: usize,
    coef: f64,
) -> Result<Option<RoughTerm>, SimError> {
    use harmonid_model::NonSmooth;
    let bad = |why: String| SimError::BadMonomial {
        name: name.to_string(),
        why,
        modes: modes.join(", "),
    };
    let var = |x: &str| -> Result<harmonid_poly::VarId, SimError> {
        let (mode, velocity) = match x.strip_prefix("d(").and_then(|v| v.strip_suffix(')')) {
            Some(v) => (v.trim(), true),
            None => (x.trim(), false),
        };
        let m = modes
            .iter()
            .position(|n| n == mode)
            .ok_or_else(|| bad(format!("`{mode}` is not a mode")))?;
        Ok(harmonid_poly::VarId(
            if velocity { modes.len() + m } else { m } as u32,
        ))
    };
    let mut poly = Vec::new();
    let mut nonsmooth = Vec::new();
    for part in name.split('*').map(str::trim) {
        let Some(f) = ["abs(", "sign(", "tanh("]
            .iter()
            .find(|f| part.starts_with(*f))
        else {
            poly.push(part);
            continue;
        };
        let close = part
            .rfind(')')
            .ok_or_else(|| bad(format!("`{part}` has no `)`")))?;
        let k = match part[close + 1..].strip_prefix('^') {
            Some(k) => k
                .trim()
                .parse::<u32>()
                .map_err(|_| bad(format!("`{k}` is not a whole exponent")))?,
            None if part[close + 1..].trim().is_empty() => 1,
            None => return Err(bad(format!("`{part}` has text after its `)`"))),
        };
        let inner = &part[f.len()..close];
        let factor = match *f {
            "abs(" => NonSmooth::Abs(var(inner)?),
            "sign(" => NonSmooth::Sign(var(inner)?),
            _ => {
                let (x, c) = inner
                    .rsplit_once('/')
                    .map_or((inner, Ok(1.0)), |(x, c)| (x, c.trim().parse::<f64>()));
                let c = c.map_err(|_| bad(format!("the scale of `{part}` is not a number")))?;
                if !(c > 0.0 && c.is_finite()) {
                    return Err(bad(format!("the scale of `{part}` must be positive")));
                }
                NonSmooth::Tanh(var(x)?, c)
            }
        };
        nonsmooth.push((factor, k));
    }
    if nonsmooth.is_empty() {
        return Ok(None);
    }
    let factors = if poly.is_empty() {
        Vec::new()
    } else {
        parse_monomial(&poly.join("*"), modes)?
    };
    Ok(Some(RoughTerm {
        eq,
        coef,
        factors,
        nonsmooth,
        name: name.to_string(),
    }))
}

impl NumericModel {
    /// The monomial of a term's factors over the model's variables (modes, velocities, pump).
    pub(crate) fn term_monomial(&self, factors: &[(usize, u32)]) -> PowerProduct {
        let mut e = vec![0u32; self.n_vars()];
        for &(m, k) in factors {
            e[m] += k;
        }
        PowerProduct::from_exponents(&e)
    }

    /// Builds the numeric model from modal data and terms. `f_hz > 0`, `Q > 1/2` (underdamped),
    /// coefficients finite; zero coefficients are dropped. Checks that no mode is unbounded by
    /// its own terms (see [`SimError::Unbounded`]).
    pub fn new(
        mode_names: Vec<String>,
        f_hz: Vec<f64>,
        q_factor: Vec<f64>,
        terms: Vec<Term>,
    ) -> Result<Self, SimError> {
        let terms = terms.into_iter().map(|t| (t, Vec::new())).collect();
        Self::with_gradients(mode_names, f_hz, q_factor, terms, Vec::new())
    }

    /// As [`NumericModel::new`] with terms that hold non-smooth factors besides (`rough`, each
    /// with its parameter gradient, possibly empty).
    pub fn with_rough_terms(
        mode_names: Vec<String>,
        f_hz: Vec<f64>,
        q_factor: Vec<f64>,
        terms: Vec<Term>,
        rough: Vec<(RoughTerm, Vec<(usize, f64)>)>,
    ) -> Result<Self, SimError> {
        let terms = terms.into_iter().map(|t| (t, Vec::new())).collect();
        Self::with_gradients(mode_names, f_hz, q_factor, terms, rough)
    }

    /// As [`NumericModel::new`], each term with its parameter gradient `(p, ∂coef/∂θ_p)`; a
    /// term with a zero coefficient is kept when its gradient is not empty (its parameter may
    /// move away from zero).
    fn with_gradients(
        mode_names: Vec<String>,
        f_hz: Vec<f64>,
        q_factor: Vec<f64>,
        terms: Vec<(Term, Vec<(usize, f64)>)>,
        rough: Vec<(RoughTerm, Vec<(usize, f64)>)>,
    ) -> Result<Self, SimError> {
        let n = mode_names.len();
        if f_hz.len() != n || q_factor.len() != n {
            return Err(SimError::Length {
                what: "frequencies and quality factors",
                found: f_hz.len().min(q_factor.len()),
                expected: n,
                per: "one of each per mode".into(),
            });
        }
        for (i, name) in mode_names.iter().enumerate() {
            check_positive(&format!("f_hz of {name}"), f_hz[i], 0.0)?;
            check_positive(&format!("Q of {name}"), q_factor[i], 0.5)?;
        }
        let mut terms: Vec<(Term, Vec<(usize, f64)>)> = terms
            .into_iter()
            .filter(|(t, g)| t.coef != 0.0 || !g.is_empty())
            .collect();
        for (t, _) in &terms {
            if t.eq >= n || t.factors.iter().any(|&(m, k)| m > 2 * n || k == 0) {
                return Err(SimError::TermBeyondModes { modes: n });
            }
            if !t.coef.is_finite() {
                return Err(SimError::BadValue {
                    what: format!("a coefficient in the equation of {}", mode_names[t.eq]),
                    value: t.coef,
                    why: "coefficients must be finite".into(),
                });
            }
        }
        let (rough, rough_grad) = check_rough(rough, &mode_names)?;
        terms.sort_by_key(|(t, _)| t.eq);
        let (terms, param_grad): (Vec<Term>, Vec<_>) = terms.into_iter().unzip();
        let mut eq_start = vec![0; n + 1];
        for t in &terms {
            eq_start[t.eq + 1] += 1;
        }
        for i in 0..n {
            eq_start[i + 1] += eq_start[i];
        }
        let rough_vars = || {
            rough.iter().flat_map(|t| {
                t.factors
                    .iter()
                    .map(|&(m, _)| m)
                    .chain(t.nonsmooth.iter().map(|(f, _)| f.var().index()))
            })
        };
        let velocities = terms
            .iter()
            .any(|t| t.factors.iter().any(|&(m, _)| (n..2 * n).contains(&m)))
            || rough_vars().any(|m| (n..2 * n).contains(&m));
        let pump = terms
            .iter()
            .any(|t| t.factors.iter().any(|&(m, _)| m == 2 * n))
            || rough_vars().any(|m| m == 2 * n);
        // The variables in use: the modes, the velocities when a term holds one, the pump
        // after every velocity slot when a term holds it.
        let n_vars = if pump {
            2 * n + 1
        } else if velocities {
            2 * n
        } else {
            n
        };
        let mut max_pow = vec![1u32; n_vars];
        for t in &terms {
            for &(m, k) in &t.factors {
                max_pow[m] = max_pow[m].max(k);
            }
        }
        let stride = max_pow.iter().copied().max().unwrap_or(1) as usize + 1;
        let mut flat = FlatTerms {
            fac_start: vec![0],
            stride,
            ..FlatTerms::default()
        };
        for t in &terms {
            flat.coef.push(t.coef);
            flat.pow_idx.extend(
                t.factors
                    .iter()
                    .map(|&(m, k)| (m * stride + k as usize) as u32),
            );
            flat.fac_start.push(flat.pow_idx.len() as u32);
        }
        let out = Self {
            mode_names,
            f_hz,
            q_factor,
            terms,
            param_grad,
            eq_start,
            max_pow,
            velocities,
            flat,
            rough,
            rough_grad,
        };
        out.check_bounded()?;
        Ok(out)
    }

    /// Evaluates a checked [`Model`] with `values`: unknown (or overridden) `f_hz`, `Q` and
    /// parameters are looked up by name. `values.eom`, when it has an entry for a mode, replaces
    /// that mode's terms.
    pub fn from_model(model: &Model, values: &ModelValues) -> Result<Self, SimError> {
        let names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
        for k in values.modes.keys().chain(values.eom.keys()) {
            if !names.contains(k) {
                return Err(SimError::UnknownMode {
                    name: k.clone(),
                    declared: names.join(", "),
                });
            }
        }
        let mut f_hz = Vec::with_capacity(names.len());
        let mut q = Vec::with_capacity(names.len());
        for m in &model.modes {
            let given = values.modes.get(&m.name).copied().unwrap_or_default();
            let f = match (given.f_hz, m.f_hz) {
                (Some(v), _) | (None, Linear::Fixed(v)) => v,
                (None, Linear::Unknown) => {
                    return Err(SimError::MissingValue {
                        what: format!("f_hz of mode {}", m.name),
                    })
                }
            };
            let qf = match (given.q, m.q_factor) {
                (Some(v), _) | (None, Linear::Fixed(v)) => v,
                (None, Linear::Unknown) => {
                    return Err(SimError::MissingValue {
                        what: format!("Q of mode {}", m.name),
                    })
                }
            };
            f_hz.push(f);
            q.push(qf);
        }
        for k in values.parameters.keys() {
            if model.param_index(k).is_none() {
                return Err(SimError::UnknownParameter {
                    name: k.clone(),
                    declared: model.param_names().join(", "),
                });
            }
        }
        let needs_params = names.iter().any(|n| !values.eom.contains_key(n));
        let pvals = if needs_params {
            model
                .param_values(|name| values.parameters.get(name).copied())
                .map_err(|what| SimError::MissingValue { what })?
        } else {
            Vec::new()
        };
        let mut terms = Vec::new();
        let mut rough = Vec::new();
        for (n, eq) in model.eom.iter().enumerate() {
            if !values.eom.contains_key(&names[n]) {
                rough_terms_of(model, n, &pvals, &mut rough)?;
            }
            if let Some(given) = values.eom.get(&names[n]) {
                for (mono, &coef) in given {
                    match parse_rough_monomial(mono, &names, n, coef)? {
                        Some(t) => rough.push((t, Vec::new())),
                        None => {
                            let factors = parse_monomial(mono, &names)?;
                            terms.push((
                                Term {
                                    eq: n,
                                    coef,
                                    factors,
                                },
                                Vec::new(),
                            ));
                        }
                    }
                }
                continue;
            }
            for (m, c) in eq.terms() {
                let mut grad = Vec::new();
                for p in c.variables() {
                    let d = c.derivative(p).map_err(|_| SimError::DerivativeOverflow {
                        monomial: model.monomial_name(m),
                        mode: names[n].clone(),
                    })?;
                    grad.push((p.index(), d.eval(&pvals)));
                }
                let term = Term {
                    eq: n,
                    coef: c.eval(&pvals),
                    factors: flat_pp(m),
                };
                terms.push((term, grad));
            }
        }
        Self::with_gradients(names, f_hz, q, terms, rough)
    }

    /// Builds a numeric model straight from values with `[modes.*]` and `[eom.*]` (a
    /// `truth.toml` or a result's `eom`), with modes in the order of `mode_names`.
    pub fn from_values(mode_names: &[String], values: &ModelValues) -> Result<Self, SimError> {
        let mut f_hz = Vec::new();
        let mut q = Vec::new();
        for n in mode_names {
            let v = values.modes.get(n).copied().unwrap_or_default();
            f_hz.push(v.f_hz.ok_or_else(|| SimError::MissingValue {
                what: format!("f_hz of mode {n}"),
            })?);
            q.push(v.q.ok_or_else(|| SimError::MissingValue {
                what: format!("Q of mode {n}"),
            })?);
        }
        let mut terms = Vec::new();
        let mut rough = Vec::new();
        for (mode, map) in &values.eom {
            let eq =
                mode_names
                    .iter()
                    .position(|n| n == mode)
                    .ok_or_else(|| SimError::UnknownMode {
                        name: mode.clone(),
                        declared: mode_names.join(", "),
                    })?;
            for (mono, &coef) in map {
                match parse_rough_monomial(mono, mode_names, eq, coef)? {
                    Some(t) => rough.push((t, Vec::new())),
                    None => terms.push(Term {
                        eq,
                        coef,
                        factors: parse_monomial(mono, mode_names)?,
                    }),
                }
            }
        }
        Self::with_rough_terms(mode_names.to_vec(), f_hz, q, terms, rough)
    }

    /// The model on the modes `modes` alone (indices into this model's modes, ascending,
    /// distinct): their equations, with the terms whose every factor (position, velocity, or
    /// non-smooth function of one) is a kept mode; the pump stays. Each term keeps its
    /// coefficient and parameter gradient, and variables are renumbered in the order of
    /// `modes`. Where every other mode is identically zero (the modes a drive cannot reach,
    /// [`crate::ActiveModes`]) the dropped terms vanish, and the kept equations are exactly
    /// the full model's. Errors: an index out of range or out of order.
    pub fn restricted(&self, modes: &[usize]) -> Result<NumericModel, SimError> {
        self.restricted_where(modes, |_, _| true)
    }

    /// [`NumericModel::restricted`], keeping only the terms `keep(equation, factors)` accepts
    /// (both in this model's numbering; a non-smooth term's factors are its polynomial ones
    /// followed by each function's variable with its exponent). The idle block of a
    /// stability check needs the idle equations' terms with one idle factor alone.
    pub(crate) fn restricted_where(
        &self,
        modes: &[usize],
        keep: impl Fn(usize, &[(usize, u32)]) -> bool,
    ) -> Result<NumericModel, SimError> {
        let n = self.n_modes();
        if let Some(&index) = modes
            .iter()
            .enumerate()
            .find(|&(i, &m)| m >= n || (i > 0 && modes[i - 1] >= m))
            .map(|(_, m)| m)
        {
            return Err(SimError::ModeIndex { index, n_modes: n });
        }
        let k = modes.len();
        // Old variable -> new variable (modes, velocities, pump), `None` when dropped.
        let mut map = vec![None; 2 * n + 1];
        for (i, &m) in modes.iter().enumerate() {
            map[m] = Some(i);
            map[n + m] = Some(k + i);
        }
        map[2 * n] = Some(2 * k);
        let eq_of = |e: usize| modes.iter().position(|&m| m == e);
        let remap = |factors: &[(usize, u32)]| -> Option<Vec<(usize, u32)>> {
            factors.iter().map(|&(v, e)| Some((map[v]?, e))).collect()
        };
        let mut terms = Vec::new();
        for (t, grad) in self.terms.iter().zip(&self.param_grad) {
            if !keep(t.eq, &t.factors) {
                continue;
            }
            if let (Some(eq), Some(factors)) = (eq_of(t.eq), remap(&t.factors)) {
                let term = Term {
                    eq,
                    coef: t.coef,
                    factors,
                };
                terms.push((term, grad.clone()));
            }
        }
        let mut rough = Vec::new();
        for (t, grad) in self.rough.iter().zip(&self.rough_grad) {
            let all: Vec<(usize, u32)> = t
                .factors
                .iter()
                .copied()
                .chain(t.nonsmooth.iter().map(|&(f, e)| (f.var().index(), e)))
                .collect();
            if !keep(t.eq, &all) {
                continue;
            }
            let nonsmooth: Option<Vec<_>> = t
                .nonsmooth
                .iter()
                .map(|&(f, e)| {
                    use harmonid_model::NonSmooth;
                    let v = harmonid_poly::VarId(map[f.var().index()]? as u32);
                    let f = match f {
                        NonSmooth::Abs(_) => NonSmooth::Abs(v),
                        NonSmooth::Sign(_) => NonSmooth::Sign(v),
                        NonSmooth::Tanh(_, c) => NonSmooth::Tanh(v, c),
                    };
                    Some((f, e))
                })
                .collect();
            if let (Some(eq), Some(factors), Some(nonsmooth)) =
                (eq_of(t.eq), remap(&t.factors), nonsmooth)
            {
                let term = RoughTerm {
                    eq,
                    coef: t.coef,
                    factors,
                    nonsmooth,
                    name: t.name.clone(),
                };
                rough.push((term, grad.clone()));
            }
        }
        Self::with_gradients(
            modes.iter().map(|&m| self.mode_names[m].clone()).collect(),
            modes.iter().map(|&m| self.f_hz[m]).collect(),
            modes.iter().map(|&m| self.q_factor[m]).collect(),
            terms,
            rough,
        )
    }

    /// Number of modes.
    pub fn n_modes(&self) -> usize {
        self.mode_names.len()
    }

    /// Angular resonance frequency `ω_n = 2π f_n`, rad/s.
    pub fn omega(&self, n: usize) -> f64 {
        std::f64::consts::TAU * self.f_hz[n]
    }

    /// Damping rate `ω_n / Q_n`, 1/s.
    pub fn gamma(&self, n: usize) -> f64 {
        self.omega(n) / self.q_factor[n]
    }

    /// All terms, grouped by equation.
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }

    /// Parameter gradient of term `t` (index into [`NumericModel::terms`]): `(p, ∂coef/∂θ_p)`
    /// for each model parameter `p` (declaration order) its coefficient depends on, at the
    /// values the model was built with. Empty for terms given as numbers ([`NumericModel::new`],
    /// `[eom]` values).
    pub fn term_param_grad(&self, t: usize) -> &[(usize, f64)] {
        &self.param_grad[t]
    }

    /// The terms of the equation of mode `n`.
    pub fn eq_terms(&self, n: usize) -> &[Term] {
        &self.terms[self.eq_start[n]..self.eq_start[n + 1]]
    }

    /// Degree of term `t` in the modes and velocities: the pump's factors left out (the pump
    /// is a given signal, so `lambda*pump*q1` is linear in the state).
    pub fn state_degree(&self, t: &Term) -> u32 {
        let pump = 2 * self.n_modes();
        t.factors
            .iter()
            .filter(|&&(m, _)| m != pump)
            .map(|&(_, k)| k)
            .sum()
    }

    /// Largest total degree of any term (0 for a linear model).
    pub fn max_degree(&self) -> u32 {
        self.terms.iter().map(Term::degree).max().unwrap_or(0)
    }

    /// Highest exponent of variable `m` (a mode, or a velocity from `N` on) in any term (at
    /// least 1).
    pub fn max_pow(&self, m: usize) -> u32 {
        self.max_pow[m]
    }

    /// Number of variables the terms are polynomials in: the modes (`N`), their velocities when
    /// a term holds one (`2N`), and the pump when a term holds it (`2N + 1`, the velocity slots
    /// then present whether used or not). [`Self::forces`] takes that many values.
    pub fn n_vars(&self) -> usize {
        self.max_pow.len()
    }

    /// The net linear damping rate of mode `n`, 1/s: `ω_n/Q_n` plus the coefficient of a term
    /// `c · q̇_n` in its own equation (a linear velocity term, van der Pol's `−μ q̇`). Zero or
    /// below, the mode at rest is unstable: it oscillates without a drive (self-excited).
    pub fn net_linear_damping(&self, n: usize) -> f64 {
        let own_velocity = [(self.n_modes() + n, 1)];
        self.gamma(n)
            + self
                .eq_terms(n)
                .iter()
                .filter(|t| t.factors == own_velocity)
                .map(|t| t.coef)
                .sum::<f64>()
    }

    /// Whether a term holds a velocity (nonlinear damping, a velocity coupling).
    pub fn has_velocity_terms(&self) -> bool {
        self.velocities
    }

    /// Whether a term holds the pump signal (variable `2N`): every excitation must then give
    /// its pump tones.
    pub fn has_pump_terms(&self) -> bool {
        self.n_vars() > 2 * self.n_modes()
    }

    /// The terms that hold the pump, as `mode: monomial` (for messages).
    pub fn pump_term_names(&self) -> Vec<String> {
        let pump = 2 * self.n_modes();
        let names = self.variable_names();
        self.terms
            .iter()
            .filter(|t| t.factors.iter().any(|&(m, _)| m == pump))
            .map(|t| {
                let pp = self.term_monomial(&t.factors);
                format!(
                    "{} in the equation of {}",
                    pp.name(&names),
                    self.mode_names[t.eq]
                )
            })
            .collect()
    }

    /// Names of the variables ([`Self::n_vars`] of them): the modes, `d(q)` of each, `pump`.
    pub fn variable_names(&self) -> Vec<String> {
        let velocities = self
            .mode_names
            .iter()
            .map(|m| harmonid_model::velocity_name(m));
        self.mode_names
            .iter()
            .cloned()
            .chain(velocities)
            .chain(std::iter::once(harmonid_model::PUMP_NAME.to_string()))
            .take(self.n_vars())
            .collect()
    }

    /// The terms of equation `n` as a map from monomial name to coefficient.
    pub fn eom_map(&self, n: usize) -> BTreeMap<String, f64> {
        self.eq_terms(n)
            .iter()
            .map(|t| {
                let pp = PowerProduct::from_exponents(&{
                    let mut e = vec![0u32; self.n_vars()];
                    for &(m, k) in &t.factors {
                        e[m] = k;
                    }
                    e
                });
                (pp.name(&self.variable_names()), t.coef)
            })
            .chain(
                self.rough
                    .iter()
                    .filter(|t| t.eq == n)
                    .map(|t| (t.name.clone(), t.coef)),
            )
            .collect()
    }

    /// Nonlinear forces `out[n] = Σ_m b_m^(n) m(x)` at `x`: the modal coordinates (m), then,
    /// for a model with velocity terms, the modal velocities (m/s) ([`Self::n_vars`] values).
    /// `pows` is scratch of length [`Self::pow_len`]. No allocation.
    #[inline]
    pub fn forces(&self, q: &[f64], pows: &mut [f64], out: &mut [f64]) {
        self.fill_pows(q, pows);
        let f = &self.flat;
        for (n, o) in out.iter_mut().enumerate().take(self.n_modes()) {
            let mut s = 0.0;
            for t in self.eq_start[n]..self.eq_start[n + 1] {
                let (lo, hi) = (f.fac_start[t] as usize, f.fac_start[t + 1] as usize);
                let mut v = f.coef[t];
                for &i in &f.pow_idx[lo..hi] {
                    v *= pows[i as usize];
                }
                s += v;
            }
            *o = s;
        }
        for t in &self.rough {
            out[t.eq] += t.value(q);
        }
    }

    /// Jacobian of the nonlinear forces, `jac[n * V + j] = ∂(Σ_m b_m^(n) m(x)) / ∂x_j` over
    /// the `V =` [`Self::n_vars`] variables (modes, then velocities).
    pub fn force_jacobian(&self, q: &[f64], pows: &mut [f64], jac: &mut [f64]) {
        self.fill_pows(q, pows);
        let stride = self.pow_stride();
        let nm = self.n_vars();
        jac[..self.n_modes() * nm].iter_mut().for_each(|x| *x = 0.0);
        for t in &self.terms {
            for (i, &(j, kj)) in t.factors.iter().enumerate() {
                let mut v = t.coef * kj as f64 * pows[j * stride + kj as usize - 1];
                for (l, &(m, k)) in t.factors.iter().enumerate() {
                    if l != i {
                        v *= pows[m * stride + k as usize];
                    }
                }
                jac[t.eq * nm + j] += v;
            }
        }
        for t in &self.rough {
            t.add_gradient(q, &mut jac[t.eq * nm..(t.eq + 1) * nm]);
        }
    }

    /// The terms with a non-smooth factor (`abs`, `sign`, `tanh`), grouped by nothing in
    /// particular; [`Self::forces`] and [`Self::force_jacobian`] include them pointwise.
    pub fn rough_terms(&self) -> &[RoughTerm] {
        &self.rough
    }

    /// Parameter gradient of rough term `t`, as [`Self::term_param_grad`].
    pub fn rough_param_grad(&self, t: usize) -> &[(usize, f64)] {
        &self.rough_grad[t]
    }

    /// Whether a term holds a non-smooth factor.
    pub fn has_nonsmooth(&self) -> bool {
        !self.rough.is_empty()
    }

    #[inline]
    fn pow_stride(&self) -> usize {
        self.flat.stride
    }

    /// Length of the power table scratch used by [`Self::forces`].
    pub fn pow_len(&self) -> usize {
        self.n_vars() * self.pow_stride()
    }

    #[inline]
    fn fill_pows(&self, q: &[f64], pows: &mut [f64]) {
        let stride = self.pow_stride();
        for (row, &x) in pows.chunks_exact_mut(stride).zip(q) {
            let mut p = 1.0;
            for v in row.iter_mut() {
                *v = p;
                p *= x;
            }
        }
    }

    /// Checks that no mode runs away along its own axis. Where the stiffness at rest
    /// (`ω² + b` of the linear own term, plus `c/τ` of a `c·tanh(q/τ)` term, s⁻²) is positive
    /// the mode has a well to oscillate in and is accepted (a softening Duffing or `|q|q`
    /// term bounds it only locally, as the sweeps need). Otherwise the force along `±q`
    /// must grow back towards rest in both directions: its leading power at large `|q|`,
    /// polynomial own powers and position-only non-smooth terms together (`abs(q)*q`
    /// grows like `q²` and is odd, `sign(q)` and `tanh(q/τ)` like `q⁰`), must push back.
    fn check_bounded(&self) -> Result<(), SimError> {
        for n in 0..self.n_modes() {
            let name = &self.mode_names[n];
            let mut lin = self.omega(n).powi(2);
            let mut at_rest = lin;
            // (degree, coefficient along +q, along −q, term) of the force at large |q|.
            let mut growth: Vec<(u32, f64, f64, String)> = Vec::new();
            for t in self.eq_terms(n) {
                if let [(m, k)] = t.factors[..] {
                    if m == n && k == 1 {
                        lin += t.coef;
                        at_rest += t.coef;
                    } else if m == n {
                        let minus = if k % 2 == 0 { t.coef } else { -t.coef };
                        growth.push((k, t.coef, minus, format!("{name}^{k}")));
                    }
                }
            }
            for t in self.rough.iter().filter(|t| t.eq == n) {
                if let Some((g, slope)) = own_axis_growth(t, n) {
                    at_rest += slope;
                    growth.push(g);
                }
            }
            if at_rest > 0.0 {
                continue;
            }
            growth.push((1, lin, -lin, format!("ω²·{name}")));
            if let Some(why) = runaway(&growth, name, at_rest) {
                return Err(SimError::Unbounded {
                    mode: name.clone(),
                    why,
                });
            }
        }
        Ok(())
    }
}

/// A position-only term of mode `n`'s own equation (`c·|q|^a·q^m·sign(q)^s·tanh(q/τ)^h`):
/// its growth at large `|q|` as `(degree a + m, coefficient along +q, along −q, name)`,
/// and its stiffness at rest (`c/τ` for `c·tanh(q/τ)`, else 0). `None` for a term holding
/// another variable.
fn own_axis_growth(t: &RoughTerm, n: usize) -> Option<((u32, f64, f64, String), f64)> {
    if t.factors.iter().any(|&(m, _)| m != n)
        || t.nonsmooth.iter().any(|(f, _)| f.var().index() != n)
    {
        return None;
    }
    let mut degree: u32 = t.factors.iter().map(|&(_, k)| k).sum();
    let mut odd = degree % 2 == 1;
    for &(f, k) in &t.nonsmooth {
        match f {
            harmonid_model::NonSmooth::Abs(_) => degree += k,
            _ => odd ^= k % 2 == 1,
        }
    }
    let slope = match (&t.factors[..], &t.nonsmooth[..]) {
        ([], [(harmonid_model::NonSmooth::Tanh(_, c), 1)]) => t.coef / c,
        _ => 0.0,
    };
    let minus = if odd { -t.coef } else { t.coef };
    Some(((degree, t.coef, minus, t.name.clone()), slope))
}

/// Why the force `Σ c_s |q|^d` (entries of `growth`: degree, coefficient along +q, along
/// −q, term) fails to push a mode back from large `|q|` in some direction, if it does: the
/// leading degree whose coefficients do not cancel must have `c₊ > 0` and `c₋ < 0`.
fn runaway(growth: &[(u32, f64, f64, String)], name: &str, at_rest: f64) -> Option<String> {
    let top = |sign: f64| {
        let mut degrees: Vec<u32> = growth.iter().map(|g| g.0).collect();
        degrees.sort_unstable();
        degrees.dedup();
        degrees.into_iter().rev().find_map(|d| {
            let of_d = growth.iter().filter(|g| g.0 == d);
            let c: f64 = of_d
                .clone()
                .map(|g| if sign > 0.0 { g.1 } else { g.2 })
                .sum();
            let scale: f64 = of_d.clone().map(|g| g.1.abs()).sum();
            let names: Vec<&str> = of_d.map(|g| g.3.as_str()).collect();
            (c.abs() > 1e-12 * scale).then(|| (d, c, names.join(" + ")))
        })
    };
    for (sign, dir) in [(1.0, "+"), (-1.0, "−")] {
        let head = format!("its stiffness at rest {at_rest:.3e} s⁻² is not positive and");
        match top(sign) {
            None => return Some(format!("{head} no higher power of {name} stops it")),
            Some((d, c, terms)) if c * sign <= 0.0 => {
                return Some(format!(
                    "{head} along {dir}{name} its leading force {terms} (degree {d}, {c:.3e} per unit |{name}|^{d}) pushes away from rest"
                ))
            }
            _ => {}
        }
    }
    None
}

fn flat_pp(m: &PowerProduct) -> Vec<(usize, u32)> {
    m.factors().iter().map(|&(v, k)| (v.index(), k)).collect()
}

/// Appends the non-smooth terms of equation `n` of `model`, evaluated at parameter values
/// `pvals`, with their parameter gradients.
fn rough_terms_of(
    model: &Model,
    n: usize,
    pvals: &[f64],
    out: &mut Vec<(RoughTerm, Vec<(usize, f64)>)>,
) -> Result<(), SimError> {
    let Some(eq) = model.nonsmooth.get(n) else {
        return Ok(());
    };
    for (m, c) in eq.terms() {
        let name = model.monomial_name(m);
        let mut grad = Vec::new();
        for p in c.variables() {
            let d = c.derivative(p).map_err(|_| SimError::DerivativeOverflow {
                monomial: name.clone(),
                mode: model.modes[n].name.clone(),
            })?;
            grad.push((p.index(), d.eval(pvals)));
        }
        let (poly, factors) = model.split_nonsmooth(m);
        let nonsmooth = factors
            .iter()
            .filter_map(|&(k, e)| model.nonsmooth_factors.get(k).map(|f| (*f, e)))
            .collect();
        let term = RoughTerm {
            eq: n,
            coef: c.eval(pvals),
            factors: flat_pp(&poly),
            nonsmooth,
            name,
        };
        out.push((term, grad));
    }
    Ok(())
}

/// Checks rough terms (equation and variables in range, finite coefficients) and drops zero
/// ones without a gradient; returns them and their gradients apart.
#[allow(clippy::type_complexity)]
fn check_rough(
    rough: Vec<(RoughTerm, Vec<(usize, f64)>)>,
    mode_names: &[String],
) -> Result<(Vec<RoughTerm>, Vec<Vec<(usize, f64)>>), SimError> {
    let n = mode_names.len();
    let mut out = (Vec::new(), Vec::new());
    for (t, g) in rough {
        if t.coef == 0.0 && g.is_empty() {
            continue;
        }
        let vars_ok = t.factors.iter().all(|&(m, k)| m <= 2 * n && k > 0)
            && t.nonsmooth
                .iter()
                .all(|(f, k)| f.var().index() < 2 * n && *k > 0);
        if t.eq >= n || !vars_ok {
            return Err(SimError::TermBeyondModes { modes: n });
        }
        if !t.coef.is_finite() {
            return Err(SimError::BadValue {
                what: format!(
                    "the coefficient of {} in the equation of {}",
                    t.name, mode_names[t.eq]
                ),
                value: t.coef,
                why: "coefficients must be finite".into(),
            });
        }
        out.0.push(t);
        out.1.push(g);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_mode() -> NumericModel {
        let names = vec!["q1".to_string(), "q2".to_string()];
        let mut v = ModelValues::default();
        v.modes.insert(
            "q1".into(),
            ModeValues {
                f_hz: Some(1.0e3),
                q: Some(100.0),
            },
        );
        v.modes.insert(
            "q2".into(),
            ModeValues {
                f_hz: Some(2.1e3),
                q: Some(200.0),
            },
        );
        v.eom.insert(
            "q1".into(),
            [("q1^3".to_string(), 2.0), ("q1*q2^2".to_string(), 3.0)].into(),
        );
        v.eom.insert(
            "q2".into(),
            [("q2^3".to_string(), 5.0), ("q1^2*q2".to_string(), 3.0)].into(),
        );
        NumericModel::from_values(&names, &v).expect("valid model")
    }

    #[test]
    fn forces_and_jacobian() {
        let m = two_mode();
        let q = [0.7, -1.3];
        let mut pows = vec![0.0; m.pow_len()];
        let mut f = [0.0; 2];
        m.forces(&q, &mut pows, &mut f);
        assert!((f[0] - (2.0 * 0.343 + 3.0 * 0.7 * 1.69)).abs() < 1e-12);
        assert!((f[1] - (5.0 * -2.197 + 3.0 * 0.49 * -1.3)).abs() < 1e-12);
        let mut jac = [0.0; 4];
        m.force_jacobian(&q, &mut pows, &mut jac);
        let h = 1e-6;
        for j in 0..2 {
            let mut qp = q;
            qp[j] += h;
            let mut qm = q;
            qm[j] -= h;
            let (mut fp, mut fm) = ([0.0; 2], [0.0; 2]);
            m.forces(&qp, &mut pows, &mut fp);
            m.forces(&qm, &mut pows, &mut fm);
            for n in 0..2 {
                let fd = (fp[n] - fm[n]) / (2.0 * h);
                assert!(
                    (jac[n * 2 + j] - fd).abs() < 1e-6,
                    "{n},{j}: {} vs {fd}",
                    jac[n * 2 + j]
                );
            }
        }
        assert_eq!(m.eom_map(0).get("q1*q2^2"), Some(&3.0));
    }

    #[test]
    fn monomial_names() {
        let names = vec!["q1".to_string(), "q2".to_string()];
        assert_eq!(
            parse_monomial("q1*q2^2", &names).ok(),
            Some(vec![(0, 1), (1, 2)])
        );
        assert_eq!(
            parse_monomial("q2 * q1^2", &names).ok(),
            Some(vec![(0, 2), (1, 1)])
        );
        assert!(parse_monomial("q3^2", &names).is_err());
        assert!(parse_monomial("q1^x", &names).is_err());
    }

    #[test]
    fn unbounded_is_refused() {
        let names = vec!["q1".to_string()];
        let t = |coef, k| Term {
            eq: 0,
            coef,
            factors: vec![(0, k)],
        };
        let w2 = (std::f64::consts::TAU * 1.0e3).powi(2);
        let r = NumericModel::new(
            names.clone(),
            vec![1.0e3],
            vec![100.0],
            vec![t(-2.0 * w2, 1)],
        );
        assert!(matches!(r, Err(SimError::Unbounded { .. })));
        let r = NumericModel::new(
            names.clone(),
            vec![1.0e3],
            vec![100.0],
            vec![t(-2.0 * w2, 1), t(1.0, 3)],
        );
        assert!(r.is_ok());
        let r = NumericModel::new(names, vec![1.0e3], vec![0.3], vec![]);
        assert!(matches!(r, Err(SimError::BadValue { .. })));
    }
}

//! The equations of motion of a [`Model`] as a physicist writes them: plain text, LaTeX, JSON.

use crate::model::{Linear, Model, ParamKind};
use harmonid_poly::{rational_to_f64, Coeff, Poly};
use std::fmt::Write as _;

const GREEK: &[&str] = &[
    "alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa",
    "lambda", "mu", "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi",
    "omega", "Gamma", "Delta", "Theta", "Lambda", "Xi", "Pi", "Sigma", "Upsilon", "Phi", "Psi",
    "Omega",
];

/// Splits a name into its letters and its subscript: `beta1 → (beta, 1)`, `g1_12 → (g, 1,12)`,
/// `k_lin → (k, lin)`, `x → (x, none)`.
fn split_name(name: &str) -> (&str, Option<String>) {
    let cut = name
        .find(|c: char| c.is_ascii_digit() || c == '_')
        .unwrap_or(name.len());
    let (base, rest) = name.split_at(cut);
    let rest = rest.trim_start_matches('_');
    if base.is_empty() || rest.is_empty() {
        return (if base.is_empty() { name } else { base }, None);
    }
    (base, Some(rest.replace('_', ",")))
}

fn latex_base(base: &str) -> String {
    if GREEK.contains(&base) {
        format!("\\{base}")
    } else if base.chars().count() == 1 {
        base.to_string()
    } else {
        format!("\\mathrm{{{base}}}")
    }
}

/// A model name in LaTeX: `beta1 → \beta_{1}`, `g12 → g_{12}`, `g1_12 → g_{1,12}`,
/// `q1 → q_{1}`, `kappa → \kappa`.
pub fn latex_name(name: &str) -> String {
    let (base, sub) = split_name(name);
    match sub {
        Some(s) => format!("{}_{{{s}}}", latex_base(base)),
        None => latex_base(base),
    }
}

/// The suffix of a mode's linear symbols: `q1 → 1` (so `w1`, `Q1`, `F1`), `x → _x`.
fn mode_suffix(name: &str) -> String {
    match split_name(name) {
        (_, Some(sub)) if sub.chars().all(|c| c.is_ascii_digit()) => sub,
        _ => format!("_{name}"),
    }
}

fn mode_suffix_latex(name: &str) -> String {
    match split_name(name) {
        (_, Some(sub)) => sub,
        _ => format!("\\mathrm{{{name}}}"),
    }
}

/// A frequency in Hz with the unit a physicist would pick: `207.58 kHz`.
pub(crate) fn format_hz(v: f64) -> String {
    let (scale, unit) = if v >= 1e9 {
        (1e9, "GHz")
    } else if v >= 1e6 {
        (1e6, "MHz")
    } else if v >= 1e3 {
        (1e3, "kHz")
    } else {
        (1.0, "Hz")
    };
    format!("{} {unit}", v / scale)
}

fn json_f64(v: f64) -> String {
    if v.is_finite() {
        serde_json::to_string(&v).unwrap_or_else(|_| "null".to_string())
    } else {
        "null".to_string()
    }
}

fn json_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".to_string())
}

fn json_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "null".to_string(), json_f64)
}

fn join_sum(lhs: &str, rest: &str) -> String {
    match rest.strip_prefix('-') {
        Some(r) => format!("{lhs} - {r}"),
        None => format!("{lhs} + {rest}"),
    }
}

impl Model {
    /// Equation `n` in readable form, as a physicist writes it:
    /// `q1'' + (w1/Q1) q1' + w1^2 q1 + beta1 q1^3 + g12 q1 q2^2 = F1(t)`.
    pub fn equation_text(&self, n: usize) -> String {
        let Some(mode) = self.modes.get(n) else {
            return String::new();
        };
        let q = &mode.name;
        let s = mode_suffix(q);
        let lhs = format!("{q}'' + (w{s}/Q{s}) {q}' + w{s}^2 {q}");
        let lhs = match self.eom.get(n) {
            Some(p) if !p.is_zero() => join_sum(
                &lhs,
                &p.to_string_with(&self.variable_names(), &self.param_names()),
            ),
            _ => lhs,
        };
        let lhs = match self.nonsmooth_display(n, false) {
            Some((p, names)) => join_sum(&lhs, &p.to_string_with(&names, &self.param_names())),
            None => lhs,
        };
        format!("{lhs} = F{s}(t)")
    }

    /// The LaTeX names of the variables, modes, velocities, then the pump (`q_{1}`,
    /// `\dot{q}_{1}`, `p(t)`), in the order of [`Model::variable_names`].
    pub fn variable_latex_names(&self) -> Vec<String> {
        self.modes
            .iter()
            .map(|m| latex_name(&m.name))
            .chain(self.modes.iter().map(|m| {
                let (base, _) = split_name(&m.name);
                format!(
                    "\\dot{{{}}}_{{{}}}",
                    latex_base(base),
                    mode_suffix_latex(&m.name)
                )
            }))
            .chain(std::iter::once("p(t)".to_string()))
            .collect()
    }

    /// Equation `n` in LaTeX (one line of an `aligned` block, `&=` before the drive).
    pub fn equation_latex(&self, n: usize) -> String {
        let Some(mode) = self.modes.get(n) else {
            return String::new();
        };
        let (base, _) = split_name(&mode.name);
        let qb = latex_base(base);
        let s = mode_suffix_latex(&mode.name);
        let q = latex_name(&mode.name);
        let lhs = format!(
            "\\ddot{{{qb}}}_{{{s}}} + \\frac{{\\omega_{{{s}}}}}{{Q_{{{s}}}}} \\dot{{{qb}}}_{{{s}}} + \\omega_{{{s}}}^{{2}} {q}"
        );
        let modes = self.variable_latex_names();
        let params: Vec<String> = self.params.iter().map(|p| latex_name(&p.name)).collect();
        let lhs = match self.eom.get(n) {
            Some(p) if !p.is_zero() => join_sum(&lhs, &p.to_latex_with(&modes, &params)),
            _ => lhs,
        };
        let lhs = match self.nonsmooth_display(n, true) {
            Some((p, names)) => join_sum(&lhs, &p.to_latex_with(&names, &params)),
            None => lhs,
        };
        format!("{lhs} &= F_{{{s}}}(t)")
    }

    /// All equations as a LaTeX `aligned` block inside `\[ ... \]`.
    pub fn to_latex(&self) -> String {
        let mut out = String::from("\\[\n\\begin{aligned}\n");
        for n in 0..self.modes.len() {
            out.push_str(&self.equation_latex(n));
            if n + 1 < self.modes.len() {
                out.push_str(" \\\\");
            }
            out.push('\n');
        }
        out.push_str("\\end{aligned}\n\\]\n");
        out
    }

    /// The model as a model file whose every term is written per equation
    /// (`eom q1 += (kappa) * q2*q3`; a potential's derivatives are written out), which
    /// [`crate::parse_str`] reads back to the same modes, parameters (kinds and bounds) and
    /// equations: for a model built or changed by a program (`harmonid discover`'s selection).
    /// `header` is written first as comment lines.
    pub fn to_source(&self, header: &str) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let _ = writeln!(out, "# {line}");
        }
        for m in &self.modes {
            let mut decl = format!("mode {}", m.name);
            if let Some(f) = m.nominal_hz {
                let _ = write!(decl, " at {f:e} Hz");
            }
            if let crate::Linear::Fixed(f) = m.f_hz {
                let _ = write!(decl, ", f = {f:e} Hz");
            }
            if let crate::Linear::Fixed(q) = m.q_factor {
                let _ = write!(decl, ", Q = {q:e}");
            }
            let _ = writeln!(out, "{decl}");
        }
        for p in &self.params {
            let mut decl = String::from("param ");
            if let (Some(lo), Some(_)) = (p.bounds.lower, p.bounds.upper) {
                let _ = write!(decl, "{lo:e} <= ");
            }
            decl.push_str(&p.name);
            match (p.kind, p.bounds.lower, p.bounds.upper) {
                (crate::ParamKind::Fixed(v), _, _) => {
                    let _ = write!(decl, " = {v:e}");
                }
                (_, _, Some(hi)) => {
                    let _ = write!(decl, " <= {hi:e}");
                }
                (_, Some(lo), None) => {
                    let _ = write!(decl, " >= {lo:e}");
                }
                _ => {}
            }
            let _ = writeln!(out, "{decl}");
        }
        let params = self.param_names();
        for (n, m, c) in self.all_terms() {
            let _ = writeln!(
                out,
                "eom {} += ({}) * {}",
                self.modes[n].name,
                c.to_string_with(&params),
                self.monomial_name(m)
            );
        }
        out
    }

    /// The parameters that appear in no equation (their identification column would be zero).
    pub fn unused_params(&self) -> Vec<&str> {
        let mut used = vec![false; self.params.len()];
        for (_, _, c) in self.all_terms() {
            for v in c.variables() {
                if let Some(u) = used.get_mut(v.index()) {
                    *u = true;
                }
            }
        }
        self.params
            .iter()
            .zip(used)
            .filter(|(_, u)| !u)
            .map(|(p, _)| p.name.as_str())
            .collect()
    }

    /// A readable report: modes, parameters, equations of motion, and whether the model can be
    /// identified by linear least squares.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "model {}", self.source);
        let _ = writeln!(out, "\nmodes ({}):", self.modes.len());
        let width = column_width(self.modes.iter().map(|m| m.name.as_str()));
        for m in &self.modes {
            let s = mode_suffix(&m.name);
            let mut parts = Vec::new();
            if let Some(v) = m.nominal_hz {
                parts.push(format!("nominal {}", format_hz(v)));
            }
            parts.push(match m.f_hz {
                Linear::Unknown => format!("f{s} unknown"),
                Linear::Fixed(v) => format!("f{s} = {} (fixed)", format_hz(v)),
            });
            parts.push(match m.q_factor {
                Linear::Unknown => format!("Q{s} unknown"),
                Linear::Fixed(v) => format!("Q{s} = {v} (fixed)"),
            });
            let _ = writeln!(out, "  {:width$}  {}", m.name, parts.join(", "));
        }
        let unknown = self
            .params
            .iter()
            .filter(|p| p.kind == ParamKind::Unknown)
            .count();
        let _ = writeln!(
            out,
            "\nparameters ({unknown} unknown, {} fixed):",
            self.params.len() - unknown
        );
        let width = column_width(self.params.iter().map(|p| p.name.as_str()));
        for p in &self.params {
            let mut desc = match p.kind {
                ParamKind::Unknown => "unknown".to_string(),
                ParamKind::Fixed(v) => format!("fixed = {v}"),
            };
            if let Some(lo) = p.bounds.lower {
                let _ = write!(desc, ", >= {lo}");
            }
            if let Some(hi) = p.bounds.upper {
                let _ = write!(desc, ", <= {hi}");
            }
            let _ = writeln!(out, "  {:width$}  {desc}", p.name);
        }
        if self.params.is_empty() {
            let _ = writeln!(out, "  (none)");
        }
        let _ = writeln!(
            out,
            "\nequations of motion (w_n = 2 pi f_n; F_n(t) is the drive of mode n):"
        );
        for n in 0..self.modes.len() {
            let _ = writeln!(out, "  {}", self.equation_text(n));
        }
        if !self.nonsmooth_factors.is_empty() {
            let vars = self.variable_names();
            let names: Vec<String> = self
                .nonsmooth_factors
                .iter()
                .map(|f| f.name(&vars))
                .collect();
            let _ = writeln!(
                out,
                "\nnon-smooth factors: {} (harmonic balance samples them in time: alternating frequency-time)",
                names.join(", ")
            );
        }
        let unused = self.unused_params();
        if !unused.is_empty() {
            let _ = writeln!(
                out,
                "\nnote: {} appear{} in no equation",
                unused.join(", "),
                if unused.len() == 1 { "s" } else { "" }
            );
        }
        let bad = self.non_affine_terms();
        if bad.is_empty() {
            let _ = writeln!(
                out,
                "\nidentification: possible (every coefficient is linear in the parameters)"
            );
        } else {
            let _ = writeln!(
                out,
                "\nidentification: NOT possible; the model is fine for simulation, but:"
            );
            for t in bad {
                let _ = writeln!(out, "  - {t}");
            }
        }
        out
    }

    /// The model as JSON: modes, parameters (kind, value, bounds) and every equation's terms as
    /// `{monomial: {parameter: factor}}` (the constant part under `"1"`; products of parameters,
    /// in models that cannot be identified, under their product name such as `"g^2"`).
    pub fn to_json(&self) -> String {
        let mut out = String::from("{\n");
        let _ = writeln!(out, "  \"format\": \"harmonid-model/1\",");
        let _ = writeln!(out, "  \"model\": {},", json_str(&self.source));
        let _ = writeln!(
            out,
            "  \"identifiable\": {},",
            self.non_affine_terms().is_empty()
        );
        out.push_str("  \"modes\": [");
        for (i, m) in self.modes.iter().enumerate() {
            let f = match m.f_hz {
                Linear::Unknown => None,
                Linear::Fixed(v) => Some(v),
            };
            let q = match m.q_factor {
                Linear::Unknown => None,
                Linear::Fixed(v) => Some(v),
            };
            let _ = write!(
                out,
                "{}\n    {{\"name\": {}, \"nominal_hz\": {}, \"f_hz\": {}, \"Q\": {}}}",
                if i == 0 { "" } else { "," },
                json_str(&m.name),
                json_opt(m.nominal_hz),
                json_opt(f),
                json_opt(q)
            );
        }
        out.push_str(if self.modes.is_empty() {
            "],\n"
        } else {
            "\n  ],\n"
        });
        out.push_str("  \"parameters\": {");
        for (i, p) in self.params.iter().enumerate() {
            let kind = match p.kind {
                ParamKind::Unknown => "\"kind\": \"unknown\"".to_string(),
                ParamKind::Fixed(v) => format!("\"kind\": \"fixed\", \"value\": {}", json_f64(v)),
            };
            let _ = write!(
                out,
                "{}\n    {}: {{{kind}, \"lower\": {}, \"upper\": {}}}",
                if i == 0 { "" } else { "," },
                json_str(&p.name),
                json_opt(p.bounds.lower),
                json_opt(p.bounds.upper)
            );
        }
        out.push_str(if self.params.is_empty() {
            "},\n"
        } else {
            "\n  },\n"
        });
        out.push_str("  \"eom\": {");
        let modes = self.mode_names();
        let params = self.param_names();
        for (n, eq) in self.eom.iter().enumerate() {
            let _ = write!(
                out,
                "{}\n    {}: {{",
                if n == 0 { "" } else { "," },
                json_str(modes.get(n).copied().unwrap_or(""))
            );
            // The polynomial terms, then those with a non-smooth factor (`abs(q1)*q1`).
            let ns = self.nonsmooth.get(n).into_iter().flat_map(|p| p.terms());
            let mut empty = true;
            for (i, (m, c)) in eq.terms().chain(ns).enumerate() {
                empty = false;
                let _ = write!(
                    out,
                    "{}\n      {}: {}",
                    if i == 0 { "" } else { "," },
                    json_str(&self.monomial_name(m)),
                    coeff_json(c, &params)
                );
            }
            out.push_str(if empty { "}" } else { "\n    }" });
        }
        out.push_str(if self.eom.is_empty() {
            "}\n"
        } else {
            "\n  }\n"
        });
        out.push_str("}\n");
        out
    }

    /// The number of terms in all equations together.
    pub fn term_count(&self) -> usize {
        self.eom.iter().chain(&self.nonsmooth).map(Poly::len).sum()
    }
}

fn coeff_json(c: &Coeff, params: &[&str]) -> String {
    let parts: Vec<String> = c
        .terms()
        .map(|(m, r)| {
            format!(
                "{}: {}",
                json_str(&m.name(params)),
                json_f64(rational_to_f64(r))
            )
        })
        .collect();
    format!("{{{}}}", parts.join(", "))
}

/// Width of a name column: the longest name, at most 40 characters (a longer name overflows its
/// column instead; a formatting width must stay small, and 65,536 would panic).
fn column_width<'a>(names: impl Iterator<Item = &'a str>) -> usize {
    names.map(|n| n.chars().count()).max().unwrap_or(0).min(40)
}

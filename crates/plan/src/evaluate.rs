//! Scores a plan: structural identifiability and the Cramér–Rao bound of every unknown.

use crate::info::{measurement_info, n_shared, Fidelity, MeasInfo, Target};
use crate::PlanError;
use harmonid_experiment::Plan;
use harmonid_ident::Unknown;
use harmonid_ident::{bounds_from_information, Bounds};
use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel};
use std::collections::BTreeSet;

/// An unknown the plan cannot determine, and the drive that would fix it.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// The unknown (`omega^2 of q1`, `beta1`, ...).
    pub unknown: String,
    /// Why the plan does not determine it.
    pub reason: String,
    /// A drive that would.
    pub suggestion: String,
}

/// The score of a plan.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Cramér–Rao bounds for the plan's shots (`f_hz:q1`, `Q:q1`, parameters).
    pub bounds: Bounds,
    /// Unknowns no measurement determines, with a drive that would fix each.
    pub findings: Vec<Finding>,
    /// Mode names.
    pub mode_names: Vec<String>,
    /// What the design skipped or could not check, one line each: candidates whose harmonic
    /// balance would exceed a size bound (`skipped couple_q1_q2_q3 with tones …: why`), a
    /// measurement whose truncation could not be checked at a wider lattice; empty for an
    /// evaluated plan.
    pub notes: Vec<String>,
}

impl Evaluation {
    /// `bounds.json`: `{"modes": {"q1": {"f_hz": rel, "Q": rel}}, "parameters": {"beta1": rel}}`,
    /// relative one-sigma bounds for the plan's shots (`null`: not identifiable).
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::{json, Map, Value};
        let num = |x: f64| {
            if x.is_finite() {
                json!(x)
            } else {
                Value::Null
            }
        };
        let mut modes = Map::new();
        let mut params = Map::new();
        for b in &self.bounds.quantities {
            match b.name.split_once(':') {
                Some((what, mode)) => {
                    let e = modes
                        .entry(mode.to_string())
                        .or_insert_with(|| Value::Object(Map::new()));
                    if let Value::Object(m) = e {
                        m.insert(what.to_string(), num(b.rel));
                    }
                }
                None => {
                    params.insert(b.name.clone(), num(b.rel));
                }
            }
        }
        json!({"modes": modes, "parameters": params})
    }

    /// A text table: quantity, value, absolute and relative bound.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:<12} {:>14} {:>12} {:>10}\n",
            "quantity", "value", "bound", "relative"
        );
        for b in &self.bounds.quantities {
            s += &format!(
                "{:<12} {:>14.6e} {:>12.3e} {:>10.3e}\n",
                b.name, b.value, b.std, b.rel
            );
        }
        s += &format!(
            "(Cramér–Rao, {} shots; condition of the scaled information {:.2e})\n",
            self.bounds.shots, self.bounds.condition
        );
        for f in &self.findings {
            s += &format!(
                "NOT IDENTIFIABLE: {}: {}; {}\n",
                f.unknown, f.reason, f.suggestion
            );
        }
        s
    }
}

/// The modes the terms of parameter `p` involve (their monomials and equations).
pub(crate) fn param_modes(model: &Model, p: usize) -> BTreeSet<usize> {
    let mut out = BTreeSet::new();
    for (n, eq) in model.eom.iter().enumerate() {
        for (m, c) in eq.terms() {
            if c.variables().iter().any(|v| v.index() == p) {
                out.insert(n);
                // A velocity `d(q)` involves its mode; the pump none.
                let nm = model.modes.len();
                out.extend(
                    m.factors()
                        .iter()
                        .filter(|(v, _)| v.index() < 2 * nm)
                        .map(|(v, _)| v.index() % nm),
                );
            }
        }
    }
    out
}

/// A drive that makes unknown `u` visible.
pub(crate) fn suggestion(model: &Model, u: &Unknown) -> String {
    let name = |n: usize| model.modes[n].name.clone();
    match u {
        Unknown::OmegaSq(n) | Unknown::Gamma(n) => format!(
            "drive {} with two tones near its resonance and measure its sidebands",
            name(*n)
        ),
        Unknown::Param(p) => {
            let modes: Vec<String> = param_modes(model, *p).into_iter().map(name).collect();
            if modes.len() <= 1 {
                format!(
                    "drive {} harder (closer to its fold) with two tones near its resonance",
                    modes.join("")
                )
            } else {
                format!(
                    "a measurement with lines near the resonances of {} together: tones near each of them, or near all but one whose frequency is a sum or difference of the others' (its line then appears through the coupling)",
                    modes.join(", ")
                )
            }
        }
        Unknown::Force { .. } | Unknown::Gain { .. } => {
            "give the measurement drive levels and phases (the gains are then common to its tones)"
                .into()
        }
    }
}

/// Joint bounds from per-measurement information on the shared unknowns.
pub(crate) fn joint_bounds(
    model: &Model,
    infos: &[&MeasInfo],
    shots: usize,
) -> Result<Evaluation, PlanError> {
    let first = infos.first().ok_or(PlanError::EmptyPlan)?;
    let s = n_shared(model);
    let mut info = vec![0.0; s * s];
    for m in infos {
        for (a, b) in info.iter_mut().zip(&m.info) {
            *a += b;
        }
    }
    let free: Vec<usize> = first.fwd.free().into_iter().filter(|&k| k < s).collect();
    let c = free.len();
    let sub: Vec<f64> = (0..c * c)
        .map(|k| info[free[k / c] * s + free[k % c]])
        .collect();
    let bounds = bounds_from_information(&first.fwd, &first.theta, &free, &sub, shots);
    let findings = bounds
        .unidentifiable
        .iter()
        .map(|u| Finding {
            unknown: u.name.clone(),
            reason: u.reason.clone(),
            suggestion: suggestion(model, &first.fwd.unknowns()[u.unknown]),
        })
        .collect();
    Ok(Evaluation {
        bounds,
        findings,
        mode_names: first.fwd.mode_names().to_vec(),
        notes: Vec::new(),
    })
}

/// Scores `plan` for a model with the guessed `values`: every measurement simulated
/// noise-free, its Fisher information for `shots` shots of per-quadrature noise `sigma_m`
/// (m) with one complex gain per mode and measurement profiled out (drive levels: the plan's
/// `drive_levels_v`/`drive_phases_rad`, or the forces themselves when it gives none), summed.
/// Errors: a measurement whose drive passes a fold or whose state is unstable or not found.
pub fn evaluate(
    model: &Model,
    values: &ModelValues,
    plan: &Plan,
    sigma_m: f64,
    shots: usize,
) -> Result<Evaluation, PlanError> {
    let num = NumericModel::from_model(model, values)?;
    let mut plan = plan.clone();
    for pm in &mut plan.measurements {
        if pm.drive_levels_v.is_none() || pm.drive_phases_rad.is_none() {
            // Levels the gains can multiply: the forces (gain 1 N/kg per unit).
            let drive = pm.excitation(&num)?;
            let (lv, ph): (Vec<f64>, Vec<f64>) = (0..pm.drives_hz.len())
                .map(|d| {
                    let z = drive
                        .force
                        .iter()
                        .map(|row| row[d])
                        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
                        .unwrap_or_default();
                    (z.norm(), z.arg())
                })
                .unzip();
            pm.drive_levels_v = Some(lv);
            pm.drive_phases_rad = Some(ph);
        }
    }
    let target = Target {
        model,
        num: &num,
        values,
        sigma_m,
        shots,
    };
    let infos = plan
        .measurements
        .iter()
        .map(|pm| measurement_info(&target, &plan, pm, Fidelity::User))
        .collect::<Result<Vec<_>, _>>()?;
    let refs: Vec<&MeasInfo> = infos.iter().collect();
    joint_bounds(model, &refs, shots)
}

//! Scores a plan: structural identifiability and the Cramér–Rao bound of every unknown.

use crate::info::{ladder_info, n_shared, Fidelity, MeasInfo, Target};
use crate::range::GuessRange;
use crate::terms::param_modes;
use crate::PlanError;
use harmonid_experiment::Plan;
use harmonid_ident::Unknown;
use harmonid_ident::{bounds_from_information, Bounds};
use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel};
use std::collections::BTreeMap;

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
    /// How the plan fares over the range of devices the guess stands for (`None`: scored at
    /// the guess only).
    pub robustness: Option<Robustness>,
}

/// A plan's bounds over the devices of a guess's range.
#[derive(Debug, Clone, Default)]
pub struct Robustness {
    /// The range, one line per quantity ([`GuessRange::describe`]).
    pub range: Vec<String>,
    /// How the design checked each measurement against the range (`None` for a plan scored,
    /// not designed).
    pub corners: Option<String>,
    /// Devices drawn from the range.
    pub draws: usize,
    /// Per quantity, the largest relative bound over the draws where every measurement was
    /// feasible.
    pub worst: BTreeMap<String, f64>,
    /// Per quantity, the median relative bound over those draws.
    pub median: BTreeMap<String, f64>,
    /// The draws where a measurement failed (a jump, an unstable or unfound state), one line
    /// each: which draw, which measurement, why, and the draw's values of its modes.
    pub failures: Vec<String>,
    /// Levels of drive ladders lost on a draw whose measurements all kept some level (`draw
    /// 3: couple_q1_q2 level 2`): the draw's bounds are those of the levels kept.
    pub lost_levels: Vec<String>,
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
        let mut out = json!({"modes": modes, "parameters": params});
        if let Some(r) = &self.robustness {
            let split = |m: &BTreeMap<String, f64>| {
                let (mut modes, mut params) = (Map::new(), Map::new());
                for (name, &rel) in m {
                    match name.split_once(':') {
                        Some((what, mode)) => {
                            if let Value::Object(o) = modes
                                .entry(mode.to_string())
                                .or_insert_with(|| Value::Object(Map::new()))
                            {
                                o.insert(what.to_string(), num(rel));
                            }
                        }
                        None => {
                            params.insert(name.clone(), num(rel));
                        }
                    }
                }
                json!({"modes": modes, "parameters": params})
            };
            out["over_range"] = json!({
                "range": r.range,
                "draws": r.draws,
                "checked": r.corners,
                "worst": split(&r.worst),
                "median": split(&r.median),
                "failures": r.failures,
                "lost_levels": r.lost_levels,
            });
        }
        out
    }

    /// A text table: quantity, value, absolute and relative bound (and, over a range, the
    /// median and worst relative bound of the draws).
    pub fn table(&self) -> String {
        let r = self.robustness.as_ref();
        // Without a feasible draw there is no median or worst to show.
        let columns = r.filter(|r| !r.median.is_empty());
        let mut s = format!(
            "{:<12} {:>14} {:>12} {:>10}",
            "quantity", "value", "bound", "relative"
        );
        if columns.is_some() {
            s += &format!(" {:>10} {:>10}", "median", "worst");
        }
        s += "\n";
        for b in &self.bounds.quantities {
            s += &format!(
                "{:<12} {:>14.6e} {:>12.3e} {:>10.3e}",
                b.name, b.value, b.std, b.rel
            );
            if let Some(r) = columns {
                let get = |m: &BTreeMap<String, f64>| m.get(&b.name).copied().unwrap_or(f64::NAN);
                s += &format!(" {:>10.3e} {:>10.3e}", get(&r.median), get(&r.worst));
            }
            s += "\n";
        }
        s += &format!(
            "(Cramér–Rao, {} shots; condition of the scaled information {:.2e})\n",
            self.bounds.shots, self.bounds.condition
        );
        if let Some(r) = r {
            s += &if r.draws == 0 {
                "(relative: at the guess; no device drawn from the range: --draws 0)\n".to_string()
            } else {
                format!(
                    "(relative: at the guess; median and worst: over {} devices drawn from the range, {} of them with every measurement feasible)\n",
                    r.draws,
                    r.draws - r.failures.len()
                )
            };
            if let Some(c) = &r.corners {
                s += &format!("(designed so that {c})\n");
            }
            for f in &r.failures {
                s += &format!("FAILS ON A DEVICE OF THE RANGE: {f}\n");
            }
            if !r.lost_levels.is_empty() {
                s += &format!(
                    "(drive ladders lost {} level(s) on the devices drawn, the bounds there use the levels kept: {})\n",
                    r.lost_levels.len(),
                    r.lost_levels.join("; ")
                );
            }
        }
        for f in &self.findings {
            s += &format!(
                "NOT IDENTIFIABLE: {}: {}; {}\n",
                f.unknown, f.reason, f.suggestion
            );
        }
        s
    }
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
        Unknown::Force { .. } | Unknown::Gain { .. } | Unknown::Background { .. } => {
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
    bounds_of_sum(model, first, &info, shots)
}

/// The information of measurements added up as each is computed, keeping only the first's
/// forward model (for the unknowns' names): a device's bounds over a plan of many
/// measurements and levels in the memory of one. (The draws are now scored level by level,
/// [`crate::draws`]; the device-by-device path is kept for the test that compares them.)
#[cfg(test)]
pub(crate) struct InfoSum {
    first: Option<MeasInfo>,
    sum: Vec<f64>,
}

#[cfg(test)]
impl InfoSum {
    /// Nothing added yet.
    pub(crate) fn new() -> Self {
        Self {
            first: None,
            sum: Vec::new(),
        }
    }

    /// Adds one measurement's (or level's) information.
    pub(crate) fn add(&mut self, m: MeasInfo) {
        if self.sum.is_empty() {
            self.sum = m.info.clone();
        } else {
            for (a, b) in self.sum.iter_mut().zip(&m.info) {
                *a += b;
            }
        }
        self.first.get_or_insert(m);
    }

    /// The joint bounds of what was added ([`joint_bounds`] of the same measurements).
    pub(crate) fn bounds(&self, model: &Model, shots: usize) -> Result<Evaluation, PlanError> {
        let first = self.first.as_ref().ok_or(PlanError::EmptyPlan)?;
        bounds_of_sum(model, first, &self.sum, shots)
    }
}

/// The bounds of the summed information `info` (`S × S` on the shared unknowns), named by
/// `first`'s forward model.
fn bounds_of_sum(
    model: &Model,
    first: &MeasInfo,
    info: &[f64],
    shots: usize,
) -> Result<Evaluation, PlanError> {
    let s = n_shared(model);
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
        robustness: None,
    })
}

/// How `plan` fares over `range`: `draws` devices drawn from it (seed 0), every measurement
/// simulated noise-free on each at the search's fidelity (the lattice at its starting order),
/// the relative bounds of the draws where every measurement is feasible, and the failures of
/// the others. `corners` is left `None` (the design fills it in).
pub fn robustness(
    model: &Model,
    range: &GuessRange,
    plan: &Plan,
    sigma_m: f64,
    shots: usize,
    draws: usize,
) -> Result<Robustness, PlanError> {
    robustness_within(
        model,
        range,
        plan,
        (sigma_m, shots),
        draws,
        None,
        &mut |_| {},
    )
    .map(|(r, _)| r)
}

/// [`robustness`] stopped between chunks of draws once `deadline` has passed (the report is
/// then over the draws scored, [`Robustness::draws`] of them; the count left out is returned
/// with it), calling `progress` with the draws scored so far.
pub(crate) fn robustness_within(
    model: &Model,
    range: &GuessRange,
    plan: &Plan,
    (sigma_m, shots): (f64, usize),
    draws: usize,
    deadline: Option<std::time::Instant>,
    progress: &mut dyn FnMut(usize),
) -> Result<(Robustness, usize), PlanError> {
    crate::check_draws(draws)?;
    let plan = with_levels(plan, &NumericModel::from_model(model, range.guess())?)?;
    // Every level is scored on a chunk of devices at once, its solvers kept across them
    // (crate::draws), then gathered in draw order.
    let devices = range.draws(draws, 0);
    let scored = crate::draws::score_draws(
        model, range, &plan, &devices, sigma_m, shots, deadline, progress,
    )?;
    let skipped = scored.skipped;
    let outcomes: Vec<Result<Draw, PlanError>> = scored
        .draws
        .into_iter()
        .map(|d| d.and_then(|d| relative(model, d, shots)))
        .collect();
    let draws = outcomes.len();
    let mut per_quantity: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut failures = Vec::new();
    let mut lost_levels = Vec::new();
    for outcome in outcomes {
        match outcome? {
            Draw::Failed(f) => failures.push(f),
            Draw::Scored { rel, lost } => {
                lost_levels.extend(lost);
                for (name, r) in rel {
                    per_quantity.entry(name).or_default().push(r);
                }
            }
        }
    }
    let mut worst = BTreeMap::new();
    let mut median = BTreeMap::new();
    for (name, mut rels) in per_quantity {
        rels.sort_by(f64::total_cmp);
        worst.insert(name.clone(), rels.last().copied().unwrap_or(f64::NAN));
        median.insert(name, rels[rels.len() / 2]);
    }
    Ok((
        Robustness {
            range: range.describe(),
            corners: None,
            draws,
            worst,
            median,
            failures,
            lost_levels,
        },
        skipped,
    ))
}

/// The relative bounds of a device whose information [`crate::draws`] summed.
fn relative(model: &Model, d: crate::draws::Draw, shots: usize) -> Result<Draw, PlanError> {
    Ok(match d {
        crate::draws::Draw::Failed(f) => Draw::Failed(f),
        crate::draws::Draw::Summed { sum, named, lost } => {
            let ev = bounds_of_sum(model, &named, &sum, shots)?;
            Draw::Scored {
                rel: ev
                    .bounds
                    .quantities
                    .iter()
                    .map(|b| (b.name.clone(), b.rel))
                    .collect(),
                lost,
            }
        }
    })
}

/// One device of [`robustness`]: a measurement it cannot run, or every quantity's relative
/// bound with the ladder levels it loses.
#[derive(Debug)]
enum Draw {
    Failed(String),
    Scored {
        rel: Vec<(String, f64)>,
        lost: Vec<String>,
    },
}

/// `plan` with drive levels on every measurement: one that gives none gets its forces as
/// levels (gain 1 N/kg per unit) and phases, so the gains can be profiled out.
fn with_levels(plan: &Plan, num: &NumericModel) -> Result<Plan, PlanError> {
    let mut plan = plan.clone();
    for pm in &mut plan.measurements {
        if pm.drive_levels_v.is_none() || pm.drive_phases_rad.is_none() {
            let drive = pm.excitation(num)?;
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
    Ok(plan)
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
    let plan = with_levels(plan, &num)?;
    let target = Target {
        model,
        num: &num,
        values,
        sigma_m,
        shots,
    };
    let mut infos = Vec::new();
    let mut notes = Vec::new();
    for pm in &plan.measurements {
        let (i, lost) = ladder_info(&target, &plan, pm, Fidelity::User)?;
        infos.extend(i);
        notes.extend(lost.iter().map(|&k| lost_note(pm, k)));
    }
    let refs: Vec<&MeasInfo> = infos.iter().collect();
    let mut ev = joint_bounds(model, &refs, shots)?;
    ev.notes = notes;
    Ok(ev)
}

/// The note on level `k` of `pm`'s ladder, lost at the guess.
pub(crate) fn lost_note(pm: &harmonid_experiment::PlanMeasurement, k: usize) -> String {
    format!(
        "{}: level {k} of its ladder ({} of the forces) has no stable steady state at the guess (the drive passes a fold, or the state is unstable); scored without it",
        pm.name, pm.levels[k]
    )
}

/// The draws scored device by device, every level simulated afresh (the path before
/// [`crate::draws`]): what the test of that module compares it with.
#[cfg(test)]
fn draws_one_by_one(
    model: &Model,
    range: &GuessRange,
    plan: &Plan,
    (sigma_m, shots): (f64, usize),
    draws: usize,
) -> Result<Vec<Draw>, PlanError> {
    use crate::info::{is_infeasible, too_large};
    let plan = with_levels(plan, &NumericModel::from_model(model, range.guess())?)?;
    let mut out = Vec::new();
    'draws: for (k, values) in range.draws(draws, 0).iter().enumerate() {
        let num = NumericModel::from_model(model, values)?;
        let target = Target {
            model,
            num: &num,
            values,
            sigma_m,
            shots,
        };
        let mut sum = InfoSum::new();
        let mut lost = Vec::new();
        for pm in &plan.measurements {
            match ladder_info(&target, &plan, pm, Fidelity::Search) {
                Ok((i, l)) => {
                    i.into_iter().for_each(|m| sum.add(m));
                    lost.extend(l.iter().map(|j| format!("draw {k}: {} level {j}", pm.name)));
                }
                Err(e) if is_infeasible(&e) || too_large(&e).is_some() => {
                    out.push(Draw::Failed(format!(
                        "draw {k} ({}): {}: {e}",
                        range.describe_device(model, values, pm),
                        pm.name
                    )));
                    continue 'draws;
                }
                Err(e) => return Err(e),
            }
        }
        let ev = sum.bounds(model, shots)?;
        out.push(Draw::Scored {
            rel: ev
                .bounds
                .quantities
                .iter()
                .map(|b| (b.name.clone(), b.rel))
                .collect(),
            lost,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod draws_tests {
    use super::*;
    use crate::draws::score_draws;
    use std::collections::BTreeMap;
    use std::time::Instant;

    /// The draws' information, relative bounds as [`robustness`] reports them.
    fn scored(model: &Model, d: Result<crate::draws::Draw, PlanError>) -> Draw {
        relative(model, d.expect("scored"), 20).expect("bounds")
    }

    /// The two-mode string's paper plan with a drive ladder on every measurement (one without
    /// its lines, chosen per device) at `scale` of its forces, over the default range: the
    /// draws scored level by level equal those scored device by device, failures word for word.
    #[test]
    fn scoring_level_by_level_equals_scoring_device_by_device() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/nanostring_2mode");
        let model = harmonid_model::load(&dir.join("model.hb")).expect("model");
        let values = harmonid_experiment::read_values(&dir.join("values.toml")).expect("values");
        let text = std::fs::read_to_string(dir.join("plan.toml")).expect("plan");
        let plan = Plan::from_toml(&text, "plan.toml").expect("plan");
        let range = GuessRange::new(&model, &values, &BTreeMap::new()).expect("range");
        let mut counts = (0, 0, 0);
        for scale in [1.0, 4.0] {
            let mut plan = plan.clone();
            for (j, pm) in plan.measurements.iter_mut().enumerate() {
                pm.levels = vec![0.5, 0.75, 1.0];
                for f in pm.force.values_mut() {
                    f.iter_mut().for_each(|x| *x *= scale);
                }
                if let Some(v) = pm.drive_levels_v.as_mut() {
                    v.iter_mut().for_each(|x| *x *= scale);
                }
                if j == 1 {
                    pm.measure_hz = None;
                }
            }
            let noise = (5e-11, 20);
            let old = draws_one_by_one(&model, &range, &plan, noise, 4).expect("one by one");
            let plan = with_levels(
                &plan,
                &NumericModel::from_model(&model, range.guess()).expect("num"),
            )
            .expect("levels");
            let new = score_draws(
                &model,
                &range,
                &plan,
                &range.draws(4, 0),
                5e-11,
                20,
                None,
                &mut |_| {},
            )
            .expect("level by level");
            assert_eq!(new.skipped, 0);
            // A deadline already past: one draw scored (the first, as without a deadline), the
            // others counted as skipped.
            let cut = score_draws(
                &model,
                &range,
                &plan,
                &range.draws(4, 0),
                5e-11,
                20,
                Some(Instant::now()),
                &mut |_| {},
            )
            .expect("cut short");
            assert_eq!((cut.draws.len(), cut.skipped), (1, 3));
            assert_eq!(
                format!(
                    "{:?}",
                    scored(&model, cut.draws.into_iter().next().expect("one"))
                ),
                format!("{:?}", old[0])
            );
            assert_eq!(old.len(), new.draws.len());
            for (a, b) in old.iter().zip(new.draws) {
                match (a, scored(&model, b)) {
                    (Draw::Failed(x), Draw::Failed(y)) => {
                        assert_eq!(x, &y);
                        counts.0 += 1;
                    }
                    (Draw::Scored { rel: r1, lost: l1 }, Draw::Scored { rel: r2, lost: l2 }) => {
                        assert_eq!(l1, &l2);
                        counts.2 += l2.len();
                        assert_eq!(r1.len(), r2.len());
                        for ((n1, x), (n2, y)) in r1.iter().zip(&r2) {
                            assert_eq!(n1, n2);
                            assert!((x - y).abs() <= 1e-6 * x.abs(), "{n1}: {x:e} vs {y:e}");
                        }
                        counts.1 += 1;
                    }
                    (x, y) => panic!("{x:?} vs {y:?}"),
                }
            }
        }
        println!("failed, scored, levels lost: {counts:?}");
        assert!(counts.1 > 0, "{counts:?}");
    }
}

//! `harmonid.plan` and `harmonid.evaluate_plan`: drive-tone planning (`harmonid plan`,
//! `harmonid_plan`): design a plan, or score one, by the Cramér–Rao bounds of the model's
//! unknowns.

use crate::convert::json_to_py;
use crate::errors::{render, PlanError};
use crate::model::Model;
use crate::values::{guess_spread, guess_values};
use harmonid_data::Point;
use harmonid_experiment::Plan;
use harmonid_plan::{DesignSettings, Evaluation, GuessRange};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A measurement plan from Python: the path of a plan TOML file, a dict in its layout
/// (`docs/simulation.md`) or a `PlanResult` (its plan). Errors, with their location, are
/// raised as `err`'s exception.
pub fn plan_from(
    py: Python<'_>,
    plan: &Bound<'_, PyAny>,
    err: fn(String) -> PyErr,
) -> PyResult<Plan> {
    if let Ok(r) = plan.cast::<PlanResult>() {
        return Ok(r.get().plan.clone());
    }
    if plan.is_instance_of::<PyDict>() {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (plan,))?
            .extract()?;
        let p: Plan = serde_json::from_str(&text).map_err(|e| {
            err(format!(
                "plan: {e}; expected the plan file's layout (docs/simulation.md)"
            ))
        })?;
        p.check("plan").map_err(|e| err(render(&e)))?;
        return Ok(p);
    }
    let path: PathBuf = plan.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "plan: expected a dict, a PlanResult or the path of a plan TOML file",
        )
    })?;
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(&path)
        .map_err(|e| err(format!("cannot read the plan {origin}: {e}")))?;
    Plan::from_toml(&text, &origin).map_err(|e| err(render(&e)))
}

/// The guess and, unless `nominal`, its range (the values' uncertainties, defaults for the
/// rest), as `harmonid plan` builds them: the design and the scores are at the range's guess.
fn guess_range(
    py: Python<'_>,
    model: &Model,
    values: &Bound<'_, PyAny>,
    nominal: bool,
) -> PyResult<(harmonid_sim::ModelValues, Option<GuessRange>)> {
    let guess = guess_values(py, &model.inner, values)?;
    if nominal {
        return Ok((guess, None));
    }
    let spread = guess_spread(py, values)?;
    let range = GuessRange::new(&model.inner, &guess, &spread)
        .map_err(|e| PlanError::new_err(render(&e)))?;
    Ok((range.guess().clone(), Some(range)))
}

fn plan_error(msg: String) -> PyErr {
    PlanError::new_err(msg)
}

/// Checks the noise σ (m) and the shots as the command line does.
fn check_noise(noise_m: f64, shots: usize) -> PyResult<()> {
    if !(noise_m.is_finite() && noise_m > 0.0) {
        return Err(PlanError::new_err(format!(
            "noise_m = {noise_m}: expected a positive per-quadrature σ in metres, e.g. 5e-11 (0.05 nm)"
        )));
    }
    if shots == 0 {
        return Err(PlanError::new_err("shots must be at least 1"));
    }
    Ok(())
}

/// Designs a drive-tone plan for `model` at the guessed `values`, as `harmonid plan MODEL
/// --values V --noise σ --shots N --out plan.toml` does (`docs/planning.md`): per mode a tone
/// pair near its resonance driven just below its fold, then measurements with the modes each
/// coupling parameter joins, every tone on the instrument grid.
///
/// `values`: a dict in the values file's layout, the path of a values TOML or result JSON, or
/// an `IdentifyResult` (the guess). `noise_m`: per-quadrature σ of every lock-in amplitude, m;
/// `shots`: shots per measurement. Limits: `max_frequencies` measured lines per measurement
/// (`--max-frequencies`), `max_measurements` (`--max-measurements`), `bandwidth_hz` the
/// instrument grid (`--bandwidth`), `max_force` N/kg per tone (`--max-force`), `points` a list
/// of `{mode: shape}` dicts, one per measurement point (`--point`; default: modal amplitudes).
/// The design is checked over the guess's range, as the command line's: the uncertainties a
/// values file or result gives, defaults for the rest (a dict gives none); `nominal=True`
/// designs at the guess alone (`--nominal`), `draws` devices of the range score it (`--draws`).
/// `ladder`: each measurement's drive ladder, fractions of its forces (`--ladder`; default
/// `[0.5, 0.75, 1.0]` over a range, none with `nominal=True`; `[1.0]` for none).
///
/// `gains`: actuator gains by mode, N/kg per V (`--gain q1=0.8`): the plan's drive levels are
/// then volts; `max_voltage` caps them (`--max-voltage`: per tone, or the tones' sum on the
/// one output with an instrument). `instrument`: `"mfli"`, `"mfli-mf"`, `"hf2li"`, `"uhfli"`,
/// `"moku"` or `"generic"` (`--instrument`; needs `gains`): the plan held to the lock-in's
/// oscillators, demodulators and output, with its `[instrument]` settings per level (the
/// filter order of `filter_order`, `--filter-order`, else the fastest to settle).
///
/// Returns a `PlanResult` (`.toml`, `.plan`, `.bounds`, ...). Raises `PlanError` when an
/// unknown cannot be identified within the limits, the budget is too small or a drive passes a
/// fold; values the simulation cannot use raise `SimulationError`. Runs without holding the
/// GIL: a design simulates every candidate (0.2 s for one mode, minutes for the two-mode
/// nanostring).
#[pyfunction]
#[pyo3(signature = (model, values, noise_m, shots = 1, *, max_frequencies = 32, max_measurements = None, bandwidth_hz = 0.5, max_force = None, points = None, nominal = false, draws = harmonid_plan::DEFAULT_DRAWS, ladder = None, gains = None, max_voltage = None, instrument = None, filter_order = None))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn plan(
    py: Python<'_>,
    model: &Model,
    values: &Bound<'_, PyAny>,
    noise_m: f64,
    shots: usize,
    max_frequencies: usize,
    max_measurements: Option<usize>,
    bandwidth_hz: f64,
    max_force: Option<f64>,
    points: Option<Vec<BTreeMap<String, f64>>>,
    nominal: bool,
    draws: usize,
    ladder: Option<Vec<f64>>,
    gains: Option<BTreeMap<String, f64>>,
    max_voltage: Option<f64>,
    instrument: Option<&str>,
    filter_order: Option<u32>,
) -> PyResult<PlanResult> {
    let lockin: harmonid_plan::LockIn = instrument
        .unwrap_or("generic")
        .parse()
        .map_err(PlanError::new_err)?;
    let inst = harmonid_plan::InstrumentSettings {
        lockin,
        max_voltage,
        filter_order,
    };
    inst.checked()
        .map_err(|e| PlanError::new_err(e.to_string()))?;
    let (values, range) = guess_range(py, model, values, nominal)?;
    check_noise(noise_m, shots)?;
    let ladder = ladder.unwrap_or_else(|| harmonid_plan::default_ladder(range.is_some()));
    let settings = DesignSettings {
        sigma_m: noise_m,
        shots,
        max_frequencies,
        max_measurements,
        grid_hz: bandwidth_hz,
        max_force: max_force.unwrap_or(f64::INFINITY),
        gains: gains.unwrap_or_default(),
        max_voltage,
        // Python callers bound the work themselves.
        time_budget_s: None,
        points: points
            .unwrap_or_default()
            .into_iter()
            .enumerate()
            .map(|(i, shape)| Point {
                name: format!("p{i}"),
                shape,
            })
            .collect(),
        range,
        draws,
        ladder,
    };
    let m = std::sync::Arc::clone(&model.inner);
    let (plan, ev) = py
        .detach(|| {
            harmonid_plan::design_for_instrument(&m, &values, &settings, &inst, &mut |_| {})
                .map_err(|e| e.to_string())
        })
        .map_err(PlanError::new_err)?;
    PlanResult::new(plan, &ev)
}

/// Scores `plan` (the path of a plan TOML file, a dict in its layout, or a `PlanResult`) for
/// `model` at the guessed `values`, as `harmonid plan MODEL --values V --noise σ --shots N
/// --evaluate plan.toml` does: every measurement simulated noise-free, the Fisher information
/// of `shots` shots with per-quadrature noise `noise_m` (m) summed, its inverse the bounds.
///
/// Returns a `PlanResult` whose `.bounds` is the `--bounds` file (relative bounds per mode and
/// parameter, None where not identifiable) and `.findings` what the plan cannot determine.
/// Raises `PlanError` (a plan file's error with its line and caret, a drive that passes a
/// fold, an unstable state). Runs without holding the GIL.
#[pyfunction]
#[pyo3(signature = (model, values, plan, noise_m, shots = 1, *, nominal = false, draws = harmonid_plan::DEFAULT_DRAWS))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn evaluate_plan(
    py: Python<'_>,
    model: &Model,
    values: &Bound<'_, PyAny>,
    plan: &Bound<'_, PyAny>,
    noise_m: f64,
    shots: usize,
    nominal: bool,
    draws: usize,
) -> PyResult<PlanResult> {
    let (values, range) = guess_range(py, model, values, nominal)?;
    let plan = plan_from(py, plan, plan_error)?;
    check_noise(noise_m, shots)?;
    let m = std::sync::Arc::clone(&model.inner);
    let ev = py
        .detach(|| {
            let mut ev = harmonid_plan::evaluate(&m, &values, &plan, noise_m, shots)?;
            if let Some(r) = &range {
                ev.robustness = Some(harmonid_plan::robustness(
                    &m, r, &plan, noise_m, shots, draws,
                )?);
            }
            Ok::<_, harmonid_plan::PlanError>(ev)
        })
        .map_err(|e| PlanError::new_err(e.to_string()))?;
    PlanResult::new(plan, &ev)
}

/// A plan and its score: what `harmonid plan` writes (`--out`, `--bounds`) and prints.
///
/// `toml` is the plan file's text (what `simulate` and `evaluate_plan` read; `plan` is the
/// same as a dict); `bounds` the `--bounds` file: `{"modes": {"q1": {"f_hz": rel, "Q": rel}},
/// "parameters": {"beta1": rel}}`, relative one-sigma Cramér–Rao bounds for the plan's shots
/// (None: not identifiable); `quantities` the absolute ones: `{"f_hz:q1": {"value", "std",
/// "rel"}, ...}` (Hz for frequencies); `findings` the unknowns the plan cannot determine, each
/// `{"unknown", "reason", "suggestion"}`; `table()` the printed table.
#[pyclass(module = "harmonid._harmonid", frozen)]
pub struct PlanResult {
    plan: Plan,
    toml: String,
    /// `{"plan", "bounds", "quantities", "findings", "condition", "shots"}`.
    json: Value,
    table: String,
}

impl PlanResult {
    fn new(plan: Plan, ev: &Evaluation) -> PyResult<Self> {
        let num = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
        let quantities: serde_json::Map<String, Value> = ev
            .bounds
            .quantities
            .iter()
            .map(|b| {
                let q = json!({"value": num(b.value), "std": num(b.std), "rel": num(b.rel)});
                (b.name.clone(), q)
            })
            .collect();
        let findings: Vec<Value> = ev
            .findings
            .iter()
            .map(|f| json!({"unknown": f.unknown, "reason": f.reason, "suggestion": f.suggestion}))
            .collect();
        let json = json!({
            "plan": serde_json::to_value(&plan)
                .map_err(|e| PlanError::new_err(format!("the plan does not convert: {e}")))?,
            "bounds": ev.to_json(),
            "quantities": quantities,
            "findings": findings,
            "condition": num(ev.bounds.condition),
            "shots": ev.bounds.shots,
        });
        Ok(PlanResult {
            toml: plan.to_toml(),
            plan,
            json,
            table: ev.table(),
        })
    }

    fn part<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, self.json.get(key).unwrap_or(&Value::Null))
    }
}

#[pymethods]
impl PlanResult {
    /// The plan file's text (TOML; what `harmonid plan --out` writes).
    #[getter]
    fn toml(&self) -> &str {
        &self.toml
    }

    /// The plan as a dict in the plan file's layout (`simulate` and `evaluate_plan` take it).
    #[getter]
    fn plan<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "plan")
    }

    /// Relative one-sigma bounds, the `--bounds` file: `{"modes": {mode: {"f_hz", "Q"}},
    /// "parameters": {name: rel}}` (None: not identifiable).
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "bounds")
    }

    /// Absolute bounds: `{"f_hz:q1": {"value", "std", "rel"}, "Q:q1": ..., "beta1": ...}`.
    #[getter]
    fn quantities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "quantities")
    }

    /// Unknowns the plan cannot determine: `[{"unknown", "reason", "suggestion"}]`.
    #[getter]
    fn findings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "findings")
    }

    /// Condition number of the scaled Fisher information.
    #[getter]
    fn condition<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "condition")
    }

    /// Shots per measurement the bounds are for.
    #[getter]
    fn shots<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "shots")
    }

    /// The table `harmonid plan` prints: quantity, value, bound, relative bound; findings.
    fn table(&self) -> &str {
        &self.table
    }

    fn __repr__(&self) -> String {
        let worst = self
            .json
            .get("quantities")
            .and_then(Value::as_object)
            .and_then(|q| {
                q.iter()
                    .filter_map(|(n, b)| Some((n, b.get("rel")?.as_f64()?)))
                    .max_by(|a, b| a.1.total_cmp(&b.1))
            });
        match worst {
            Some((n, r)) => format!(
                "PlanResult({} measurements, worst relative bound {n} {r:.3e})",
                self.plan.measurements.len()
            ),
            None => format!("PlanResult({} measurements)", self.plan.measurements.len()),
        }
    }
}

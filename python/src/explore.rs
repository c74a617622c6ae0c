//! `harmonid.states`: every steady state of a model at one drive or pump (`harmonid states`),
//! by the total-degree homotopy of `harmonid_explore`, each continued onto the full lattice;
//! `harmonid.phase_diagram`: their counts over a plane (`harmonid phase-diagram`).

use crate::errors::SimulationError;
use crate::linear_response::{excitation, pump_tones};
use crate::model::Model;
use crate::sweep::numeric_model;
use harmonid_explore::{Continued, StatesSettings};
use harmonid_sim::Excitation;
use numpy::{IntoPyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

/// Every steady state of `model` with `values` under one drive tone (`drives={"q1": [Hz]}`,
/// `force={"q1": N/kg}`, peak) and/or a pump (`pumps=[(Hz, level[, phase_rad])]`), as
/// `harmonid states --json` gives them: a dict with `tone_hz`, `paths`, `complex_solutions`,
/// `at_infinity`, `failed` and `states`, each state a dict with `amplitudes` (complex numpy
/// array, m, one per mode, `Re[X e^{i2πft}]` at the tone), `stable`, `eigenvalues` (the
/// slow-flow eigenvalues, 1/s, complex numpy array) and, with `lattice=True`, `lattice`:
/// `{"continued": True, "stable", "growth_rate", "shift", "same_as"}` or `{"continued":
/// False, "why"}`.
#[pyfunction]
#[pyo3(signature = (model, values, *, drives = BTreeMap::new(), force = BTreeMap::new(), pumps = Vec::new(), lattice = true))]
pub fn states<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    drives: BTreeMap<String, Vec<f64>>,
    force: BTreeMap<String, f64>,
    pumps: Vec<Vec<f64>>,
    lattice: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let nm = numeric_model(model, values)?;
    let pumps = pump_tones(&pumps)?;
    let drive = match excitation(&nm, &drives, &force, &pumps)? {
        Some(d) => d,
        None if !pumps.is_empty() => Excitation {
            tones_hz: vec![],
            force: vec![vec![]; nm.n_modes()],
            pumps,
        },
        None => {
            return Err(SimulationError::new_err(
                "no excitation: a steady state needs drives={\"q1\": [Hz]} with force=, or pumps=[(Hz, level)]",
            ))
        }
    };
    let settings = StatesSettings {
        lattice,
        ..StatesSettings::default()
    };
    let s = py
        .detach(|| harmonid_explore::states(&nm, &drive, &settings))
        .map_err(|e| SimulationError::new_err(e.to_string()))?;
    let out = PyDict::new(py);
    out.set_item("tone_hz", s.tone_hz)?;
    out.set_item("paths", s.paths)?;
    out.set_item("complex_solutions", s.complex_solutions)?;
    out.set_item("at_infinity", s.at_infinity)?;
    out.set_item("failed", s.failed)?;
    let list = pyo3::types::PyList::empty(py);
    for st in &s.states {
        let d = PyDict::new(py);
        d.set_item("amplitudes", st.amplitudes.clone().into_pyarray(py))?;
        d.set_item("stable", st.stable)?;
        d.set_item(
            "oscillatory",
            harmonid_explore::unstable_through_complex_pair(&nm, &st.eigenvalues),
        )?;
        d.set_item("eigenvalues", st.eigenvalues.clone().into_pyarray(py))?;
        let l = PyDict::new(py);
        match &st.lattice {
            Continued::NotAsked => {}
            Continued::Yes {
                stable,
                growth_rate,
                eigenvalues,
                shift,
                same_as,
                ..
            } => {
                l.set_item("continued", true)?;
                l.set_item("stable", stable)?;
                l.set_item("growth_rate", growth_rate)?;
                l.set_item("eigenvalues", eigenvalues.clone().into_pyarray(py))?;
                l.set_item("shift", shift)?;
                l.set_item("same_as", same_as)?;
            }
            Continued::No { why } => {
                l.set_item("continued", false)?;
                l.set_item("why", why)?;
            }
        }
        if !matches!(st.lattice, Continued::NotAsked) {
            d.set_item("lattice", l)?;
        }
        list.append(d)?;
    }
    out.set_item("states", list)?;
    Ok(out)
}

/// `(axis, from, to, n)` of `phase_diagram`'s `x` or `y`.
fn axis_range(t: &(String, f64, f64, usize)) -> harmonid_explore::AxisRange {
    harmonid_explore::AxisRange {
        axis: t
            .0
            .parse()
            .unwrap_or_else(|e: std::convert::Infallible| match e {}),
        from: t.1,
        to: t.2,
        n: t.3,
    }
}

/// The phase diagram of `model` with `values` over `x` and `y`, each `(axis, from, to, n)`
/// with axis `"freq"` (the drive tone), `"force:q1"`, `"pump_hz"`, `"pump_level"` or a
/// parameter's name, under the drive and pumps given as for [`states`], as `harmonid
/// phase-diagram` computes it: a dict with `x` and `y` (numpy), `stable` and `unstable`
/// (numpy int arrays of shape `(len(y), len(x))`, -1 where `time_budget` (s) left a row out),
/// `generic_count` and `complete`. Counts are of the single-harmonic states.
#[pyfunction]
#[pyo3(signature = (model, values, x, y, *, drives = BTreeMap::new(), force = BTreeMap::new(), pumps = Vec::new(), time_budget = None))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn phase_diagram<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    x: (String, f64, f64, usize),
    y: (String, f64, f64, usize),
    drives: BTreeMap<String, Vec<f64>>,
    force: BTreeMap<String, f64>,
    pumps: Vec<Vec<f64>>,
    time_budget: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let mv = crate::values::model_values(py, values)?;
    let nm = numeric_model(model, values)?;
    let pumps = pump_tones(&pumps)?;
    let drive = match excitation(&nm, &drives, &force, &pumps)? {
        Some(d) => d,
        None => Excitation {
            tones_hz: vec![],
            force: vec![vec![]; nm.n_modes()],
            pumps,
        },
    };
    let (xr, yr) = (axis_range(&x), axis_range(&y));
    let settings = harmonid_explore::PhaseSettings {
        time_budget_s: time_budget,
        ..harmonid_explore::PhaseSettings::default()
    };
    let inner = &model.inner;
    let d = py
        .detach(|| {
            let problem = harmonid_explore::Problem {
                model: inner,
                values: &mv,
                drive: &drive,
            };
            harmonid_explore::phase_diagram(&problem, &xr, &yr, &settings, &|_| {})
        })
        .map_err(|e| SimulationError::new_err(e.to_string()))?;
    let (nx, ny) = (d.x.len(), d.y.len());
    let count = |f: fn(&harmonid_explore::Count) -> u32| -> Vec<i64> {
        d.counts
            .iter()
            .map(|c| c.as_ref().map_or(-1, |c| i64::from(f(c))))
            .collect()
    };
    let out = PyDict::new(py);
    out.set_item("x", d.x.clone().into_pyarray(py))?;
    out.set_item("y", d.y.clone().into_pyarray(py))?;
    out.set_item(
        "stable",
        count(|c| c.stable).into_pyarray(py).reshape([ny, nx])?,
    )?;
    out.set_item(
        "unstable",
        count(|c| c.unstable).into_pyarray(py).reshape([ny, nx])?,
    )?;
    out.set_item(
        "oscillatory",
        count(|c| c.oscillatory)
            .into_pyarray(py)
            .reshape([ny, nx])?,
    )?;
    out.set_item("generic_count", d.generic_count)?;
    out.set_item("complete", d.complete)?;
    Ok(out)
}

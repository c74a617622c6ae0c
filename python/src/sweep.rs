//! `harmonid.sweep`: frequency-response curves with continuation through folds
//! (`harmonid sweep`), returned as numpy arrays.

use crate::errors::SimulationError;
use crate::model::Model;
use harmonid_sim::{self as sim, ModelValues, NumericModel, SweepSettings, TwoToneSettings};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

fn sim_error(e: &sim::SimError) -> PyErr {
    SimulationError::new_err(e.to_string())
}

/// Reads `values`: a dict in the layout of a values file (`{"modes": {"q1": {"f_hz": ..,
/// "Q": ..}}, "parameters": {"beta1": ..}, "eom": {..}}`) or the path of a values TOML file.
pub fn model_values(py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<ModelValues> {
    let bad = |what: String, e: String| {
        SimulationError::new_err(format!(
            "{what}: {e}; expected the values file's layout: [modes.q1] f_hz = ..., Q = ...; [parameters] beta1 = ..."
        ))
    };
    if values.is_instance_of::<PyDict>() {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (values,))?
            .extract()?;
        return serde_json::from_str(&text).map_err(|e| bad("values".into(), e.to_string()));
    }
    let path: std::path::PathBuf = values.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "values: expected a dict or the path of a values TOML file",
        )
    })?;
    let text = std::fs::read_to_string(&path).map_err(|e| {
        SimulationError::new_err(format!(
            "cannot read the values file {}: {e}",
            path.display()
        ))
    })?;
    toml::from_str(&text).map_err(|e| bad(path.display().to_string(), e.to_string()))
}

/// The model evaluated with `values` (see [`model_values`]).
pub fn numeric_model(model: &Model, values: &Bound<'_, PyAny>) -> PyResult<NumericModel> {
    let values = model_values(values.py(), values)?;
    NumericModel::from_model(&model.inner, &values).map_err(|e| {
        SimulationError::new_err(format!(
            "cannot evaluate {} with these values: {e}",
            model.inner.source
        ))
    })
}

/// Force per mode (N/kg, peak, phase 0) from `{mode: amplitude}`, in the model's mode order.
fn force_vector(model: &NumericModel, force: &BTreeMap<String, f64>) -> PyResult<Vec<Complex64>> {
    let mut out = vec![Complex64::new(0.0, 0.0); model.n_modes()];
    for (m, &a) in force {
        let n = model
            .mode_names
            .iter()
            .position(|x| x == m)
            .ok_or_else(|| {
                SimulationError::new_err(format!(
                    "force on `{m}`, which is not a mode ({})",
                    model.mode_names.join(", ")
                ))
            })?;
        out[n] = Complex64::new(a, 0.0);
    }
    if force.is_empty() {
        return Err(SimulationError::new_err(
            "no force given: pass force={\"q1\": 3.5} (N/kg, peak)",
        ));
    }
    Ok(out)
}

/// Single-tone sweep from `f_from_hz` to `f_to_hz` (see the Python docstring of `sweep`).
#[pyfunction]
#[pyo3(signature = (model, values, f_from_hz, f_to_hz, force, points = 2000, harmonics = 3))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn sweep_single<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    f_from_hz: f64,
    f_to_hz: f64,
    force: BTreeMap<String, f64>,
    points: usize,
    harmonics: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let nm = numeric_model(model, values)?;
    let f = force_vector(&nm, &force)?;
    let s = SweepSettings {
        f_start_hz: f_from_hz,
        f_stop_hz: f_to_hz,
        points,
        harmonics,
        ..SweepSettings::default()
    };
    let r = py
        .detach(|| sim::sweep(&nm, &f, &s))
        .map_err(|e| sim_error(&e))?;
    let (n_pts, n_modes, n_h) = (r.points.len(), nm.n_modes(), r.harmonics.len());
    let mut amps = Vec::with_capacity(n_pts * n_modes * n_h);
    for p in &r.points {
        for row in &p.amplitudes {
            amps.extend_from_slice(row);
        }
    }
    let (up, down) = r.jumps();
    let d = PyDict::new(py);
    d.set_item(
        "f_hz",
        r.points
            .iter()
            .map(|p| p.f_hz)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "stable",
        r.points
            .iter()
            .map(|p| p.stable)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "amplitudes",
        amps.into_pyarray(py).reshape([n_pts, n_modes, n_h])?,
    )?;
    d.set_item("modes", nm.mode_names.clone())?;
    d.set_item("harmonics", r.harmonics.clone())?;
    d.set_item("jumps_up_hz", up)?;
    d.set_item("jumps_down_hz", down)?;
    d.set_item(
        "folds_hz",
        r.folds.iter().map(|f| f.f_hz).collect::<Vec<_>>(),
    )?;
    d.set_item("complete", r.complete)?;
    Ok(d)
}

/// Two-tone sweep of a pair's centre, up and down (see the Python docstring of `sweep`).
#[pyfunction]
#[pyo3(signature = (model, values, f_from_hz, f_to_hz, force, spacing_hz, points = 2000))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn sweep_two_tone<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    f_from_hz: f64,
    f_to_hz: f64,
    force: BTreeMap<String, f64>,
    spacing_hz: f64,
    points: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let nm = numeric_model(model, values)?;
    let f = force_vector(&nm, &force)?;
    let s = TwoToneSettings {
        c_start_hz: f_from_hz,
        c_end_hz: f_to_hz,
        spacing_hz,
        force_low: f.clone(),
        force_high: f,
        points,
        ..TwoToneSettings::default()
    };
    let r = py
        .detach(|| sim::sweep_two_tone(&nm, &s))
        .map_err(|e| sim_error(&e))?;
    let out = PyDict::new(py);
    out.set_item("lines_offset_hz", r.lines_offset_hz.clone())?;
    out.set_item("modes", nm.mode_names.clone())?;
    for c in [&r.up, &r.down] {
        let n_lines = r.lines_offset_hz.len();
        let n = c.points.len();
        let mut amps = Vec::with_capacity(n * nm.n_modes() * n_lines);
        for p in &c.points {
            for row in &p.amplitudes {
                amps.extend_from_slice(row);
            }
        }
        let d = PyDict::new(py);
        d.set_item(
            "centre_hz",
            c.points
                .iter()
                .map(|p| p.centre_hz)
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        d.set_item(
            "stable",
            c.points
                .iter()
                .map(|p| p.stable)
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        d.set_item(
            "amplitudes",
            amps.into_pyarray(py).reshape([n, nm.n_modes(), n_lines])?,
        )?;
        d.set_item(
            "jumps_hz",
            c.jumps
                .iter()
                .map(|j| (j.from_hz, j.to_hz))
                .collect::<Vec<_>>(),
        )?;
        match &c.status {
            sim::TwoToneStatus::Complete => d.set_item("stopped", py.None())?,
            sim::TwoToneStatus::Stopped { at_hz, why } => {
                d.set_item("stopped", (*at_hz, why.to_string()))?
            }
        }
        out.set_item(if c.up { "up" } else { "down" }, d)?;
    }
    Ok(out)
}

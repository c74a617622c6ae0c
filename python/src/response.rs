//! `harmonid.response`: a stepped-sine frequency response as numpy arrays, the data of the
//! report's frequency-response figure (`harmonid_report::response`).

use crate::dataset::Dataset;
use crate::errors::{DatasetError, SimulationError};
use crate::identify::IdentifyResult;
use crate::model::Model;
use harmonid_data::result::Report;
use harmonid_report::response::{self as frf, FamilyResponse};
use harmonid_sim::NumericModel;
use num_complex::Complex64;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Puts `x` (complex, the dataset's unit) into `d` as `x`, `amplitude` and `phase_rad`.
fn put_x(d: &Bound<'_, PyDict>, prefix: &str, x: &[Complex64]) -> PyResult<()> {
    let py = d.py();
    d.set_item(format!("{prefix}x"), x.to_vec().into_pyarray(py))?;
    d.set_item(
        format!("{prefix}amplitude"),
        x.iter()
            .map(|z| z.norm())
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        format!("{prefix}phase_rad"),
        x.iter()
            .map(|z| z.arg())
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    Ok(())
}

/// The family's response as a dict of numpy arrays.
fn to_dict<'py>(py: Python<'py>, r: &FamilyResponse) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("family", &r.family.label)?;
    d.set_item("level", r.family.level)?;
    d.set_item("unit", &r.unit)?;
    d.set_item("point", &r.point)?;
    d.set_item("notes", r.notes.clone())?;
    let mut sweeps = Vec::new();
    for s in &r.sweeps {
        let sd = PyDict::new(py);
        sd.set_item("name", &s.name)?;
        sd.set_item("direction", s.direction.name())?;
        sd.set_item("steps", s.steps.clone())?;
        sd.set_item("f_hz", s.f_hz.clone().into_pyarray(py))?;
        put_x(&sd, "", &s.x)?;
        match &s.model {
            Some(m) => put_x(&sd, "model_", m)?,
            None => sd.set_item("model_x", py.None())?,
        }
        sweeps.push(sd);
    }
    d.set_item("sweeps", sweeps)?;
    match &r.model {
        Some(c) => {
            let md = PyDict::new(py);
            md.set_item("f_hz", c.f_hz.clone().into_pyarray(py))?;
            put_x(&md, "", &c.x)?;
            md.set_item("stable", c.stable.clone().into_pyarray(py))?;
            md.set_item("force", c.force.clone().into_pyarray(py))?;
            md.set_item("harmonics", c.harmonics)?;
            d.set_item("model", md)?;
        }
        None => d.set_item("model", py.None())?,
    }
    Ok(d)
}

/// The frequency response of a stepped sweep, the data of `harmonid report`'s
/// frequency-response figure: the sweep's family (every sweep of its drive level) measured and
/// as the identified model gives it.
///
/// `result` is the `IdentifyResult` of `identify(model, dataset, ...)`. Returns a dict:
/// `family` (`"level 0.1"`), `level`, `unit` (the dataset's: every `x` is in it), `point`,
/// `notes`; `sweeps`, one dict per sweep of the family with `name`, `direction`, `steps`,
/// `f_hz`, `x` (complex, the response at the drive frequency, median over shots, its phase
/// against the step's identified force), `amplitude`, `phase_rad`, and `model_x`,
/// `model_amplitude`, `model_phase_rad` (the model's steady state at each step, followed from
/// step to step as the sweep was); `model` (None without a curve): `f_hz`, `x`, `amplitude`,
/// `phase_rad`, `stable` (the curve through its folds, in arclength order), `force` (N/kg per
/// mode) and `harmonics`. Runs without holding the GIL.
#[pyfunction]
pub fn response<'py>(
    py: Python<'py>,
    model: &Model,
    result: &IdentifyResult,
    dataset: &Dataset,
    sweep: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let report: Report = serde_json::from_value(result.json.clone())
        .map_err(|e| SimulationError::new_err(format!("the result cannot be read back: {e}")))?;
    let names: Vec<String> = model
        .inner
        .mode_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    let values = harmonid_report::result::model_values(&report);
    let nm = NumericModel::from_values(&names, &values).map_err(|e| {
        SimulationError::new_err(format!("the identified model is incomplete: {e}"))
    })?;
    let ds = dataset.inner.clone();
    let r = py.detach(|| frf::sweep_response(Some(&nm), &report, &ds, sweep));
    let r = r.ok_or_else(|| {
        let names: Vec<&str> = ds
            .manifest
            .sweeps
            .iter()
            .filter(|s| frf::is_frequency_sweep(s))
            .map(|s| s.name.as_str())
            .collect();
        DatasetError::new_err(format!(
            "no single-tone frequency sweep called {sweep:?} in the dataset; its frequency sweeps: {}",
            if names.is_empty() { "none".to_string() } else { names.join(", ") }
        ))
    })?;
    to_dict(py, &r)
}

//! Parameter values for simulations and sweeps, from whatever a Python user holds: a dict in
//! the values file's layout, the path of a values file (TOML, or a result JSON), or an
//! `IdentifyResult`. Files and results are read by `harmonid_experiment`, as the command line
//! reads them.

use crate::errors::{render, SimulationError};
use crate::identify::IdentifyResult;
use harmonid_ident::Report;
use harmonid_sim::ModelValues;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Reads `values` (see the module docs).
pub fn model_values(py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<ModelValues> {
    if let Ok(r) = values.cast::<IdentifyResult>() {
        let report: Report = serde_json::from_value(r.get().json.clone())
            .map_err(|e| SimulationError::new_err(format!("the result does not read back: {e}")))?;
        return Ok(harmonid_experiment::values_from_report(&report));
    }
    if values.is_instance_of::<PyDict>() {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (values,))?
            .extract()?;
        return serde_json::from_str(&text).map_err(|e| {
            SimulationError::new_err(format!(
                "values: {e}; expected the values file's layout: {{\"modes\": {{\"q1\": {{\"f_hz\": ..., \"Q\": ...}}}}, \"parameters\": {{\"beta1\": ...}}}}"
            ))
        });
    }
    let path: PathBuf = values.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "values: expected a dict, an IdentifyResult, or the path of a values TOML file or result JSON",
        )
    })?;
    py.detach(|| harmonid_experiment::read_values(&path).map_err(|e| render(&e)))
        .map_err(SimulationError::new_err)
}

/// The uncertainties `values` gives with its values, by quantity name: a values file's
/// (`beta1 = { value = .., factor = 2 }`), an identification's (its estimates ± 3 standard
/// errors); none for a dict.
pub fn guess_spread(
    py: Python<'_>,
    values: &Bound<'_, PyAny>,
) -> PyResult<BTreeMap<String, harmonid_experiment::Spread>> {
    if let Ok(r) = values.cast::<IdentifyResult>() {
        let report: Report = serde_json::from_value(r.get().json.clone())
            .map_err(|e| SimulationError::new_err(format!("the result does not read back: {e}")))?;
        return Ok(harmonid_experiment::guess_from_report(&report).spread);
    }
    if values.is_instance_of::<PyDict>() {
        return Ok(BTreeMap::new());
    }
    let path: PathBuf = values.extract()?;
    py.detach(|| harmonid_experiment::read_guess(&path).map_err(|e| render(&e)))
        .map(|g| g.spread)
        .map_err(SimulationError::new_err)
}

/// [`model_values`] for planning, which needs the parameters themselves: those a `truth.toml`
/// (or a per-equation result) gives only as `[eom]` coefficients are solved from them, as
/// `harmonid plan --values` does.
pub fn guess_values(
    py: Python<'_>,
    model: &harmonid_model::Model,
    values: &Bound<'_, PyAny>,
) -> PyResult<ModelValues> {
    let given = model_values(py, values)?;
    match harmonid_experiment::parameters_from_eom(model, &given, "values") {
        Ok(Some(d)) => Ok(d.values),
        Ok(None) => Ok(given),
        Err(e) => Err(SimulationError::new_err(render(&e))),
    }
}

//! `harmonid.compare` and `harmonid.discover`: which model, and which terms, the data support
//! (`harmonid compare`, `harmonid discover`).

use crate::convert::json_to_py;
use crate::dataset::Dataset;
use crate::errors::HarmonidError;
use crate::identify::{force_model, IdentifyResult};
use crate::model::Model;
use harmonid_ident::{DiscoverSettings, Library, LibraryForm, Settings};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::Value;

/// `background=`: `"drive"`, `"slope"`, `"constant"` or several joined by commas (as
/// `--background`); `None` fits none.
fn background(b: Option<String>) -> PyResult<harmonid_ident::Background> {
    match b {
        None => Ok(harmonid_ident::Background::default()),
        Some(b) => b
            .parse()
            .map_err(|e| HarmonidError::new_err(format!("background={b:?}: {e}"))),
    }
}

fn parse(json: &str) -> PyResult<Value> {
    serde_json::from_str(json)
        .map_err(|e| HarmonidError::new_err(format!("harmonid wrote invalid JSON: {e}")))
}

/// Fits `dataset` by every model of `models` (pairs `(name, Model)`, or a dict name → Model)
/// and compares them, as `harmonid compare DATASET MODEL...` does: a dict equal to its
/// `--json` (`observations`, `models` with `unknowns`, `chi2`, `chi2_per_dof`, `fits`,
/// `p_value`, `log_likelihood`, `aic`, `bic`, `delta_aic`, `delta_bic`, with `holdout` also
/// `holdout_relative_rms`, `holdout_rms_sigma`; `nested` likelihood-ratio tests; `best`;
/// `ranked_by`; `verdict`). `force_model` as for `identify`; `holdout` (names of measurements or
/// sweeps) fits every model without them and reports how well each predicts them;
/// `error_floor=True` fits a floor to every model and ranks by that prediction (it needs
/// `holdout`); `background` (`"drive"`, `"slope"`, `"constant"`, joined by commas) fits a
/// measurement background with every model, as `--background`.
#[pyfunction]
#[pyo3(signature = (dataset, models, *, force_model = "auto", holdout = Vec::new(), error_floor = false, background = None))]
pub fn compare<'py>(
    py: Python<'py>,
    dataset: &Dataset,
    models: Vec<(String, PyRef<'py, Model>)>,
    force_model: &str,
    holdout: Vec<String>,
    error_floor: bool,
    background: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings = Settings {
        force_model: self::force_model(force_model)?,
        error_floor,
        background: self::background(background)?,
        ..Settings::default()
    };
    let models: Vec<(String, harmonid_model::Model)> = models
        .iter()
        .map(|(name, m)| (name.clone(), (*m.inner).clone()))
        .collect();
    let ds = std::sync::Arc::clone(&dataset.inner);
    let json = py
        .detach(|| {
            harmonid_ident::compare_with_holdout(&models, &ds, &holdout, &settings)
                .map(|c| c.to_json())
        })
        .map_err(|e| HarmonidError::new_err(e.to_string()))?;
    json_to_py(py, &parse(&json)?)
}

/// Which candidate terms the data support, as `harmonid discover DATASET MODEL --degrees ...`
/// does: from `model`, the library of every monomial of the equation degrees `degrees`, per
/// equation or (`potential=True`) as potential terms, with (`velocities=True`) every monomial
/// holding a velocity per equation (nonlinear damping), with (`nonsmooth=True`) each mode's
/// `abs(q)*q`, `abs(d(q))*d(q)` and `sign(d(q))` in its own equation (then `degrees` may be
/// empty: that family alone); `alpha` the family-wise error per step,
/// `max_terms` the most additions. `holdout` (names of measurements or sweeps) selects terms
/// by how well the fit of the rest predicts them instead: a term is added when it lowers their
/// relative RMS by more than the fraction `min_improvement`; `error_floor=True` fits a floor to
/// every model (it needs `holdout`); `background` as for `compare`. Returns a dict: `candidates`, `steps` (each `action`,
/// `parameter`, `term`, `among`, `value`, and `delta_chi2`, `p_value` or, with `holdout`,
/// `holdout_rms_before`, `holdout_rms_after`), `fits`, `selected_by` (`"chi2"` or
/// `"holdout"`), with `holdout` also `held_out` and `holdout_relative_rms`, `model` (the
/// selected `Model`), `source` (its model file's text) and `result` (its `IdentifyResult`).
#[pyfunction]
#[pyo3(signature = (model, dataset, degrees, *, potential = false, alpha = 0.01, max_terms = 10, force_model = "auto", velocities = false, holdout = Vec::new(), error_floor = false, min_improvement = 0.05, background = None, nonsmooth = false))]
#[allow(clippy::too_many_arguments)]
pub fn discover<'py>(
    py: Python<'py>,
    model: &Model,
    dataset: &Dataset,
    degrees: Vec<u32>,
    potential: bool,
    alpha: f64,
    max_terms: usize,
    force_model: &str,
    velocities: bool,
    holdout: Vec<String>,
    error_floor: bool,
    min_improvement: f64,
    background: Option<String>,
    nonsmooth: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let settings = DiscoverSettings {
        identify: Settings {
            force_model: self::force_model(force_model)?,
            jackknife: false,
            error_floor,
            background: self::background(background)?,
            ..Settings::default()
        },
        alpha,
        max_added: max_terms,
        holdout,
        min_improvement,
    };
    let library = Library {
        degrees,
        form: if potential {
            LibraryForm::Potential
        } else {
            LibraryForm::Equation
        },
        velocities,
        nonsmooth,
    };
    let (m, ds) = (
        std::sync::Arc::clone(&model.inner),
        std::sync::Arc::clone(&dataset.inner),
    );
    let found = py
        .detach(|| harmonid_ident::discover(&m, &ds, &library, &settings, |_, _| {}))
        .map_err(|e| HarmonidError::new_err(e.to_string()))?;
    let out = PyDict::new(py);
    let steps = parse(&found.to_json())?;
    for key in [
        "candidates",
        "steps",
        "fits",
        "selected_by",
        "held_out",
        "holdout_relative_rms",
    ] {
        if let Some(v) = steps.get(key) {
            out.set_item(key, json_to_py(py, v)?)?;
        }
    }
    let source = found.model_source(&ds.dir.display().to_string(), &m.source);
    out.set_item("source", &source)?;
    let summary = found.result.summary(ds.truth.as_ref());
    out.set_item("model", Model::new(found.model)?)?;
    out.set_item("result", IdentifyResult::new(found.result, summary)?)?;
    Ok(out)
}

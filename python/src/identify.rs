//! `harmonid.identify`: the model's unknowns from a dataset (`docs/identification.md`), and the
//! result object.

use crate::convert::json_to_py;
use crate::dataset::Dataset;
use crate::errors::{ident_error, HarmonidError};
use crate::model::Model;
use harmonid_ident::{Background, Estimator, ForceModel, Report, Settings};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyDict;
use serde_json::Value;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

pub(crate) fn force_model(name: &str) -> PyResult<ForceModel> {
    name.parse::<ForceModel>()
        .map_err(|e| HarmonidError::new_err(format!("force_model={name:?}: {e}")))
}

fn estimator(name: &str) -> PyResult<Estimator> {
    name.parse::<Estimator>()
        .map_err(|e| HarmonidError::new_err(format!("estimator={name:?}: {e}")))
}

/// Identifies `model`'s unknowns from `dataset` (sequential stages unless `joint`), exactly as
/// `harmonid identify MODEL DATASET` does with the matching options:
///
/// - `joint`: fit everything in one problem (`--joint`);
/// - `force_model`: `"auto"` (drive levels when the manifest gives them), `"free"`
///   (`--free-forces`), `"gain_per_measurement"`, `"gain_per_mode"` (`--gain-per-mode`);
/// - `nominal_hz`: `{mode: Hz}` overriding the dataset's and the model's (`--nominal`);
/// - `near_rel`: how close (relative) a drive tone must be to a resonance (`--near-rel`);
/// - `unweighted`: no weights from the scatter across shots (`--unweighted`);
/// - `estimator`: `"ml"` (default), output-error maximum likelihood by harmonic balance on the
///   pooled shots (falls back to `"linear"` with a warning when the model cannot be
///   simulated), or `"linear"`, the equation-error fit of the pooled shots (`--estimator`);
/// - `crlb`: also compute the Cramér–Rao bound of every quantity at the estimate (`--crlb`;
///   `result.crlb`);
/// - `error_floor`: add an error floor to the shot noise, estimated with the fit
///   (`--error-floor`; `result.goodness_of_fit["error_floor"]`, and no p-value);
/// - `background`: a measurement background fitted with the model, `"drive"`, `"slope"`,
///   `"constant"` or several joined by commas (`"drive,slope"`; `--background`): per mode on
///   every measured drive line, `B·D + S·D·(f − f_ref) + C` (D the drive level and phase), in
///   the data's unit; `result.background`;
/// - `holdout`: measurement names to leave out of the fit (or a sweep's, or the input file or
///   label an imported sweep came from); the result's `holdout` says how well the estimate
///   predicts them (`--holdout`);
/// - `rank_tol`, `gls`, `gls_iterations`, `sample_covariance`: the library's settings
///   (`Settings` in `harmonid_ident`); None keeps the documented default.
///
/// Runs without holding the GIL. Returns an `IdentifyResult`.
#[pyfunction]
#[pyo3(signature = (model, dataset, *, joint = false, force_model = "auto", nominal_hz = None, near_rel = None, unweighted = false, estimator = "ml", crlb = false, error_floor = false, background = None, rank_tol = None, gls = None, gls_iterations = None, sample_covariance = None, holdout = None))]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    model: &Model,
    dataset: &Dataset,
    joint: bool,
    force_model: &str,
    nominal_hz: Option<BTreeMap<String, f64>>,
    near_rel: Option<f64>,
    unweighted: bool,
    estimator: &str,
    crlb: bool,
    error_floor: bool,
    background: Option<String>,
    rank_tol: Option<f64>,
    gls: Option<bool>,
    gls_iterations: Option<usize>,
    sample_covariance: Option<bool>,
    holdout: Option<Vec<String>>,
) -> PyResult<IdentifyResult> {
    let mut nominal = BTreeMap::new();
    for (name, hz) in nominal_hz.unwrap_or_default() {
        if model.inner.mode_index(&name).is_none() {
            return Err(HarmonidError::new_err(format!(
                "nominal_hz: the model declares no mode \"{name}\" (modes: {})",
                model.inner.mode_names().join(", ")
            )));
        }
        if !(hz.is_finite() && hz > 0.0) {
            return Err(HarmonidError::new_err(format!(
                "nominal_hz[\"{name}\"] = {hz} is not a positive frequency in Hz"
            )));
        }
        nominal.insert(name, hz);
    }
    // Field by field from the defaults, so settings the library adds keep their defaults.
    let mut settings = Settings {
        force_model: self::force_model(force_model)?,
        joint,
        nominal_hz: nominal,
        estimator: self::estimator(estimator)?,
        crlb,
        error_floor,
        ..Settings::default()
    };
    if let Some(b) = background {
        settings.background = b
            .parse::<Background>()
            .map_err(|e| HarmonidError::new_err(format!("background={b:?}: {e}")))?;
    }
    if let Some(x) = near_rel {
        settings.near_rel = x;
    }
    if unweighted {
        settings.min_shots_for_weights = 0;
    }
    if let Some(x) = rank_tol {
        settings.rank_tol = x;
    }
    if let Some(x) = gls {
        settings.gls = x;
    }
    if let Some(x) = gls_iterations {
        settings.gls_iterations = x;
    }
    if let Some(x) = sample_covariance {
        settings.sample_covariance = x;
    }
    let (m, ds) = (Arc::clone(&model.inner), Arc::clone(&dataset.inner));
    let (report, summary) = py
        .detach(|| {
            let held = holdout.unwrap_or_default();
            let result = if held.is_empty() {
                harmonid_ident::identify(&m, &ds, &settings)
            } else {
                harmonid_ident::identify_with_holdout(&m, &ds, &ds.resolve_names(&held), &settings)
            };
            result.map(|r| {
                let s = r.summary(ds.truth.as_ref());
                (r, s)
            })
        })
        .map_err(|e| ident_error(&e))?;
    IdentifyResult::new(report, summary)
}

/// The result of an identification.
///
/// `to_dict()` is the result file `harmonid identify --out` writes (`harmonid-result/1`,
/// `DATA_FORMAT.md`); `parameters` and `modes` are its parts; `per_shot` holds every shot's
/// estimate as numpy arrays (the columns of `--per-shot`); `summary()` is the printed table.
#[pyclass(module = "harmonid._harmonid", frozen)]
pub struct IdentifyResult {
    /// The result file's content (read back as a `Report` where values are taken from it).
    pub(crate) json: Value,
    /// Every shot's estimates per column, until `per_shot` first moves them into numpy (so
    /// that an identification does not import numpy unless the estimates are asked for).
    columns: Mutex<Vec<(String, Vec<f64>)>>,
    outlier: Vec<bool>,
    per_shot: PyOnceLock<Py<PyDict>>,
    summary: String,
}

impl IdentifyResult {
    pub(crate) fn new(mut report: Report, summary: String) -> PyResult<Self> {
        let json = serde_json::to_value(&report)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        let mut columns = Vec::new();
        for (n, m) in &mut report.modes {
            columns.push((format!("f_hz:{n}"), std::mem::take(&mut m.f_hz.per_shot)));
            columns.push((format!("Q:{n}"), std::mem::take(&mut m.q.per_shot)));
        }
        for (p, e) in &mut report.parameters {
            columns.push((p.clone(), std::mem::take(&mut e.per_shot)));
        }
        let outlier = (0..report.shots)
            .map(|s| report.outlier_shots.contains(&s))
            .collect();
        Ok(IdentifyResult {
            json,
            columns: Mutex::new(columns),
            outlier,
            per_shot: PyOnceLock::new(),
            summary,
        })
    }

    fn part<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, self.json.get(key).unwrap_or(&Value::Null))
    }
}

#[pymethods]
impl IdentifyResult {
    /// The result file as a dict (equal to `json.load` of `harmonid identify --out`).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    /// The result file's text (what `harmonid identify --out` writes).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.json)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))
    }

    /// `{name: {"value", "std", "stderr", ...}}` for the model's parameters.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "parameters")
    }

    /// `{mode: {"f_hz": {...}, "Q": {...}}}`.
    #[getter]
    fn modes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "modes")
    }

    /// Every monomial coefficient of every equation: `{mode: {monomial: value}}`.
    #[getter]
    fn eom<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "eom")
    }

    /// The measurement background fitted with the model (`background=`): `{mode: {"unit",
    /// "f_ref_hz", "drive", "slope", "constant"}}`, each term `{"re": {...}, "im": {...}}` with
    /// value and stderr in the data's unit (per drive unit, per Hz); `{}` without one.
    #[getter]
    fn background<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(
            py,
            self.json
                .get("background")
                .unwrap_or(&Value::Object(serde_json::Map::new())),
        )
    }

    /// Whether the model fits the data (`result.goodness_of_fit` of `docs/data-format.md`:
    /// `chi2_per_dof`, its `expected_chi2_per_dof` and spread, `p_value`, `fits`, per
    /// measurement and per line), or None for the linear estimator.
    #[getter]
    fn goodness_of_fit<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "goodness_of_fit")
    }

    /// The groups of unknowns the identification could not fit (`unfit` of the result file,
    /// `docs/data-format.md`): a list of `{"why", "unknowns", "measurements", "chi2_per_dof",
    /// "detail", "advice"}` (`why`: `"no_output_error"`, `"not_converged"`,
    /// `"group_not_fitted"`, `"not_determined"` or `"at_bound"`; `advice`: the measurement that
    /// would help), or None when every unknown was fitted and determined.
    #[getter]
    fn unfit<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "unfit")
    }

    /// Warnings (conditioning, quantities the data do not determine, ...); the first is the
    /// verdict when the model does not fit the data.
    #[getter]
    fn warnings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.part(py, "warnings")
    }

    /// Every shot's estimates: `{"f_hz:q1": array, "Q:q1": array, ..., parameter: array,
    /// "outlier": bool array}` (numpy, one entry per shot; `pandas.DataFrame(result.per_shot)`
    /// is the `--per-shot` table).
    #[getter]
    fn per_shot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = self
            .per_shot
            .get_or_try_init(py, || -> PyResult<Py<PyDict>> {
                let d = PyDict::new(py);
                let columns = std::mem::take(&mut *self.columns.lock().map_err(|_| {
                    pyo3::exceptions::PyRuntimeError::new_err("per-shot estimates unavailable")
                })?);
                for (name, v) in columns {
                    d.set_item(name, v.into_pyarray(py))?;
                }
                d.set_item("outlier", self.outlier.clone().into_pyarray(py))?;
                Ok(d.unbind())
            })?;
        Ok(d.bind(py).clone())
    }

    /// The Cramér–Rao bound of each quantity that reports one (`{"beta1": ..., "f_hz:q1": ...}`),
    /// or None when the result has none.
    #[getter]
    fn crlb<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut out = serde_json::Map::new();
        let mut take = |name: String, e: &Value| {
            if let Some(c) = e.get("crlb") {
                out.insert(name, c.clone());
            }
        };
        if let Some(Value::Object(modes)) = self.json.get("modes") {
            for (n, m) in modes {
                for key in ["f_hz", "Q"] {
                    if let Some(e) = m.get(key) {
                        take(format!("{key}:{n}"), e);
                    }
                }
            }
        }
        if let Some(Value::Object(ps)) = self.json.get("parameters") {
            for (p, e) in ps {
                take(p.clone(), e);
            }
        }
        if out.is_empty() {
            Ok(py.None().into_bound(py))
        } else {
            json_to_py(py, &Value::Object(out))
        }
    }

    /// The readable summary `harmonid identify` prints (value ± std, stages, residuals,
    /// conditioning, warnings; truth when the dataset has it).
    fn summary(&self) -> &str {
        &self.summary
    }

    fn __repr__(&self) -> String {
        let params: Vec<String> = match self.json.get("parameters") {
            Some(Value::Object(ps)) => ps
                .iter()
                .map(|(p, e)| {
                    let v = e.get("value").and_then(Value::as_f64).unwrap_or(f64::NAN);
                    let s = e.get("stderr").and_then(Value::as_f64).unwrap_or(f64::NAN);
                    format!("{p}={v:.4e}±{s:.1e}")
                })
                .collect(),
            _ => Vec::new(),
        };
        let gof = self.json.get("goodness_of_fit");
        let verdict = match gof.and_then(|g| g.get("fits")).and_then(Value::as_bool) {
            Some(false) => format!(
                "THE MODEL DOES NOT FIT THE DATA (chi2/dof {:.3e}, p {:.1e}; error bars model-limited): ",
                gof.and_then(|g| g.get("chi2_per_dof")).and_then(Value::as_f64).unwrap_or(f64::NAN),
                gof.and_then(|g| g.get("p_value")).and_then(Value::as_f64).unwrap_or(f64::NAN),
            ),
            _ => String::new(),
        };
        format!("IdentifyResult({verdict}{})", params.join(", "))
    }
}

//! `harmonid.Model`: a parsed and checked model (the model language, `docs/model-language.md`).

use crate::convert::{json_text_to_py, json_to_py};
use crate::errors::model_error;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::Value;
use std::path::PathBuf;
use std::sync::Arc;

/// A resonator model: modes, parameters and the exact equations of motion
///
///     q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = F_n(t)   (SI, per kg of modal mass).
///
/// Build it with `Model.from_file(path)` or `Model.from_str(text)`; a model that does not parse
/// or check raises `ModelError` whose message lists every diagnostic with file:line:column.
#[pyclass(module = "harmonid._harmonid", frozen)]
pub struct Model {
    pub(crate) inner: Arc<harmonid_model::Model>,
    /// `Model::to_json()` parsed once: the source of `modes`, `parameters` and `equations()`.
    json: Value,
}

impl Model {
    pub(crate) fn new(inner: harmonid_model::Model) -> PyResult<Self> {
        let json = serde_json::from_str(&inner.to_json())
            .map_err(|e| PyValueError::new_err(format!("harmonid wrote invalid JSON: {e}")))?;
        Ok(Model {
            inner: Arc::new(inner),
            json,
        })
    }
}

#[pymethods]
impl Model {
    /// Reads and checks the model file at `path` (`*.hb`).
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let m = py
            .detach(|| harmonid_model::load(&path))
            .map_err(|e| model_error(&e))?;
        Model::new(m)
    }

    /// Parses and checks model text; `origin` names it in error messages and results.
    #[staticmethod]
    #[pyo3(signature = (text, origin = "<string>"))]
    fn from_str(py: Python<'_>, text: &str, origin: &str) -> PyResult<Self> {
        let m = py
            .detach(|| harmonid_model::parse_str(text, origin))
            .map_err(|e| model_error(&e))?;
        Model::new(m)
    }

    /// Where the model came from (the path given to `from_file`, or `origin`).
    #[getter]
    fn source(&self) -> &str {
        &self.inner.source
    }

    /// The modes in declaration order: `{name: {"nominal_hz", "f_hz", "Q"}}` (None where the
    /// model leaves a value unknown), as `harmonid check --json` lists them.
    #[getter]
    fn modes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        if let Some(Value::Array(modes)) = self.json.get("modes") {
            for m in modes {
                let mut m = m.clone();
                let name = m
                    .as_object_mut()
                    .and_then(|o| o.remove("name"))
                    .and_then(|n| n.as_str().map(str::to_string))
                    .unwrap_or_default();
                d.set_item(name, json_to_py(py, &m)?)?;
            }
        }
        Ok(d)
    }

    /// The parameters: `{name: {"kind": "unknown"|"fixed", "value"?, "lower", "upper"}}`, as
    /// `harmonid check --json` lists them.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, self.json.get("parameters").unwrap_or(&Value::Null))
    }

    /// Whether every coefficient is linear in the parameters (needed to identify them).
    #[getter]
    fn identifiable(&self) -> bool {
        self.inner.non_affine_terms().is_empty()
    }

    /// The equations of motion.
    ///
    /// `format="dict"` (default): `{mode: {monomial: {parameter: factor}}}` (the constant part
    /// under `"1"`), as in `harmonid check --json`; `"latex"`: a LaTeX `aligned` block; `"text"`:
    /// the readable report of `harmonid check`.
    #[pyo3(signature = (format = "dict"))]
    fn equations<'py>(&self, py: Python<'py>, format: &str) -> PyResult<Bound<'py, PyAny>> {
        match format {
            "dict" => json_to_py(py, self.json.get("eom").unwrap_or(&Value::Null)),
            "latex" => Ok(pyo3::types::PyString::new(py, &self.inner.to_latex()).into_any()),
            "text" => Ok(pyo3::types::PyString::new(py, &self.inner.to_text()).into_any()),
            other => Err(PyValueError::new_err(format!(
                "equations(format={other:?}): expected \"dict\", \"latex\" or \"text\""
            ))),
        }
    }

    /// Everything `harmonid check --json` prints, as a dict.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_text_to_py(py, &self.inner.to_json())
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({:?}, modes=[{}], parameters=[{}])",
            self.inner.source,
            self.inner.mode_names().join(", "),
            self.inner.param_names().join(", ")
        )
    }
}

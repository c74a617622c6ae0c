//! Python exceptions. Every one carries the library's located message (file, line or row, what
//! was expected, what to try) as its text.

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(
    harmonid,
    HarmonidError,
    PyValueError,
    "Base class of harmonid's errors; the message names the file, line or row and what to try."
);
create_exception!(
    harmonid,
    ModelError,
    HarmonidError,
    "A model file or text that does not parse or check (every diagnostic, with line and caret)."
);
create_exception!(
    harmonid,
    DatasetError,
    HarmonidError,
    "A dataset folder or arrays that break the data contract (docs/data-format.md)."
);
create_exception!(
    harmonid,
    IdentifyError,
    HarmonidError,
    "A model and dataset that cannot be identified together."
);
create_exception!(
    harmonid,
    SimulationError,
    HarmonidError,
    "Values, plans or settings a simulation or sweep cannot use."
);
create_exception!(
    harmonid,
    PlanError,
    HarmonidError,
    "A plan that cannot be designed or scored (an unknown no drive reveals, a budget too small, a drive past a fold), or a plan file that does not read."
);

/// Adds the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("HarmonidError", py.get_type::<HarmonidError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("DatasetError", py.get_type::<DatasetError>())?;
    m.add("IdentifyError", py.get_type::<IdentifyError>())?;
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("PlanError", py.get_type::<PlanError>())?;
    Ok(())
}

/// A model's diagnostics, rendered as plain text (file:line:column, the line, a caret, help).
pub fn model_error(e: &harmonid_model::ModelErrors) -> PyErr {
    ModelError::new_err(e.render_plain(100))
}

/// A dataset error (its message names the file and row).
pub fn dataset_error(e: &harmonid_data::DatasetError) -> PyErr {
    DatasetError::new_err(e.to_string())
}

/// An identification error; dataset errors keep their own class.
pub fn ident_error(e: &harmonid_ident::IdentError) -> PyErr {
    match e {
        harmonid_ident::IdentError::Dataset(d) => dataset_error(d),
        other => IdentifyError::new_err(other.to_string()),
    }
}

/// A miette diagnostic (a plan's error with its span, a values file's error) as plain text:
/// `file:line:column`, the line, a caret, the help.
pub fn render(d: &dyn miette::Diagnostic) -> String {
    let handler =
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor())
            .with_width(100)
            .with_links(false);
    let mut out = String::new();
    if handler.render_report(&mut out, d).is_err() {
        out = d.to_string();
    }
    out
}

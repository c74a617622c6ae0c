//! Parameter values for a simulation: a values file (TOML: `[modes.q1] f_hz, Q`, `[parameters]`,
//! optionally `[eom.q1]`; a `truth.toml` is accepted too) or an identification result
//! (`harmonid-result/1` JSON, read through its own types).

use crate::ExperimentError;
use harmonid_data::result::Report;
use harmonid_sim::{ModeValues, ModelValues};
use std::path::Path;

/// Reads a values file: an identification result when the name ends in `.json`, TOML otherwise.
pub fn read_values(path: &Path) -> Result<ModelValues, ExperimentError> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ExperimentError::Values {
        origin: origin.clone(),
        message: format!("cannot read the values file: {e}"),
    })?;
    if path.extension().is_some_and(|e| e == "json") {
        values_from_json(&text, &origin)
    } else {
        values_from_toml(&text, &origin)
    }
}

/// Values from TOML text. Keys of a `truth.toml` other than modes, parameters and eom
/// (`forces`, `noise`) are ignored; any other table is refused.
pub fn values_from_toml(text: &str, origin: &str) -> Result<ModelValues, ExperimentError> {
    let err = |message: String| ExperimentError::Values {
        origin: origin.to_string(),
        message,
    };
    let v: toml::Table = toml::from_str(text).map_err(|e| {
        let at = e
            .span()
            .map(|s| format!(" ({})", harmonid_files::quote_line(text, s)))
            .unwrap_or_default();
        err(format!("not valid TOML: {}{at}", e.message().trim_end()))
    })?;
    if let Some(k) = v
        .keys()
        .find(|k| !["modes", "parameters", "eom", "forces", "noise"].contains(&k.as_str()))
    {
        return Err(err(format!(
            "unknown table `{k}` (a values file has [modes.<mode>], [parameters] and optionally [eom.<mode>])"
        )));
    }
    let mut t = toml::Table::new();
    for key in ["modes", "parameters", "eom"] {
        if let Some(x) = v.get(key) {
            t.insert(key.into(), x.clone());
        }
    }
    toml::Value::Table(t)
        .try_into::<ModelValues>()
        .map_err(|e| {
            err(format!(
                "expected [modes.<mode>] f_hz/Q, [parameters] name = value, [eom.<mode>]: {e}"
            ))
        })
}

/// Values from an identification result (`harmonid-result/1`).
pub fn values_from_json(text: &str, origin: &str) -> Result<ModelValues, ExperimentError> {
    let r = Report::from_json(text).map_err(|e| ExperimentError::Values {
        origin: origin.to_string(),
        message: format!("not an identification result (harmonid-result/1): {e}"),
    })?;
    Ok(values_from_report(&r))
}

/// The values of an identification result: each mode's f and Q, each parameter's value (an
/// undetermined, NaN value is left out); when the result has no parameters, its `eom`
/// coefficients.
pub fn values_from_report(r: &Report) -> ModelValues {
    let finite = |x: f64| x.is_finite().then_some(x);
    let mut out = ModelValues::default();
    for (k, m) in &r.modes {
        out.modes.insert(
            k.clone(),
            ModeValues {
                f_hz: finite(m.f_hz.value),
                q: finite(m.q.value),
            },
        );
    }
    for (k, e) in &r.parameters {
        if let Some(x) = finite(e.value) {
            out.parameters.insert(k.clone(), x);
        }
    }
    if out.parameters.is_empty() {
        for (mode, terms) in &r.eom {
            let map = terms
                .iter()
                .filter_map(|(k, x)| x.map(|x| (k.clone(), x)))
                .collect();
            out.eom.insert(mode.clone(), map);
        }
    }
    out
}

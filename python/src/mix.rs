//! `harmonid.mix`: the lines every term of every equation generates under a set of tones, with
//! exact coefficients (the mixing tables of `harmonid mix`, Supplementary Note II).

use crate::errors::HarmonidError;
use crate::model::Model;
use harmonid_model::Linear;
use harmonid_spectral::{mixing_table, ToneAssignment, Window};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

fn spectral_error(e: harmonid_spectral::SpectralError) -> PyErr {
    HarmonidError::new_err(format!("{e}; check the drives and the sidebands order"))
}

/// One record per line of every term's mixing table: `equation`, `monomial`,
/// `term_coefficient`, `combination` (e.g. `2·f1 − f2`), `coeffs` (the integer combination of
/// the tones), `freq_hz`, `coefficient` (the line's amplitude as a polynomial in the component
/// amplitudes X1, X2, ...; for a term with velocities `d(q)`, `i·(...)`: its complex amplitude,
/// also in the components' angular frequencies ω(X1), ...), `velocity_factors`, `near` (the mode it is near, or None), `second_order` and `via` (the
/// modes without a tone whose response through the coupling, amplitudes Z1, Z2, ..., the line
/// goes through; empty for a first-order line). `pandas.DataFrame(records)` takes them as they
/// are. Tones are numbered f1, f2, ... in the order `drives` gives them (`harmonid mix` prints
/// them as Ω1, Ω2, ...).
#[pyfunction]
#[pyo3(signature = (model, drives, sidebands = None, window_hz = None, nominal_hz = None))]
pub fn mix<'py>(
    py: Python<'py>,
    model: &Model,
    drives: Vec<(String, Vec<f64>)>,
    sidebands: Option<u32>,
    window_hz: Option<f64>,
    nominal_hz: Option<BTreeMap<String, f64>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let m = &*model.inner;
    let mode_names: Vec<String> = m.modes.iter().map(|x| x.name.clone()).collect();
    let mut nominal: Vec<Option<f64>> = m
        .modes
        .iter()
        .map(|x| match x.f_hz {
            Linear::Fixed(f) => x.nominal_hz.or(Some(f)),
            Linear::Unknown => x.nominal_hz,
        })
        .collect();
    for (name, hz) in nominal_hz.unwrap_or_default() {
        let n = m.mode_index(&name).ok_or_else(|| {
            HarmonidError::new_err(format!(
                "nominal_hz gives `{name}`, which the model does not declare (modes: {})",
                mode_names.join(", ")
            ))
        })?;
        nominal[n] = Some(hz);
    }
    if drives.is_empty() {
        return Err(HarmonidError::new_err(
            "no tones given: pass drives={\"q1\": [207572, 207592], \"q2\": [415842]}",
        ));
    }
    let mut assignment =
        ToneAssignment::from_drives(&mode_names, &drives).map_err(spectral_error)?;
    if let Some(order) = sidebands {
        if order > 15 {
            return Err(HarmonidError::new_err(format!(
                "sidebands={order} is too high (at most 15; 3, 5, 7 give ω ± 3δ, ± 5δ, ± 7δ)"
            )));
        }
        assignment
            .add_own_sidebands(order)
            .map_err(spectral_error)?;
    }
    // A mode without a nominal frequency sits at the mean of its own tones (as `harmonid mix`).
    assignment.fill_nominal_from_drives(&mut nominal);
    // A mode without a tone responds through the coupling (as `harmonid mix`).
    let equations: Vec<Vec<harmonid_poly::PowerProduct>> = m
        .eom
        .iter()
        .map(|eq| eq.terms().map(|(mono, _)| mono.clone()).collect())
        .collect();
    assignment
        .add_responses(&equations)
        .map_err(spectral_error)?;
    let window = match window_hz {
        Some(w) if w.is_finite() && w >= 0.0 => Window::Hz(w),
        Some(w) => {
            return Err(HarmonidError::new_err(format!(
                "window_hz={w}: the window must be a number ≥ 0 Hz"
            )))
        }
        None => Window::default(),
    };
    let params: Vec<&str> = m.param_names();
    let symbols = assignment.symbols_with_frequencies();
    let variables = m.variable_names();
    let labels = assignment.tones().labels();
    let mut records = Vec::new();
    for (n, eq) in m.eom.iter().enumerate() {
        for (mono, c) in eq.terms() {
            let table =
                mixing_table(mono, &assignment, &nominal, window).map_err(spectral_error)?;
            let monomial = mono.name(&variables);
            let term_coefficient = c.to_string_with(&params);
            for l in &table.lines {
                let r = PyDict::new(py);
                r.set_item("equation", &mode_names[n])?;
                r.set_item("monomial", &monomial)?;
                r.set_item("term_coefficient", &term_coefficient)?;
                r.set_item("combination", l.combination.display_with(labels))?;
                r.set_item("coeffs", l.combination.coeffs())?;
                r.set_item("freq_hz", l.hz)?;
                r.set_item("coefficient", table.coefficient_text(l, &symbols))?;
                r.set_item("velocity_factors", table.velocity_factors)?;
                r.set_item("near", l.near_mode().map(|k| mode_names[k].as_str()))?;
                let via: Vec<&str> = assignment
                    .responses_in(&l.coefficient)
                    .into_iter()
                    .map(|k| mode_names[k].as_str())
                    .collect();
                r.set_item("second_order", !via.is_empty())?;
                r.set_item("via", via)?;
                records.push(r);
            }
        }
    }
    Ok(records)
}

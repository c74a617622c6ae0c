//! Held-out prediction: fit without some measurements, then predict them.
//!
//! The model is identified from the other measurements ([`identify`]); then every quantity it
//! describes (`f`, `Q`, every parameter) is fixed at the estimate and the held-out measurements
//! are fitted for their forces or actuator gains alone (per-measurement nuisances the fit could
//! not know; a gain shared with the fitted measurements is refitted too), by the same
//! output-error fit. How well that model then reproduces them, in noise units and relative to
//! the measured amplitudes, is the prediction error: a model that only fits the data it saw
//! predicts the others badly.

use crate::finalize::Report;
use crate::identify::identify;
use crate::problem::IdentError;
use crate::settings::Settings;
use harmonid_data::Dataset;
use harmonid_model::{Linear, Model, ParamKind};

pub use harmonid_data::result::HeldOut;

/// Identifies `model` from `ds` without the measurements named in `held`, and reports how well
/// the estimate predicts them in [`Report::holdout`]; see the module documentation.
pub fn identify_with_holdout(
    model: &Model,
    ds: &Dataset,
    held: &[String],
    settings: &Settings,
) -> Result<Report, IdentError> {
    // A name holds out one measurement, or every step of a sweep.
    let named = |m: &harmonid_data::Measurement, name: &String| {
        &m.spec.name == name || m.spec.sweep.as_ref().is_some_and(|s| &s.sweep == name)
    };
    let is_held = |m: &harmonid_data::Measurement| held.iter().any(|h| named(m, h));
    for name in held {
        if !ds.measurements.iter().any(|m| named(m, name)) {
            let mut names: Vec<String> =
                ds.manifest.sweeps.iter().map(|s| s.name.clone()).collect();
            names.extend(
                ds.measurements
                    .iter()
                    .filter(|m| m.spec.sweep.is_none())
                    .map(|m| m.spec.name.clone()),
            );
            return Err(IdentError::Holdout(format!(
                "--holdout {name}: the dataset has no measurement or sweep \"{name}\" (it has: {})",
                harmonid_data::text::first_and_more(names, 12).join(", ")
            )));
        }
    }
    let split = |keep_held: bool| -> Result<Dataset, IdentError> {
        let ms = ds
            .measurements
            .iter()
            .filter(|m| is_held(m) == keep_held)
            .cloned()
            .collect();
        Ok(Dataset::from_parts(
            ds.dir.clone(),
            ds.manifest.clone(),
            ms,
            ds.truth.clone(),
        )?)
    };
    if ds.measurements.iter().all(is_held) {
        return Err(IdentError::Holdout(format!(
            "--holdout {}: that is every measurement of the dataset; hold out fewer so some are left to fit",
            held.join(",")
        )));
    }
    let fit_ds = split(false)?;
    let held_ds = split(true)?;
    let mut report = identify(model, &fit_ds, settings)?;
    let undetermined: Vec<(String, String)> = report
        .estimates()
        .into_iter()
        .filter(|(_, e)| !e.identifiable)
        .map(|(name, e)| (name, e.reason.clone().unwrap_or_default()))
        .collect();
    if !undetermined.is_empty() {
        return Err(IdentError::Holdout(format!(
            "--holdout {}: without {} the other measurements do not determine {} ({}: {}); hold out a measurement they do not need",
            held.join(","),
            if held.len() == 1 { "it" } else { "them" },
            undetermined.iter().map(|u| u.0.as_str()).collect::<Vec<_>>().join(", "),
            undetermined[0].0,
            undetermined[0].1
        )));
    }
    let fixed = fixed_at(model, &report);
    let prediction = identify(&fixed, &held_ds, settings)?;
    report.holdout = match &prediction.goodness_of_fit {
        Some(g) => g
            .measurements
            .iter()
            .map(|m| HeldOut {
                measurement: m.name.clone(),
                lines: m.lines,
                rms_sigma: g.p_value.map(|_| m.rms_residual_sigma),
                relative_rms: m.relative_rms,
            })
            .collect(),
        None => {
            return Err(IdentError::Holdout(format!(
                "--holdout {}: the estimate cannot be simulated for the held-out measurements ({})",
                held.join(","),
                prediction.warnings.first().cloned().unwrap_or_default()
            )))
        }
    };
    Ok(report)
}

/// `model` with every mode's `f`, `Q` and every parameter fixed at `report`'s values.
fn fixed_at(model: &Model, report: &Report) -> Model {
    let mut m = model.clone();
    for mode in &mut m.modes {
        if let Some(r) = report.modes.get(&mode.name) {
            mode.f_hz = Linear::Fixed(r.f_hz.value);
            mode.q_factor = Linear::Fixed(r.q.value);
        }
    }
    for p in &mut m.params {
        if let Some(e) = report.parameters.get(&p.name) {
            p.kind = ParamKind::Fixed(e.value);
        }
    }
    m
}

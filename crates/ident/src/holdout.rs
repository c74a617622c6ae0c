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
///
/// A quantity the remaining measurements do not determine does not stop the prediction: it is
/// made from the estimate and a warning names the quantity (unless the fit left it without a
/// finite value: then it is refused, naming it). Its relative standard error can be
/// unbounded while the prediction does not depend on it (a linear damping 1/Q at zero beside a
/// quadratic drag that carries the damping: Q → ∞), and the held-out misfit itself says whether
/// it mattered. `compare` still sets such a model apart (through the same fit and prediction).
pub fn identify_with_holdout(
    model: &Model,
    ds: &Dataset,
    held: &[String],
    settings: &Settings,
) -> Result<Report, IdentError> {
    let mut report = fit_and_predict(model, ds, held, settings, false)?
        .map_err(|u| IdentError::Holdout(u.message))?;
    let undetermined: Vec<String> = undetermined(&report).into_iter().map(|u| u.0).collect();
    if !undetermined.is_empty() {
        report.warnings.push(format!(
            "--holdout {}: the other measurements do not determine {}; the held-out data are predicted from the estimate as it stands, so the prediction error says whether that matters (fix the quantity in the model, e.g. `Q = ...` on the mode, to predict without it)",
            held.join(","),
            undetermined.join(", ")
        ));
    }
    Ok(report)
}

/// A model the measurements left after a holdout do not determine: a property of the model and
/// the split (a comparison reports it and ranks the others), not a failure of the fit.
#[derive(Debug, Clone)]
pub(crate) struct Undetermined {
    /// The quantities not determined.
    pub names: Vec<String>,
    /// The message, naming them, the first one's reason and what to hold out instead.
    pub message: String,
}

/// [`identify_with_holdout`], with a model the remaining measurements do not determine told
/// apart from the errors (`Ok(Err(..))`); unless `require_determined`, such a model still
/// predicts the held-out data from its estimate (a discovery's starting point).
pub(crate) fn fit_and_predict(
    model: &Model,
    ds: &Dataset,
    held: &[String],
    settings: &Settings,
    require_determined: bool,
) -> Result<Result<Report, Undetermined>, IdentError> {
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
    let undetermined = undetermined(&report);
    // Without a value (the fit left it NaN) nothing can be predicted, whatever was asked.
    let valueless = report.estimates().iter().any(|(_, e)| !e.value.is_finite());
    if (require_determined || valueless) && !undetermined.is_empty() {
        return Ok(Err(Undetermined {
            names: undetermined.iter().map(|u| u.0.clone()).collect(),
            message: format!(
                "--holdout {}: without {} the other measurements do not determine {} ({}: {}); hold out a measurement they do not need",
                held.join(","),
                if held.len() == 1 { "it" } else { "them" },
                undetermined.iter().map(|u| u.0.as_str()).collect::<Vec<_>>().join(", "),
                undetermined[0].0,
                undetermined[0].1
            ),
        }));
    }
    let fixed = fixed_at(model, &report);
    // The prediction's misfit in the shot noise's units (an error floor fitted to the
    // held-out lines would hide what it is there to measure).
    let shot_noise = Settings {
        error_floor: false,
        background_fixed: report.background.clone(),
        ..settings.clone()
    };
    let prediction = identify(&fixed, &held_ds, &shot_noise)?;
    let floor = report.goodness_of_fit.as_ref().and_then(|g| g.error_floor);
    report.holdout = match &prediction.goodness_of_fit {
        Some(g) => held_out(g, &held_ds, held, floor),
        None => {
            return Err(IdentError::Holdout(format!(
                "--holdout {}: the estimate cannot be simulated for the held-out measurements ({})",
                held.join(","),
                prediction.warnings.first().cloned().unwrap_or_default()
            )))
        }
    };
    Ok(Ok(report))
}

/// The quantities `report` leaves undetermined, each with its reason.
fn undetermined(report: &Report) -> Vec<(String, String)> {
    report
        .estimates()
        .into_iter()
        .filter(|(_, e)| !e.identifiable)
        .map(|(name, e)| (name, e.reason.clone().unwrap_or_default()))
        .collect()
}

/// The held-out entries of the prediction's verdict `g` on `held_ds`: one per measurement
/// (a step of a sweep names its sweep), then one per held-out sweep summing its steps. With
/// the fit's error `floor`, each also in floor-inclusive sigmas.
fn held_out(
    g: &harmonid_data::result::GoodnessOfFit,
    held_ds: &Dataset,
    held: &[String],
    floor: Option<f64>,
) -> Vec<HeldOut> {
    let judged = g.p_value.is_some();
    // Per measurement: Σ|X̄ − X|²/(s² + floor²) over its lines.
    let floored: Option<Vec<f64>> = floor
        .filter(|_| judged)
        .map(|s0| floored_chi2(g, held_ds, s0));
    let mut out: Vec<HeldOut> = g
        .measurements
        .iter()
        .zip(&held_ds.measurements)
        .enumerate()
        .map(|(i, (m, dm))| HeldOut {
            measurement: m.name.clone(),
            lines: m.lines,
            rms_sigma: judged.then_some(m.rms_residual_sigma),
            rms_sigma_floor: floored
                .as_ref()
                .map(|c| (c[i] / (2 * m.lines).max(1) as f64).sqrt()),
            relative_rms: m.relative_rms,
            sweep: dm.spec.sweep.as_ref().map(|s| s.sweep.clone()),
            steps: None,
        })
        .collect();
    for name in held {
        let steps: Vec<_> = g
            .measurements
            .iter()
            .zip(&held_ds.measurements)
            .filter(|(_, dm)| dm.spec.sweep.as_ref().is_some_and(|s| &s.sweep == name))
            .map(|(m, _)| m)
            .collect();
        if steps.is_empty() {
            continue;
        }
        let sum = harmonid_data::result::SweepFit::of_steps(name, &steps);
        let floor_chi2 = floored.as_ref().map(|c| {
            held_ds
                .measurements
                .iter()
                .zip(c)
                .filter(|(dm, _)| dm.spec.sweep.as_ref().is_some_and(|s| &s.sweep == name))
                .map(|(_, c)| c)
                .sum::<f64>()
        });
        out.push(HeldOut {
            measurement: name.clone(),
            lines: sum.lines,
            rms_sigma: judged.then_some(sum.rms_residual_sigma),
            rms_sigma_floor: floor_chi2.map(|c| (c / (2 * sum.lines).max(1) as f64).sqrt()),
            relative_rms: sum.relative_rms,
            sweep: None,
            steps: Some(sum.steps),
        });
    }
    out
}

/// Per measurement of `held_ds`, the prediction's `χ²` with the error floor `s0` added in
/// quadrature to every line's shot noise of the mean (as the fit weighed its own lines): the
/// residual `|X̄ − X| = (line's sigmas) · s` of `g`'s lines, `s` from the held-out shots.
fn floored_chi2(g: &harmonid_data::result::GoodnessOfFit, held_ds: &Dataset, s0: f64) -> Vec<f64> {
    let pooled = crate::shots::pool(held_ds);
    let mut lines = g.lines.iter();
    pooled
        .sigma
        .iter()
        .zip(&pooled.used)
        .map(|(sigma, &n)| {
            let Some(sigma) = sigma else {
                return f64::NAN;
            };
            sigma
                .iter()
                .map(|s| {
                    let s = s / (n as f64).sqrt();
                    let r = lines.next().map_or(f64::NAN, |l| l.sigma * s);
                    r * r / (s * s + s0 * s0)
                })
                .sum()
        })
        .collect()
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

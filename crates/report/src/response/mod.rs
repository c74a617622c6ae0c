//! Stepped-sine frequency responses: the measured response of every sweep at its drive
//! frequency, grouped into families of one drive level, with the identified model's response
//! curve through its folds at that level (harmonid_sim's pseudo-arclength continuation, with
//! stability) and the model's steady state at every measured step, all in the dataset's unit.
//!
//! Conventions. `X` is the complex amplitude at the drive frequency at the dataset's first
//! point (`Σ_n shape_n X_n`), divided by the dataset's metres per unit (so in `V` for a dataset
//! in volts, `nm` for one in nanometres), and its phase is taken against the force the
//! identification gives the step on its driven mode (`X · e^{-i arg F}`): a linear mode lags by
//! 0° well below resonance, −90° at it, −180° above it. The force of a step is the result's
//! (`Report::forces`: the fitted actuator gain times the drive level and its phase, or the
//! fitted force), so the model is converted exactly as the identification converted it.

mod background;
mod family;
mod figure;
mod measured;
mod model;

pub use family::{families, is_frequency_sweep, Family};
pub use figure::{figure, overview};
pub use measured::{measured, MeasuredSweep};
pub use model::{harmonics_kept, model_at_steps, model_curve, shape, ModelCurve, CURVE_POINTS};

use harmonid_data::result::Report;
use harmonid_data::Dataset;
use harmonid_sim::NumericModel;

/// The [`FamilyResponse::point`] of a dataset without points (its amplitudes are modal).
pub const MODAL: &str = "modal coordinates";

/// One family's response: its measured sweeps and the model's curve.
#[derive(Debug, Clone)]
pub struct FamilyResponse {
    /// The family.
    pub family: Family,
    /// The unit of every `X` (the dataset's `displacement_unit`).
    pub unit: String,
    /// The point the response is read at (`p0`), or [`MODAL`] for a dataset without points.
    pub point: String,
    /// Every sweep of the family, in manifest order.
    pub sweeps: Vec<MeasuredSweep>,
    /// The model's curve, when the identified model gives one.
    pub model: Option<ModelCurve>,
    /// Why the model's curve (or its values at the steps) is missing or approximate.
    pub notes: Vec<String>,
}

/// The response of `fam`: the measured sweeps, and with an identified `model` its curve
/// (continuation over the measured range, at the family's median force) and its steady state
/// at every step (each sweep followed step by step from its first, as the experiment did).
pub fn family_response(
    model: Option<&NumericModel>,
    result: &Report,
    ds: &Dataset,
    fam: &Family,
) -> FamilyResponse {
    let names: Vec<String> = match model {
        Some(m) => m.mode_names.clone(),
        None => result.modes.keys().cloned().collect(),
    };
    let mut notes = Vec::new();
    let mut sweeps: Vec<MeasuredSweep> = fam
        .sweeps
        .iter()
        .filter_map(|&s| measured(ds, result, &names, s))
        .collect();
    let mut curve = None;
    if let Some(nm) = model {
        for sw in &mut sweeps {
            match model_at_steps(nm, ds, sw) {
                Ok(x) => sw.model = Some(x),
                Err(e) => notes.push(format!("{}: no model at the steps ({e})", sw.name)),
            }
        }
        match model_curve(nm, ds, &sweeps) {
            Ok((c, note)) => {
                notes.extend(note.map(|n| format!("{}: {n}", fam.label)));
                curve = Some(c);
            }
            Err(e) => notes.push(format!("{}: no model curve ({e})", fam.label)),
        }
    }
    notes.extend(background::add(result, ds, &mut sweeps, curve.as_mut()));
    let point = ds
        .manifest
        .points
        .first()
        .map_or_else(|| MODAL.to_string(), |p| p.name.clone());
    FamilyResponse {
        family: fam.clone(),
        unit: ds.manifest.displacement_unit.clone(),
        point,
        sweeps,
        model: curve,
        notes,
    }
}

/// The response of the family holding the sweep called `sweep` (the one sweep alone when it
/// has no constant drive level), or `None` when no sweep of that name is a single-tone
/// frequency sweep.
pub fn sweep_response(
    model: Option<&NumericModel>,
    result: &Report,
    ds: &Dataset,
    sweep: &str,
) -> Option<FamilyResponse> {
    let fam = families(ds).into_iter().find(|f| {
        f.sweeps
            .iter()
            .any(|&s| ds.manifest.sweeps[s].name == sweep)
    })?;
    Some(family_response(model, result, ds, &fam))
}

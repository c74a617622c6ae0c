//! The identification, in the method's order: the equation-error fits per shot and of the
//! pooled shots ([`crate::Problem`]), the output-error fit started from the pooled one
//! ([`crate::output_error`]), and the result built once from both ([`crate::finalize`]).

use crate::finalize::{finalize, Found, Report};
use crate::forward::{ForwardModel, ForwardSettings};
use crate::output_error::{self, OutputErrorFailure, POOR_STAGE};
use crate::problem::{IdentError, Problem};
use crate::settings::Settings;
use crate::shots::pool;
use harmonid_data::Dataset;
use harmonid_model::Model;

/// Identifies `model`'s unknowns from `ds`: the output-error maximum-likelihood estimate
/// (or the pooled equation-error one, [`Settings::estimator`]) with its standard errors, the
/// per-shot spread, the tables of the result file and its warnings. See
/// `docs/identification.md`.
pub fn identify(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Report, IdentError> {
    let prob = Problem::new(model, ds, settings)?;
    let per_shot = prob.fit(ds)?;
    let pooled = pool(ds);
    let start = prob.fit(&pooled.mean)?;
    let mut notes = Vec::new();
    if !pooled.noise_from_shots() {
        notes.push(if per_shot.values.len() <= 1 {
            "one shot: no shot scatter; the noise is taken from the fit's residual".to_string()
        } else {
            "the shots do not scatter (noise-free data?): the noise is taken from the fit's residual".to_string()
        });
    }
    let linear = &start.values[0];
    let output_error = (settings.estimator.is_output_error() || settings.crlb).then(|| {
        let mut fwd = ForwardModel::with_table(
            model,
            &pooled.mean,
            prob.table.clone(),
            &ForwardSettings {
                nominal_hz: settings.nominal_hz.clone(),
                ..ForwardSettings::default()
            },
        )
        .map_err(OutputErrorFailure::Setup)?;
        fwd.start_from_data(&pooled.mean);
        // Unknowns of a stage whose equation-error fit misses its equations by more than
        // POOR_STAGE: their linear estimates are no guide for the output-error start.
        let poor: Vec<usize> = start
            .groups
            .iter()
            .filter(|g| g.rms_residual > POOR_STAGE)
            .flat_map(|g| g.unknowns.iter().copied())
            .collect();
        output_error::fit(
            &prob,
            ds,
            &mut fwd,
            &pooled,
            (linear, &start.cov_diag[0], &poor),
            settings,
        )
    });
    Ok(finalize(Found {
        model_path: &model.source,
        ds,
        prob: &prob,
        per_shot: &per_shot,
        pooled: &pooled,
        linear,
        asked: settings.estimator,
        output_error,
        notes,
        settings,
    }))
}

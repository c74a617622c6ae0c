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

/// Shots fitted one by one for the per-shot spread (`std`, outlier shots, the `linear`
/// estimator's median): every shot up to this many. A longer record (a lock-in stream of 10⁵
/// samples) is represented by this many shots spread evenly over it: their spread is known to
/// about 1/√(2·1000) ≈ 2 %, and fitting every shot would cost time and memory in proportion to
/// the record for no better answer. The pooled mean, the noise, the output-error fit and its
/// standard errors use every shot.
pub const MAX_SHOT_FITS: usize = 1000;

/// The shots of `ds` fitted one by one (see [`MAX_SHOT_FITS`]): `None` when that is all of
/// them, else the dataset of those shots and their indices (of a measurement with the most
/// shots; a measurement with fewer keeps the nearest of its own).
fn shot_sample(ds: &Dataset) -> Option<(Dataset, Vec<usize>)> {
    let n = ds.measurements.iter().map(|m| m.n_shots).max().unwrap_or(1);
    if n <= MAX_SHOT_FITS {
        return None;
    }
    let index: Vec<usize> = (0..MAX_SHOT_FITS).map(|k| k * n / MAX_SHOT_FITS).collect();
    let measurements = ds
        .measurements
        .iter()
        .map(|m| {
            let own: Vec<usize> = index.iter().map(|&s| s * m.n_shots / n).collect();
            m.select_shots(&own)
        })
        .collect();
    let sample = Dataset {
        dir: ds.dir.clone(),
        manifest: ds.manifest.clone(),
        measurements,
        truth: ds.truth.clone(),
        notes: ds.notes.clone(),
    };
    Some((sample, index))
}

/// Identifies `model`'s unknowns from `ds`: the output-error maximum-likelihood estimate
/// (or the pooled equation-error one, [`Settings::estimator`]) with its standard errors, the
/// per-shot spread, the tables of the result file and its warnings. See
/// `docs/identification.md`.
pub fn identify(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Report, IdentError> {
    let prob = Problem::new(model, ds, settings)?;
    let sample = shot_sample(ds);
    let per_shot = prob.fit(sample.as_ref().map_or(ds, |s| &s.0))?;
    let shot_index = sample.map(|s| s.1).unwrap_or_default();
    let pooled = pool(ds);
    let start = prob.fit(&pooled.mean)?;
    let mut notes = Vec::new();
    if !shot_index.is_empty() {
        notes.push(format!(
            "per-shot fits (std, outlier shots) on {} of the {} shots, spread evenly over the record; the pooled mean and its fit use every shot",
            shot_index.len(),
            ds.measurements.iter().map(|m| m.n_shots).max().unwrap_or(1)
        ));
    }
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
        shot_index: &shot_index,
        pooled: &pooled,
        linear,
        asked: settings.estimator,
        output_error,
        notes,
        settings,
    }))
}

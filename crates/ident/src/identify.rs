//! The identification, in the method's order: the equation-error fits per shot and of the
//! pooled shots ([`crate::Problem`]), the output-error fit started from the pooled one
//! ([`crate::output_error`]), and the result built once from both ([`crate::finalize`]).

use crate::finalize::{finalize, Found, Report};
use crate::forward::{ForwardModel, ForwardSettings};
use crate::output_error::{self, OutputErrorFailure, POOR_STAGE};
use crate::problem::{IdentError, Problem};
use crate::settings::Settings;
use crate::shots::pool;
use harmonid_data::result::ExcludedLevel;
use harmonid_data::{Dataset, Direction, Measurement};
use harmonid_model::Model;
use std::collections::BTreeMap;

/// Shots fitted one by one for the per-shot spread (`std`, outlier shots, the `linear`
/// estimator's median): every shot up to this many. A longer record (a lock-in stream of 10⁵
/// samples) is represented by this many shots spread evenly over it: their spread is known to
/// about 1/√(2·1000) ≈ 2 %, and fitting every shot would cost time and memory in proportion to
/// the record for no better answer. The pooled mean, the noise, the output-error fit and its
/// standard errors use every shot.
pub const MAX_SHOT_FITS: usize = 1000;

/// The most measurements (steps of stepped sweeps, mostly) one identification takes: its cost
/// is linear in them, about 27 kB and 0.3 ms per one-line step with five samples (the 10,008-step
/// bench: 267 MB, 2.3 s), so 50,000 steps hold about 1.4 GB. A larger dataset is refused before
/// any work ([`IdentError::TooManyMeasurements`]), saying what to do.
pub const MAX_MEASUREMENTS: usize = 50_000;

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
/// per-shot spread, the tables of the result file and its warnings. A level of a drive
/// ladder (a `direction = "level"` sweep of three levels or more) that does not fit the
/// branch the ladder's other levels define is left out: when a level's fit is rejected at
/// [`LADDER_ALPHA`] (Bonferroni over every ladder level), each level of that ladder is left
/// out in turn, and the one after which all the others fit (the best fit if several) is
/// excluded, repeatedly ([`Report::excluded_levels`], and a warning each); not when more than
/// a quarter of the ladders (at least one) miss (then the model does, and a note says so). See
/// `docs/identification.md`.
pub fn identify(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Report, IdentError> {
    if ds.measurements.len() > MAX_MEASUREMENTS {
        return Err(IdentError::TooManyMeasurements {
            file: ds.dir.join("dataset.toml").display().to_string(),
            found: ds.measurements.len(),
            limit: MAX_MEASUREMENTS,
        });
    }
    let mut report = identify_every_level(model, ds, settings)?;
    let levels: usize = ladders(ds).iter().map(|l| l.1.len()).sum();
    if levels == 0 {
        return Ok(report);
    }
    let cut = LADDER_ALPHA / levels as f64;
    let mut current: Option<Dataset> = None;
    let mut excluded = Vec::new();
    // Greedy: while a ladder has a rejected level, leave out the level of such a ladder after
    // which the ladder's other levels all fit (the best fit if several do).
    loop {
        let now = current.as_ref().unwrap_or(ds);
        let fits = level_fits(now, &report);
        let all = ladders(now);
        let n_ladders = all.len();
        let suspect: Vec<(String, Vec<String>)> = all
            .into_iter()
            .filter(|(_, steps)| {
                steps.len() >= 3 && steps.iter().any(|m| fits.get(m).is_some_and(|f| f.2 < cut))
            })
            .collect();
        // A jumped level is the exception: when many ladders miss, the model misses something
        // that no level left out would explain (and trying each would cost a fit per level).
        if suspect.len() > (n_ladders / 4).max(1) {
            report.notes.push(format!(
                "drive ladders: {} of {n_ladders} have levels that do not fit; no level was left out (so many misses are the model's, not jumps)",
                suspect.len()
            ));
            break;
        }
        let mut best: Option<(f64, Report, Dataset, ExcludedLevel)> = None;
        for (ladder, steps) in &suspect {
            for step in steps {
                let Some(without) = without_measurement(now, step) else {
                    continue;
                };
                let Ok(r) = identify_every_level(model, &without, settings) else {
                    continue;
                };
                let after = level_fits(&without, &r);
                let rest_fit = steps
                    .iter()
                    .filter(|m| *m != step)
                    .all(|m| after.get(m).is_some_and(|f| f.2 >= cut));
                let score = r
                    .goodness_of_fit
                    .as_ref()
                    .map_or(f64::INFINITY, |g| g.chi2_per_dof);
                if rest_fit && best.as_ref().is_none_or(|b| score < b.0) {
                    let (chi2_per_dof, expected_chi2_per_dof, p_value) = fits
                        .get(step)
                        .copied()
                        .unwrap_or((f64::NAN, f64::NAN, f64::NAN));
                    let level = ExcludedLevel {
                        measurement: step.clone(),
                        ladder: ladder.clone(),
                        chi2_per_dof,
                        expected_chi2_per_dof,
                        p_value,
                    };
                    best = Some((score, r, without, level));
                }
            }
        }
        let Some((_, r, without, level)) = best else {
            for (ladder, _) in &suspect {
                report.notes.push(format!(
                    "drive ladder {ladder}: its levels do not fit, and leaving out any one of them does not make the others fit (the model or the recorded drive misses something, not one level); no level was left out"
                ));
            }
            break;
        };
        report = r;
        current = Some(without);
        excluded.push(level);
    }
    for o in &excluded {
        report.warnings.push(format!(
            "{}: left out of the fit: it does not fit the branch the other levels of its drive ladder {} define (χ²/dof {:.3} where a correct model gives {:.3}, p = {:.1e}; without it the ladder's other levels fit); the response may have jumped or drifted at this level",
            o.measurement, o.ladder, o.chi2_per_dof, o.expected_chi2_per_dof, o.p_value
        ));
    }
    report.excluded_levels = excluded;
    Ok(report)
}

/// Family-wise probability that the ladder check leaves out a level of data a correct model
/// fits (Bonferroni over every ladder level of the dataset).
pub const LADDER_ALPHA: f64 = 0.01;

/// `ds`'s drive ladders (sweeps of `direction = "level"`): each one's name and its levels'
/// measurement names, in order.
fn ladders(ds: &Dataset) -> Vec<(String, Vec<String>)> {
    ds.manifest
        .sweeps
        .iter()
        .filter(|s| s.direction == Direction::Level)
        .map(|s| {
            let steps = ds
                .measurements
                .iter()
                .filter(|m| m.spec.sweep.as_ref().is_some_and(|st| st.sweep == s.name))
                .map(|m| m.spec.name.clone())
                .collect();
            (s.name.clone(), steps)
        })
        .collect()
}

/// Per measurement of `report`'s output-error fit: `χ²/dof`, its expectation and `p`; empty
/// without a `p` (no shot noise, an error floor, the linear estimator) or a converged fit.
fn level_fits(ds: &Dataset, report: &Report) -> BTreeMap<String, (f64, f64, f64)> {
    let Some(g) = report
        .goodness_of_fit
        .as_ref()
        .filter(|g| g.converged && g.error_floor.is_none())
    else {
        return BTreeMap::new();
    };
    debug_assert_eq!(g.measurements.len(), ds.measurements.len());
    g.measurements
        .iter()
        .filter_map(|m| {
            let p = m.p_value?;
            Some((m.name.clone(), (m.chi2_per_dof, m.expected_chi2_per_dof, p)))
        })
        .collect()
}

/// `ds` without the measurement `name` (`None` when the rest is not a dataset).
fn without_measurement(ds: &Dataset, name: &str) -> Option<Dataset> {
    let kept: Vec<Measurement> = ds
        .measurements
        .iter()
        .filter(|m| m.spec.name != name)
        .cloned()
        .collect();
    let mut out =
        Dataset::from_parts(ds.dir.clone(), ds.manifest.clone(), kept, ds.truth.clone()).ok()?;
    out.notes = ds.notes.clone();
    Some(out)
}

/// [`identify`] with every measurement of `ds`.
fn identify_every_level(
    model: &Model,
    ds: &Dataset,
    settings: &Settings,
) -> Result<Report, IdentError> {
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

//! The result, built once: the reported values (the output-error estimate, or the pooled
//! equation-error one), their standard errors (Fisher information at the estimate, or the
//! per-shot spread), the per-shot spread as a diagnostic, the tables, and the warnings, all
//! from typed state.

mod background;
mod tables;
mod unfit;

pub use harmonid_data::result::{
    Estimate, FitReport, ForceResult, GainResult, ModeResult, Report, RESULT_FORMAT,
};
pub use tables::report_from_shots;

use crate::layout::{Quantity, Unknown};
use crate::output_error::{OutputError, OutputErrorFailure};
use crate::problem::{Fit, Problem};
use crate::settings::{Estimator, Settings};
use crate::shots::Pooled;
use harmonid_data::{text::first_and_more, text::index_list, Dataset};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use tables::FIXED_BY_THE_MODEL;

/// Relative standard error above which a quantity is reported as not determined.
pub const MAX_REL_STDERR: f64 = 0.3;
/// Relative disagreement of the jackknife and the Fisher standard error that is warned about.
pub const JACKKNIFE_TOL: f64 = 0.3;

/// The reason of every quantity of an output-error fit that stopped before converging.
const NOT_CONVERGED: &str =
    "the output-error fit stopped before converging: this is where it stopped, not an estimate";

/// What an identification found, for [`finalize`].
pub(crate) struct Found<'a> {
    /// Path of the model file, as the result names it.
    pub model_path: &'a str,
    /// The dataset (every shot).
    pub ds: &'a Dataset,
    /// The problem set up for it.
    pub prob: &'a Problem,
    /// The per-shot equation-error fits (the spread reported as `std`).
    pub per_shot: &'a Fit,
    /// The shot of each of `per_shot`'s rows, when not every shot was fitted (empty: all).
    pub shot_index: &'a [usize],
    /// The pooled shots.
    pub pooled: &'a Pooled,
    /// The pooled equation-error estimate (layout of `prob.table`).
    pub linear: &'a [f64],
    /// The estimator asked for.
    pub asked: Estimator,
    /// The output-error fit, or why it failed (`None`: not run).
    pub output_error: Option<Result<OutputError, OutputErrorFailure>>,
    /// Notes on the noise source.
    pub notes: Vec<String>,
    /// The settings.
    pub settings: &'a Settings,
}

/// The result of an identification from what it found.
pub(crate) fn finalize(found: Found<'_>) -> Report {
    let Found {
        model_path,
        ds,
        prob,
        per_shot,
        shot_index,
        pooled,
        linear,
        asked,
        output_error,
        notes,
        settings,
    } = found;
    let (estimator, fo, fallback) = match output_error {
        Some(Ok(f)) => (asked, Some(f), None),
        Some(Err(why)) => (Estimator::Linear, None, Some(why)),
        None => (asked, None, None),
    };
    let values = match (&fo, estimator) {
        (Some(f), e) if e.is_output_error() => ml_values(prob, &f.fit.theta, linear),
        _ => linear.to_vec(),
    };
    let judge = Judge {
        prob,
        fo: fo.as_ref(),
        estimator,
        n_used: pooled.used.iter().copied().min().unwrap_or(1).max(1) as f64,
        crlb: settings.crlb,
        structural: structural(prob, fo.as_ref()),
    };
    let mut jackknife_warnings = Vec::new();
    let mut modes = tables::mode_estimates(prob, per_shot);
    for (n, name) in prob.mode_names.iter().enumerate() {
        let (Some(iw), Some(ig)) = (
            prob.index_of(&Unknown::OmegaSq(n)),
            prob.index_of(&Unknown::Gamma(n)),
        ) else {
            continue;
        };
        let Some(m) = modes.get_mut(name) else {
            continue;
        };
        let w = values[iw].sqrt();
        let (f, q) = (w / (2.0 * PI), w / values[ig]);
        judge.apply(
            Quantity::Frequency(n),
            &mut m.f_hz,
            f,
            &mut jackknife_warnings,
        );
        judge.apply(Quantity::Q(n), &mut m.q, q, &mut jackknife_warnings);
    }
    let mut parameters = tables::param_estimates(prob, per_shot);
    for (p, name) in prob.param_names.iter().enumerate() {
        let Some(i) = prob.index_of(&Unknown::Param(p)) else {
            continue;
        };
        let Some(e) = parameters.get_mut(name) else {
            continue;
        };
        let v = if prob.not_identifiable.iter().any(|x| x.unknown == i) {
            f64::NAN
        } else {
            values[i]
        };
        judge.apply(Quantity::Param(p), e, v, &mut jackknife_warnings);
    }
    let background = background::reported(&judge, &values, ds, &mut jackknife_warnings);
    number_outlier_shots(&mut modes, &mut parameters, shot_index);
    let fits = tables::fit_reports(ds, prob, &per_shot.groups);
    let mut rejected_shots = BTreeMap::new();
    let goodness_of_fit = fo
        .as_ref()
        .filter(|_| estimator.is_output_error())
        .map(|f| f.goodness.clone());
    let ml_fits = goodness_of_fit
        .as_ref()
        .is_some_and(|g| g.converged && g.fits == Some(true));
    let (start_warnings, start_notes) =
        start_diagnostics(tables::conditioning_warnings(&fits), ml_fits);
    let mut warnings = prob.warnings.clone();
    warnings.extend(start_warnings);
    warnings.extend(tables::force_warnings(prob));
    for (mi, bad) in pooled.rejected.iter().enumerate() {
        if !bad.is_empty() {
            rejected_shots.insert(ds.measurements[mi].spec.name.clone(), bad.clone());
        }
    }
    warnings.extend(rejected_warning(&rejected_shots, ds.measurements.len()));
    let unfit = unfit::unfit_groups(&unfit::Verdicts {
        prob,
        fo: fo.as_ref().filter(|_| estimator.is_output_error()),
        fallback: fallback.as_ref().filter(|_| asked.is_output_error()),
        modes: &modes,
        parameters: &parameters,
    });
    if let Some(why) = fallback {
        warnings.push(format!(
            "{why}; reporting the pooled equation-error (linear) estimate"
        ));
        warnings.extend(background::not_fitted(&settings.background));
    }
    warnings.extend(tables::undetermined_warnings(&modes, &parameters));
    warnings.extend(jackknife_warning(&jackknife_warnings, &judge));
    if let Some(text) = goodness_of_fit.as_ref().and_then(|g| g.headline()) {
        warnings.insert(0, text);
    }
    let mut all_notes = Vec::new();
    let mut consistency = Vec::new();
    if let Some(f) = &fo {
        all_notes.extend(f.notes.iter().cloned());
        warnings.extend(f.drift.iter().cloned());
        warnings.extend(crate::uncertainty::consistency::warnings(&f.consistency));
        consistency = f.consistency.clone();
    }
    all_notes.extend(notes);
    all_notes.extend(start_notes);
    let one = [values];
    Report {
        format: RESULT_FORMAT.to_string(),
        model: model_path.to_string(),
        dataset: ds.dir.display().to_string(),
        force_model: prob.table.force_model().description().to_string(),
        estimator: estimator.to_string(),
        rejected_shots,
        notes: all_notes,
        goodness_of_fit,
        excluded_levels: Vec::new(),
        holdout: Vec::new(),
        unfit,
        shots: ds.measurements.iter().map(|m| m.n_shots).max().unwrap_or(1),
        shots_fitted: (!shot_index.is_empty()).then_some(per_shot.values.len()),
        shot_index: shot_index.to_vec(),
        outlier_shots: tables::outlier_shots(&modes, &parameters),
        eom: tables::eom_table(prob, &one),
        forces: tables::force_table(ds, prob, &one),
        gains: tables::gain_table(ds, prob, &one),
        background,
        modes,
        parameters,
        fits,
        warnings,
        consistency,
    }
}

/// Every estimate's outlier shots as shot numbers: the per-shot fits' rows are the shots
/// `shot_index` (when not every shot was fitted; empty: row `k` is shot `k`).
fn number_outlier_shots(
    modes: &mut BTreeMap<String, ModeResult>,
    parameters: &mut BTreeMap<String, Estimate>,
    shot_index: &[usize],
) {
    if shot_index.is_empty() {
        return;
    }
    let estimates = modes
        .values_mut()
        .flat_map(|m| [&mut m.f_hz, &mut m.q])
        .chain(parameters.values_mut());
    for e in estimates {
        for s in &mut e.outlier_shots {
            *s = shot_index[*s];
        }
    }
}

/// A quantity whose jackknife standard error disagrees with its Fisher one.
#[derive(Debug, Clone)]
struct JackknifeDisagreement {
    key: String,
    jackknife: f64,
    fisher: f64,
}

/// The family-wise probability that a correct jackknife's ratio to the Fisher error falls
/// outside [`jackknife_band`] for some quantity of a result.
const JACKKNIFE_FAMILY_ALPHA: f64 = 0.01;

/// The range of jackknife/Fisher ratios a correct fit gives with `shots` shots over
/// `quantities` quantities, widened to at least ± [`JACKKNIFE_TOL`]. Why: the jackknife's
/// variance from `n` shots scatters like `σ²·χ²(n−1)/(n−1)` (relative standard error
/// `1/√(2(n−1))`, 13 % at 30 shots), so a fixed 30 % is 2.3 of its own sigmas and a
/// ten-mode string's 75 quantities cross it about 1.6 times a result by chance (measured: 25
/// of 1500 over 20 such strings, in both directions). The band is the `χ²(n−1)` quantiles at
/// [`JACKKNIFE_FAMILY_ALPHA`] shared over the quantities (Bonferroni, two-sided).
fn jackknife_band(shots: f64, quantities: usize) -> (f64, f64) {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    let nu = (shots - 1.0).max(1.0);
    let p = JACKKNIFE_FAMILY_ALPHA / (2.0 * quantities.max(1) as f64);
    let ratio = |x: f64| {
        ChiSquared::new(nu)
            .ok()
            .map(|c| (c.inverse_cdf(x) / nu).sqrt())
            .filter(|r| r.is_finite())
    };
    let lo = ratio(p).unwrap_or(0.0).min(1.0 - JACKKNIFE_TOL);
    let hi = ratio(1.0 - p)
        .unwrap_or(f64::INFINITY)
        .max(1.0 + JACKKNIFE_TOL);
    (lo, hi)
}

/// [`jackknife_warning_in`] with the band of the fewest shots any measurement's mean used
/// over the quantities the jackknife was computed for.
fn jackknife_warning(list: &[JackknifeDisagreement], judge: &Judge) -> Option<String> {
    let jackknifed = judge.fo.map_or(0, |f| f.jackknife.len());
    jackknife_warning_in(list, jackknife_band(judge.n_used, jackknifed))
}

/// One warning for every quantity whose jackknife/Fisher ratio lies outside `band` (see
/// [`jackknife_band`]; one warning: a quantity each drowned the others on real data), the
/// largest ratios named first, or `None`.
fn jackknife_warning_in(list: &[JackknifeDisagreement], band: (f64, f64)) -> Option<String> {
    const NAMED: usize = 3;
    let list: Vec<&JackknifeDisagreement> = list
        .iter()
        .filter(|d| {
            let r = d.jackknife / d.fisher;
            !(band.0..=band.1).contains(&r)
        })
        .collect();
    let mut sorted = list.clone();
    let ratio = |d: &JackknifeDisagreement| (d.fisher / d.jackknife).ln().abs();
    sorted.sort_by(|a, b| ratio(b).total_cmp(&ratio(a)));
    let named: Vec<String> = sorted
        .iter()
        .take(NAMED)
        .map(|d| {
            format!(
                "{} (jackknife {:.3e}, Fisher {:.3e})",
                d.key, d.jackknife, d.fisher
            )
        })
        .collect();
    let more = match sorted.len().saturating_sub(NAMED) {
        0 => String::new(),
        n => format!(" and {n} more"),
    };
    let s = if list.len() == 1 { "" } else { "s" };
    (!list.is_empty()).then(|| {
        format!(
            "the jackknife and Fisher standard errors disagree beyond what the shots allow (a ratio outside {:.2} to {:.2}) for {} quantit{}: {}{more}",
            band.0,
            band.1,
            list.len(),
            if s.is_empty() { "y" } else { "ies" },
            named.join(", ")
        )
    })
}

/// The equation-error fits' conditioning warnings: warnings when their estimate is reported or
/// the output-error fit does not fit, notes otherwise (`ml_fits`: the output-error fit
/// converged and fits the data; the equation-error fits were only its start, and their
/// troubles must not drown the warnings a user acts on).
fn start_diagnostics(conditioning: Vec<String>, ml_fits: bool) -> (Vec<String>, Vec<String>) {
    if ml_fits {
        let notes = conditioning
            .into_iter()
            .map(|w| {
                format!("equation-error start: {w} (the output-error fit started from it fits the data)")
            })
            .collect();
        (Vec::new(), notes)
    } else {
        (conditioning, Vec::new())
    }
}

/// One warning for every shot rejected as disturbed: measurements that lost the same shots
/// share a clause ("shots 10-12 in all 15 measurements"), at most five names per clause.
fn rejected_warning(
    rejected: &BTreeMap<String, Vec<usize>>,
    measurements: usize,
) -> Option<String> {
    if rejected.is_empty() {
        return None;
    }
    let mut by_shots: BTreeMap<&[usize], Vec<&str>> = BTreeMap::new();
    for (name, shots) in rejected {
        by_shots.entry(shots).or_default().push(name);
    }
    let clauses: Vec<String> = by_shots
        .iter()
        .map(|(shots, names)| {
            let which = if names.len() == measurements && measurements > 1 {
                format!("all {measurements} measurements")
            } else {
                first_and_more(names.iter().map(|n| format!("\"{n}\"")).collect(), 5).join(", ")
            };
            format!(
                "shot{} {} in {which}",
                if shots.len() == 1 { "" } else { "s" },
                index_list(shots)
            )
        })
        .collect();
    Some(format!(
        "shots rejected as disturbed (too far from their measurement's other shots for the noise those show; a clean dataset loses any in at most 1 %) in {} of {measurements} measurements, each pooled mean using the others: {}",
        rejected.len(),
        clauses.join("; ")
    ))
}

/// The reported values: the output-error estimate `ml` where it is identified, the
/// equation-error `linear` elsewhere (fixed values), and `γ = √ω²/Q` of a mode whose `Q` is
/// fixed from the reported `ω²` (the linear fit's `γ` came from its own `ω²`, which put the
/// reported `Q` about 1e-7 off the model's). Both are in the layout of `prob.table`.
fn ml_values(prob: &Problem, ml: &[f64], linear: &[f64]) -> Vec<f64> {
    let mut out = linear.to_vec();
    for (k, v) in out.iter_mut().enumerate() {
        if prob.table.is_free(k) && !prob.not_identifiable.iter().any(|x| x.unknown == k) {
            *v = ml[k];
        }
    }
    for n in 0..prob.mode_names.len() {
        let (Some(q), Some(iw), Some(ig)) = (
            prob.table.fixed_q(n),
            prob.index_of(&Unknown::OmegaSq(n)),
            prob.index_of(&Unknown::Gamma(n)),
        ) else {
            continue;
        };
        out[ig] = out[iw].sqrt() / q;
    }
    out
}

/// The quantities no measurement (or the information at the estimate) determines, with why:
/// the equation-error set-up's first, then the output-error fit's.
fn structural(prob: &Problem, fo: Option<&OutputError>) -> Vec<(Quantity, String)> {
    let mut out: Vec<(Quantity, String)> = prob
        .not_identifiable
        .iter()
        .filter_map(|ni| {
            Some((
                Quantity::of(&prob.table.unknowns()[ni.unknown])?,
                ni.reason.clone(),
            ))
        })
        .collect();
    if let Some(f) = fo {
        out.extend(f.unidentifiable.iter().cloned());
    }
    out
}

/// The rules that turn a quantity's per-shot estimate into the reported one.
struct Judge<'a> {
    prob: &'a Problem,
    fo: Option<&'a OutputError>,
    estimator: Estimator,
    /// Fewest shots any measurement's pooled mean used.
    n_used: f64,
    crlb: bool,
    structural: Vec<(Quantity, String)>,
}

impl Judge<'_> {
    /// Sets `e`'s value and, unless the model fixes it, its standard error (for ml the Fisher
    /// bound, corrected per quantity for weights estimated from the shots, times the
    /// model-misfit inflation; the per-shot spread over `√n` for linear),
    /// bounds, jackknife and whether the data determine it. A jackknife that disagrees with
    /// the Fisher error is added to `disagreements`.
    fn apply(
        &self,
        q: Quantity,
        e: &mut Estimate,
        value: f64,
        disagreements: &mut Vec<JackknifeDisagreement>,
    ) {
        let fixed = e.reason.as_deref() == Some(FIXED_BY_THE_MODEL);
        // A single value's median, as the per-shot tables read it: NaN unless finite.
        e.value = if value.is_finite() { value } else { f64::NAN };
        if fixed {
            return;
        }
        if let Some((_, why)) = self.structural.iter().find(|(s, _)| *s == q) {
            e.identifiable = false;
            e.reason = Some(why.clone());
            e.stderr = f64::NAN;
            return;
        }
        let ml = self.estimator.is_output_error();
        let bound = self.fo.and_then(|f| {
            f.bounds
                .quantities
                .iter()
                .find(|b| b.quantity == q)
                .map(|b| b.std)
        });
        e.crlb = if self.crlb || ml { bound } else { None };
        e.jackknife = self
            .fo
            .and_then(|f| f.jackknife.iter().find(|(j, _)| *j == q).map(|x| x.1));
        let corrected = self.fo.and_then(|f| {
            f.stderr_bounds
                .quantities
                .iter()
                .find(|b| b.quantity == q)
                .map(|b| b.std)
        });
        e.stderr = match (ml, corrected, self.fo) {
            (true, Some(b), Some(f)) => b * f.inflation,
            _ => e.std / self.n_used.sqrt(),
        };
        if ml && self.fo.is_some_and(|f| !f.fit.converged) {
            e.identifiable = false;
            e.reason = Some(NOT_CONVERGED.into());
            return;
        }
        if ml && self.fo.is_some_and(|f| f.at_bound.contains(&q)) {
            e.at_bound = true;
            e.identifiable = false;
            e.reason = Some(
                "at its bound: the data favour a value beyond it (the estimate is the bound)"
                    .into(),
            );
            return;
        }
        let rel = e.stderr / e.value.abs();
        if rel.is_nan() || rel > MAX_REL_STDERR {
            e.identifiable = false;
            e.reason = Some(format!(
                "relative standard error {rel:.2} above {MAX_REL_STDERR}: the data do not determine it"
            ));
        } else {
            e.identifiable = true;
            e.reason = None;
        }
        if let Some(j) = e.jackknife {
            if (j / e.stderr - 1.0).abs() > JACKKNIFE_TOL {
                disagreements.push(JackknifeDisagreement {
                    key: q.key(&self.prob.mode_names, &self.prob.param_names),
                    jackknife: j,
                    fisher: e.stderr,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jackknife_disagreements_are_one_warning_largest_first() {
        let d = |key: &str, jackknife: f64| JackknifeDisagreement {
            key: key.into(),
            jackknife,
            fisher: 1.0,
        };
        let tol = (1.0 - JACKKNIFE_TOL, 1.0 + JACKKNIFE_TOL);
        assert_eq!(jackknife_warning_in(&[], tol), None);
        let one = jackknife_warning_in(&[d("beta1", 2.0)], tol).expect("one");
        assert!(
            one.ends_with("for 1 quantity: beta1 (jackknife 2.000e0, Fisher 1.000e0)"),
            "{one}"
        );
        // Within the band nothing is said.
        assert_eq!(jackknife_warning_in(&[d("beta1", 1.4)], (0.5, 1.5)), None);
        let list = [
            d("a", 1.5),
            d("b", 1e-3),
            d("c", 10.0),
            d("e", 0.5),
            d("f", 3.0),
        ];
        let w = jackknife_warning_in(&list, tol).expect("many");
        // Largest ratios either way first: b (1000x), c (10x), f (3x); two more counted.
        assert!(
            w.contains("for 5 quantities: b (")
                && w.contains("), c (")
                && w.contains("), f (")
                && w.ends_with(" and 2 more"),
            "{w}"
        );
    }

    /// The band of a correct jackknife: the χ²(n−1) quantiles shared over the quantities,
    /// never narrower than ± JACKKNIFE_TOL.
    #[test]
    fn the_jackknife_band_widens_with_few_shots_and_many_quantities() {
        // One quantity, 30 shots: χ²(29) quantiles at 0.5 % and 99.5 %, 13.12 and 52.34.
        let (lo, hi) = jackknife_band(30.0, 1);
        assert!((lo - (13.121_1_f64 / 29.0).sqrt()).abs() < 1e-3, "{lo}");
        assert!((hi - (52.335_6_f64 / 29.0).sqrt()).abs() < 1e-3, "{hi}");
        // 75 quantities (the ten-mode string): wider still.
        let (lo75, hi75) = jackknife_band(30.0, 75);
        assert!(
            lo75 < lo && hi75 > hi && lo75 > 0.4 && hi75 < 1.6,
            "{lo75} {hi75}"
        );
        // Many shots: the fixed tolerance.
        assert_eq!(jackknife_band(100_000.0, 1), (0.7, 1.3));
    }

    #[test]
    fn start_diagnostics_are_notes_when_the_output_error_fit_fits() {
        let w = vec!["fit of \"a\" (stage 2): condition number ...".to_string()];
        let (warnings, notes) = start_diagnostics(w.clone(), true);
        assert!(warnings.is_empty());
        assert!(
            notes[0].starts_with("equation-error start: fit of \"a\""),
            "{notes:?}"
        );
        assert_eq!(start_diagnostics(w.clone(), false), (w, Vec::new()));
    }

    #[test]
    fn rejected_shots_are_one_warning_grouped_by_shots() {
        assert_eq!(rejected_warning(&BTreeMap::new(), 3), None);
        let same: BTreeMap<String, Vec<usize>> = (0..15)
            .map(|m| (format!("m{m:02}"), vec![10, 11, 12]))
            .collect();
        let w = rejected_warning(&same, 15).expect("a warning");
        assert!(
            w.ends_with(": shots 10, 11, 12 in all 15 measurements"),
            "{w}"
        );
        let mut mixed: BTreeMap<String, Vec<usize>> =
            (0..7).map(|m| (format!("m{m}"), vec![0])).collect();
        mixed.insert("x".into(), vec![3, 4]);
        let w = rejected_warning(&mixed, 20).expect("a warning");
        assert!(w.contains("in 8 of 20 measurements"), "{w}");
        assert!(
            w.ends_with(
                ": shot 0 in \"m0\", \"m1\", \"m2\", \"m3\", \"m4\", 2 more; shots 3, 4 in \"x\""
            ),
            "{w}"
        );
    }
}

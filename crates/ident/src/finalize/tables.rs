//! The result's tables from fitted values: per-shot statistics of f, Q and the parameters,
//! every equation's coefficients, forces, actuator gains and the fits' diagnostics. The final
//! result ([`super::finalize`]) and the per-shot report ([`report_from_shots`]) are both
//! made of them.

use crate::layout::Unknown;
use crate::problem::{Fit, GroupDiagnostics, Problem};
use crate::shots::shot_stats;
use harmonid_data::result::{
    Estimate, FitReport, ForceResult, GainResult, ModeResult, Report, RESULT_FORMAT,
};
use harmonid_data::Dataset;
use num_complex::Complex64;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// An estimate from its per-shot values (`value` their median, `std` their spread after
/// outlier rejection) or, with one shot, from the fit's variance `single_var`.
pub(super) fn estimate(per_shot: Vec<f64>, single_var: f64) -> Estimate {
    let st = shot_stats(&per_shot);
    let n = per_shot.len();
    let single = single_var.max(0.0).sqrt();
    let (value, std, stderr) = if n <= 1 {
        (st.median, single, single)
    } else {
        (
            st.median,
            st.std,
            1.2533 * st.std / (st.n_used.max(1) as f64).sqrt(),
        )
    };
    let identifiable = value.is_finite() && std.is_finite() && std <= value.abs();
    Estimate {
        value,
        std,
        stderr,
        crlb: None,
        jackknife: None,
        at_bound: false,
        identifiable,
        reason: (!identifiable)
            .then(|| "the data do not determine it (relative std above 1)".to_string()),
        outlier_shots: if n > 1 { st.outliers } else { Vec::new() },
        single_shot_std: single,
        per_shot,
    }
}

/// The reason of a quantity the model fixes.
pub(super) const FIXED_BY_THE_MODEL: &str = "fixed by the model";

fn mark_fixed(e: &mut Estimate) {
    e.std = 0.0;
    e.stderr = 0.0;
    e.identifiable = true;
    e.reason = Some(FIXED_BY_THE_MODEL.into());
}

/// Per-shot values of unknown `i`.
fn column(fit: &Fit, i: usize) -> Vec<f64> {
    fit.values.iter().map(|v| v[i]).collect()
}

/// f and Q of every mode from the per-shot fits (variances of shot 0 for a single shot).
pub(super) fn mode_estimates(prob: &Problem, fit: &Fit) -> BTreeMap<String, ModeResult> {
    let not_id = |i: usize| prob.not_identifiable.iter().find(|x| x.unknown == i);
    let mut modes = BTreeMap::new();
    for (n, name) in prob.mode_names.iter().enumerate() {
        let (Some(iw), Some(ig)) = (
            prob.index_of(&Unknown::OmegaSq(n)),
            prob.index_of(&Unknown::Gamma(n)),
        ) else {
            continue;
        };
        let w2 = column(fit, iw);
        let g = column(fit, ig);
        let f: Vec<f64> = w2.iter().map(|w| w.sqrt() / (2.0 * PI)).collect();
        let q: Vec<f64> = w2.iter().zip(&g).map(|(w, g)| w.sqrt() / g).collect();
        let (var_f, var_q) = match fit.cov_lin.first().and_then(|m| m.get(&n)) {
            Some(c) => {
                let w = w2[0].sqrt();
                let df = 1.0 / (2.0 * w * 2.0 * PI);
                let dq_dw2 = 1.0 / (2.0 * w * g[0]);
                let dq_dg = -w / (g[0] * g[0]);
                (
                    df * df * c[0],
                    dq_dw2 * dq_dw2 * c[0] + 2.0 * dq_dw2 * dq_dg * c[1] + dq_dg * dq_dg * c[3],
                )
            }
            None => {
                let df = 1.0 / (2.0 * w2[0].sqrt() * 2.0 * PI);
                (df * df * fit.cov_diag[0][iw], f64::NAN)
            }
        };
        let mut fe = estimate(f, var_f);
        let mut qe = estimate(q, var_q);
        // Q's distribution is skewed (Q = ω/γ): the data determine Q only when they also
        // determine the damping rate γ = ω/Q itself.
        let ge = estimate(g, fit.cov_diag[0][ig]);
        if qe.identifiable && !ge.identifiable {
            qe.identifiable = false;
            qe.reason = Some(format!(
                "the damping rate ω/Q is not determined (relative std {:.2})",
                ge.std / ge.value.abs()
            ));
        }
        if prob.table.fixed()[iw].is_some() {
            mark_fixed(&mut fe);
        }
        if prob.table.fixed()[ig].is_some() {
            mark_fixed(&mut qe);
        }
        for (e, i) in [(&mut fe, iw), (&mut qe, ig)] {
            if let Some(ni) = not_id(i) {
                e.identifiable = false;
                e.reason = Some(ni.reason.clone());
            }
        }
        modes.insert(name.clone(), ModeResult { f_hz: fe, q: qe });
    }
    modes
}

/// Every model parameter from the per-shot fits (NaN where no measurement determines it).
pub(super) fn param_estimates(prob: &Problem, fit: &Fit) -> BTreeMap<String, Estimate> {
    let mut parameters = BTreeMap::new();
    for (p, name) in prob.param_names.iter().enumerate() {
        let Some(i) = prob.index_of(&Unknown::Param(p)) else {
            continue;
        };
        let mut e = estimate(column(fit, i), fit.cov_diag[0][i]);
        if prob.table.fixed()[i].is_some() {
            mark_fixed(&mut e);
        }
        if let Some(ni) = prob.not_identifiable.iter().find(|x| x.unknown == i) {
            e.identifiable = false;
            e.reason = Some(ni.reason.clone());
            e.value = f64::NAN;
        }
        parameters.insert(name.clone(), e);
    }
    parameters
}

/// Every monomial coefficient of every equation: the median over `values` (one vector per
/// shot, in the layout of `prob.table`).
pub(super) fn eom_table(
    prob: &Problem,
    values: &[Vec<f64>],
) -> BTreeMap<String, BTreeMap<String, Option<f64>>> {
    let theta: Vec<Vec<f64>> = values
        .iter()
        .map(|v| {
            (0..prob.param_names.len())
                .map(|p| prob.index_of(&Unknown::Param(p)).map_or(f64::NAN, |i| v[i]))
                .collect()
        })
        .collect();
    let mut eom = BTreeMap::new();
    for (n, name) in prob.mode_names.iter().enumerate() {
        let mut per: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for th in &theta {
            for (m, b) in prob.eom_coefficients(n, th) {
                per.entry(prob.monomial_name(&m)).or_default().push(b);
            }
        }
        let row: BTreeMap<String, Option<f64>> = per
            .into_iter()
            .map(|(k, v)| {
                let med = shot_stats(&v).median;
                (k, med.is_finite().then_some(med))
            })
            .collect();
        if !row.is_empty() {
            eom.insert(name.clone(), row);
        }
    }
    eom
}

/// Forces per measurement and mode (median over `values` of each complex force).
pub(super) fn force_table(
    ds: &Dataset,
    prob: &Problem,
    values: &[Vec<f64>],
) -> BTreeMap<String, BTreeMap<String, Vec<ForceResult>>> {
    let mut forces: BTreeMap<String, BTreeMap<String, Vec<ForceResult>>> = BTreeMap::new();
    for (mi, m) in ds.measurements.iter().enumerate() {
        let per: Vec<_> = values.iter().map(|v| prob.forces(mi, v)).collect();
        let Some(first) = per.first() else { continue };
        for (k, &(tone, n, _)) in first.iter().enumerate() {
            let re: Vec<f64> = per.iter().map(|x| x[k].2.re).collect();
            let im: Vec<f64> = per.iter().map(|x| x[k].2.im).collect();
            let z = Complex64::new(shot_stats(&re).median, shot_stats(&im).median);
            forces
                .entry(m.spec.name.clone())
                .or_default()
                .entry(prob.mode_names[n].clone())
                .or_default()
                .push(ForceResult {
                    f_hz: m.spec.drives_hz[tone],
                    amplitude: z.norm(),
                    phase_rad: z.arg(),
                });
        }
    }
    forces
}

/// Actuator gains per measurement (or "all") and mode (median over `values`).
pub(super) fn gain_table(
    ds: &Dataset,
    prob: &Problem,
    values: &[Vec<f64>],
) -> BTreeMap<String, BTreeMap<String, GainResult>> {
    let median = |i: usize| shot_stats(&values.iter().map(|v| v[i]).collect::<Vec<_>>()).median;
    let mut gains: BTreeMap<String, BTreeMap<String, GainResult>> = BTreeMap::new();
    for (i, u) in prob.table.unknowns().iter().enumerate() {
        let Unknown::Gain {
            meas,
            mode,
            quad: 0,
        } = *u
        else {
            continue;
        };
        let Some(j) = prob.index_of(&Unknown::Gain {
            meas,
            mode,
            quad: 1,
        }) else {
            continue;
        };
        let (re, im) = (median(i), median(j));
        let z = Complex64::new(re, im);
        let key = meas.map_or("all".to_string(), |m| ds.measurements[m].spec.name.clone());
        gains.entry(key).or_default().insert(
            prob.mode_names[mode].clone(),
            GainResult {
                amplitude: z.norm(),
                phase_rad: z.arg(),
                re,
                im,
            },
        );
    }
    gains
}

/// The fits' diagnostics as reported.
pub(super) fn fit_reports(
    ds: &Dataset,
    prob: &Problem,
    groups: &[GroupDiagnostics],
) -> Vec<FitReport> {
    groups
        .iter()
        .map(|g| FitReport {
            stage: g.stage,
            measurements: g
                .measurements
                .iter()
                .map(|&m| ds.measurements[m].spec.name.clone())
                .collect(),
            unknowns: g.unknowns.iter().map(|&u| prob.label(u)).collect(),
            condition_number: g.cond,
            relative_residual: g.rms_residual,
            rows: g.rows,
            weighted: g.weighted,
            noise_from_shots: g.noise_from_shots,
            shots_with_active_bounds: g.status_bounds,
        })
        .collect()
}

/// Warnings about fits whose conditioning exceeds what the data's precision supports (the
/// relative noise of the right-hand side: warned when cond × residual > 1).
pub(super) fn conditioning_warnings(fits: &[FitReport]) -> Vec<String> {
    let mut warnings = Vec::new();
    for f in fits {
        let (cond, meas) = (f.condition_number, f.measurements.join(" + "));
        if cond > 1e12 || !cond.is_finite() {
            warnings.push(format!(
                "fit of {meas} (stage {}) is badly conditioned (condition number {cond:.2e} after column equilibration): its estimates are sensitive to noise at the {:.0e} level",
                f.stage,
                1.0 / cond
            ));
        } else if cond * f.relative_residual > 1.0 {
            warnings.push(format!(
                "fit of {meas} (stage {}): condition number {cond:.2e} times the relative residual {:.2e} exceeds 1, beyond what the data's precision supports",
                f.stage, f.relative_residual
            ));
        }
    }
    warnings
}

/// Warnings about forces and gains no measurement determines.
pub(super) fn force_warnings(prob: &Problem) -> Vec<String> {
    prob.not_identifiable
        .iter()
        .filter(|ni| {
            matches!(
                prob.table.unknowns()[ni.unknown],
                Unknown::Force { .. } | Unknown::Gain { .. }
            )
        })
        .map(|ni| format!("{}: {}", prob.label(ni.unknown), ni.reason))
        .collect()
}

/// Warnings about the frequencies, quality factors and parameters the data do not
/// determine, with why.
pub(super) fn undetermined_warnings(
    modes: &BTreeMap<String, ModeResult>,
    parameters: &BTreeMap<String, Estimate>,
) -> Vec<String> {
    let mut warnings = Vec::new();
    for (n, m) in modes {
        for (what, e) in [("f", &m.f_hz), ("Q", &m.q)] {
            if !e.identifiable {
                warnings.push(format!(
                    "{what} of {n} is not determined by the data: {}",
                    e.reason.clone().unwrap_or_default()
                ));
            }
        }
    }
    for (p, e) in parameters {
        if !e.identifiable {
            warnings.push(format!(
                "parameter {p} is not determined: {}",
                e.reason.clone().unwrap_or_default()
            ));
        }
    }
    warnings
}

/// Shots flagged as outliers by any quantity, sorted.
pub(super) fn outlier_shots(
    modes: &BTreeMap<String, ModeResult>,
    parameters: &BTreeMap<String, Estimate>,
) -> Vec<usize> {
    let mut shots: Vec<usize> = modes
        .values()
        .flat_map(|m| m.f_hz.outlier_shots.iter().chain(&m.q.outlier_shots))
        .chain(parameters.values().flat_map(|e| e.outlier_shots.iter()))
        .copied()
        .collect();
    shots.sort_unstable();
    shots.dedup();
    shots
}

/// The per-shot report: every quantity the median and spread of the per-shot
/// equation-error estimates of `fit` (estimator `per-shot`), as the method's paper reports
/// them; a noise study's view. `identify`'s result is built from the output-error fit instead.
pub fn report_from_shots(model_path: &str, ds: &Dataset, prob: &Problem, fit: &Fit) -> Report {
    let modes = mode_estimates(prob, fit);
    let parameters = param_estimates(prob, fit);
    let fits = fit_reports(ds, prob, &fit.groups);
    let mut warnings = prob.warnings.clone();
    warnings.extend(undetermined_warnings(&modes, &parameters));
    warnings.extend(conditioning_warnings(&fits));
    warnings.extend(force_warnings(prob));
    Report {
        format: RESULT_FORMAT.to_string(),
        model: model_path.to_string(),
        dataset: ds.dir.display().to_string(),
        estimator: "per-shot".into(),
        rejected_shots: BTreeMap::new(),
        notes: Vec::new(),
        force_model: prob.table.force_model().description().to_string(),
        goodness_of_fit: None,
        excluded_levels: Vec::new(),
        holdout: Vec::new(),
        unfit: Vec::new(),
        shots: fit.values.len(),
        shots_fitted: None,
        shot_index: Vec::new(),
        outlier_shots: outlier_shots(&modes, &parameters),
        eom: eom_table(prob, &fit.values),
        forces: force_table(ds, prob, &fit.values),
        gains: gain_table(ds, prob, &fit.values),
        background: BTreeMap::new(),
        modes,
        parameters,
        fits,
        warnings,
        consistency: Vec::new(),
    }
}

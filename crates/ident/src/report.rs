//! Statistics over shots and the result of an identification (`DATA_FORMAT.md`, "Result of an
//! identification"), with a readable summary table and a per-shot CSV.

use crate::dataset::{index_list, Dataset};
use crate::problem::{Estimator, Fit, ForceModel, Problem, Unknown};
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt::Write as _;

/// The result format written by [`Report`].
pub const RESULT_FORMAT: &str = "harmonid-result/1";

/// Robust statistics of per-shot estimates.
#[derive(Debug, Clone, PartialEq)]
pub struct ShotStats {
    /// Median of the finite estimates.
    pub median: f64,
    /// Sample standard deviation of the estimates inside the IQR fences.
    pub std: f64,
    /// Shots outside the fences `[Q1 − 1.5 IQR, Q3 + 1.5 IQR]` (or not finite).
    pub outliers: Vec<usize>,
    /// Number of estimates used for `std`.
    pub n_used: usize,
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let j = (i + 1).min(sorted.len() - 1);
    let t = pos - i as f64;
    sorted[i] * (1.0 - t) + sorted[j] * t
}

/// Median, the standard deviation after rejecting outliers by the interquartile rule (the
/// method's paper discards estimates outside the IQR fences and fits a normal distribution to
/// the rest), and the outlier shots. With fewer than 4 estimates nothing is rejected.
pub fn shot_stats(values: &[f64]) -> ShotStats {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    finite.sort_by(f64::total_cmp);
    let median = quantile(&finite, 0.5);
    let (lo, hi) = if finite.len() >= 4 {
        let (q1, q3) = (quantile(&finite, 0.25), quantile(&finite, 0.75));
        let iqr = q3 - q1;
        (q1 - 1.5 * iqr, q3 + 1.5 * iqr)
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    };
    let mut outliers = Vec::new();
    let mut used = Vec::new();
    for (s, &v) in values.iter().enumerate() {
        if v.is_finite() && v >= lo && v <= hi {
            used.push(v);
        } else {
            outliers.push(s);
        }
    }
    let n = used.len();
    let std = if n >= 2 {
        let mean = used.iter().sum::<f64>() / n as f64;
        (used.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        f64::NAN
    };
    ShotStats {
        median,
        std,
        outliers,
        n_used: n,
    }
}

/// One reported quantity.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Estimate {
    /// The estimate: output-error maximum likelihood on the pooled shots (`estimator` "ml"),
    /// or the equation-error fit of the pooled shots ("linear"); see `docs/identification.md`.
    #[serde(deserialize_with = "nan_if_null")]
    pub value: f64,
    /// One-sigma spread of the per-shot (equation-error) estimates after outlier rejection,
    /// the width of the paper's histograms; with one shot, the fit's standard error from its
    /// residuals. A diagnostic: it is not the uncertainty of `value`.
    #[serde(deserialize_with = "nan_if_null")]
    pub std: f64,
    /// Standard error of `value`: ml, `√diag((JᵀWJ)⁻¹)` at the estimate with the noise of
    /// every line from the shot scatter (nuisances profiled), times `√(χ²/dof)` when the fit
    /// is worse than the noise; linear, the per-shot spread over `√n`.
    #[serde(deserialize_with = "nan_if_null")]
    pub stderr: f64,
    /// Cramér–Rao bound at the estimate (same noise, `√diag(I⁻¹)`), when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crlb: Option<f64>,
    /// Linearised delete-one-shot jackknife standard error of `value`, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jackknife: Option<f64>,
    /// The estimate sits at a bound of the parameter (the data favour a value beyond it).
    #[serde(default, skip_serializing_if = "is_false")]
    pub at_bound: bool,
    /// False when the data do not determine it (relative stderr above 0.3, or not
    /// identifiable).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub identifiable: bool,
    /// Why it is not identifiable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Shots flagged as outliers for this quantity.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outlier_shots: Vec<usize>,
    /// The fit's own standard error of shot 0 (from the least-squares residuals).
    #[serde(default = "nan", deserialize_with = "nan_if_null")]
    pub single_shot_std: f64,
    /// Per-shot estimates.
    #[serde(skip)]
    pub per_shot: Vec<f64>,
}

fn is_true(b: &bool) -> bool {
    *b
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn yes() -> bool {
    true
}

fn nan() -> f64 {
    f64::NAN
}

/// Reads a number written by [`Report::to_json`], where NaN became `null`, back as NaN.
fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Linear parameters of one mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModeResult {
    /// Linear resonance frequency, Hz.
    pub f_hz: Estimate,
    /// Quality factor.
    #[serde(rename = "Q")]
    pub q: Estimate,
}

/// A drive tone's identified force on a mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ForceResult {
    /// Tone frequency, Hz.
    #[serde(deserialize_with = "nan_if_null")]
    pub f_hz: f64,
    /// Peak force amplitude, N/kg (median over shots of the complex force).
    #[serde(deserialize_with = "nan_if_null")]
    pub amplitude: f64,
    /// Phase, rad.
    #[serde(deserialize_with = "nan_if_null")]
    pub phase_rad: f64,
}

/// One complex actuator gain.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GainResult {
    /// |G|, N/kg per drive-level unit.
    #[serde(deserialize_with = "nan_if_null")]
    pub amplitude: f64,
    /// arg G, rad.
    #[serde(deserialize_with = "nan_if_null")]
    pub phase_rad: f64,
    /// Real part (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub re: f64,
    /// Imaginary part (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub im: f64,
}

/// Diagnostics of one fit, as reported.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitReport {
    /// Stage (1 = single-mode measurements, 2 = two-mode, ...; 0 = joint fit).
    pub stage: usize,
    /// Measurement names.
    pub measurements: Vec<String>,
    /// Fitted unknowns.
    pub unknowns: Vec<String>,
    /// Condition number of the column-equilibrated matrix (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub condition_number: f64,
    /// Relative residual `sqrt(Σ RSS / Σ ‖b‖²)`.
    #[serde(deserialize_with = "nan_if_null")]
    pub relative_residual: f64,
    /// Real equations.
    pub rows: usize,
    /// Whether the equations were weighted by the covariance of their errors (generalised
    /// least squares).
    pub weighted: bool,
    /// Whether the measured amplitudes' noise came from the scatter across shots.
    pub noise_from_shots: bool,
    /// Shots in which a bound was active.
    pub shots_with_active_bounds: usize,
}

/// The result of an identification (`DATA_FORMAT.md` schema, plus diagnostics).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// [`RESULT_FORMAT`].
    pub format: String,
    /// Model path.
    pub model: String,
    /// Dataset path.
    pub dataset: String,
    /// Force model used.
    #[serde(default)]
    pub force_model: String,
    /// The estimator of `value`: `"ml"` (output-error maximum likelihood by harmonic balance)
    /// or `"linear"` (equation-error fit of the pooled shots).
    #[serde(default)]
    pub estimator: String,
    /// Per measurement, the shots left out of the pooled mean as disturbed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub rejected_shots: BTreeMap<String, Vec<usize>>,
    /// Notes on how the estimate was made (noise source, fall-backs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Number of shots.
    #[serde(default)]
    pub shots: usize,
    /// Linear parameters per mode.
    pub modes: BTreeMap<String, ModeResult>,
    /// Parameters by their model names.
    pub parameters: BTreeMap<String, Estimate>,
    /// Every monomial coefficient of every equation (median over shots).
    #[serde(default)]
    pub eom: BTreeMap<String, BTreeMap<String, Option<f64>>>,
    /// Forces per measurement and mode, one entry per drive tone acting on that mode.
    #[serde(default)]
    pub forces: BTreeMap<String, BTreeMap<String, Vec<ForceResult>>>,
    /// Actuator gains per measurement (or "all") and mode, for the drive-level force model.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub gains: BTreeMap<String, BTreeMap<String, GainResult>>,
    /// The fits, in order.
    #[serde(default)]
    pub fits: Vec<FitReport>,
    /// Shots flagged as outliers by any quantity.
    #[serde(default)]
    pub outlier_shots: Vec<usize>,
    /// Warnings (conditioning, unidentifiable quantities, ...).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Every comparison of a frequency, Q or actuator gain between two measurements
    /// ([`crate::consistency`]); those beyond the threshold are also in `warnings`. Not
    /// written to the result file.
    #[serde(skip)]
    pub consistency: Vec<crate::consistency::Comparison>,
}

fn estimate(per_shot: Vec<f64>, single_var: f64) -> Estimate {
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

impl Report {
    /// Builds the report from a fitted problem.
    pub fn new(model_path: &str, ds: &Dataset, prob: &Problem, fit: &Fit) -> Report {
        let nshots = fit.values.len();
        let col = |i: usize| -> Vec<f64> { fit.values.iter().map(|v| v[i]).collect() };
        let mut warnings = prob.warnings.clone();
        let not_id = |i: usize| prob.not_identifiable.iter().find(|x| x.unknown == i);
        let mut modes = BTreeMap::new();
        for (n, name) in prob.mode_names.iter().enumerate() {
            let (Some(iw), Some(ig)) = (
                prob.index_of(&Unknown::OmegaSq(n)),
                prob.index_of(&Unknown::Gamma(n)),
            ) else {
                continue;
            };
            let w2 = col(iw);
            let g = col(ig);
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
            let ge = estimate(g.clone(), fit.cov_diag[0][ig]);
            if qe.identifiable && !ge.identifiable {
                qe.identifiable = false;
                qe.reason = Some(format!(
                    "the damping rate ω/Q is not determined (relative std {:.2})",
                    ge.std / ge.value.abs()
                ));
            }
            if prob.table.fixed()[iw].is_some() {
                fe.std = 0.0;
                fe.stderr = 0.0;
                fe.identifiable = true;
                fe.reason = Some("fixed by the model".into());
            }
            if prob.table.fixed()[ig].is_some() {
                qe.std = 0.0;
                qe.stderr = 0.0;
                qe.identifiable = true;
                qe.reason = Some("fixed by the model".into());
            }
            for (e, i) in [(&mut fe, iw), (&mut qe, ig)] {
                if let Some(ni) = not_id(i) {
                    e.identifiable = false;
                    e.reason = Some(ni.reason.clone());
                }
            }
            if !qe.identifiable {
                warnings.push(format!(
                    "Q of {name} is not determined by the data: {}",
                    qe.reason.clone().unwrap_or_default()
                ));
            }
            if !fe.identifiable {
                warnings.push(format!(
                    "f of {name} is not determined by the data: {}",
                    fe.reason.clone().unwrap_or_default()
                ));
            }
            modes.insert(name.clone(), ModeResult { f_hz: fe, q: qe });
        }
        let mut parameters = BTreeMap::new();
        let mut theta_per_shot = vec![vec![f64::NAN; prob.param_names.len()]; nshots];
        for (p, name) in prob.param_names.iter().enumerate() {
            let Some(i) = prob.index_of(&Unknown::Param(p)) else {
                continue;
            };
            let v = col(i);
            for (s, x) in v.iter().enumerate() {
                theta_per_shot[s][p] = *x;
            }
            let mut e = estimate(v, fit.cov_diag[0][i]);
            if prob.table.fixed()[i].is_some() {
                e.std = 0.0;
                e.stderr = 0.0;
                e.identifiable = true;
                e.reason = Some("fixed by the model".into());
            }
            if let Some(ni) = not_id(i) {
                e.identifiable = false;
                e.reason = Some(ni.reason.clone());
                e.value = f64::NAN;
            }
            if !e.identifiable {
                warnings.push(format!(
                    "parameter {name} is not determined: {}",
                    e.reason.clone().unwrap_or_default()
                ));
            }
            parameters.insert(name.clone(), e);
        }
        let mut eom = BTreeMap::new();
        for (n, name) in prob.mode_names.iter().enumerate() {
            let mut per: BTreeMap<String, Vec<f64>> = BTreeMap::new();
            for th in &theta_per_shot {
                for (m, b) in prob.eom_coefficients(n, th) {
                    per.entry(m.name(&prob.mode_names)).or_default().push(b);
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
        let mut forces: BTreeMap<String, BTreeMap<String, Vec<ForceResult>>> = BTreeMap::new();
        for (mi, m) in ds.measurements.iter().enumerate() {
            let per: Vec<_> = fit.values.iter().map(|v| prob.forces(mi, v)).collect();
            let Some(first) = per.first() else { continue };
            for (k, &(tone, n, _)) in first.iter().enumerate() {
                let re: Vec<f64> = per.iter().map(|x| x[k].2.re).collect();
                let im: Vec<f64> = per.iter().map(|x| x[k].2.im).collect();
                let z = num_complex::Complex64::new(shot_stats(&re).median, shot_stats(&im).median);
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
        let mut gains: BTreeMap<String, BTreeMap<String, GainResult>> = BTreeMap::new();
        for (i, u) in prob.table.unknowns().iter().enumerate() {
            if let Unknown::Gain {
                meas,
                mode,
                quad: 0,
            } = u
            {
                let Some(j) = prob.index_of(&Unknown::Gain {
                    meas: *meas,
                    mode: *mode,
                    quad: 1,
                }) else {
                    continue;
                };
                let (re, im) = (shot_stats(&col(i)).median, shot_stats(&col(j)).median);
                let z = num_complex::Complex64::new(re, im);
                let key = meas.map_or("all".to_string(), |m| ds.measurements[m].spec.name.clone());
                gains.entry(key).or_default().insert(
                    prob.mode_names[*mode].clone(),
                    GainResult {
                        amplitude: z.norm(),
                        phase_rad: z.arg(),
                        re,
                        im,
                    },
                );
            }
        }
        let mut fits = Vec::new();
        for g in &fit.groups {
            let meas: Vec<String> = g
                .measurements
                .iter()
                .map(|&m| ds.measurements[m].spec.name.clone())
                .collect();
            // Data precision: relative noise of the right-hand side; warn when cond × noise > 1.
            if g.cond > 1e12 || !g.cond.is_finite() {
                warnings.push(format!(
                    "fit of {} (stage {}) is badly conditioned (condition number {:.2e} after column equilibration): its estimates are sensitive to noise at the {:.0e} level",
                    meas.join(" + "),
                    g.stage,
                    g.cond,
                    1.0 / g.cond
                ));
            } else if g.cond * g.rms_residual > 1.0 {
                warnings.push(format!(
                    "fit of {} (stage {}): condition number {:.2e} times the relative residual {:.2e} exceeds 1, beyond what the data's precision supports",
                    meas.join(" + "),
                    g.stage,
                    g.cond,
                    g.rms_residual
                ));
            }
            fits.push(FitReport {
                stage: g.stage,
                measurements: meas,
                unknowns: g.unknowns.iter().map(|&u| prob.label(u)).collect(),
                condition_number: g.cond,
                relative_residual: g.rms_residual,
                rows: g.rows,
                weighted: g.weighted,
                noise_from_shots: g.noise_from_shots,
                shots_with_active_bounds: g.status_bounds,
            });
        }
        for ni in &prob.not_identifiable {
            if matches!(
                prob.table.unknowns()[ni.unknown],
                Unknown::Force { .. } | Unknown::Gain { .. }
            ) {
                warnings.push(format!("{}: {}", prob.label(ni.unknown), ni.reason));
            }
        }
        let mut outlier_shots: Vec<usize> = modes
            .values()
            .flat_map(|m| m.f_hz.outlier_shots.iter().chain(&m.q.outlier_shots))
            .chain(parameters.values().flat_map(|e| e.outlier_shots.iter()))
            .copied()
            .collect();
        outlier_shots.sort_unstable();
        outlier_shots.dedup();
        Report {
            format: RESULT_FORMAT.to_string(),
            model: model_path.to_string(),
            dataset: ds.dir.display().to_string(),
            estimator: "per-shot".into(),
            rejected_shots: BTreeMap::new(),
            notes: Vec::new(),
            force_model: match prob.table.force_model() {
                ForceModel::Free | ForceModel::Auto => "free complex force per drive tone".into(),
                ForceModel::GainPerMeasurement => {
                    "drive levels: one complex actuator gain per mode and measurement".into()
                }
                ForceModel::GainPerMode => {
                    "drive levels: one complex actuator gain per mode for the whole dataset".into()
                }
            },
            shots: nshots,
            modes,
            parameters,
            eom,
            forces,
            gains,
            fits,
            outlier_shots,
            warnings,
            consistency: Vec::new(),
        }
    }

    /// The result as pretty JSON (NaN written as `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// Reads a result written by [`Report::to_json`] (`null` numbers come back as NaN; keys
    /// added after `harmonid-result/1`'s first version default when missing). Refuses another
    /// `format`.
    pub fn from_json(text: &str) -> Result<Report, serde_json::Error> {
        use serde::de::Error as _;
        let r: Report = serde_json::from_str(text)?;
        if r.format != RESULT_FORMAT {
            return Err(serde_json::Error::custom(format!(
                "format `{}`, expected `{RESULT_FORMAT}`",
                r.format
            )));
        }
        Ok(r)
    }

    /// Every shot's estimates as CSV: `shot`, `f_hz:<mode>`, `Q:<mode>`, parameters, `outlier`.
    pub fn per_shot_csv(&self) -> String {
        let mut cols: Vec<(String, &Estimate)> = Vec::new();
        for (n, m) in &self.modes {
            cols.push((format!("f_hz:{n}"), &m.f_hz));
            cols.push((format!("Q:{n}"), &m.q));
        }
        for (p, e) in &self.parameters {
            cols.push((p.clone(), e));
        }
        let mut s = String::from("shot");
        for (c, _) in &cols {
            s.push(',');
            s.push_str(c);
        }
        s.push_str(",outlier\n");
        for shot in 0..self.shots {
            let _ = write!(s, "{shot}");
            for (_, e) in &cols {
                let _ = write!(
                    s,
                    ",{:e}",
                    e.per_shot.get(shot).copied().unwrap_or(f64::NAN)
                );
            }
            let _ = writeln!(s, ",{}", u8::from(self.outlier_shots.contains(&shot)));
        }
        s
    }

    /// A readable summary: value ± std per quantity (with truth, when the dataset has it), the
    /// fits per stage with residuals and conditioning, warnings.
    pub fn summary(&self, truth: Option<&crate::dataset::Truth>) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "harmonid identify: {} shot(s), force model: {}",
            self.shots, self.force_model
        );
        let _ = writeln!(
            s,
            "  estimator: {}; value ± stderr{}; std = spread of per-shot estimates (diagnostic){}",
            match self.estimator.parse::<Estimator>() {
                Ok(e) => e.description(),
                Err(_) => self.estimator.as_str(),
            },
            if self.estimator == Estimator::Ml.name() {
                " (Fisher information at the estimate)"
            } else {
                ""
            },
            if self.shots <= 1 {
                " (single shot: the fit's standard error)"
            } else {
                ""
            }
        );
        let with_crlb = self
            .modes
            .values()
            .flat_map(|m| [&m.f_hz, &m.q])
            .chain(self.parameters.values())
            .any(|e| e.crlb.is_some());
        let _ = write!(
            s,
            "\n{:<14} {:>18} {:>11} {:>9} {:>11}",
            "quantity", "value", "± stderr", "rel.", "std"
        );
        if with_crlb {
            let _ = write!(s, " {:>11}", "crlb");
        }
        let _ = writeln!(s, " {:>18} {:>10}", "truth", "dev/stderr");
        let mut line = |name: String, e: &Estimate, t: Option<f64>| {
            let rel = e.stderr / e.value.abs();
            let (tt, dev) = match t {
                Some(t) => (
                    format!("{t:.10e}"),
                    format!("{:+.2}", (e.value - t) / e.stderr),
                ),
                None => (String::new(), String::new()),
            };
            let flag = if e.at_bound {
                "  AT BOUND"
            } else if e.identifiable {
                ""
            } else {
                "  NOT DETERMINED"
            };
            let _ = write!(
                s,
                "{name:<14} {:>18.10e} {:>11.3e} {:>9.2e} {:>11.3e}",
                e.value, e.stderr, rel, e.std
            );
            if with_crlb {
                match e.crlb {
                    Some(c) => {
                        let _ = write!(s, " {c:>11.3e}");
                    }
                    None => {
                        let _ = write!(s, " {:>11}", "");
                    }
                }
            }
            let _ = writeln!(s, " {tt:>18} {dev:>10}{flag}");
        };
        for (n, m) in &self.modes {
            let tm = truth.and_then(|t| t.modes.get(n));
            line(format!("f_{n} [Hz]"), &m.f_hz, tm.map(|t| t.f_hz));
            line(format!("Q_{n}"), &m.q, tm.map(|t| t.q));
        }
        for (p, e) in &self.parameters {
            // Truth of a parameter: the truth coefficient of a monomial it alone sets.
            let t = truth.and_then(|t| self.truth_of_param(p, t));
            line(p.clone(), e, t);
        }
        let _ = writeln!(s, "\nfits:");
        for f in &self.fits {
            let _ = writeln!(
                s,
                "  stage {} [{}]: {} unknowns, {} rows, cond {:.2e}, rel. residual {:.2e}{}",
                f.stage,
                f.measurements.join(", "),
                f.unknowns.len(),
                f.rows,
                f.condition_number,
                f.relative_residual,
                match (f.weighted, f.noise_from_shots) {
                    (true, true) => ", GLS, noise from shot scatter",
                    (true, false) => ", GLS with equal amplitude noise",
                    _ => ", unweighted",
                }
            );
        }
        if !self.gains.is_empty() {
            let _ = writeln!(s, "\nactuator gains (N/kg per drive unit):");
            for (m, g) in &self.gains {
                for (n, x) in g {
                    let _ = writeln!(
                        s,
                        "  {m} {n}: |G| = {:.6e}, arg G = {:+.4} rad",
                        x.amplitude, x.phase_rad
                    );
                }
            }
        }
        for (m, shots) in &self.rejected_shots {
            let _ = writeln!(
                s,
                "\nrejected from the pooled mean of {m}: shots {}",
                index_list(shots)
            );
        }
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        if !self.outlier_shots.is_empty() {
            let _ = writeln!(
                s,
                "\noutlier shots of the per-shot fits (outside the IQR fences for some quantity): {}",
                index_list(&self.outlier_shots)
            );
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }

    /// The truth value of parameter `p`: found through the `eom` table, as the coefficient of a
    /// monomial whose identified coefficient equals the parameter (single-parameter terms).
    fn truth_of_param(&self, p: &str, t: &crate::dataset::Truth) -> Option<f64> {
        let e = self.parameters.get(p)?;
        for (mode, row) in &self.eom {
            for (mono, v) in row {
                let v = (*v)?;
                if (v - e.value).abs() <= 1e-12 * e.value.abs() {
                    return t.eom.get(mode).and_then(|r| r.get(mono)).copied();
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iqr_rule_flags_outliers() {
        let mut v: Vec<f64> = (0..20).map(|i| 10.0 + 0.1 * f64::from(i % 5)).collect();
        v[7] = 100.0;
        v[13] = f64::NAN;
        let s = shot_stats(&v);
        assert_eq!(s.outliers, vec![7, 13]);
        assert_eq!(s.n_used, 18);
        assert!((s.median - 10.2).abs() < 1e-12);
        assert!(s.std < 0.2 && s.std > 0.1, "{}", s.std);
    }

    fn est(value: f64, std: f64) -> Estimate {
        let identifiable = std <= value.abs();
        Estimate {
            value,
            std,
            stderr: std / 3.0,
            crlb: Some(std / 3.1),
            jackknife: None,
            at_bound: false,
            identifiable,
            reason: (!identifiable).then(|| "the data do not determine it".to_string()),
            outlier_shots: vec![2],
            single_shot_std: std,
            per_shot: Vec::new(),
        }
    }

    fn sample_report() -> Report {
        let mode = ModeResult {
            f_hz: est(207582.0, 0.8),
            q: est(116232.0, 1.3e4),
        };
        Report {
            format: RESULT_FORMAT.into(),
            model: "model.hb".into(),
            dataset: "ds".into(),
            force_model: "free complex force per drive tone".into(),
            estimator: "ml".into(),
            rejected_shots: [("m".to_string(), vec![1])].into(),
            notes: vec!["a note".into()],
            shots: 3,
            modes: [("q1".to_string(), mode)].into(),
            parameters: [
                ("beta1".to_string(), est(2.68e22, 1.1e21)),
                ("g12".to_string(), est(f64::NAN, 5.0)),
            ]
            .into(),
            eom: [(
                "q1".to_string(),
                [
                    ("q1^3".to_string(), Some(2.68e22)),
                    ("q1*q2^2".to_string(), None),
                ]
                .into(),
            )]
            .into(),
            forces: [(
                "single_q1".to_string(),
                [(
                    "q1".to_string(),
                    vec![ForceResult {
                        f_hz: 207572.5,
                        amplitude: 3.5,
                        phase_rad: -0.25,
                    }],
                )]
                .into(),
            )]
            .into(),
            gains: [(
                "all".to_string(),
                [(
                    "q1".to_string(),
                    GainResult {
                        amplitude: 2.0,
                        phase_rad: 0.5,
                        re: 2.0 * 0.5f64.cos(),
                        im: 2.0 * 0.5f64.sin(),
                    },
                )]
                .into(),
            )]
            .into(),
            fits: vec![FitReport {
                stage: 1,
                measurements: vec!["single_q1".into()],
                unknowns: vec!["f(q1)".into()],
                condition_number: f64::NAN,
                relative_residual: 1e-7,
                rows: 20,
                weighted: true,
                noise_from_shots: false,
                shots_with_active_bounds: 0,
            }],
            outlier_shots: vec![2],
            warnings: vec!["parameter g12 is not determined".into()],
            consistency: Vec::new(),
        }
    }

    #[test]
    fn result_file_reads_back_equal() {
        let r = sample_report();
        let text = r.to_json();
        let back = Report::from_json(&text).expect("reads back");
        // Written again, the same bytes: every field survived (NaN as null, both ways).
        assert_eq!(back.to_json(), text);
        assert_eq!(back.modes["q1"].f_hz.value, 207582.0);
        assert_eq!(back.modes["q1"].q.std, 1.3e4);
        assert!(back.modes["q1"].q.identifiable);
        let g12 = &back.parameters["g12"];
        assert!(g12.value.is_nan() && !g12.identifiable);
        assert_eq!(g12.reason.as_deref(), Some("the data do not determine it"));
        assert_eq!(back.eom["q1"]["q1*q2^2"], None);
        assert_eq!(back.gains["all"]["q1"].im, 2.0 * 0.5f64.sin());
        assert!(back.fits[0].condition_number.is_nan());
        assert_eq!(back.fits[0].rows, 20);
    }

    #[test]
    fn result_file_of_the_data_format_reads_with_defaults() {
        // The minimal example of DATA_FORMAT.md: no diagnostics, no single-shot std.
        let text = r#"{
          "format": "harmonid-result/1",
          "model": "examples/nanostring_2mode/model.hb",
          "dataset": "path/of/the/dataset",
          "modes": {"q1": {"f_hz": {"value": 207582.01, "std": 0.8, "stderr": 0.11},
                           "Q": {"value": 116240.0, "std": 13000.0, "stderr": 1400.0}}},
          "parameters": {"beta1": {"value": 2.68e22, "std": 1.1e22, "stderr": 1.5e21}},
          "eom": {"q1": {"q1^3": 2.68e22}},
          "forces": {"single_q1": {"q1": [{"f_hz": 207572.0, "amplitude": 10.06, "phase_rad": 0.01}]}}
        }"#;
        let r = Report::from_json(text).expect("reads");
        assert_eq!(r.parameters["beta1"].value, 2.68e22);
        assert!(r.parameters["beta1"].identifiable);
        assert!(r.parameters["beta1"].single_shot_std.is_nan());
        assert!(r.warnings.is_empty() && r.fits.is_empty() && r.gains.is_empty());
        let other = text.replace("harmonid-result/1", "harmonid-result/9");
        let e = Report::from_json(&other).expect_err("another format");
        assert!(e.to_string().contains("harmonid-result/9"), "{e}");
    }

    #[test]
    fn gaussian_std_is_recovered() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let d = Normal::new(5.0, 2.0).expect("normal");
        let v: Vec<f64> = (0..4000).map(|_| d.sample(&mut rng)).collect();
        let s = shot_stats(&v);
        // The IQR fences cut ~0.7 % of a normal sample: std shrinks by ~1-2 %.
        assert!((s.std / 2.0 - 1.0).abs() < 0.05, "{}", s.std);
        assert!((s.median - 5.0).abs() < 0.1);
    }
}

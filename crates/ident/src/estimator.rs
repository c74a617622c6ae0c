//! The estimate and its uncertainty: per-shot fits (diagnostic), pooled shots, the pooled
//! equation-error fit (start, or the `linear` estimate), output-error maximum likelihood by
//! harmonic balance (`ml`), Fisher-information standard errors, a linearised jackknife.
//!
//! See `docs/identification.md` ("Estimators and uncertainties") for the rules stated here.

use crate::dataset::Dataset;
use crate::fisher::{self, Noise};
use crate::forward::{ForwardModel, ForwardSettings};
use crate::ml::{self, MlFit, MlSettings};
use crate::pool::{pool, Pooled};
use crate::problem::{Estimator, Fit, IdentError, Problem, Settings, Unknown};
use crate::report::{Estimate, Report};
use harmonid_model::Model;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Relative standard error above which a quantity is reported as not determined.
pub const MAX_REL_STDERR: f64 = 0.3;
/// Relative disagreement of the jackknife and the Fisher standard error that is warned about.
pub const JACKKNIFE_TOL: f64 = 0.3;

/// Identifies `model`'s unknowns from `ds`; see the module documentation.
pub fn identify(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Report, IdentError> {
    let prob = Problem::new(model, ds, settings)?;
    let per_shot = prob.fit(ds)?;
    let pooled = pool(ds);
    let start = prob.fit(&pooled.mean)?;
    let mut report = Report::new(&model.source, ds, &prob, &per_shot);
    let mut notes = Vec::new();
    let shots = per_shot.values.len();
    for (mi, bad) in pooled.rejected.iter().enumerate() {
        if !bad.is_empty() {
            report
                .rejected_shots
                .insert(ds.measurements[mi].spec.name.clone(), bad.clone());
            report.warnings.push(format!(
                "measurement \"{}\": shot(s) {} rejected as disturbed (far from the median spectrum); the estimate uses the other {}",
                ds.measurements[mi].spec.name,
                crate::dataset::index_list(bad),
                pooled.used[mi]
            ));
        }
    }
    if !pooled.noise_from_shots() {
        notes.push(if shots <= 1 {
            "one shot: no shot scatter; the noise is taken from the fit's residual".to_string()
        } else {
            "the shots do not scatter (noise-free data?): the noise is taken from the fit's residual".to_string()
        });
    }
    let theta_lin = start.values[0].clone();
    let mut final_theta = theta_lin.clone();
    let mut estimator = settings.estimator;
    let mut fisher_out: Option<FisherOut> = None;
    if settings.estimator == Estimator::Ml || settings.crlb {
        match ForwardModel::with_table(
            model,
            &pooled.mean,
            prob.table.clone(),
            &ForwardSettings {
                nominal_hz: settings.nominal_hz.clone(),
                ..ForwardSettings::default()
            },
        ) {
            Ok(mut fwd) => {
                fwd.start_from_data(&pooled.mean);
                // Unknowns of a stage whose equation-error fit misses its equations by more
                // than POOR_STAGE: their linear estimates are no guide for the ML start.
                let poor: Vec<usize> = start
                    .groups
                    .iter()
                    .filter(|g| g.rms_residual > POOR_STAGE)
                    .flat_map(|g| g.unknowns.iter().copied())
                    .collect();
                match run_ml(
                    &prob,
                    ds,
                    &mut fwd,
                    &pooled,
                    (&theta_lin, &start.cov_diag[0], &poor),
                    settings,
                ) {
                    Ok(out) => {
                        if settings.estimator == Estimator::Ml {
                            final_theta = ml_values(&prob, &out.fit.theta, &theta_lin);
                        }
                        fisher_out = Some(out);
                    }
                    Err(why) => {
                        report.warnings.push(format!(
                            "{why}; reporting the pooled equation-error (linear) estimate"
                        ));
                        estimator = Estimator::Linear;
                    }
                }
            }
            Err(e) => {
                report.warnings.push(format!(
                    "the model cannot be simulated for this dataset ({e}); reporting the pooled equation-error (linear) estimate"
                ));
                estimator = Estimator::Linear;
            }
        }
    }
    let value_fit = Fit {
        values: vec![final_theta],
        cov_diag: vec![start.cov_diag[0].clone()],
        cov_lin: vec![start.cov_lin[0].clone()],
        groups: start.groups.clone(),
    };
    let values = Report::new(&model.source, ds, &prob, &value_fit);
    merge(
        &mut report,
        &prob,
        &values,
        &pooled,
        estimator,
        fisher_out.as_ref(),
        settings,
    );
    report.notes.extend(notes);
    Ok(report)
}

/// The ML estimate with its Fisher bounds and jackknife.
struct FisherOut {
    fit: MlFit,
    bounds: fisher::Bounds,
    /// `√max(1, χ²/(dof·E₀))` when the noise came from the shot scatter
    /// ([`expected_reduced_chi2`]); 1 otherwise.
    inflation: f64,
    /// Jackknife standard error by quantity name (`f_hz:q1`, `Q:q1`, parameter).
    jackknife: Vec<(String, f64)>,
    /// Drift-check warnings.
    drift: Vec<String>,
    /// Frequencies, Q and gains compared between measurements.
    consistency: Vec<crate::consistency::Comparison>,
    /// Quantities held at a bound (names as in `jackknife`).
    at_bound: Vec<String>,
    /// Quantities the information at the estimate does not determine, with why.
    unidentifiable: Vec<(String, String)>,
    notes: Vec<String>,
}

/// The reported values: the output-error estimate `ml` where it is identified, the
/// equation-error `linear` elsewhere (fixed values, and `γ` of a mode whose `Q` is fixed,
/// which the linear fit derived from its `ω²`). Both are in the layout of `prob.table`.
fn ml_values(prob: &Problem, ml: &[f64], linear: &[f64]) -> Vec<f64> {
    let mut out = linear.to_vec();
    for (k, v) in out.iter_mut().enumerate() {
        if prob.table.is_free(k) && !prob.not_identifiable.iter().any(|x| x.unknown == k) {
            *v = ml[k];
        }
    }
    out
}

/// The reported quantity an unknown is (`f_hz:q1` for ω², `Q:q1` for γ, the parameter's
/// name), as [`fisher::Bound::name`] spells it.
fn quantity_name(fwd: &ForwardModel, prob: &Problem, u: &Unknown) -> String {
    match *u {
        Unknown::OmegaSq(n) => format!("f_hz:{}", fwd.mode_names()[n]),
        Unknown::Gamma(n) => format!("Q:{}", fwd.mode_names()[n]),
        Unknown::Param(p) => prob.param_names[p].clone(),
        _ => String::new(),
    }
}

/// An equation-error stage whose relative residual exceeds this misses its own equations
/// (lines its terms need were not measured, or the state is far from where the harmonic
/// expansion is good): its linear estimates are no guide for the output-error start.
const POOR_STAGE: f64 = 1e-2;

/// A fit whose `χ²/dof` is within this factor of a correct model's expectation is kept
/// without trying the other starts. A wrong minimum is far above it (the designed five-mode
/// plan at 0.01 nm: 10⁴ times); a correct one scatters by `√(2/dof)` around 1.
const GOOD_FIT: f64 = 2.0;

fn run_ml(
    prob: &Problem,
    ds_shots: &Dataset,
    fwd: &mut ForwardModel,
    pooled: &Pooled,
    (theta_lin, start_cov, poor): (&[f64], &[f64], &[usize]),
    settings: &Settings,
) -> Result<FisherOut, String> {
    let ds = &pooled.mean;
    let meas: Vec<Complex64> = ds
        .measurements
        .iter()
        .flat_map(|m| m.data.iter().copied())
        .collect();
    let from_shots = pooled.noise_from_shots();
    // Noise of the pooled mean per observation (forward order = a shot's data order).
    let sigma: Vec<f64> = if from_shots {
        pooled
            .sigma
            .iter()
            .zip(&pooled.used)
            .flat_map(|(s, &n)| {
                s.iter()
                    .flatten()
                    .map(move |x| x / (n as f64).sqrt())
                    .collect::<Vec<_>>()
            })
            .collect()
    } else {
        vec![1.0; meas.len()]
    };
    let theta0 = prob.table.start_from(theta_lin);
    let cols: Vec<usize> = fwd
        .free()
        .into_iter()
        .filter(|&k| !prob.not_identifiable.iter().any(|x| x.unknown == k))
        .collect();
    let bounds = prob.table.bounds();
    let mut notes = Vec::new();
    // Starts, in order: the pooled linear estimate; the same with the model parameters it
    // does not determine (relative standard error above 1) at zero (or their bound); the same
    // with the parameters of a stage whose equation-error fit is poor at zero; every model
    // parameter at zero. A linear estimate far off in a poorly determined coupling can put
    // the harmonic balance past a fold, or the fit into another minimum; a weaker
    // nonlinearity always has a steady state near the data, and the fit moves the parameters
    // from there.
    let mut starts = vec![(theta0.clone(), None)];
    let zero_params = |which: &dyn Fn(usize) -> bool| -> Vec<f64> {
        let mut t = theta0.clone();
        for (k, u) in fwd.unknowns().iter().enumerate() {
            let Unknown::Param(_) = u else { continue };
            if fwd.fixed()[k].is_some() || !which(k) {
                continue;
            }
            let (lo, hi) = bounds[k];
            t[k] = 0.0_f64
                .max(lo.unwrap_or(f64::NEG_INFINITY))
                .min(hi.unwrap_or(f64::INFINITY));
        }
        t
    };
    starts.push((
        zero_params(&|k| {
            // Loose: a relative standard error above 1, or none at all (NaN).
            let se = start_cov.get(k).copied().unwrap_or(f64::NAN).sqrt();
            se.is_nan() || se > theta_lin[k].abs()
        }),
        Some("the model parameters the pooled linear fit does not determine at zero"),
    ));
    starts.push((
        zero_params(&|k| poor.contains(&k)),
        Some("the model parameters of poorly fitting equation-error stages at zero"),
    ));
    starts.push((
        zero_params(&|_| true),
        Some("every model parameter at zero"),
    ));
    starts.dedup_by(|b, a| a.0 == b.0);
    // Each start in turn until a fit is as good as a correct model's (χ²/dof within GOOD_FIT
    // of its expectation, judged when the noise comes from the shot scatter); of the fits
    // reached, the one with the smallest χ².
    let e0 = if from_shots {
        expected_reduced_chi2(ds_shots, pooled)
    } else {
        f64::INFINITY
    };
    let reduced = |f: &MlFit| f.chi2 / f.dof.max(1) as f64;
    let mut first_err = None;
    let mut best: Option<(MlFit, usize)> = None;
    let mut first_fit_chi2: Option<f64> = None;
    let mut last_run = 0;
    let n_starts = starts.len();
    for (i, (theta_s, _)) in starts.iter().enumerate() {
        if best
            .as_ref()
            .is_some_and(|(f, _)| reduced(f) <= GOOD_FIT * e0)
        {
            break;
        }
        // Newton from the data at each start; the drive ramp from rest only at the last.
        if i > 0 {
            fwd.start_from_data(ds);
        }
        last_run = i;
        let ml_settings = MlSettings {
            ramp_at_start: i + 1 == n_starts,
            ..MlSettings::default()
        };
        match ml::refine(fwd, &meas, &sigma, theta_s, &cols, bounds, &ml_settings) {
            Ok(f) => {
                if i == 0 {
                    first_fit_chi2 = Some(reduced(&f));
                }
                if best.as_ref().is_none_or(|(b, _)| f.chi2 < b.chi2) {
                    best = Some((f, i));
                }
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    let fit = match (best, first_err) {
        (Some((f, i)), first_err) => {
            if i != last_run {
                // The forward model's states are another start's: back to this fit's, found
                // from the data it matches.
                fwd.start_from_data(ds);
                let mut x = vec![Complex64::new(0.0, 0.0); fwd.n_observations()];
                fwd.evaluate_trial(&f.theta, &mut x)
                    .map_err(|e| format!("output-error fit: back at its estimate: {e}"))?;
            }
            if let Some(what) = starts[i].1 {
                let why = match (first_fit_chi2, first_err) {
                    (Some(c), _) => format!(
                        "from the pooled linear estimate it ended at χ²/dof = {c:.3e}, {:.3e} from here (a correct model gives about {e0:.3})",
                        reduced(&f)
                    ),
                    (None, Some(e)) => format!("at the pooled linear estimate {e}"),
                    (None, None) => String::new(),
                };
                notes.push(format!("the output-error fit started from {what}: {why}"));
            }
            f
        }
        (None, Some(e)) => return Err(format!("output-error fit: {e}")),
        (None, None) => return Err("output-error fit: no start".into()),
    };
    let dof = fit.dof.max(1) as f64;
    let (noise, inflation) = if from_shots {
        let red = fit.chi2 / dof / expected_reduced_chi2(ds_shots, pooled);
        (Noise::PerObservation(sigma.clone()), red.max(1.0).sqrt())
    } else {
        let s = (fit.chi2 / dof).sqrt();
        (
            Noise::Uniform(if s > 0.0 { s } else { f64::MIN_POSITIVE }),
            1.0,
        )
    };
    let bounds_f = fisher::crlb_from_jacobian(fwd, &fit.theta, &fit.jac, &noise, 1)
        .map_err(|e| format!("Fisher information at the estimate: {e}"))?;
    let jackknife = if settings.jackknife && from_shots {
        jackknife(fwd, prob, &fit, &sigma, ds_shots, pooled, &cols)
    } else {
        Vec::new()
    };
    let drift = if from_shots {
        drift_warnings(fwd, &fit, &sigma, ds_shots, pooled)
    } else {
        Vec::new()
    };
    let consistency = {
        let kept: Vec<usize> = cols
            .iter()
            .copied()
            .filter(|k| !fit.at_bound.contains(k))
            .collect();
        let sigma_used: Vec<f64> = match &noise {
            Noise::PerObservation(v) => v.clone(),
            Noise::Uniform(s) => vec![*s; meas.len()],
        };
        let names: Vec<String> = ds
            .measurements
            .iter()
            .map(|m| m.spec.name.clone())
            .collect();
        crate::consistency::compare(&crate::consistency::Fitted {
            fwd,
            theta: &fit.theta,
            meas: &meas,
            x: &fit.x,
            jac: &fit.jac,
            sigma: &sigma_used,
            cols: &kept,
            dof: fit.dof,
            names: &names,
        })
    };
    if !fit.converged {
        notes.push(format!(
            "the output-error fit stopped after {} steps before converging (χ² {:.4e} from {:.4e})",
            fit.steps, fit.chi2, fit.chi2_start
        ));
    }
    let at_bound = fit
        .at_bound
        .iter()
        .map(|&k| quantity_name(fwd, prob, &fwd.unknowns()[k]))
        .collect();
    let unidentifiable = bounds_f
        .unidentifiable
        .iter()
        .map(|u| {
            (
                quantity_name(fwd, prob, &fwd.unknowns()[u.unknown]),
                format!("the data do not determine it at the estimate: {}", u.reason),
            )
        })
        .filter(|(n, _)| !n.is_empty())
        .collect();
    Ok(FisherOut {
        drift,
        consistency,
        fit,
        unidentifiable,
        bounds: bounds_f,
        inflation,
        jackknife,
        at_bound,
        notes,
    })
}

/// `E₀`, the expected `χ²/dof` of a correct model when every line's noise is its sample
/// standard deviation over the kept shots (as [`crate::pool`] estimates it): `σ̂²` has
/// `ν = 2(n − 1)` degrees of freedom (real and imaginary parts of `n` shots) and is
/// independent of the mean, so `E[σ²/σ̂²] = ν/(ν − 2)`, averaged over the observations (1
/// where `ν ≤ 4`, whose expectation is unbounded or large). The fit is worse than the noise
/// when `χ²/dof` exceeds this, not 1: 20 shots give 1.056, and comparing with 1 inflated the
/// standard errors of a correct model by 5 % on average (two-mode nanostring, 1600
/// realisations: ±1 stderr held the truth in 70.6 %, not 68.3 %).
fn expected_reduced_chi2(ds: &Dataset, pooled: &Pooled) -> f64 {
    let (mut sum, mut count) = (0.0, 0.0);
    for (m, &n) in ds.measurements.iter().zip(&pooled.used) {
        let obs = (m.freqs_hz.len() * m.points.len()) as f64;
        let nu = 2.0 * (n as f64 - 1.0);
        sum += obs * if nu > 4.0 { nu / (nu - 2.0) } else { 1.0 };
        count += obs;
    }
    if count > 0.0 {
        sum / count
    } else {
        1.0
    }
}

/// Linearised delete-one-shot jackknife: leaving shot `i` (of every measurement) out moves
/// the pooled mean by `δX = (X̄ − X_i)/(n − 1)` and the estimate by one Gauss–Newton step
/// `δθ = (AᵀA)⁻¹Aᵀ δX/σ`; the jackknife variance is `(n−1)/n Σ (δθ_i − mean)²`, propagated to
/// f and Q to first order. It checks the noise model (per-line σ, correlations between lines
/// that the diagonal weighting ignores) without refitting.
fn jackknife(
    fwd: &ForwardModel,
    prob: &Problem,
    fit: &MlFit,
    sigma: &[f64],
    ds: &Dataset,
    pooled: &Pooled,
    cols: &[usize],
) -> Vec<(String, f64)> {
    let nk = fwd.unknowns().len();
    let n_obs = sigma.len();
    let free: Vec<usize> = cols
        .iter()
        .copied()
        .filter(|k| !fit.at_bound.contains(k))
        .collect();
    let nf = free.len();
    let kept = pooled.kept(ds);
    let groups = kept.iter().map(Vec::len).max().unwrap_or(0);
    if nf == 0 || groups < 3 {
        return Vec::new();
    }
    let mut a = DMatrix::<f64>::zeros(2 * n_obs, nf);
    for o in 0..n_obs {
        for (j, &k) in free.iter().enumerate() {
            let z = fit.jac[o * nk + k] / sigma[o];
            a[(2 * o, j)] = z.re;
            a[(2 * o + 1, j)] = z.im;
        }
    }
    let mut scale = vec![0.0; nf];
    for (j, s) in scale.iter_mut().enumerate() {
        let n = a.column(j).norm();
        *s = if n > 0.0 { 1.0 / n } else { 0.0 };
        a.column_mut(j).scale_mut(*s);
    }
    let svd = a.svd(true, true);
    let mut b = DMatrix::<f64>::zeros(2 * n_obs, groups);
    let mut offset = 0;
    for (mi, m) in ds.measurements.iter().enumerate() {
        let per = m.freqs_hz.len() * m.points.len();
        let mean = &pooled.mean.measurements[mi].data;
        let n = kept[mi].len();
        for (g, &s) in kept[mi].iter().enumerate() {
            if n < 2 {
                break;
            }
            for o in 0..per {
                let d = (mean[o] - m.data[s * per + o]) / ((n - 1) as f64 * sigma[offset + o]);
                b[(2 * (offset + o), g)] = d.re;
                b[(2 * (offset + o) + 1, g)] = d.im;
            }
        }
        offset += per;
    }
    let Ok(y) = svd.solve(&b, 1e-14) else {
        return Vec::new();
    };
    // δθ per group for every unknown (zero for those not fitted).
    let delta = |g: usize, k: usize| -> f64 {
        free.iter()
            .position(|&x| x == k)
            .map_or(0.0, |j| y[(j, g)] * scale[j])
    };
    let col = |u: &Unknown| fwd.unknowns().iter().position(|x| x == u);
    let th = &fit.theta;
    let mut out = Vec::new();
    let mut push = |name: String, samples: Vec<f64>| {
        let n = samples.len() as f64;
        let mean = samples.iter().sum::<f64>() / n;
        let var = (n - 1.0) / n * samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        out.push((name, var.sqrt()));
    };
    for (n, name) in fwd.mode_names().iter().enumerate() {
        let (Some(iw), Some(ig)) = (col(&Unknown::OmegaSq(n)), col(&Unknown::Gamma(n))) else {
            continue;
        };
        let (w2, g) = (th[iw], fwd.gamma(th, n));
        let (f, q) = (w2.sqrt() / TAU, w2.sqrt() / g);
        if free.contains(&iw) {
            push(
                format!("f_hz:{name}"),
                (0..groups).map(|s| f * delta(s, iw) / (2.0 * w2)).collect(),
            );
        }
        if free.contains(&ig) {
            push(
                format!("Q:{name}"),
                (0..groups)
                    .map(|s| q * (delta(s, iw) / (2.0 * w2) - delta(s, ig) / g))
                    .collect(),
            );
        }
    }
    for (k, u) in fwd.unknowns().iter().enumerate() {
        if let Unknown::Param(p) = *u {
            if free.contains(&k) {
                push(
                    prob.param_names[p].clone(),
                    (0..groups).map(|s| delta(s, k)).collect(),
                );
            }
        }
    }
    out
}

/// Drift check of every identified resonance frequency: per shot, `ω_n²` with everything else
/// fixed at the estimate (one Gauss–Newton step on that shot's residual, per-line weights of
/// one shot), tested for a trend and excess scatter ([`crate::drift`]). Shot `g` is the `g`-th
/// kept shot of every measurement.
fn drift_warnings(
    fwd: &ForwardModel,
    fit: &MlFit,
    sigma_mean: &[f64],
    ds: &Dataset,
    pooled: &Pooled,
) -> Vec<String> {
    let nk = fwd.unknowns().len();
    let kept = pooled.kept(ds);
    let groups = kept.iter().map(Vec::len).min().unwrap_or(0);
    let mut out = Vec::new();
    if groups < 5 {
        return out;
    }
    for (n, name) in fwd.mode_names().iter().enumerate() {
        let Some(k) = fwd
            .unknowns()
            .iter()
            .position(|u| *u == Unknown::OmegaSq(n))
            .filter(|&k| fwd.fixed()[k].is_none())
        else {
            continue;
        };
        // Information of one shot and the per-shot projections.
        let mut info = 0.0;
        let mut delta = vec![0.0; groups];
        let mut offset = 0;
        for (mi, m) in ds.measurements.iter().enumerate() {
            let per = m.freqs_hz.len() * m.points.len();
            let nm = kept[mi].len() as f64;
            for o in 0..per {
                let a = fit.jac[(offset + o) * nk + k];
                if a.norm_sqr() == 0.0 {
                    continue;
                }
                // Noise variance of one shot at this line.
                let v = sigma_mean[offset + o].powi(2) * nm;
                info += a.norm_sqr() / v;
                for (g, d) in delta.iter_mut().enumerate() {
                    let r = m.data[kept[mi][g] * per + o] - fit.x[offset + o];
                    *d += (a.conj() * r).re / v;
                }
            }
            offset += per;
        }
        if info.is_nan() || info <= 0.0 {
            continue;
        }
        for d in delta.iter_mut() {
            *d /= info;
        }
        let w2 = fit.theta[k];
        let hz = w2.sqrt() / TAU / (2.0 * w2);
        if let Some(d) = crate::drift::check(&delta, 1.0 / info) {
            if d.trend {
                out.push(format!(
                    "f of {name} drifts over the shots: {:+.3e} Hz per shot (t = {:.1}); pooling assumes a stationary device, so its stderr is too small",
                    d.slope * hz,
                    d.t
                ));
            }
            if d.excess {
                out.push(format!(
                    "f of {name} scatters {:.1}× more from shot to shot than the noise explains (fitted per shot, the rest fixed); the device may drift or the noise is not stationary",
                    d.scatter_ratio.sqrt()
                ));
            }
        }
    }
    out
}

/// Fills `report`'s values from `values` (the final estimate's report), stderr from the
/// Fisher bounds (ml) or the per-shot spread (linear), and identifiability.
fn merge(
    report: &mut Report,
    prob: &Problem,
    values: &Report,
    pooled: &Pooled,
    estimator: Estimator,
    fo: Option<&FisherOut>,
    settings: &Settings,
) {
    report.estimator = estimator.to_string();
    report.eom = values.eom.clone();
    report.forces = values.forces.clone();
    report.gains = values.gains.clone();
    let n_used = pooled.used.iter().copied().min().unwrap_or(1).max(1) as f64;
    let fisher_of = |name: &str| fo.and_then(|f| f.bounds.get(name).map(|b| b.std));
    let jack_of =
        |name: &str| fo.and_then(|f| f.jackknife.iter().find(|(n, _)| n == name).map(|x| x.1));
    let mut warnings = Vec::new();
    // Quantities no measurement (or the information at the estimate) determines, with why.
    let mut structural: Vec<(String, String)> = prob
        .not_identifiable
        .iter()
        .filter_map(|ni| {
            let name = match prob.table.unknowns()[ni.unknown] {
                Unknown::OmegaSq(n) => format!("f_hz:{}", prob.mode_names[n]),
                Unknown::Gamma(n) => format!("Q:{}", prob.mode_names[n]),
                Unknown::Param(p) => prob.param_names[p].clone(),
                _ => return None,
            };
            Some((name, ni.reason.clone()))
        })
        .collect();
    if let Some(f) = fo {
        structural.extend(f.unidentifiable.iter().cloned());
    }
    let mut apply = |name: String, e: &mut Estimate, v: &Estimate| {
        let fixed = e.reason.as_deref() == Some("fixed by the model");
        e.value = v.value;
        if fixed {
            return;
        }
        if let Some((_, why)) = structural.iter().find(|(n, _)| *n == name) {
            e.identifiable = false;
            e.reason = Some(why.clone());
            e.stderr = f64::NAN;
            return;
        }
        let bound = fisher_of(&name);
        e.crlb = if settings.crlb || estimator == Estimator::Ml {
            bound
        } else {
            None
        };
        e.jackknife = jack_of(&name);
        e.stderr = match (estimator, bound, fo) {
            (Estimator::Ml, Some(b), Some(f)) => b * f.inflation,
            _ => e.std / n_used.sqrt(),
        };
        if estimator == Estimator::Ml && fo.is_some_and(|f| f.at_bound.contains(&name)) {
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
                warnings.push(format!(
                    "{name}: the jackknife standard error {j:.3e} and the Fisher one {:.3e} disagree by more than {:.0} %",
                    e.stderr,
                    100.0 * JACKKNIFE_TOL
                ));
            }
        }
    };
    for (n, m) in report.modes.iter_mut() {
        if let Some(v) = values.modes.get(n) {
            apply(format!("f_hz:{n}"), &mut m.f_hz, &v.f_hz);
            apply(format!("Q:{n}"), &mut m.q, &v.q);
        }
    }
    for (p, e) in report.parameters.iter_mut() {
        if let Some(v) = values.parameters.get(p) {
            apply(p.clone(), e, v);
        }
    }
    // Warnings about undetermined quantities: rebuilt from the final state.
    report.warnings.retain(|w| {
        !(w.starts_with("parameter ") || w.starts_with("Q of ") || w.starts_with("f of "))
    });
    for (n, m) in &report.modes {
        for (what, e) in [("f", &m.f_hz), ("Q", &m.q)] {
            if !e.identifiable {
                report.warnings.push(format!(
                    "{what} of {n} is not determined by the data: {}",
                    e.reason.clone().unwrap_or_default()
                ));
            }
        }
    }
    for (p, e) in &report.parameters {
        if !e.identifiable {
            report.warnings.push(format!(
                "parameter {p} is not determined: {}",
                e.reason.clone().unwrap_or_default()
            ));
        }
    }
    report.warnings.extend(warnings);
    if let Some(f) = fo {
        report.notes.extend(f.notes.iter().cloned());
        report.warnings.extend(f.drift.iter().cloned());
        report
            .warnings
            .extend(crate::consistency::warnings(&f.consistency));
        report.consistency = f.consistency.clone();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{Manifest, Measurement, MeasurementSpec};

    fn measurement(name: &str, lines: usize, shots: usize) -> Measurement {
        let spec = MeasurementSpec::new(name, vec![1000.0]);
        let freqs = (0..lines).map(|k| 1000.0 + 10.0 * k as f64).collect();
        Measurement::zeros(spec, freqs, vec![], shots)
    }

    #[test]
    fn expected_reduced_chi2_with_noise_from_the_shots() {
        // 20 shots: ν = 38, E[σ²/σ̂²] = 38/36 on two lines; 3 shots (ν = 4): 1 on one line.
        let ds = Dataset::from_parts(
            "d",
            Manifest::new("t"),
            vec![measurement("a", 2, 20), measurement("b", 1, 3)],
            None,
        )
        .expect("dataset");
        let pooled = Pooled {
            mean: ds.clone(),
            rejected: vec![vec![], vec![]],
            used: vec![20, 3],
            sigma: vec![None, None],
        };
        let want = (2.0 * 38.0 / 36.0 + 1.0) / 3.0;
        assert!((expected_reduced_chi2(&ds, &pooled) - want).abs() < 1e-15);
        // Shots rejected: the kept ones count (18 of 20: ν = 34).
        let pooled = Pooled {
            used: vec![18, 3],
            ..pooled
        };
        let want = (2.0 * 34.0 / 32.0 + 1.0) / 3.0;
        assert!((expected_reduced_chi2(&ds, &pooled) - want).abs() < 1e-15);
    }
}

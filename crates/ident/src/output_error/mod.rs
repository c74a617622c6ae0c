//! The output-error maximum-likelihood estimate: the forward model ([`crate::ForwardModel`])
//! fitted to the pooled mean of the shots, each line weighted by its noise from the shot
//! scatter ([`ml::refine`]), from one of several starts ([`Start`]), and its uncertainty
//! ([`crate::uncertainty`]): Fisher bounds at the estimate, inflated when the fit is worse than
//! the noise, a linearised jackknife, drift and cross-measurement consistency checks.

pub mod ml;
mod staged;
pub(crate) use staged::PoorGroup;

use crate::forward::{ForwardError, ForwardModel, Widened};
use crate::layout::{Quantity, Unknown};
use crate::problem::Problem;
use crate::settings::Settings;
use crate::shots::Pooled;
use crate::uncertainty::{
    self, consistency, drift_warnings, expected_reduced_chi2, goodness_of_fit, jackknife,
    FisherError, GoodnessOfFit, Noise,
};
use harmonid_data::Dataset;
use ml::{MlFit, MlSettings};
use num_complex::Complex64;

/// An equation-error stage whose relative residual exceeds this misses its own equations
/// (lines its terms need were not measured, or the state is far from where the harmonic
/// expansion is good): its linear estimates are no guide for the output-error start.
pub(crate) const POOR_STAGE: f64 = 1e-2;

/// A fit whose `χ²/dof` is within this factor of a correct model's expectation is kept
/// without trying the other starts. A wrong minimum is far above it (the designed five-mode
/// plan at 0.01 nm: 10⁴ times); a correct one scatters by `√(2/dof)` around 1.
const GOOD_FIT: f64 = 2.0;

/// The harmonic balance's truncation error allowed at a measured line, in units of that
/// line's noise: well below it, so the model's own error never shows as misfit.
const TRUNCATION_SIGMA: f64 = 0.1;

/// Most widenings of a measurement's lattice after the fit (each order +2).
const MAX_WIDENINGS: usize = 4;

/// Where the output-error fit starts, tried in this order. A linear estimate far off in a
/// poorly determined coupling can put the harmonic balance past a fold, or the fit into
/// another minimum; a weaker nonlinearity always has a steady state near the data, and the
/// fit moves the parameters from there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Start {
    /// The pooled equation-error estimate.
    PooledLinear,
    /// The pooled equation-error estimate refined by output-error group of measurements by
    /// group ([`staged`]), computed only when the fit from the pooled estimate is not good.
    Staged,
    /// The same with the model parameters it does not determine (relative standard error
    /// above 1) at zero (or their bound).
    UndeterminedAtZero,
    /// The same with the parameters of a stage whose equation-error fit is poor at zero.
    PoorStagesAtZero,
    /// Every model parameter at zero.
    EveryParameterAtZero,
}

impl Start {
    /// What the start is, as a note says it.
    fn description(self) -> &'static str {
        match self {
            Start::Staged => "the pooled linear estimate refined group of measurements by group",
            Start::PooledLinear => "the pooled linear estimate",
            Start::UndeterminedAtZero => {
                "the model parameters the pooled linear fit does not determine at zero"
            }
            Start::PoorStagesAtZero => {
                "the model parameters of poorly fitting equation-error stages at zero"
            }
            Start::EveryParameterAtZero => "every model parameter at zero",
        }
    }
}

/// Why the output-error estimate is not available (the linear one is reported instead).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum OutputErrorFailure {
    /// The forward model could not be set up for the dataset.
    #[error("the model cannot be simulated for this dataset ({0})")]
    Setup(ForwardError),
    /// No start reached a fit; the first start's error.
    #[error("output-error fit: {0}")]
    Fit(ForwardError),
    /// There was no start to try.
    #[error("output-error fit: no start")]
    NoStart,
    /// The harmonic balance failed when brought back to the best fit's estimate.
    #[error("output-error fit: back at its estimate: {0}")]
    BackAtEstimate(ForwardError),
    /// The information at the estimate could not be computed.
    #[error("Fisher information at the estimate: {0}")]
    Fisher(FisherError),
}

/// The output-error estimate with its Fisher bounds and checks.
pub(crate) struct OutputError {
    pub fit: MlFit,
    pub bounds: uncertainty::Bounds,
    /// The bounds the standard errors are: `bounds` corrected, quantity by quantity, for
    /// weights estimated from the shot scatter (`uncertainty::estimated_noise`);
    /// `bounds` otherwise.
    pub stderr_bounds: uncertainty::Bounds,
    /// `√max(1, χ²/(dof·E₀))` when the noise came from the shot scatter
    /// ([`expected_reduced_chi2`]); 1 otherwise.
    pub inflation: f64,
    /// Jackknife standard error per quantity.
    pub jackknife: Vec<(Quantity, f64)>,
    /// Drift-check warnings.
    pub drift: Vec<String>,
    /// Frequencies, Q and gains compared between measurements.
    pub consistency: Vec<consistency::Comparison>,
    /// Quantities held at a bound.
    pub at_bound: Vec<Quantity>,
    /// Quantities the information at the estimate does not determine, with why.
    pub unidentifiable: Vec<(Quantity, String)>,
    /// Whether the model fits the data at the estimate.
    pub goodness: GoodnessOfFit,
    /// The staged start's groups whose own fit failed, when the joint fit did not converge
    /// or fit (empty otherwise): the result's `unfit` entries.
    pub poor_groups: Vec<PoorGroup>,
    pub notes: Vec<String>,
}

/// The measured amplitudes of the pooled mean (forward order: a shot's data order) and the
/// noise of each (the shot scatter over `√n`, or 1 when the shots do not scatter).
fn observations(pooled: &Pooled) -> (Vec<Complex64>, Vec<f64>) {
    let meas: Vec<Complex64> = pooled
        .mean
        .measurements
        .iter()
        .flat_map(|m| m.data.iter().copied())
        .collect();
    let sigma = if pooled.noise_from_shots() {
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
    (meas, sigma)
}

/// The starts from the pooled linear estimate `linear` with the variances `linear_var` of
/// its unknowns; `poor`: unknowns of stages that miss their equations. Equal starts are
/// tried once.
fn starts(
    prob: &Problem,
    linear: &[f64],
    linear_var: &[f64],
    poor: &[usize],
) -> Vec<(Vec<f64>, Start)> {
    let theta0 = prob.table.start_from(linear);
    let bounds = prob.table.bounds();
    let zero_params = |which: &dyn Fn(usize) -> bool| -> Vec<f64> {
        let mut t = theta0.clone();
        for (k, u) in prob.table.unknowns().iter().enumerate() {
            let Unknown::Param(_) = u else { continue };
            if !prob.table.is_free(k) || !which(k) {
                continue;
            }
            let (lo, hi) = bounds[k];
            t[k] = 0.0_f64
                .max(lo.unwrap_or(f64::NEG_INFINITY))
                .min(hi.unwrap_or(f64::INFINITY));
        }
        t
    };
    let mut starts = vec![
        (theta0.clone(), Start::PooledLinear),
        (
            zero_params(&|k| {
                // Loose: a relative standard error above 1, or none at all (NaN).
                let se = linear_var.get(k).copied().unwrap_or(f64::NAN).sqrt();
                se.is_nan() || se > linear[k].abs()
            }),
            Start::UndeterminedAtZero,
        ),
        (zero_params(&|k| poor.contains(&k)), Start::PoorStagesAtZero),
        (zero_params(&|_| true), Start::EveryParameterAtZero),
    ];
    starts.dedup_by(|b, a| a.0 == b.0);
    starts
}

/// The output-error fit of `prob` to the pooled shots, from the pooled linear estimate
/// `linear` (variances `linear_var`; `poor`: unknowns of poorly fitting stages), with its
/// uncertainty. `ds_shots` has every shot (jackknife, drift).
pub(crate) fn fit(
    prob: &Problem,
    ds_shots: &Dataset,
    fwd: &mut ForwardModel,
    pooled: &Pooled,
    (linear, linear_var, poor): (&[f64], &[f64], &[usize]),
    settings: &Settings,
) -> Result<OutputError, OutputErrorFailure> {
    let (meas, sigma) = observations(pooled);
    let from_shots = pooled.noise_from_shots();
    let cols: Vec<usize> = fwd
        .free()
        .into_iter()
        .filter(|&k| !prob.not_identifiable.iter().any(|x| x.unknown == k))
        .collect();
    // Each start in turn until a fit is as good as a correct model's (χ²/dof within GOOD_FIT
    // of its expectation, judged when the noise comes from the shot scatter).
    let e0 = if from_shots {
        expected_reduced_chi2(ds_shots, pooled)
    } else {
        f64::INFINITY
    };
    let tries = Tries {
        meas: &meas,
        sigma: &sigma,
        cols: &cols,
        bounds: prob.table.bounds(),
        e0,
        scan: settings.staged_scan,
    };
    // The pooled linear start first; where its fit is not as good as a correct model's, the
    // staged start (computed only then: a hundred small fits on ten modes), then the others.
    // The staged start costs more than the pooled linear fit where that converges (the
    // ten-mode example: 4.3 s of 5.8 s), and from it a group whose own fit failed can hold
    // the joint fit far off (there: χ² 2.0·10⁶, no step accepted).
    let mut all_starts = starts(prob, linear, linear_var, poor);
    let at = all_starts.len().min(1);
    all_starts.insert(at, (Vec::new(), Start::Staged));
    let mut staged: Option<staged::Staged> = None;
    let theta_lin = prob.table.start_from(linear);
    let mut run_staged = |f: &mut ForwardModel| -> Option<Vec<f64>> {
        let s = staged::staged_start(f, &pooled.mean, &tries, &theta_lin)?;
        let theta = s.theta.clone();
        staged = Some(s);
        Some(theta)
    };
    let (mut fit, mut notes) = tries.best(fwd, &pooled.mean, &all_starts, &mut run_staged)?;
    let shot_sigma = &sigma[..];
    let mut floor = None;
    let mut sigma_used = sigma.clone();
    if settings.error_floor && from_shots {
        let (f, s0, floored) = fit_error_floor(fwd, &tries, fit)?;
        fit = f;
        floor = Some(s0);
        sigma_used = floored;
    }
    let sigma = sigma_used;
    if let Some(s0) = floor {
        notes.push(floor_note(shot_sigma, s0));
    }
    let (fit, after) = widen_and_refine(fwd, &tries, &sigma, fit, from_shots)?;
    // Those the staged start widened after a group's fit first (its lattices are the joint
    // fit's), then those widened after the joint fit.
    let mut widenings = Vec::new();
    let staged_widened = staged.iter().flat_map(|s| s.widened.iter().cloned());
    for w in staged_widened.chain(after) {
        merge_widening(&mut widenings, w);
    }
    notes.extend(widening_note(&widenings));
    let (noise, inflation) = noise_at(&fit, &sigma, from_shots, e0);
    let bounds = uncertainty::crlb_from_jacobian(fwd, &fit.theta, &fit.jac, &noise, 1)
        .map_err(OutputErrorFailure::Fisher)?;
    // Weights from the shot scatter cost precision that `bounds` does not see.
    let stderr_bounds =
        uncertainty::stderr_bounds(fwd, &fit.at_estimate(), pooled, shot_sigma, &sigma, &bounds)
            .map_err(OutputErrorFailure::Fisher)?;
    // The delete-one-shot jackknife sees the shots' scatter only, not the floor.
    let jackknife = if settings.jackknife && from_shots && floor.is_none() {
        jackknife(fwd, &fit.at_estimate(), &sigma, ds_shots, pooled, &cols)
    } else {
        Vec::new()
    };
    let drift = if from_shots {
        drift_warnings(fwd, &fit.at_estimate(), shot_sigma, ds_shots, pooled)
    } else {
        Vec::new()
    };
    let mut goodness = goodness(pooled, &meas, &fit, &sigma, &noise, from_shots);
    // Widened for a misfit only beyond the χ²'s own spread (with the noise from the shots).
    let inflation = uncertainty::misfit_inflation(&goodness, from_shots).unwrap_or(inflation);
    goodness.stderr_inflation = inflation;
    goodness.converged = fit.converged;
    if let Some(s0) = floor {
        // Fitted to these residuals: χ² is near its expectation by construction.
        goodness.expected_chi2_per_dof = floor_expectation(shot_sigma, s0, e0);
        goodness.p_value = None;
        goodness.fits = None;
        goodness.error_floor = floor;
    }
    let judged = (shot_sigma, from_shots.then_some(&goodness));
    let (consistency, skipped) =
        compare_measurements(fwd, &fit, (&meas, &noise, &cols), pooled, judged);
    notes.extend(skipped);
    if !fit.converged {
        notes.push(format!(
            "the output-error fit stopped after {} steps before converging (χ² {:.4e} from {:.4e})",
            fit.steps, fit.chi2, fit.chi2_start
        ));
    }
    let mut poor_groups = Vec::new();
    if !fit.converged || fit.chi2 / fit.dof.max(1) as f64 > GOOD_FIT * e0 {
        if let Some(s) = &staged {
            poor_groups = staged::poor_groups(fwd, &s.groups, e0);
            notes.extend(staged::poor_groups_note(
                fwd,
                &poor_groups,
                s.groups.len(),
                e0,
            ));
        }
    }
    let quantity = |k: usize| Quantity::of(&fwd.unknowns()[k]);
    let at_bound = fit.at_bound.iter().filter_map(|&k| quantity(k)).collect();
    let unidentifiable = bounds
        .unidentifiable
        .iter()
        .filter_map(|u| {
            Some((
                quantity(u.unknown)?,
                format!("the data do not determine it at the estimate: {}", u.reason),
            ))
        })
        .collect();
    Ok(OutputError {
        goodness,
        drift,
        consistency,
        fit,
        unidentifiable,
        bounds,
        stderr_bounds,
        inflation,
        jackknife,
        at_bound,
        poor_groups,
        notes,
    })
}

/// The note on an error floor `s0` added to every line's noise, against the median of the
/// lines' own noise `shot_sigma`: once fitted with it, χ² no longer tests the model.
fn floor_note(shot_sigma: &[f64], s0: f64) -> String {
    let mut sorted = shot_sigma.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
    format!(
        "error floor: {s0:.3e} per quadrature added to every line's noise, {:.3} times the median noise of a line's mean from its shots ({median:.3e}); χ² was fitted with it and no longer tests the model: judge by a held-out prediction (--holdout)",
        s0 / median
    )
}

/// The lattice chosen at the start may be truncated too coarsely for the data's precision
/// at the estimate: widens it where that shows (at most [`MAX_WIDENINGS`] times) and refines
/// `fit` on the wider lattice each time. Returns the fit and each measurement's last
/// widening, with how far its first moved a line.
fn widen_and_refine(
    fwd: &mut ForwardModel,
    tries: &Tries,
    sigma: &[f64],
    mut fit: MlFit,
    from_shots: bool,
) -> Result<(MlFit, Vec<Widened>), OutputErrorFailure> {
    let mut widenings: Vec<Widened> = Vec::new();
    for _ in 0..MAX_WIDENINGS {
        let scale = if from_shots {
            1.0
        } else {
            (fit.chi2 / fit.dof.max(1) as f64).sqrt()
        };
        let tol: Vec<f64> = sigma.iter().map(|s| TRUNCATION_SIGMA * s * scale).collect();
        let widened = fwd
            .widen_where_truncated(&fit.theta, &tol)
            .map_err(OutputErrorFailure::Fit)?;
        if widened.is_empty() {
            break;
        }
        for w in widened {
            merge_widening(&mut widenings, w);
        }
        fit = ml::refine(
            fwd,
            tries.meas,
            sigma,
            &fit.theta,
            tries.cols,
            tries.bounds,
            &MlSettings::default(),
        )
        .map_err(OutputErrorFailure::Fit)?;
    }
    Ok((fit, widenings))
}

/// Adds `w` to `widenings`: a measurement widened again keeps its last order and lines and
/// the largest move.
fn merge_widening(widenings: &mut Vec<Widened>, w: Widened) {
    match widenings
        .iter_mut()
        .find(|e| e.measurement == w.measurement)
    {
        Some(e) => {
            e.order = w.order;
            e.lines = w.lines;
            e.moved = e.moved.max(w.moved);
        }
        None => widenings.push(w),
    }
}

/// The noise the bounds use and the factor their standard errors are inflated by: with shot
/// noise, `sigma` per observation and inflation by the excess of `χ²/dof` over `e0`; without,
/// the residual's uniform scale and no inflation.
fn noise_at(fit: &MlFit, sigma: &[f64], from_shots: bool, e0: f64) -> (Noise, f64) {
    let dof = fit.dof.max(1) as f64;
    if from_shots {
        let red = fit.chi2 / dof / e0;
        (Noise::PerObservation(sigma.to_vec()), red.max(1.0).sqrt())
    } else {
        let s = (fit.chi2 / dof).sqrt();
        (
            Noise::Uniform(if s > 0.0 { s } else { f64::MIN_POSITIVE }),
            1.0,
        )
    }
}

/// The goodness of `fit` against the pooled means, residuals standardized by `sigma` (times
/// the residual's scale when there is no shot noise: then the residual is the noise).
fn goodness(
    pooled: &Pooled,
    meas: &[Complex64],
    fit: &MlFit,
    sigma: &[f64],
    noise: &Noise,
    from_shots: bool,
) -> GoodnessOfFit {
    let residual_scale = match noise {
        Noise::Uniform(s) => *s,
        _ => 1.0,
    };
    let scaled: Vec<f64> = sigma.iter().map(|s| s * residual_scale).collect();
    goodness_of_fit(
        &pooled.mean,
        &pooled.used,
        (meas, &fit.x, &scaled),
        fit.dof,
        from_shots,
    )
}

/// One note for every widened lattice: the measurement's own words when it is one, else how
/// many, the first few by name with their order, and the largest move (a long sweep through
/// a strongly driven resonance widens dozens of steps, which one line each would drown).
fn widening_note(widened: &[Widened]) -> Option<String> {
    let why = "where the truncation moved a measured line by more than its tolerance (a tenth of the line's noise)";
    match widened {
        [] => None,
        [w] => Some(format!(
            "measurement \"{}\": harmonic balance widened to order {} ({} lines), {why}: by {:.2} times",
            w.measurement, w.order, w.lines, w.moved
        )),
        many => {
            let named = harmonid_data::text::first_and_more(
                many.iter()
                    .map(|w| format!("\"{}\" to order {}", w.measurement, w.order))
                    .collect(),
                4,
            );
            let worst = many.iter().map(|w| w.moved).fold(0.0, f64::max);
            Some(format!(
                "harmonic balance widened in {} measurements ({}), {why}: by up to {worst:.2} times",
                many.len(),
                named.join(", ")
            ))
        }
    }
}

/// Most rounds of the error floor's fixed point (floor from the residuals, then the fit
/// with it); it stops earlier once the floor moves by less than [`FLOOR_REL_TOL`].
const FLOOR_ROUNDS: usize = 20;
const FLOOR_REL_TOL: f64 = 1e-3;

/// The output-error fit with an error floor (see [`Settings::error_floor`]): alternately the
/// floor `σ₀` at which `χ²` with the noise `√(s² + σ₀²)` is a correct model's expectation at
/// the current fit ([`floor_for`]; zero when the shot noise alone already gives that), and the
/// fit with that noise, until the floor settles (`tries`: the data, the shot noise, and `e0`,
/// a correct model's `χ²/dof` with the shot noise alone). Returns the last fit, its floor (m
/// per quadrature) and the noise it was fitted with.
fn fit_error_floor(
    fwd: &mut ForwardModel,
    tries: &Tries,
    mut fit: MlFit,
) -> Result<(MlFit, f64, Vec<f64>), OutputErrorFailure> {
    let Tries {
        meas,
        sigma: shot_sigma,
        cols,
        bounds,
        e0,
        ..
    } = *tries;
    let mut floor = 0.0;
    let mut sigma = shot_sigma.to_vec();
    for _ in 0..FLOOR_ROUNDS {
        let miss2: Vec<f64> = meas
            .iter()
            .zip(&fit.x)
            .map(|(m, x)| (m - x).norm_sqr())
            .collect();
        let next = floor_for(&miss2, shot_sigma, e0, fit.dof.max(1) as f64);
        let settled = (next - floor).abs() <= FLOOR_REL_TOL * next;
        floor = next;
        sigma = shot_sigma.iter().map(|s| s.hypot(floor)).collect();
        fit = ml::refine(
            fwd,
            meas,
            &sigma,
            &fit.theta,
            cols,
            bounds,
            &MlSettings::default(),
        )
        .map_err(OutputErrorFailure::Fit)?;
        if settled {
            break;
        }
    }
    Ok((fit, floor, sigma))
}

/// A correct model's `χ²/dof` with the noise `√(sᵢ² + σ₀²)`: `1 + (e0 − 1)·mean wᵢ²`, see
/// [`floor_for`].
fn floor_expectation(sigma: &[f64], s0: f64, e0: f64) -> f64 {
    let w2: f64 = sigma
        .iter()
        .map(|s| (s * s / (s * s + s0 * s0)).powi(2))
        .sum();
    1.0 + (e0 - 1.0).max(0.0) * w2 / sigma.len().max(1) as f64
}

/// The floor `σ₀ ≥ 0` at which `Σ miss2ᵢ/(sᵢ² + σ₀²)` (`miss2ᵢ = |X̄ − X|²`) is its
/// expectation for a correct model, `dof·(1 + (e0 − 1)·mean wᵢ²)` with `wᵢ = sᵢ²/(sᵢ² + σ₀²)`
/// the share of the shot noise: a line's noise estimated from its shots inflates its term
/// by `e0` when the shot noise is all of it (`ν/(ν − 2)`) and not at all when the floor
/// dominates (to second order in the estimate's scatter, `1 + w²(e0 − 1)`). By bisection:
/// the difference falls from positive (when the shot noise alone misses) to negative at
/// `σ₀ = √(Σ miss2/dof)`.
fn floor_for(miss2: &[f64], sigma: &[f64], e0: f64, dof: f64) -> f64 {
    let excess = |s0: f64| -> f64 {
        let chi2: f64 = miss2
            .iter()
            .zip(sigma)
            .map(|(m, s)| m / (s * s + s0 * s0))
            .sum();
        chi2 - dof * floor_expectation(sigma, s0, e0)
    };
    if excess(0.0) <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, (miss2.iter().sum::<f64>() / dof).sqrt());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if excess(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// What every start's fit shares.
struct Tries<'a> {
    meas: &'a [Complex64],
    sigma: &'a [f64],
    cols: &'a [usize],
    bounds: &'a [(Option<f64>, Option<f64>)],
    /// A correct model's expected `χ²/dof` (infinite when the noise is not from the shots).
    e0: f64,
    /// Whether the staged start may scan a poorly started group and refit the groups that
    /// share unknowns at the combined values ([`Settings::staged_scan`]; off for `discover`).
    scan: bool,
}

impl Tries<'_> {
    /// Tries the starts in turn until a fit is good (within [`GOOD_FIT`] of `e0`), each from
    /// the data's amplitudes but the staged one, whose values and steady states `staged`
    /// computes when it is reached (skipped when it has none); of the fits reached, the one
    /// with the smallest χ², the forward model left at its states, and a note when it is not
    /// the first start's.
    fn best(
        &self,
        fwd: &mut ForwardModel,
        mean: &Dataset,
        starts: &[(Vec<f64>, Start)],
        staged: &mut dyn FnMut(&mut ForwardModel) -> Option<Vec<f64>>,
    ) -> Result<(MlFit, Vec<String>), OutputErrorFailure> {
        let reduced = |f: &MlFit| f.chi2 / f.dof.max(1) as f64;
        let mut first_err = None;
        let mut best: Option<(MlFit, usize)> = None;
        // The forward model at the best fit's steady states, for when they cannot be found
        // again from the data (a state on a branch the data-based start does not reach).
        let mut best_fwd: Option<ForwardModel> = None;
        let mut first_fit_chi2: Option<f64> = None;
        let mut last_run = 0;
        for (i, (theta_s, _)) in starts.iter().enumerate() {
            if best
                .as_ref()
                .is_some_and(|(f, _)| reduced(f) <= GOOD_FIT * self.e0)
            {
                break;
            }
            let staged_theta;
            let theta_s = if starts[i].1 == Start::Staged {
                // It leaves `fwd` at its steady states.
                let Some(t) = staged(fwd) else {
                    continue;
                };
                staged_theta = t;
                &staged_theta
            } else {
                fwd.start_from_data(mean);
                theta_s
            };
            // Newton from the data at each start; the drive ramp from rest only at the last,
            // and at the staged start (its steady states are the groups', where a measurement
            // no group fitted may have none).
            last_run = i;
            let ml_settings = MlSettings {
                ramp_at_start: i + 1 == starts.len() || starts[i].1 == Start::Staged,
                ..MlSettings::default()
            };
            let r = ml::refine(
                fwd,
                self.meas,
                self.sigma,
                theta_s,
                self.cols,
                self.bounds,
                &ml_settings,
            );
            match r {
                Ok(f) => {
                    if i == 0 {
                        first_fit_chi2 = Some(reduced(&f));
                    }
                    if best.as_ref().is_none_or(|(b, _)| f.chi2 < b.chi2) {
                        best = Some((f, i));
                        best_fwd = (i + 1 < starts.len()).then(|| fwd.clone());
                    }
                }
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        let Some((f, i)) = best else {
            return Err(first_err.map_or(OutputErrorFailure::NoStart, OutputErrorFailure::Fit));
        };
        if i != last_run {
            // The forward model's states are another start's: back to this fit's, found from
            // the data it matches.
            fwd.start_from_data(mean);
            let mut x = vec![Complex64::new(0.0, 0.0); fwd.n_observations()];
            if let Err(e) = fwd.evaluate_trial(&f.theta, &mut x) {
                *fwd = best_fwd.ok_or(OutputErrorFailure::BackAtEstimate(e))?;
            }
        }
        let mut notes = Vec::new();
        let start = starts[i].1;
        if i != 0 {
            let first = starts[0].1.description();
            let why = match (first_fit_chi2, first_err) {
                (Some(c), _) => format!(
                    "from {first} it ended at χ²/dof = {c:.3e}, {:.3e} from here (a correct model gives about {:.3})",
                    reduced(&f),
                    self.e0
                ),
                (None, Some(e)) => format!("at {first}: {e}"),
                (None, None) => String::new(),
            };
            notes.push(format!(
                "the output-error fit started from {}: {why}",
                start.description()
            ));
        }
        Ok((f, notes))
    }
}

/// Every frequency, Q and gain compared between the measurements that see it
/// ([`consistency::compare`]), with the noise the fit used, and the note when the dataset has
/// too many units to compare ([`consistency::too_many_units`]). With the noise from the shots
/// (`judged`, the fit's goodness; `shot_sigma` the lines' own noise) the comparisons' standard
/// errors are the estimates' own: the weights' noise counted, widened only for a misfit beyond
/// a correct model's `χ²`.
fn compare_measurements(
    fwd: &ForwardModel,
    fit: &MlFit,
    (meas, noise, cols): (&[Complex64], &Noise, &[usize]),
    pooled: &Pooled,
    (shot_sigma, judged): (&[f64], Option<&GoodnessOfFit>),
) -> (Vec<consistency::Comparison>, Option<String>) {
    let mean = &pooled.mean;
    let kept: Vec<usize> = cols
        .iter()
        .copied()
        .filter(|k| !fit.at_bound.contains(k))
        .collect();
    let sigma_used: Vec<f64> = match noise {
        Noise::PerObservation(v) => v.clone(),
        Noise::Uniform(s) => vec![*s; meas.len()],
    };
    let names: Vec<String> = mean
        .measurements
        .iter()
        .map(|m| m.spec.name.clone())
        .collect();
    let units = consistency::units(mean);
    let nu =
        judged.map(|_| uncertainty::estimated_noise::weight_dof(pooled, shot_sigma, &sigma_used));
    let expected = judged.map(|g| (g.expected_chi2_per_dof, g.spread_chi2_per_dof));
    let comparisons = consistency::compare(&consistency::Fitted {
        fwd,
        theta: &fit.theta,
        meas,
        x: &fit.x,
        jac: &fit.jac,
        sigma: &sigma_used,
        cols: &kept,
        dof: fit.dof,
        names: &names,
        units: &units,
        nu: nu.as_deref(),
        expected_chi2: expected,
    });
    (comparisons, consistency::too_many_units(&units))
}

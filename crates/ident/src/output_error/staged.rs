//! The staged start of the output-error fit: the pooled linear estimate refined by
//! output-error, group of measurements by group, before the joint fit.
//!
//! Why: on a many-mode device of high Q, the linear estimate of a poorly measured coupling
//! can be tens of linewidths of frequency shift off. From there the joint fit either finds no
//! steady state (a fold) or, started with every parameter at zero, slides into a minimum
//! where per-measurement gains stand in for a mode's wrong frequency (a ten-mode string with
//! every Q ≈ 1.3·10⁵: χ²/dof 4.5 to 320 where a correct model gives 1.04). A single
//! measurement of few modes has few unknowns, and once the modes it shares with others are
//! fitted, the rest of it is a small, well-started fit.
//!
//! The groups: the unknowns each measurement depends on are read from the Jacobian at the
//! linear start with every model parameter at zero (a linear response, always solvable: a
//! coupling term of two modes vanishes unless both respond, so a measurement driving one
//! mode does not depend on that mode's couplings). Measurements are taken by the number of
//! modes they depend on, one mode first; within a count, those sharing an unknown not yet
//! fitted (or steps of one sweep) form a group. Each group fits only its new unknowns, the
//! others held at what earlier groups found, from the current values and, when that fit is
//! not as good as a correct model's, also from its new model parameters at zero, and when
//! neither is, from a scan of its new model parameters over a geometric grid with its gains
//! at those earlier groups fitted for the same modes (the twenty-mode string, noise seed 20:
//! 12 of the 210 pair groups missed from the first two starts, the linear estimate of their
//! coupling up to 400 times off and their gains between −24 and 8 where they are about 1;
//! with the scan none misses); the best is kept. Every unknown then goes to the minimum of the
//! groups' `χ²` summed, each a quadratic model around its own fit with the correlations of its
//! information ([`combine`]; an inverse-variance mean of each unknown moved the strongly driven
//! pairs' modes out of their regime: seed 20 stopped at `χ²/dof` 25, seed 7 at 500, where now
//! both converge to the noise), and the groups sharing unknowns refit their own there. A
//! group that had to move the unknowns earlier groups fitted is first checked against the
//! combination of the groups that did not, and left out when its values are far from it
//! ([`consistent_models`]; the twenty-mode string, seed 11: two pair groups' refinement put a
//! mode's damping near zero, the combination followed half way and the joint fit ended at
//! `χ²/dof` 1.52 with that mode's frequency 44 stderr off; left out and refitted over their
//! own unknowns at the combination, it converges at 1.036). The steady states found are the
//! joint fit's warm starts.

use super::ml::{self, MlSettings};
use super::{Tries, GOOD_FIT, MAX_WIDENINGS, TRUNCATION_SIGMA};
use crate::forward::{ForwardModel, Widened};
use crate::layout::Unknown;
use harmonid_data::Dataset;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::collections::BTreeSet;

/// One group's fit.
#[derive(Debug, Clone)]
pub(crate) struct GroupFit {
    /// Its measurements (indices).
    pub measurements: Vec<usize>,
    /// The unknowns fitted in it (those no earlier group fitted).
    pub unknowns: Vec<usize>,
    /// `χ²/dof` of its best fit (infinite when no start reached one).
    pub reduced_chi2: f64,
}

/// The staged start: the values of every unknown and each group's fit.
pub(crate) struct Staged {
    pub theta: Vec<f64>,
    pub groups: Vec<GroupFit>,
    /// The lattices widened after a group's fit ([`settle_truncation`]), for the report's note.
    pub widened: Vec<Widened>,
}

/// `theta` with the model parameters among `which` at zero (or their nearest bound).
fn params_at_zero(
    fwd: &ForwardModel,
    theta: &[f64],
    which: &[usize],
    bounds: &[(Option<f64>, Option<f64>)],
) -> Vec<f64> {
    let mut t = theta.to_vec();
    for &k in which {
        if let Unknown::Param(_) = fwd.unknowns()[k] {
            let (lo, hi) = bounds[k];
            t[k] = 0.0_f64
                .max(lo.unwrap_or(f64::NEG_INFINITY))
                .min(hi.unwrap_or(f64::INFINITY));
        }
    }
    t
}

/// `ds` with the measurements `keep` only.
fn select(ds: &Dataset, keep: &[usize]) -> Dataset {
    Dataset {
        dir: ds.dir.clone(),
        manifest: ds.manifest.clone(),
        measurements: keep.iter().map(|&i| ds.measurements[i].clone()).collect(),
        truth: None,
        notes: Vec::new(),
    }
}

/// A measurement depends on an unknown when changing it by its own size (its start value)
/// moves the measurement's lines by more than this many noise sigmas (root sum of squares);
/// below, the dependence is the harmonic balance's round-off (a mode no tone drives responds
/// at 1e-30 of the others).
const DEPENDS: f64 = 1e-3;

/// Per measurement, the unknowns among `cols` it depends on and the modes it depends on,
/// from the Jacobian `jac` (every unknown, `nk` columns) at a linear response at `theta`
/// (scales: a model parameter at zero there is scaled by its value in `theta0`).
fn dependencies(
    fwd: &ForwardModel,
    (jac, sigma): (&[Complex64], &[f64]),
    theta0: &[f64],
    cols: &[usize],
) -> Vec<(BTreeSet<usize>, usize)> {
    let nk = fwd.unknowns().len();
    let touches = |mi: usize, k: usize| {
        // No size to judge by (an unknown the linear fit left at zero): any dependence.
        let scale = match theta0[k].abs() {
            s if s > 0.0 => s,
            _ => f64::INFINITY,
        };
        let effect: f64 = fwd
            .observations_of(mi)
            .map(|o| (jac[o * nk + k] / sigma[o]).norm_sqr())
            .sum();
        effect > 0.0 && effect.sqrt() * scale > DEPENDS
    };
    (0..fwd.n_measurements())
        .map(|mi| {
            let deps = cols.iter().copied().filter(|&k| touches(mi, k)).collect();
            let modes = (0..fwd.mode_names().len())
                .filter(|&n| {
                    fwd.unknowns().iter().enumerate().any(|(k, u)| {
                        matches!(*u, Unknown::OmegaSq(m) | Unknown::Gamma(m) if m == n)
                            && touches(mi, k)
                    })
                })
                .count();
            (deps, modes)
        })
        .collect()
}

/// The groups of measurements with `modes` modes: those sharing an unknown not in
/// `settled` (or steps of one sweep, `follows`) together; each with its new unknowns.
fn groups_of(
    deps: &[(BTreeSet<usize>, usize)],
    modes: usize,
    settled: &BTreeSet<usize>,
    follows: &[Option<usize>],
) -> Vec<(Vec<usize>, BTreeSet<usize>)> {
    let mut groups: Vec<(Vec<usize>, BTreeSet<usize>)> = Vec::new();
    for (mi, (d, m)) in deps.iter().enumerate() {
        if *m != modes {
            continue;
        }
        let new: BTreeSet<usize> = d.difference(settled).copied().collect();
        // Every group this one joins: sharing a new unknown or holding its previous step.
        let (mut joined, rest): (Vec<_>, Vec<_>) = groups.into_iter().partition(|(ms, u)| {
            !u.is_disjoint(&new) || follows[mi].is_some_and(|p| ms.contains(&p))
        });
        let mut merged = (vec![mi], new);
        for (ms, u) in joined.drain(..) {
            merged.0.extend(ms);
            merged.1.extend(u);
        }
        merged.0.sort_unstable();
        groups = rest;
        groups.push(merged);
    }
    groups.retain(|g| !g.1.is_empty());
    groups
}

/// A group's fit ([`fit_group`]).
struct GroupResult {
    /// The best fit, over the group's new unknowns or over all it depends on.
    fit: ml::MlFit,
    /// The group's forward model at the fit's steady states.
    sub: ForwardModel,
    /// Its `χ²` as a quadratic model over every unknown it depends on ([`Quadratic`]).
    model: Option<Quadratic>,
    /// Its measurements' lattices widened after the fit ([`settle_truncation`]).
    widened: Vec<Widened>,
    /// Whether the fit moved the unknowns earlier groups fitted (the refinement over all it
    /// depends on was kept): its values of those are then checked against the others'
    /// before they are combined ([`consistent_models`]).
    moved_shared: bool,
}

/// Refits the group `keep` over its `new` unknowns from `theta` (the others held there),
/// Newton from the group's steady states in `fwd`.
fn refit_held(
    fwd: &ForwardModel,
    tries: &Tries,
    theta: &[f64],
    (keep, new): (&[usize], &[usize]),
) -> Option<(ml::MlFit, ForwardModel)> {
    let (meas, sigma) = observations_of(fwd, keep, tries.meas, tries.sigma);
    let mut sub = fwd.subset(keep);
    let f = ml::refine(
        &mut sub,
        &meas,
        &sigma,
        theta,
        new,
        tries.bounds,
        &MlSettings::default(),
    )
    .ok()?;
    Some((f, sub))
}

/// The observations of `fwd`'s measurements `keep`, concatenated (the subset's order).
fn observations_of(
    fwd: &ForwardModel,
    keep: &[usize],
    meas: &[Complex64],
    sigma: &[f64],
) -> (Vec<Complex64>, Vec<f64>) {
    let mut m = Vec::new();
    let mut s = Vec::new();
    for &mi in keep {
        let r = fwd.observations_of(mi);
        m.extend_from_slice(&meas[r.clone()]);
        s.extend_from_slice(&sigma[r]);
    }
    (m, s)
}

/// Fits the group `keep` (measurements) over `new` (unknowns) from `theta`, and from `new`'s
/// model parameters at zero when that is not good enough; when the better is still not good,
/// refines it over `all` the unknowns the group depends on (a strongly driven measurement
/// sees its modes more sharply than the measurements that fitted them: held at their values
/// it can miss by many sigmas). The best fit's values (only `new`'s are the group's
/// estimates) and its forward model (the subset, at the fit's steady states), or `None` when
/// neither start reached a fit. With them, the group's `χ²` as a quadratic model over `all`
/// at the fit ([`Quadratic`]).
fn fit_group(
    fwd: &ForwardModel,
    mean: &Dataset,
    tries: &Tries,
    (theta, neighbours): (&[f64], &[f64]),
    (keep, new, all): (&[usize], &[usize], &[usize]),
) -> Option<GroupResult> {
    let sub_ds = select(mean, keep);
    let (meas, sigma) = observations_of(fwd, keep, tries.meas, tries.sigma);
    let reduced = |f: &ml::MlFit| f.chi2 / f.dof.max(1) as f64;
    let mut best: Option<(ml::MlFit, ForwardModel)> = None;
    let from_zero = params_at_zero(fwd, theta, new, tries.bounds);
    let starts: &[(&[f64], bool)] = if from_zero == theta {
        &[(theta, true)]
    } else {
        &[(theta, false), (&from_zero, true)]
    };
    for &(start, ramp) in starts {
        if best
            .as_ref()
            .is_some_and(|(f, _)| reduced(f) <= GOOD_FIT * tries.e0)
        {
            break;
        }
        let mut sub = fwd.subset(keep);
        sub.start_from_data(&sub_ds);
        let settings = MlSettings {
            ramp_at_start: ramp,
            ..MlSettings::default()
        };
        let r = ml::refine(&mut sub, &meas, &sigma, start, new, tries.bounds, &settings);
        let Ok(f) = r else {
            continue;
        };
        if best.as_ref().is_none_or(|(b, _)| f.chi2 < b.chi2) {
            best = Some((f, sub));
        }
    }
    let poor = |b: &Option<(ml::MlFit, ForwardModel)>| {
        b.as_ref()
            .is_none_or(|(f, _)| reduced(f) > GOOD_FIT * tries.e0)
    };
    if tries.scan && poor(&best) {
        if let Some(t) = scan_params(fwd, &sub_ds, tries, (keep, new), neighbours) {
            let mut sub = fwd.subset(keep);
            sub.start_from_data(&sub_ds);
            let r = ml::refine(
                &mut sub,
                &meas,
                &sigma,
                &t,
                new,
                tries.bounds,
                &MlSettings::default(),
            );
            if let Ok(f) = r {
                if best.as_ref().is_none_or(|(b, _)| f.chi2 < b.chi2) {
                    best = Some((f, sub));
                }
            }
        }
    }
    let (f, sub) = best?;
    let with_precisions = |fit: ml::MlFit, mut sub: ForwardModel, cols: &[usize]| {
        let moved_shared = cols.len() > new.len();
        let (fit, widened) = settle_truncation(&mut sub, (&meas, &sigma), fit, cols, tries);
        // A fit worse than a correct model's counts as that much noisier.
        let inflation = (reduced(&fit) / tries.e0).max(1.0);
        let resid: Vec<Complex64> = meas.iter().zip(&fit.x).map(|(m, x)| m - x).collect();
        let model = Quadratic::of_fit(
            (&fit.jac, fwd.unknowns().len()),
            (&resid, &sigma),
            all,
            &fit.theta,
            1.0 / inflation,
        );
        Some(GroupResult {
            fit,
            sub,
            model,
            widened,
            moved_shared,
        })
    };
    if reduced(&f) <= GOOD_FIT * tries.e0 || all.len() == new.len() {
        return with_precisions(f, sub, new);
    }
    // `sub` is at `f`'s steady states: Newton from there.
    let mut wider = sub.clone();
    let settings = MlSettings {
        ramp_at_start: false,
        ..MlSettings::default()
    };
    let r = ml::refine(
        &mut wider,
        &meas,
        &sigma,
        &f.theta,
        all,
        tries.bounds,
        &settings,
    );
    match r {
        Ok(g) if g.chi2 < f.chi2 => with_precisions(g, wider, all),
        _ => with_precisions(f, sub, new),
    }
}

/// `fit` (of `sub`'s measurements, observations `meas` with noise `sigma`, over `cols`) on
/// lattices wide enough for the data: where a measurement's truncation at the estimate moves a
/// line by more than [`TRUNCATION_SIGMA`] of its noise, its lattice is widened
/// ([`ForwardModel::widen_where_truncated`]) and the group refitted from there, at most
/// [`MAX_WIDENINGS`] times. Why here and not only after the joint fit: a strongly driven
/// coupling measurement's truncation can move its lines by thousands of sigmas (the
/// twenty-mode string, seed 7: `couple_q1_q8`), so its group fits a biased forward model, and
/// the joint fit starts from those values. A refit that fails keeps the last fit (the
/// lattice stays widened: the joint fit refits on it). Returns the fit and every widening.
fn settle_truncation(
    sub: &mut ForwardModel,
    (meas, sigma): (&[Complex64], &[f64]),
    mut fit: ml::MlFit,
    cols: &[usize],
    tries: &Tries,
) -> (ml::MlFit, Vec<Widened>) {
    let mut widenings = Vec::new();
    for _ in 0..MAX_WIDENINGS {
        // Without noise from the shots (`e0` infinite), the residuals' own scale.
        let scale = if tries.e0.is_finite() {
            1.0
        } else {
            (fit.chi2 / fit.dof.max(1) as f64).sqrt()
        };
        let tol: Vec<f64> = sigma.iter().map(|s| TRUNCATION_SIGMA * s * scale).collect();
        match sub.widen_where_truncated(&fit.theta, &tol) {
            Ok(w) if !w.is_empty() => widenings.extend(w),
            _ => break,
        }
        let settings = MlSettings {
            ramp_at_start: false,
            ..MlSettings::default()
        };
        match ml::refine(sub, meas, sigma, &fit.theta, cols, tries.bounds, &settings) {
            Ok(g) => fit = g,
            Err(_) => break,
        }
    }
    (fit, widenings)
}

/// `theta` with the actuator gains among `new` at the mean of the gains of the same mode and
/// quadrature fitted before (`settled`: the actuator is the same whichever measurement drives
/// it, so a gain another measurement fitted is a good start; the pooled linear fit of a
/// measurement it misses can put its gains at −24 where they are about 1), and the model
/// parameters among `new` at zero (or their nearest bound).
fn from_neighbours(
    fwd: &ForwardModel,
    theta: &[f64],
    new: &[usize],
    settled: &BTreeSet<usize>,
    bounds: &[(Option<f64>, Option<f64>)],
) -> Vec<f64> {
    let mut t = params_at_zero(fwd, theta, new, bounds);
    let unknowns = fwd.unknowns();
    for &k in new {
        let Unknown::Gain { mode, quad, .. } = unknowns[k] else {
            continue;
        };
        let same: Vec<f64> = settled
            .iter()
            .filter(|&&j| {
                matches!(unknowns[j], Unknown::Gain { mode: m, quad: q, .. } if m == mode && q == quad)
            })
            .map(|&j| theta[j])
            .filter(|v| v.is_finite())
            .collect();
        if !same.is_empty() {
            t[k] = same.iter().sum::<f64>() / same.len() as f64;
        }
    }
    t
}

/// Powers of two of a parameter's scale tried by [`scan_params`]: `2^-SCAN_OCTAVES` to
/// `2^SCAN_OCTAVES`, each sign its bounds allow.
const SCAN_OCTAVES: i32 = 6;

/// A start for a group that neither the linear estimate nor zero started well: from `start`
/// (every unknown; the group's new parameters at zero, its gains at the neighbours'), each of
/// the new model parameters in turn on a geometric grid around its scale, the one of least
/// `χ²` kept. The scale of a parameter is the value whose first-order effect on the group's
/// lines equals the lines themselves (`‖X/σ‖ / ‖∂X/∂θ_k/σ‖` at `start`, where it is zero:
/// a linear response, always solvable). Each grid point's steady states are sought by Newton
/// from the measured amplitudes, which are near the solution exactly when the value is near
/// the device's: a coupling tens of linewidths of shift off has no steady state near the
/// data, and no local step from there finds the basin. `None` when `start` itself cannot be
/// evaluated.
fn scan_params(
    fwd: &ForwardModel,
    sub_ds: &Dataset,
    tries: &Tries,
    (keep, new): (&[usize], &[usize]),
    start: &[f64],
) -> Option<Vec<f64>> {
    let (meas, sigma) = observations_of(fwd, keep, tries.meas, tries.sigma);
    let nk = fwd.unknowns().len();
    let mut sub = fwd.subset(keep);
    sub.start_from_data(sub_ds);
    let mut x = vec![Complex64::new(0.0, 0.0); sub.n_observations()];
    let mut jac = vec![Complex64::new(0.0, 0.0); sub.n_observations() * nk];
    sub.evaluate(start, &mut x, Some(&mut jac)).ok()?;
    let chi2 = |x: &[Complex64]| -> f64 {
        meas.iter()
            .zip(x)
            .zip(&sigma)
            .map(|((m, x), s)| (m - x).norm_sqr() / (s * s))
            .sum()
    };
    let size: f64 = x
        .iter()
        .zip(&sigma)
        .map(|(x, s)| (x / s).norm_sqr())
        .sum::<f64>()
        .sqrt();
    let mut best = (chi2(&x), start.to_vec());
    for &k in new {
        if !matches!(fwd.unknowns()[k], Unknown::Param(_)) {
            continue;
        }
        let slope: f64 = sigma
            .iter()
            .enumerate()
            .map(|(o, s)| (jac[o * nk + k] / s).norm_sqr())
            .sum::<f64>()
            .sqrt();
        let scale = size / slope;
        if !(scale.is_finite() && scale > 0.0) {
            continue;
        }
        let (lo, hi) = tries.bounds[k];
        let mut trial = best.1.clone();
        for sign in [1.0, -1.0] {
            for j in -SCAN_OCTAVES..=SCAN_OCTAVES {
                let v = sign * scale * 2f64.powi(j);
                if lo.is_some_and(|l| v < l) || hi.is_some_and(|h| v > h) {
                    continue;
                }
                trial[k] = v;
                sub.start_from_data(sub_ds);
                if sub.evaluate_trial(&trial, &mut x).is_ok() {
                    let c = chi2(&x);
                    if c < best.0 {
                        best = (c, trial.clone());
                    }
                }
            }
        }
    }
    Some(best.1)
}

/// One group's `χ²` as a quadratic model around its fit `θ_g`, over the unknowns `cols` it
/// depends on: `χ²_g(θ) ≈ χ²_g(θ_g) − 2 bᵀ(θ − θ_g) + (θ − θ_g)ᵀ I (θ − θ_g)` with the
/// information `I = AᵀA` and `b = Aᵀr` (`A = J/σ` and `r = (y − x)/σ` at the fit, real and
/// imaginary rows), times a weight (below 1 for a fit worse than a correct model's). Stored as
/// `I` and `I θ_g + b`, the model's contribution to the normal equations of the sum over
/// groups ([`combine`]).
///
/// Why the full matrix and not each unknown's precision: a strongly driven pair measurement
/// pins a combination of its modes' `f`, `Q`, `β` and its coupling (a line's shifted frequency)
/// thousands of times more sharply than each of them alone. An inverse-variance mean of each
/// unknown over the groups moves the combination by thousands of the pair's sigmas, out of the
/// pair's regime (the twenty-mode string, seed 20: `couple_q2_q9` missed by `χ²/dof` 2.6·10⁴
/// at that mean and refitting its coupling there left it so); the minimum of the summed
/// models moves the coupling with the modes along the pair's valley.
#[derive(Debug, Clone)]
struct Quadratic {
    /// The unknowns (indices into the forward model's).
    cols: Vec<usize>,
    /// `w I` over `cols`.
    info: DMatrix<f64>,
    /// `w (I θ_g + b)` over `cols`.
    rhs: DVector<f64>,
    /// `θ_g` over `cols`: where the model was taken.
    at: DVector<f64>,
}

impl Quadratic {
    /// The model of a fit at `theta` (every unknown) with Jacobian `jac` (`nk` columns, the
    /// layout of [`ForwardModel::evaluate`]) and residuals `resid = y − x` of noise `sigma`,
    /// over `cols`, weighted by `weight`. `None` when a value is not finite.
    fn of_fit(
        (jac, nk): (&[Complex64], usize),
        (resid, sigma): (&[Complex64], &[f64]),
        cols: &[usize],
        theta: &[f64],
        weight: f64,
    ) -> Option<Quadratic> {
        let m = cols.len();
        let mut info = DMatrix::<f64>::zeros(m, m);
        let mut grad = DVector::<f64>::zeros(m);
        let mut row = vec![Complex64::new(0.0, 0.0); m];
        for (o, (r, s)) in resid.iter().zip(sigma).enumerate() {
            for (z, &k) in row.iter_mut().zip(cols) {
                *z = jac[o * nk + k] / *s;
            }
            let r = r / *s;
            for (i, zi) in row.iter().enumerate() {
                grad[i] += zi.re * r.re + zi.im * r.im;
                for (j, zj) in row.iter().enumerate().skip(i) {
                    info[(i, j)] += zi.re * zj.re + zi.im * zj.im;
                }
            }
        }
        info.fill_lower_triangle_with_upper_triangle();
        let at = DVector::from_iterator(m, cols.iter().map(|&k| theta[k]));
        let rhs = (&info * &at + grad) * weight;
        info *= weight;
        (info.iter().chain(rhs.iter()).all(|v| v.is_finite())).then_some(Quadratic {
            cols: cols.to_vec(),
            info,
            rhs,
            at,
        })
    }
}

impl Quadratic {
    /// The rise of the model's `χ²` when the unknowns of its `cols` not among `own` move from
    /// the model's point to their values in `theta`, those among `own` re-minimised for them:
    /// `f(δ_s) − f(0)` with `f(δ_s) = min over δ_o of δᵀIδ − 2bᵀδ` (`δ = θ − θ_g`, `b` the
    /// gradient term of [`Quadratic::of_fit`], `s` the shared unknowns, `o` the own). In the
    /// model's units of `χ²` (weighted). `None` when the own block is singular or a value is
    /// not finite.
    fn shift_cost(&self, own: &[usize], theta: &[f64]) -> Option<f64> {
        let (o, s): (Vec<usize>, Vec<usize>) =
            (0..self.cols.len()).partition(|&i| own.contains(&self.cols[i]));
        if s.is_empty() {
            return Some(0.0);
        }
        let b = &self.rhs - &self.info * &self.at;
        let ds =
            DVector::from_iterator(s.len(), s.iter().map(|&i| theta[self.cols[i]] - self.at[i]));
        let iss = self.info.select_rows(&s).select_columns(&s);
        let bs = DVector::from_iterator(s.len(), s.iter().map(|&i| b[i]));
        let mut f = ds.dot(&(&iss * &ds)) - 2.0 * bs.dot(&ds);
        if !o.is_empty() {
            let ino = self.info.select_rows(&o).select_columns(&s);
            let bo = DVector::from_iterator(o.len(), o.iter().map(|&i| b[i]));
            let mut inn = self.info.select_rows(&o).select_columns(&o);
            // Equilibrated, with the ridge of [`combine`].
            let d: Vec<f64> = (0..o.len())
                .map(|i| match inn[(i, i)] {
                    v if v > 0.0 && v.is_finite() => 1.0 / v.sqrt(),
                    _ => 1.0,
                })
                .collect();
            for i in 0..o.len() {
                for j in 0..o.len() {
                    inn[(i, j)] *= d[i] * d[j];
                }
                inn[(i, i)] += COMBINE_RIDGE;
            }
            let chol = inn.cholesky()?;
            let quad = |v: DVector<f64>| -> f64 {
                let v = DVector::from_iterator(v.len(), v.iter().zip(&d).map(|(x, d)| x * d));
                v.dot(&chol.solve(&v))
            };
            f -= quad(&bo - &ino * &ds) - quad(bo);
        }
        f.is_finite().then_some(f)
    }
}

/// A group's model that may be left out of the combination: its index among the models and
/// the unknowns the group fitted as its own ([`consistent_models`]).
type Suspect = (usize, Vec<usize>);

/// A group that moved the unknowns earlier groups fitted ([`GroupResult::moved_shared`]) is
/// left out of the combination when, at the combination of the groups that did not, its own
/// `χ²` would rise by more than this many units per unknown it shares (beyond
/// [`INCONSISTENT_FLOOR`]): a consistent group's rise is about one per shared unknown.
const INCONSISTENT_PER_SHARED: f64 = 10.0;

/// See [`INCONSISTENT_PER_SHARED`].
const INCONSISTENT_FLOOR: f64 = 25.0;

/// Which of `models` to combine: all but those of `suspects` (each an index into `models`
/// with the unknowns its group fitted as its own) whose values of the shared unknowns the
/// combination of the unsuspected models rules out ([`Quadratic::shift_cost`] above
/// [`INCONSISTENT_PER_SHARED`] per shared unknown plus [`INCONSISTENT_FLOOR`]).
///
/// Why: a group whose fit over its new unknowns alone missed is refined over the shared
/// ones too, and that refinement can end in another minimum far from what every other group
/// says (the twenty-mode string, noise seed 11: `couple_q6_q11` and `couple_q7_q11` put q11's
/// damping at 5·10⁻⁴ of the truth and their coupling at zero, at `χ²/dof` 1.5 of their own).
/// Combined with the others by its information, such a fit pulls the shared unknowns half way
/// (q11's damping to −55 %), where the groups that fitted well miss. Judged against the
/// unsuspected groups only, several such fits cannot mask each other.
fn consistent_models(
    models: &[Quadratic],
    suspects: &[Suspect],
    theta: &[f64],
    bounds: &[(Option<f64>, Option<f64>)],
) -> Vec<bool> {
    let mut keep = vec![true; models.len()];
    if suspects.is_empty() {
        return keep;
    }
    let clean: Vec<Quadratic> = models
        .iter()
        .enumerate()
        .filter(|(i, _)| !suspects.iter().any(|s| s.0 == *i))
        .map(|(_, q)| q.clone())
        .collect();
    let others = combine(&clean, theta, bounds);
    for (i, own) in suspects {
        let q = &models[*i];
        let shared = q.cols.len() - q.cols.iter().filter(|k| own.contains(k)).count();
        let limit = INCONSISTENT_FLOOR + INCONSISTENT_PER_SHARED * shared as f64;
        let rise = q.shift_cost(own, &others);
        if rise.is_some_and(|r| r > limit) {
            keep[*i] = false;
        }
    }
    keep
}

/// Below this fraction of its own information (equilibrated diagonal), an unknown is held
/// near its value in `theta` by [`combine`]: a direction no group determines stays put.
const COMBINE_RIDGE: f64 = 1e-9;

/// The minimum of the sum of the groups' quadratic models ([`Quadratic`]): `θ = (Σ I_g)⁻¹
/// Σ (I_g θ_g + b_g)`, the weighted least-squares combination of the groups' fits with their
/// correlations (for linear measurements, exactly the joint fit of all of them). The unknowns
/// no model covers keep their value in `theta`; each is held towards it by [`COMBINE_RIDGE`]
/// of its information, solved equilibrated (`D (Σ I) D`, `D = diag^-1/2`) by Cholesky, and
/// clamped to its `bounds`. `theta` unchanged when the sum is not positive definite or the
/// solution not finite.
fn combine(models: &[Quadratic], theta: &[f64], bounds: &[(Option<f64>, Option<f64>)]) -> Vec<f64> {
    let mut index: Vec<Option<usize>> = vec![None; theta.len()];
    let mut cols = Vec::new();
    for &k in models.iter().flat_map(|q| &q.cols) {
        if index[k].is_none() {
            index[k] = Some(cols.len());
            cols.push(k);
        }
    }
    let n = cols.len();
    let mut info = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    for q in models {
        let at: Vec<usize> = q.cols.iter().filter_map(|&k| index[k]).collect();
        for (a, &i) in at.iter().enumerate() {
            rhs[i] += q.rhs[a];
            for (b, &j) in at.iter().enumerate() {
                info[(i, j)] += q.info[(a, b)];
            }
        }
    }
    let d: Vec<f64> = (0..n)
        .map(|i| match info[(i, i)] {
            v if v > 0.0 && v.is_finite() => 1.0 / v.sqrt(),
            _ => 0.0,
        })
        .collect();
    for i in 0..n {
        for j in 0..n {
            info[(i, j)] *= d[i] * d[j];
        }
        // A column no model informs: the identity row keeps its value.
        let ridge = if d[i] > 0.0 { COMBINE_RIDGE } else { 1.0 };
        info[(i, i)] += ridge;
        rhs[i] = rhs[i] * d[i] + ridge * theta[cols[i]] / if d[i] > 0.0 { d[i] } else { 1.0 };
    }
    let mut out = theta.to_vec();
    let Some(y) = info.cholesky().map(|c| c.solve(&rhs)) else {
        return out;
    };
    if !y.iter().all(|v| v.is_finite()) {
        return out;
    }
    for (i, &k) in cols.iter().enumerate() {
        let (lo, hi) = bounds[k];
        let v = if d[i] > 0.0 { y[i] * d[i] } else { y[i] };
        out[k] = v
            .max(lo.unwrap_or(f64::NEG_INFINITY))
            .min(hi.unwrap_or(f64::INFINITY));
    }
    out
}

/// `theta` at the combination of the groups' `models` ([`combine`]) without those of the
/// `suspects` (each with its group in `suspect_groups`) that [`consistent_models`] leaves out,
/// only where groups share unknowns (a group alone keeps its own fit: its model's
/// Gauss-Newton step from there lost the steady state of ml_fallback's control, one strongly
/// driven mode below its escape amplitude). Returns the groups left out.
fn combine_consistent(
    (models, suspects, suspect_groups): (&[Quadratic], &[Suspect], &[usize]),
    theta: &mut Vec<f64>,
    bounds: &[(Option<f64>, Option<f64>)],
) -> Vec<usize> {
    let mut covered = vec![0usize; theta.len()];
    models
        .iter()
        .flat_map(|q| &q.cols)
        .for_each(|&k| covered[k] += 1);
    if covered.iter().all(|&c| c <= 1) {
        return Vec::new();
    }
    let keep = consistent_models(models, suspects, theta, bounds);
    let kept: Vec<Quadratic> = models
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(q, _)| q.clone())
        .collect();
    *theta = combine(&kept, theta, bounds);
    suspects
        .iter()
        .zip(suspect_groups)
        .filter(|((i, _), _)| !keep[*i])
        .map(|(_, &g)| g)
        .collect()
}

/// Fits the group `g`, left out of the combination ([`consistent_models`]), again from the
/// combined values `theta` over its own unknowns alone (the shared ones held: its refinement
/// over them is what went astray), from each of [`fit_group`]'s starts; its own unknowns'
/// values and steady states are kept when the fit is reached. Returns the lattices it widened.
fn refit_outlier(
    fwd: &mut ForwardModel,
    mean: &Dataset,
    tries: &Tries,
    (theta, settled): (&mut [f64], &BTreeSet<usize>),
    g: &mut GroupFit,
) -> Vec<Widened> {
    let neighbours = from_neighbours(fwd, theta, &g.unknowns, settled, tries.bounds);
    let (keep, own) = (&g.measurements, &g.unknowns);
    let Some(r) = fit_group(fwd, mean, tries, (theta, &neighbours), (keep, own, own)) else {
        return Vec::new();
    };
    for &k in own {
        theta[k] = r.fit.theta[k];
    }
    fwd.adopt(&r.sub, keep);
    g.reduced_chi2 = r.fit.chi2 / r.fit.dof.max(1) as f64;
    r.widened
}

/// The staged start from `theta0` (the pooled linear estimate as values of every unknown):
/// see the module documentation. `fwd` is left at the staged values' steady states (every
/// measurement's, the warm starts of the joint fit). `None` when the linear response itself
/// cannot be evaluated; `fwd` is then as it was started from the data.
pub(crate) fn staged_start(
    fwd: &mut ForwardModel,
    mean: &Dataset,
    tries: &Tries,
    theta0: &[f64],
) -> Option<Staged> {
    let nk = fwd.unknowns().len();
    let mut x = vec![Complex64::new(0.0, 0.0); fwd.n_observations()];
    let mut jac = vec![Complex64::new(0.0, 0.0); fwd.n_observations() * nk];
    let linear = params_at_zero(fwd, theta0, tries.cols, tries.bounds);
    fwd.start_from_data(mean);
    if fwd.evaluate(&linear, &mut x, Some(&mut jac)).is_err() {
        fwd.start_from_data(mean);
        return None;
    }
    let deps = dependencies(fwd, (&jac, tries.sigma), theta0, tries.cols);
    let follows = fwd.follows();
    let most = deps.iter().map(|d| d.1).max().unwrap_or(0);
    let mut theta = theta0.to_vec();
    let mut settled = BTreeSet::new();
    let mut groups = Vec::new();
    let mut fitted = vec![false; fwd.n_measurements()];
    // Each group's χ² as a quadratic model around its fit.
    let mut models = Vec::new();
    // The groups that share unknowns with earlier ones.
    let mut sharing = Vec::new();
    // The models of groups that moved the shared unknowns (index into `models`, the group's
    // own unknowns, the group's index).
    let mut suspects: Vec<Suspect> = Vec::new();
    let mut suspect_groups = Vec::new();
    let mut widened = Vec::new();
    for modes in 0..=most {
        let class = groups_of(&deps, modes, &settled, &follows);
        for (keep, new) in &class {
            let new: Vec<usize> = new.iter().copied().collect();
            let all: BTreeSet<usize> = keep
                .iter()
                .flat_map(|&mi| deps[mi].0.iter().copied())
                .collect();
            let all: Vec<usize> = all.into_iter().collect();
            let shares = all.len() > new.len();
            let neighbours = from_neighbours(fwd, &theta, &new, &settled, tries.bounds);
            let fit = fit_group(fwd, mean, tries, (&theta, &neighbours), (keep, &new, &all));
            let reduced_chi2 = match fit {
                Some(GroupResult {
                    fit: f,
                    sub,
                    model,
                    widened: w,
                    moved_shared,
                }) => {
                    widened.extend(w);
                    for &k in &new {
                        theta[k] = f.theta[k];
                    }
                    if moved_shared && model.is_some() {
                        suspects.push((models.len(), new.clone()));
                        suspect_groups.push(groups.len());
                    }
                    models.extend(model);
                    fwd.adopt(&sub, keep);
                    keep.iter().for_each(|&mi| fitted[mi] = true);
                    if shares {
                        sharing.push(groups.len());
                    }
                    f.chi2 / f.dof.max(1) as f64
                }
                None => f64::INFINITY,
            };
            groups.push(GroupFit {
                measurements: keep.clone(),
                unknowns: new,
                reduced_chi2,
            });
        }
        for (_, new) in class {
            settled.extend(new);
        }
    }
    // Every unknown at the minimum of the groups' models summed, with their correlations
    // ([`Quadratic`]): a strongly driven measurement fits combinations of its modes' f, Q and
    // β far more sharply than the measurement that fitted them first, and where those move by
    // many of its sigmas its own state may not exist (past a fold).
    // Groups far from the others' combination are left out of it and refitted below.
    let outliers = combine_consistent(
        (&models, &suspects, &suspect_groups),
        &mut theta,
        tries.bounds,
    );
    // There, each group that shares unknowns fits its own again, from the combined values
    // (its own moved with the shared ones along its valley; from the values it had with the
    // shared ones held, the twenty-mode string, seed 20, stopped at χ²/dof 196), so every
    // steady state is at the start. Not for `discover`'s candidates (`tries.scan` off): most
    // lack a term the device has, their groups refit poorly from every start, and the refits
    // were a third of a discovery's time; the joint fit follows their states from their own fits.
    let sharing = if tries.scan { sharing } else { Vec::new() };
    for &gi in &outliers {
        widened.extend(refit_outlier(
            fwd,
            mean,
            tries,
            (&mut theta, &settled),
            &mut groups[gi],
        ));
    }
    for gi in sharing.into_iter().filter(|g| !outliers.contains(g)) {
        let g = &mut groups[gi];
        if let Some((f, sub)) = refit_held(fwd, tries, &theta, (&g.measurements, &g.unknowns)) {
            for &k in &g.unknowns {
                theta[k] = f.theta[k];
            }
            fwd.adopt(&sub, &g.measurements);
            g.reduced_chi2 = f.chi2 / f.dof.max(1) as f64;
        }
    }
    // The measurements no group fitted (nothing new in them, or their fit failed): their
    // steady states at the staged values, from the data.
    // One by one: one that fails keeps its start from the data.
    for mi in (0..fitted.len()).filter(|&mi| !fitted[mi]) {
        let mut sub = fwd.subset(&[mi]);
        sub.start_from_data(&select(mean, &[mi]));
        let mut xs = vec![Complex64::new(0.0, 0.0); sub.n_observations()];
        if sub.evaluate(&theta, &mut xs, None).is_ok() {
            fwd.adopt(&sub, &[mi]);
        }
    }
    Some(Staged {
        theta,
        groups,
        widened,
    })
}

/// A group whose own fit is far from a correct model's (`χ²/dof` above [`GOOD_FIT`] times
/// `e0`): the result's `unfit` entry of kind "group not fitted" and the note.
#[derive(Debug, Clone)]
pub(crate) struct PoorGroup {
    /// Its measurements' names.
    pub measurements: Vec<String>,
    /// The unknowns it fitted (indices into the forward model's unknowns).
    pub unknowns: Vec<usize>,
    /// `χ²/dof` of its best fit (infinite when no start reached one).
    pub reduced_chi2: f64,
}

/// The groups of `groups` whose own fit is far from a correct model's (`χ²/dof` above
/// [`GOOD_FIT`] times `e0`, or none reached), in fitting order.
pub(crate) fn poor_groups(fwd: &ForwardModel, groups: &[GroupFit], e0: f64) -> Vec<PoorGroup> {
    let names = fwd.measurement_names();
    groups
        .iter()
        .filter(|g| g.reduced_chi2.is_nan() || g.reduced_chi2 > GOOD_FIT * e0)
        .map(|g| PoorGroup {
            measurements: g
                .measurements
                .iter()
                .map(|&mi| names[mi].to_string())
                .collect(),
            unknowns: g.unknowns.clone(),
            reduced_chi2: g.reduced_chi2,
        })
        .collect()
}

/// The note on the `poor` groups (of `total`) when the joint fit failed: which unknowns, in
/// which measurements, and what measurement would help. `None` when every group fitted.
pub(crate) fn poor_groups_note(
    fwd: &ForwardModel,
    poor: &[PoorGroup],
    total: usize,
    e0: f64,
) -> Option<String> {
    if poor.is_empty() {
        return None;
    }
    let items: Vec<String> = poor
        .iter()
        .map(|g| {
            let unknowns: Vec<String> = g.unknowns.iter().map(|&k| fwd.label(k)).collect();
            let meas: Vec<String> = g.measurements.iter().map(|m| format!("\"{m}\"")).collect();
            format!(
                "{} in {} (χ²/dof {:.3e})",
                harmonid_data::text::first_and_more(unknowns, 4).join(", "),
                harmonid_data::text::first_and_more(meas, 3).join(", "),
                g.reduced_chi2
            )
        })
        .collect();
    Some(format!(
        "output-error fit by groups of measurements: {} of {total} groups could not be fitted on their own (a correct model gives χ²/dof about {e0:.3}): {}; the modes they share with the groups fitted before them were held there. A measurement of these unknowns' modes driven alone, or this group's measurement at a lower drive (nearer the linear response, where the linear estimate is a good start), would help",
        poor.len(),
        harmonid_data::text::first_and_more(items, 4).join("; ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::ForwardSettings;
    use crate::ForceModel;
    use harmonid_data::{Manifest, Measurement, MeasurementSpec, Point};
    use std::f64::consts::PI;

    const MODEL: &str =
        "mode a at 1 kHz\nmode b at 3 kHz\nparam beta, g\npotential: beta/4*a^4 + g/2*a^2*b^2\n";

    /// The precision `1/var` of each unknown in `cols` from the information `AᵀA` of the fit
    /// (`A = J/σ`, real and imaginary rows; `jac` with `nk` columns), by its equilibrated
    /// inverse; none when the information is singular.
    fn precisions(
        jac: &[Complex64],
        nk: usize,
        sigma: &[f64],
        cols: &[usize],
    ) -> Vec<(usize, f64)> {
        let m = cols.len();
        let mut a = DMatrix::<f64>::zeros(2 * sigma.len(), m);
        for (o, s) in sigma.iter().enumerate() {
            for (j, &k) in cols.iter().enumerate() {
                let z = jac[o * nk + k] / *s;
                a[(2 * o, j)] = z.re;
                a[(2 * o + 1, j)] = z.im;
            }
        }
        let d: Vec<f64> = (0..m)
            .map(|j| match a.column(j).norm() {
                n if n > 0.0 && n.is_finite() => 1.0 / n,
                _ => 0.0,
            })
            .collect();
        for (j, dj) in d.iter().enumerate() {
            a.column_mut(j).scale_mut(*dj);
        }
        let Some(inv) = (a.transpose() * &a).try_inverse() else {
            return Vec::new();
        };
        cols.iter()
            .enumerate()
            .filter_map(|(j, &k)| {
                let var = inv[(j, j)] * d[j] * d[j];
                (var.is_finite() && var > 0.0).then_some((k, 1.0 / var))
            })
            .collect()
    }

    /// Two linear "groups" of complex observations `y = J θ + e` of three unknowns, sharing
    /// the middle one, with correlated information (each group's columns nearly collinear),
    /// each linearised at an arbitrary point, the second weighted by ½: [`combine`] of their
    /// [`Quadratic`]s is the weighted least-squares fit of all the rows (normal equations of
    /// the stacked rows, the second's noise `σ/√½`) to 10⁻⁵ of its standard errors (the
    /// ridge of [`COMBINE_RIDGE`] towards the start), and the per-unknown
    /// inverse-variance mean of the two groups' own fits is not (2.2 of the joint fit's
    /// standard errors off).
    #[test]
    fn combining_groups_is_the_joint_weighted_least_squares() {
        let nk = 3;
        let c = |re: f64, im: f64| Complex64::new(re, im);
        // Rows of each group over (θ0, θ1, θ2), its observations and noise.
        let rows1 = [
            [c(1.0, 0.2), c(0.9, 0.25), c(0.0, 0.0)],
            [c(0.5, -1.0), c(0.45, -0.9), c(0.0, 0.0)],
            [c(2.0, 0.1), c(1.9, 0.0), c(0.0, 0.0)],
        ];
        let rows2 = [
            [c(0.0, 0.0), c(1.0, 1.0), c(-1.0, -0.9)],
            [c(0.0, 0.0), c(0.3, 0.1), c(0.2, 0.3)],
            [c(0.0, 0.0), c(-0.7, 0.4), c(-0.6, 0.5)],
        ];
        let truth = [1.5, -0.5, 2.0];
        let noise = [c(0.01, -0.02), c(-0.03, 0.01), c(0.02, 0.02)];
        let sigma = [0.02, 0.01, 0.03];
        let weights = [1.0, 0.5];
        let observe = |rows: &[[Complex64; 3]; 3], shift: f64| -> Vec<Complex64> {
            rows.iter()
                .zip(&noise)
                .map(|(r, e)| {
                    r.iter().zip(&truth).map(|(z, t)| z * t).sum::<Complex64>() + e * shift
                })
                .collect()
        };
        let ys = [observe(&rows1, 1.0), observe(&rows2, -0.7)];
        let groups = [(&rows1, vec![0, 1]), (&rows2, vec![1, 2])];
        let at = [[1.0, 0.0, 7.0], [-3.0, 0.4, 1.0]];
        let mut models = Vec::new();
        let mut own = Vec::new();
        for (g, (rows, cols)) in groups.iter().enumerate() {
            let jac: Vec<Complex64> = rows.iter().flatten().copied().collect();
            let x: Vec<Complex64> = rows
                .iter()
                .map(|r| r.iter().zip(&at[g]).map(|(z, t)| z * t).sum())
                .collect();
            let resid: Vec<Complex64> = ys[g].iter().zip(&x).map(|(y, x)| y - x).collect();
            let q = Quadratic::of_fit((&jac, nk), (&resid, &sigma), cols, &at[g], weights[g])
                .expect("finite");
            // The group's own fit and each unknown's precision (diagonal of I⁻¹).
            let sol = q.info.clone().cholesky().expect("pd").solve(&q.rhs);
            let inv = q.info.clone().try_inverse().expect("invertible");
            own.extend(
                cols.iter()
                    .enumerate()
                    .map(|(i, &k)| (k, sol[i], 1.0 / inv[(i, i)])),
            );
            models.push(q);
        }
        let bounds = vec![(None, None); nk];
        let combined = combine(&models, &[0.0; 3], &bounds);
        // The weighted least-squares fit of all six complex rows.
        let mut a = DMatrix::<f64>::zeros(12, nk);
        let mut b = DVector::<f64>::zeros(12);
        for (g, (rows, _)) in groups.iter().enumerate() {
            for (o, r) in rows.iter().enumerate() {
                let s = sigma[o] / weights[g].sqrt();
                let i = 2 * (3 * g + o);
                for k in 0..nk {
                    a[(i, k)] = r[k].re / s;
                    a[(i + 1, k)] = r[k].im / s;
                }
                b[i] = ys[g][o].re / s;
                b[i + 1] = ys[g][o].im / s;
            }
        }
        let normal = a.transpose() * &a;
        let wls = normal
            .clone()
            .cholesky()
            .expect("pd")
            .solve(&(a.transpose() * b));
        let stderr: Vec<f64> = {
            let inv = normal.try_inverse().expect("invertible");
            (0..nk).map(|k| inv[(k, k)].sqrt()).collect()
        };
        for k in 0..nk {
            let off = (combined[k] - wls[k]).abs() / stderr[k];
            assert!(
                off < 1e-5,
                "unknown {k}: {} vs {} ({off} stderr)",
                combined[k],
                wls[k]
            );
        }
        // Each unknown's inverse-variance mean over the groups' own fits.
        let mean = |k: usize| {
            let (w, wt) = own
                .iter()
                .filter(|o| o.0 == k)
                .fold((0.0, 0.0), |(w, wt), o| (w + o.2, wt + o.2 * o.1));
            wt / w
        };
        let worst = (0..nk)
            .map(|k| (mean(k) - wls[k]).abs() / stderr[k])
            .fold(0.0, f64::max);
        println!("the per-unknown mean is {worst:.2} stderr off the joint fit");
        assert!(worst > 1.0, "{worst}");
    }

    /// An unknown no group informs keeps its value; one held at a bound is clamped.
    #[test]
    fn combine_keeps_the_uninformed_and_clamps_to_bounds() {
        let q = Quadratic {
            cols: vec![0],
            info: DMatrix::from_element(1, 1, 4.0),
            rhs: DVector::from_element(1, -8.0),
            at: DVector::from_element(1, -2.0),
        };
        let bounds = vec![(Some(0.0), None), (None, None)];
        assert_eq!(
            combine(std::slice::from_ref(&q), &[1.0, 3.0], &bounds),
            vec![0.0, 3.0]
        );
        let free = vec![(None, None); 2];
        let v = combine(&[q], &[1.0, 3.0], &free);
        assert!((v[0] + 2.0).abs() < 1e-6 && v[1] == 3.0, "{v:?}");
    }

    /// A model `δᵀIδ − 2bᵀδ` around `at` over `cols` (`rhs = I at + b`).
    fn quadratic(cols: &[usize], info: &[f64], b: &[f64], at: &[f64]) -> Quadratic {
        let n = cols.len();
        let info = DMatrix::from_row_slice(n, n, info);
        let at = DVector::from_column_slice(at);
        let rhs = &info * &at + DVector::from_column_slice(b);
        Quadratic {
            cols: cols.to_vec(),
            info,
            rhs,
            at,
        }
    }

    /// [`Quadratic::shift_cost`] of a two-unknown model (`I = [[a, c], [c, d]]`, gradient term
    /// `b`, the second unknown its own) is the closed form of its minimum over the own one,
    /// `a δ² − 2 b₁ δ − ((b₂ − c δ)² − b₂²)/d`; an unknown that is all its own costs nothing.
    #[test]
    fn shift_cost_is_the_rise_of_the_minimum_over_the_own_unknowns() {
        let (a, c, d) = (4.0e6, -3.0e3, 2.5);
        let (b1, b2) = (20.0, -0.7);
        let q = quadratic(&[3, 7], &[a, c, c, d], &[b1, b2], &[1.5, -2.0]);
        let mut theta = vec![0.0; 8];
        theta[3] = 1.5 + 2e-3;
        theta[7] = 55.0; // the own unknown's value does not matter
        let delta = 2e-3;
        let want = a * delta * delta - 2.0 * b1 * delta - ((b2 - c * delta).powi(2) - b2 * b2) / d;
        let got = q.shift_cost(&[7], &theta).expect("finite");
        assert!((got - want).abs() < 1e-6 * want.abs(), "{got} vs {want}");
        assert_eq!(q.shift_cost(&[3, 7], &theta), Some(0.0));
    }

    /// Two groups that moved a shared unknown (index 0, fitted first by a clean group at 1.0
    /// with standard error 0.1): one at 1.05 (its information on it 75 once its own unknown,
    /// correlated, is free: a `χ²` rise of 0.19) is combined, one at 3.0 (information 10⁴: a
    /// rise of 4·10⁴) is left out. The combination of the rest is the information-weighted
    /// mean of the two, `(100·1 + 75·1.05)/175`; all three combined would move it to 2.97.
    #[test]
    fn an_inconsistent_group_is_left_out_of_the_combination() {
        let clean = quadratic(&[0, 1], &[100.0, 0.0, 0.0, 1.0], &[0.0, 0.0], &[1.0, 5.0]);
        let near = quadratic(
            &[0, 2],
            &[100.0, 50.0, 50.0, 100.0],
            &[0.0, 0.0],
            &[1.05, 2.0],
        );
        let far = quadratic(&[0, 3], &[1e4, 0.0, 0.0, 1.0], &[0.0, 0.0], &[3.0, 7.0]);
        let models = vec![clean, near, far];
        let suspects = vec![(1, vec![2]), (2, vec![3])];
        let theta = vec![1.0, 5.0, 2.0, 7.0];
        let bounds = vec![(None, None); 4];
        let keep = consistent_models(&models, &suspects, &theta, &bounds);
        assert_eq!(keep, vec![true, true, false]);
        let mut v = theta.clone();
        let left_out = combine_consistent((&models, &suspects, &[11, 12]), &mut v, &bounds);
        assert_eq!(left_out, vec![12]);
        let all = combine(&models, &theta, &bounds);
        println!("shared unknown: {} kept, {} with every group", v[0], all[0]);
        let mean = (100.0 * 1.0 + 75.0 * 1.05) / 175.0;
        assert!((v[0] - mean).abs() < 1e-6, "{} vs {mean}", v[0]);
        assert!((all[0] - 1.0).abs() > 1.5, "{}", all[0]);
        assert!((v[3] - 7.0).abs() < 1e-6, "{}", v[3]);
    }

    /// One strongly driven pair: two tones on `a` 10 Hz apart across its resonance (Q 100,
    /// a Duffing shift of about a linewidth), one on `b`; `a`'s intermodulation sidebands out
    /// to ±35 Hz and `b`'s ±10 Hz measured (amplitudes zero: the shape only).
    fn dataset() -> Dataset {
        let mut manifest = Manifest::new("pair");
        manifest.points.push(Point {
            name: "p0".into(),
            shape: [("a".to_string(), 0.5), ("b".to_string(), 0.8)]
                .into_iter()
                .collect(),
        });
        let drives = [995.0, 1005.0, 3005.0];
        let spec = MeasurementSpec {
            name: "couple_a_b".to_string(),
            file: None,
            drives_hz: drives.to_vec(),
            drive_levels_v: Some(vec![1.0, 1.0, 0.5]),
            drive_phases_rad: Some(vec![0.0; 3]),
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            bandwidth_hz: None,
            sweep: None,
        };
        let freqs: Vec<f64> = (0..8)
            .map(|k| 965.0 + 10.0 * k as f64)
            .chain([2995.0, 3005.0, 3015.0])
            .collect();
        let m = Measurement::zeros(spec, freqs, vec![0], 1);
        manifest.measurements = vec![m.spec.clone()];
        Dataset {
            dir: "pair".into(),
            manifest,
            measurements: vec![m],
            truth: None,
            notes: Vec::new(),
        }
    }

    /// The truth: f 1 and 3 kHz, Q 100 and 200, gains 3+i and −2+4i, β 4·10¹⁵, g 2·10¹⁵.
    fn truth(fwd: &ForwardModel) -> Vec<f64> {
        let (f, q) = ([1000.0, 3000.0], [100.0, 200.0]);
        let gain = [Complex64::new(3.0, 1.0), Complex64::new(-2.0, 4.0)];
        fwd.unknowns()
            .iter()
            .map(|u| match *u {
                Unknown::OmegaSq(n) => (2.0 * PI * f[n]).powi(2),
                Unknown::Gamma(n) => 2.0 * PI * f[n] / q[n],
                Unknown::Param(p) => [4e15, 2e15][p],
                Unknown::Gain { mode, quad, .. } => {
                    [gain[mode].re, gain[mode].im][usize::from(quad)]
                }
                Unknown::Force { .. } | Unknown::Background { .. } => f64::NAN,
            })
            .collect()
    }

    /// A group whose lattice at the start's order (9) is too coarse for its noise: the data
    /// simulated at order 17, noise 10⁻¹¹ m (a tenth of a percent of the sidebands). Fitted on
    /// the start's lattice the estimate is biased by more than a standard error; after
    /// [`settle_truncation`] every unknown is within one standard error of the truth.
    #[test]
    fn a_truncated_group_is_refitted_on_a_wider_lattice() {
        let model = harmonid_model::parse_str(MODEL, "pair.hb").expect("model");
        let mut ds = dataset();
        let mut wide_settings = ForwardSettings::default();
        wide_settings.hb.lattice.order = 17;
        wide_settings.hb.lattice.window_rel *= 1.5_f64.powi(4);
        wide_settings.hb.lattice.harmonics = true;
        let mut wide =
            ForwardModel::new(&model, &ds, ForceModel::Auto, &wide_settings).expect("forward");
        let theta = truth(&wide);
        assert!(theta.iter().all(|t| t.is_finite()), "{:?}", wide.unknowns());
        let mut x = vec![Complex64::new(0.0, 0.0); wide.n_observations()];
        wide.evaluate(&theta, &mut x, None).expect("simulate");
        for (r, &v) in x.iter().enumerate() {
            *ds.measurements[0].amplitude_mut(0, r, 0) = v;
        }
        let sigma = vec![1e-11; x.len()];
        let mut narrow =
            ForwardModel::new(&model, &ds, ForceModel::Auto, &ForwardSettings::default())
                .expect("forward");
        narrow.start_from_data(&ds);
        let cols = narrow.free();
        let bounds = vec![(None, None); theta.len()];
        let tries = Tries {
            meas: &x,
            sigma: &sigma,
            cols: &cols,
            bounds: &bounds,
            e0: 1.0,
            scan: true,
        };
        let settings = MlSettings {
            ramp_at_start: false,
            ..MlSettings::default()
        };
        let fit = ml::refine(&mut narrow, &x, &sigma, &theta, &cols, &bounds, &settings)
            .expect("fit on the start's lattice");
        let offsets = |fit: &ml::MlFit| -> f64 {
            precisions(&fit.jac, theta.len(), &sigma, &cols)
                .into_iter()
                .map(|(k, p)| (fit.theta[k] - theta[k]).abs() * p.sqrt())
                .fold(0.0, f64::max)
        };
        let before = offsets(&fit);
        assert!(
            before > 1.0,
            "the start's lattice biased by only {before} stderr"
        );
        let (settled, widened) = settle_truncation(&mut narrow, (&x, &sigma), fit, &cols, &tries);
        assert!(widened
            .iter()
            .all(|w| w.measurement == "couple_a_b" && w.order > 9));
        assert!(!widened.is_empty());
        let after = offsets(&settled);
        println!("worst offset {before:.2} stderr on the start's lattice, {after:.3} widened");
        assert!(
            after < 1.0,
            "{after} stderr off after widening ({before} before)"
        );
    }
}

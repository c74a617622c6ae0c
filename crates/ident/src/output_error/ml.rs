//! Output-error maximum likelihood: the unknowns that make the harmonic-balance prediction of
//! every measured line of every measurement match the (pooled) data, jointly.
//!
//! Minimises `χ²(θ) = Σ_o |X_o − X_o^HB(θ)|² / σ_o²` over the free unknowns by
//! Levenberg–Marquardt with the Jacobian of [`crate::forward`] (implicit differentiation of the
//! harmonic balance, never finite differences). Each step solves the damped, column-equilibrated
//! least-squares problem `min ‖r − A D y‖² + λ ‖y‖²` (`A = J/σ` with real and imaginary rows,
//! `D = diag(1/‖A_j‖)`, `δθ = D y`) by QR and SVD, or, for a large problem (hundreds of
//! unknowns, thousands of lines), from its normal equations built once per Jacobian from the
//! rows' non-zero entries and factorised by Cholesky per damping, so unknowns spanning 25
//! decades (ω² ~ 1e12, couplings ~ 1e23, gains ~ 1) are steps of comparable size. A step is accepted when it lowers
//! `χ²` (then `λ /= 3`), else `λ *= 4` and the step is recomputed; a trial at which the
//! harmonic balance fails or a value leaves its physical range counts as a rejected step.
//!
//! **Bounds** are handled in the step (projection with an active set): an unknown at a bound
//! whose gradient points outwards is held there and the step is recomputed without it; a step
//! that would cross a bound stops the unknown at it. Unknowns held at a bound at the end are
//! reported in [`MlFit::at_bound`].

use crate::forward::{ForwardError, ForwardModel};
use crate::uncertainty::AtEstimate;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Settings of the refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MlSettings {
    /// Largest number of accepted and rejected steps (default 60).
    pub max_steps: usize,
    /// Stop when an accepted step lowers `χ²` by less than this fraction (default 1e-10).
    pub rel_tol: f64,
    /// Whether a steady state that Newton does not reach from its warm start at `θ0` is
    /// sought by the drive ramp from rest (default `true`; a caller with other starts to try
    /// first says `false`: the ramp is the costly last resort).
    pub ramp_at_start: bool,
}

impl Default for MlSettings {
    fn default() -> Self {
        MlSettings {
            max_steps: 60,
            rel_tol: 1e-10,
            ramp_at_start: true,
        }
    }
}

/// Result of [`refine`].
#[derive(Debug, Clone)]
pub struct MlFit {
    /// Every unknown of the forward model at the estimate (fixed ones included).
    pub theta: Vec<f64>,
    /// Predictions at the estimate, m.
    pub x: Vec<Complex64>,
    /// Jacobian at the estimate, `jac[o·K + k]` (layout of [`ForwardModel::evaluate`]).
    pub jac: Vec<Complex64>,
    /// `χ²` at the start and at the estimate.
    pub chi2_start: f64,
    /// `χ²` at the estimate.
    pub chi2: f64,
    /// Real residuals minus fitted unknowns not at a bound.
    pub dof: usize,
    /// Unknowns held at a bound at the estimate.
    pub at_bound: Vec<usize>,
    /// Accepted steps.
    pub steps: usize,
    /// Whether the relative decrease of `χ²` fell below the tolerance.
    pub converged: bool,
}

impl MlFit {
    /// The estimate as the linearised uncertainty checks read it.
    pub(crate) fn at_estimate(&self) -> AtEstimate<'_> {
        AtEstimate {
            theta: &self.theta,
            x: &self.x,
            jac: &self.jac,
            at_bound: &self.at_bound,
        }
    }
}

fn chi2(meas: &[Complex64], x: &[Complex64], sigma: &[f64]) -> f64 {
    meas.iter()
        .zip(x)
        .zip(sigma)
        .map(|((m, x), s)| (m - x).norm_sqr() / (s * s))
        .sum()
}

/// Above this many floating-point operations for one dense step (`2·rows·cols²`, the QR of
/// the weighted Jacobian), a step is solved from the normal equations ([`Normal`]) instead:
/// the twenty-mode string's 12,600 × 1,050 Jacobian costs tens of seconds per QR, and a
/// Levenberg–Marquardt step is taken for several damping values per Jacobian. Below it (a
/// few measurements, tens of unknowns) the QR of the rows keeps the full precision.
const NORMAL_EQUATIONS_WORK: f64 = 1e8;

/// The equilibrated normal equations of one Jacobian and residual: `G = D AᵀA D` and
/// `h = D Aᵀ r` over `cols` (`A = J/σ`, real and imaginary rows; `D = diag(1/‖A_j‖)`). Built
/// once per accepted point from each row's non-zero entries only (a measurement's lines
/// depend on few unknowns: the work is `Σ_rows nnz²`, not `rows·cols²`); every damping `λ`
/// and active set then costs one Cholesky factorisation of `G + λI` (`cols³/3`).
struct Normal {
    /// `D`'s diagonal per column of `cols` (0 for a column of zero norm).
    scale: Vec<f64>,
    /// `G`, row-major, `cols.len()` square.
    gram: Vec<f64>,
    /// `h`.
    rhs: Vec<f64>,
    /// `(Aᵀ r)_j` unscaled: the gradient direction that decides the active set.
    grad: Vec<f64>,
}

impl Normal {
    fn new(
        jac: &[Complex64],
        nk: usize,
        resid: &[Complex64],
        sigma: &[f64],
        cols: &[usize],
    ) -> Self {
        let nc = cols.len();
        let mut gram = vec![0.0; nc * nc];
        let mut grad = vec![0.0; nc];
        let mut nz: Vec<(usize, Complex64)> = Vec::with_capacity(nc);
        for (o, (r, s)) in resid.iter().zip(sigma).enumerate() {
            let w = 1.0 / s;
            let row = &jac[o * nk..(o + 1) * nk];
            nz.clear();
            nz.extend(
                cols.iter()
                    .enumerate()
                    .map(|(j, &k)| (j, row[k] * w))
                    .filter(|(_, z)| *z != Complex64::new(0.0, 0.0)),
            );
            let r = r * w;
            for (a, &(i, zi)) in nz.iter().enumerate() {
                grad[i] += zi.re * r.re + zi.im * r.im;
                for &(j, zj) in &nz[a..] {
                    gram[i * nc + j] += zi.re * zj.re + zi.im * zj.im;
                }
            }
        }
        let scale: Vec<f64> = (0..nc)
            .map(|j| match gram[j * nc + j].sqrt() {
                n if n > 0.0 && n.is_finite() => 1.0 / n,
                _ => 0.0,
            })
            .collect();
        for i in 0..nc {
            for j in i..nc {
                let g = gram[i * nc + j] * scale[i] * scale[j];
                gram[i * nc + j] = g;
                gram[j * nc + i] = g;
            }
        }
        let rhs = grad.iter().zip(&scale).map(|(g, s)| g * s).collect();
        Normal {
            scale,
            gram,
            rhs,
            grad,
        }
    }

    /// `y` of `(G + λI) y = h` over the columns `free` (positions in `cols`), and their
    /// scales; `None` when `G + λI` is not numerically positive definite.
    fn solve(&self, free: &[usize], lambda: f64) -> Option<(Vec<f64>, Vec<f64>)> {
        let nc = self.scale.len();
        let nf = free.len();
        let g = faer::Mat::<f64>::from_fn(nf, nf, |a, b| {
            self.gram[free[a] * nc + free[b]] + if a == b { lambda } else { 0.0 }
        });
        let h = faer::Mat::<f64>::from_fn(nf, 1, |a, _| self.rhs[free[a]]);
        let llt = g.llt(faer::Side::Lower).ok()?;
        let y = faer::linalg::solvers::Solve::solve(&llt, &h);
        let y: Vec<f64> = (0..nf).map(|a| y[(a, 0)]).collect();
        y.iter()
            .all(|v| v.is_finite())
            .then(|| (y, free.iter().map(|&j| self.scale[j]).collect()))
    }
}

/// The damped, equilibrated least-squares step `y` of [`step`] over the unknowns `free`
/// from the rows themselves: `min ‖A D y − r‖² + λ‖y‖²` by QR and SVD. Returns `y` and `D`.
fn dense_solve(
    (jac, nk): (&[Complex64], usize),
    resid: &[Complex64],
    sigma: &[f64],
    free: &[usize],
    lambda: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n_obs = resid.len();
    let nf = free.len();
    let rows = 2 * n_obs + nf;
    let mut a = DMatrix::<f64>::zeros(rows, nf);
    let mut b = DVector::<f64>::zeros(rows);
    for o in 0..n_obs {
        let w = 1.0 / sigma[o];
        for (j, &k) in free.iter().enumerate() {
            let z = jac[o * nk + k] * w;
            a[(2 * o, j)] = z.re;
            a[(2 * o + 1, j)] = z.im;
        }
        b[2 * o] = resid[o].re * w;
        b[2 * o + 1] = resid[o].im * w;
    }
    let mut scale = vec![0.0; nf];
    for (j, s) in scale.iter_mut().enumerate() {
        let n = a.column(j).norm();
        *s = if n > 0.0 && n.is_finite() {
            1.0 / n
        } else {
            0.0
        };
        a.column_mut(j).scale_mut(*s);
        a[(2 * n_obs + j, j)] = lambda.sqrt();
    }
    let y = crate::solve::tall_lstsq(a, DMatrix::from_column_slice(rows, 1, b.as_slice()), 1e-14)
        .map_or_else(|| vec![0.0; nf], |y| y.column(0).iter().copied().collect());
    (y, scale)
}

/// One damped, equilibrated, bounded step: returns `δθ` for `cols` (zero for held ones) and
/// the columns held at a bound. With `normal` (the normal equations of this `jac` and
/// `resid` over `cols`) the step is solved from them, else (or when their Cholesky
/// factorisation fails) from the rows ([`dense_solve`]).
#[allow(clippy::too_many_arguments)]
fn step(
    jac: &[Complex64],
    nk: usize,
    resid: &[Complex64],
    sigma: &[f64],
    cols: &[usize],
    theta: &[f64],
    bounds: &[(Option<f64>, Option<f64>)],
    lambda: f64,
    normal: Option<&Normal>,
) -> (Vec<f64>, Vec<usize>) {
    let n_obs = resid.len();
    let mut held: Vec<usize> = Vec::new();
    // Gradient direction of each column: (Aᵀ r)_j.
    let grad = |j: usize, k: usize| -> f64 {
        if let Some(ne) = normal {
            return ne.grad[j];
        }
        (0..n_obs)
            .map(|o| {
                let a = jac[o * nk + k];
                (a.re * resid[o].re + a.im * resid[o].im) / (sigma[o] * sigma[o])
            })
            .sum()
    };
    for (j, &k) in cols.iter().enumerate() {
        let (lo, hi) = bounds[k];
        let g = grad(j, k);
        if lo.is_some_and(|l| theta[k] <= l && g <= 0.0)
            || hi.is_some_and(|h| theta[k] >= h && g >= 0.0)
        {
            held.push(k);
        }
    }
    loop {
        let free_at: Vec<usize> = (0..cols.len())
            .filter(|&j| !held.contains(&cols[j]))
            .collect();
        let free: Vec<usize> = free_at.iter().map(|&j| cols[j]).collect();
        let mut delta = vec![0.0; nk];
        if free.is_empty() {
            return (delta, held);
        }
        let (y, scale) = normal
            .and_then(|ne| ne.solve(&free_at, lambda))
            .unwrap_or_else(|| dense_solve((jac, nk), resid, sigma, &free, lambda));
        // The first bound the step crosses (fraction of the step, unknown, bound value).
        let mut crossed: Option<(f64, usize, f64)> = None;
        for (j, &k) in free.iter().enumerate() {
            let d = y[j] * scale[j];
            delta[k] = d;
            let t = theta[k] + d;
            let (lo, hi) = bounds[k];
            let hit = lo.filter(|&l| t < l).or(hi.filter(|&h| t > h));
            if let Some(bv) = hit {
                let f = ((bv - theta[k]) / d).clamp(0.0, 1.0);
                if crossed.is_none_or(|c| f < c.0) {
                    crossed = Some((f, k, bv));
                }
            }
        }
        match crossed {
            // Already at the bound: hold the unknown there and recompute the rest.
            Some((f, k, _)) if f <= 0.0 => held.push(k),
            // Stop the step at the first bound crossed, exactly on it.
            Some((f, k, bv)) => {
                for d in delta.iter_mut() {
                    *d *= f;
                }
                delta[k] = bv - theta[k];
                return (delta, held);
            }
            None => return (delta, held),
        }
    }
}

/// Refines `theta0` (every unknown of `fwd`, finite) by Levenberg–Marquardt over the unknowns
/// `cols`, given the measured amplitudes `meas` (m, forward order) and their noise `sigma` (m
/// per quadrature, of the data given: for a mean over `n` shots, `σ_shot/√n`). `bounds` per
/// unknown of `fwd`. Errors only when the harmonic balance fails at `theta0` itself (the caller
/// falls back to its starting estimate).
pub fn refine(
    fwd: &mut ForwardModel,
    meas: &[Complex64],
    sigma: &[f64],
    theta0: &[f64],
    cols: &[usize],
    bounds: &[(Option<f64>, Option<f64>)],
    settings: &MlSettings,
) -> Result<MlFit, ForwardError> {
    let nk = fwd.unknowns().len();
    let n_obs = fwd.n_observations();
    let mut theta = theta0.to_vec();
    // Start inside the bounds.
    for &k in cols {
        let (lo, hi) = bounds[k];
        if let Some(l) = lo {
            theta[k] = theta[k].max(l);
        }
        if let Some(h) = hi {
            theta[k] = theta[k].min(h);
        }
    }
    let mut x = vec![Complex64::new(0.0, 0.0); n_obs];
    let mut jac = vec![Complex64::new(0.0, 0.0); n_obs * nk];
    if settings.ramp_at_start {
        fwd.evaluate(&theta, &mut x, Some(&mut jac))?;
    } else {
        fwd.evaluate_trial(&theta, &mut x)?;
        fwd.jacobian(&theta, &mut jac)?;
    }
    let chi2_start = chi2(meas, &x, sigma);
    let mut cost = chi2_start;
    let mut lambda = 1e-3;
    let mut steps = 0;
    let mut converged = false;
    let mut held = Vec::new();
    let mut x_try = x.clone();
    let mut jac_try = jac.clone();
    let large = 2.0 * (2 * n_obs) as f64 * (cols.len() as f64).powi(2) > NORMAL_EQUATIONS_WORK;
    // The normal equations at the current point (when large), built once per point.
    let mut normal: Option<Normal> = None;
    for _ in 0..settings.max_steps {
        let resid: Vec<Complex64> = meas.iter().zip(&x).map(|(m, x)| m - x).collect();
        if large && normal.is_none() {
            normal = Some(Normal::new(&jac, nk, &resid, sigma, cols));
        }
        let (delta, h) = step(
            &jac,
            nk,
            &resid,
            sigma,
            cols,
            &theta,
            bounds,
            lambda,
            normal.as_ref(),
        );
        held = h;
        let trial: Vec<f64> = theta.iter().zip(&delta).map(|(t, d)| t + d).collect();
        let moved = cols
            .iter()
            .any(|&k| delta[k] != 0.0 && theta[k] + delta[k] != theta[k]);
        if !moved {
            converged = true;
            break;
        }
        // The trial's prediction only; its Jacobian (a factorisation per measurement) once it
        // is accepted.
        match fwd.evaluate_trial(&trial, &mut x_try) {
            Ok(()) => {
                let c = chi2(meas, &x_try, sigma);
                // A trial whose Jacobian fails (singular at a fold) counts as rejected.
                if c <= cost && fwd.jacobian(&trial, &mut jac_try).is_ok() {
                    let rel = (cost - c) / cost.max(f64::MIN_POSITIVE);
                    theta = trial;
                    std::mem::swap(&mut x, &mut x_try);
                    std::mem::swap(&mut jac, &mut jac_try);
                    cost = c;
                    normal = None;
                    steps += 1;
                    lambda = (lambda / 3.0).max(1e-12);
                    if rel < settings.rel_tol {
                        converged = true;
                        break;
                    }
                    continue;
                }
            }
            Err(ForwardError::Hb { .. } | ForwardError::BadValue { .. }) => {}
            Err(e) => return Err(e),
        }
        lambda *= 4.0;
        if lambda > 1e12 {
            // No downhill step left: the estimate is a (possibly bounded) minimum.
            converged = true;
            break;
        }
    }
    // Leave the forward model's state at the estimate (a rejected trial moved it).
    fwd.evaluate(&theta, &mut x, None)?;
    let at_bound: Vec<usize> = held
        .into_iter()
        .filter(|&k| {
            let (lo, hi) = bounds[k];
            lo.is_some_and(|l| theta[k] <= l) || hi.is_some_and(|h| theta[k] >= h)
        })
        .collect();
    let dof = (2 * n_obs).saturating_sub(cols.len() - at_bound.len());
    Ok(MlFit {
        theta,
        x,
        jac,
        chi2_start,
        chi2: cost,
        dof,
        at_bound,
        steps,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A sparse Jacobian like an output-error fit's (each observation depends on a few of the
    /// unknowns, columns spanning 20 decades), a residual and per-line noise.
    fn problem(n_obs: usize, nk: usize, seed: u64) -> (Vec<Complex64>, Vec<Complex64>, Vec<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut jac = vec![Complex64::new(0.0, 0.0); n_obs * nk];
        for o in 0..n_obs {
            for _ in 0..4 {
                let k = rng.random_range(0..nk);
                jac[o * nk + k] =
                    Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                        * 10f64.powi(k as i32 % 20 - 10);
            }
        }
        let resid = (0..n_obs)
            .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
            .collect();
        let sigma = (0..n_obs).map(|_| rng.random_range(0.5..2.0)).collect();
        (jac, resid, sigma)
    }

    #[test]
    fn normal_equations_step_equals_the_dense_step() {
        let (n_obs, nk) = (120, 30);
        let (jac, resid, sigma) = problem(n_obs, nk, 3);
        // Every unknown but the last free; one bounded below near its value.
        let cols: Vec<usize> = (0..nk - 1).collect();
        let theta: Vec<f64> = (0..nk).map(|k| 10f64.powi(10 - k as i32 % 20)).collect();
        let mut bounds = vec![(None, None); nk];
        bounds[4] = (Some(theta[4] * 0.999_999), None);
        let ne = Normal::new(&jac, nk, &resid, &sigma, &cols);
        for lambda in [1e-6, 1e-3, 1.0] {
            let (dense, held_d) = step(
                &jac, nk, &resid, &sigma, &cols, &theta, &bounds, lambda, None,
            );
            let (normal, held_n) = step(
                &jac,
                nk,
                &resid,
                &sigma,
                &cols,
                &theta,
                &bounds,
                lambda,
                Some(&ne),
            );
            assert_eq!(held_d, held_n);
            for k in 0..nk {
                let scale = dense[k].abs().max(1e-300);
                assert!(
                    (dense[k] - normal[k]).abs() <= 1e-8 * scale
                        || (dense[k] - normal[k]).abs() < 1e-14 * theta[k].abs(),
                    "λ {lambda}, unknown {k}: dense {} normal {}",
                    dense[k],
                    normal[k]
                );
            }
            assert_eq!(normal[nk - 1], 0.0);
        }
    }
}

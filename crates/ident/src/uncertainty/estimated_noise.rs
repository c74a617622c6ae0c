//! Standard errors of a fit weighted by noise estimated from the same data, per quantity.
//!
//! The output-error fit weighs each line `l` by `ŵ_l = 1/σ̂_l²`, `σ̂_l` the scatter of its
//! complex amplitude over `n` shots: `σ̂²` has `ν = 2(n − 1)` degrees of freedom and, for
//! Gaussian noise, is independent of the mean. Write `ŵ_l = w_l r_l`, `w_l = 1/σ_l²` the true
//! weight and `r_l = ν/χ²_ν` (`E r = ν/(ν − 2)`, relative variance `κ = 2/(ν − 4)`), and
//! `P_l = w_l Re(J_lᴴ J_l)` the line's information (`J_l` its row of the Jacobian, both
//! quadratures), `F = Σ P_l`, `K = F⁻¹` the Cramér–Rao bound. Conditional on the weights the
//! weighted least-squares estimate has the sandwich covariance `Â⁻¹ (Σ ŵ_l² σ_l² …) Â⁻¹`,
//! `Â = Σ r_l P_l` the information at the estimated weights, whose inverse is what the Fisher
//! standard error reports. Expanding both to second order in `r_l/E r − 1` and averaging:
//!
//! ```text
//! E[var θ̂]  = (1 + κ) K − κ S,       E[Â⁻¹] = (ν − 2)/ν · (K + κ S),
//! S = Σ_l K P_l K P_l K
//! ```
//!
//! `S` is where it matters how many lines carry a quantity: in the direction `g` of a
//! quantity, `h = gᵀSg / gᵀKg` lies in `[0, 1]` (the lines' leverages `H_l = K^{½}P_lK^{½}` sum
//! to the identity), `h = 1/N` when `N` equal lines carry it, `h = 1` when one line does. So
//! the Fisher standard error is `√(ν/(ν − 4))` too small for a quantity fixed by many lines
//! (1.134 at 10 shots, 1.021 at 50) and right for one fixed by one line (there `θ̂` is the
//! line itself and `E σ̂² = σ²` exactly). The estimate of `var θ̂` from the data, unbiased to
//! this order and exact at both ends (`h = 0` and `h = 1`), is
//!
//! ```text
//! V = Â⁻¹ [ Σ_l ŵ_l (c_l Re(J_lᴴJ_l) − d_l ŵ_l Re(J_lᴴJ_l) Â⁻¹ Re(J_lᴴJ_l)) ] Â⁻¹,
//! c = ν/(ν − 4),   d = 4/(ν − 4),
//! ```
//!
//! in a quantity's direction `gᵀÂ⁻¹g · (ν − 4ĥ)/(ν − 4)`, `ĥ` its leverage concentration at the
//! estimated weights. (The expansion's own slope, `κ(ν/(ν − 2) + ν/(ν − 4))`, is `4/(ν − 4)` to
//! leading order in `1/ν`; `4/(ν − 4)` also makes `h = 1` exact.) `V ≥ Â⁻¹`: each line's
//! middle `c − d·Ĥ_l` is at least 1, `Ĥ_l`'s eigenvalues lying in `[0, 1]`.
//!
//! `c` and `d` are infinite for `ν ≤ 4` (2 or 3 shots: a weight from a near-zero scatter can
//! dominate); they are taken at `ν = 6` there (`c = 3`, `d = 2`), a lower estimate for
//! quantities carried by many lines (a line's own quantity keeps factor 1). An error floor
//! `s₀` added to every line's noise (`σ_l² = σ̂_l² + s₀²`) makes the weight less random: its
//! relative variance is `2/ν · (σ̂_l²/σ_l²)²`, so the line counts with `ν_eff = ν (σ_l/σ̂_l)⁴`.
//! Noise given with the data (an instrument's `std` of `samples`) is an estimate the same way.

use super::fisher::{bounds_from_covariance, information, invert, Bounds, FisherError, Noise};
use super::AtEstimate;
use crate::forward::ForwardModel;
use crate::shots::Pooled;
use num_complex::Complex64;

/// `(c, d) = (ν/(ν − 4), 4/(ν − 4))` of the module documentation for a weight estimated with
/// `ν` degrees of freedom, taken at `ν = 6` below it; `(1, 0)` for `ν = ∞` (a known noise).
pub fn weight_noise_factors(nu: f64) -> (f64, f64) {
    if nu.is_infinite() {
        return (1.0, 0.0);
    }
    let nu = nu.max(6.0);
    (nu / (nu - 4.0), 4.0 / (nu - 4.0))
}

/// The degrees of freedom of every observation's weight (forward order: a shot's data order,
/// measurement by measurement): `2(n − 1)` for `n` shots pooled, times `(σ_o/σ̂_o)⁴` where an
/// error floor widened `shot_sigma` (the lines' own noise) to `sigma`.
pub(crate) fn weight_dof(pooled: &Pooled, shot_sigma: &[f64], sigma: &[f64]) -> Vec<f64> {
    let mut nu = Vec::with_capacity(sigma.len());
    for (m, &n) in pooled.mean.measurements.iter().zip(&pooled.used) {
        let obs = m.freqs_hz.len() * m.points.len();
        nu.extend(std::iter::repeat_n(2.0 * (n as f64 - 1.0), obs));
    }
    for ((v, s), s0) in nu.iter_mut().zip(sigma).zip(shot_sigma) {
        if *s0 > 0.0 && s > s0 {
            *v *= (s / s0).powi(4);
        }
    }
    nu
}

/// The covariance `V` of the module documentation of the unknowns `free` (indices into a
/// Jacobian row of `n_unknowns`; `jac[o·K + k] = ∂X_o/∂θ_k`), the fit weighted by `1/σ_o²`
/// (`sigma`, per quadrature of the fitted mean) estimated with `nu[o]` degrees of freedom.
/// `Â` is inverted as [`invert`] does (labels `labels`); unknowns it leaves out keep an
/// infinite variance. Returns what [`invert`] returns, with `V` as the covariance.
pub fn estimated_noise_covariance(
    jac: &[Complex64],
    n_unknowns: usize,
    free: &[usize],
    (sigma, nu): (&[f64], &[f64]),
    labels: &[String],
) -> (Vec<f64>, f64, Vec<(usize, String)>) {
    let c = free.len();
    let a = information(
        jac,
        n_unknowns,
        free,
        &Noise::PerObservation(sigma.to_vec()),
        1,
    );
    let (inv, condition, dropped) = invert(&a, labels);
    let kept: Vec<usize> = (0..c).filter(|&i| inv[i * c + i].is_finite()).collect();
    let mut middle = vec![0.0; c * c];
    let mut row: Vec<(usize, f64, f64)> = Vec::with_capacity(c);
    for (o, (&s, &v)) in sigma.iter().zip(nu).enumerate() {
        let jo = &jac[o * n_unknowns..(o + 1) * n_unknowns];
        row.clear();
        row.extend(
            kept.iter()
                .map(|&i| (i, jo[free[i]]))
                .filter(|(_, z)| z.re != 0.0 || z.im != 0.0)
                .map(|(i, z)| (i, z.re, z.im)),
        );
        if row.is_empty() {
            continue;
        }
        let w = 1.0 / (s * s);
        let (cf, df) = weight_noise_factors(v);
        // The line's leverage Ĥ = ŵ [a b]ᵀ Â⁻¹ [a b] (a, b: the row's real and imaginary parts).
        let (mut haa, mut hab, mut hbb) = (0.0, 0.0, 0.0);
        for &(i, ai, bi) in &row {
            for &(j, aj, bj) in &row {
                let g = inv[i * c + j];
                haa += ai * g * aj;
                hab += ai * g * bj;
                hbb += bi * g * bj;
            }
        }
        let (haa, hab, hbb) = (w * haa, w * hab, w * hbb);
        // ŵ (c − d Ĥ) in the basis (a, b).
        let (taa, tab, tbb) = (w * (cf - df * haa), -w * df * hab, w * (cf - df * hbb));
        for &(i, ai, bi) in &row {
            for &(j, aj, bj) in &row {
                middle[i * c + j] += taa * ai * aj + tab * (ai * bj + bi * aj) + tbb * bi * bj;
            }
        }
    }
    let mut cov = vec![0.0; c * c];
    let mut is_kept = vec![false; c];
    kept.iter().for_each(|&i| is_kept[i] = true);
    for i in 0..c {
        if !is_kept[i] {
            cov[i * c + i] = f64::INFINITY;
        }
    }
    // Â⁻¹ M Â⁻¹ on the kept unknowns: two matrix products (k³ each).
    let nk = kept.len();
    let inv_k = faer::Mat::<f64>::from_fn(nk, nk, |a, b| inv[kept[a] * c + kept[b]]);
    let middle_k = faer::Mat::<f64>::from_fn(nk, nk, |a, b| middle[kept[a] * c + kept[b]]);
    let v = &inv_k * &middle_k * &inv_k;
    for (a, &i) in kept.iter().enumerate() {
        for (b, &j) in kept.iter().enumerate() {
            cov[i * c + j] = v[(a, b)];
        }
    }
    (cov, condition, dropped)
}

/// The standard-error bounds of `fwd`'s free unknowns at `θ` (Jacobian `jac` there) for a fit
/// weighted by `1/σ_o²` with `σ_o` (m, per quadrature of the fitted mean) estimated with `nu[o]`
/// degrees of freedom: [`estimated_noise_covariance`] in the reported parametrisation (`f_n`
/// Hz, `Q_n`, parameters; first-order propagation, so `f` and `Q` get their own factor).
/// Errors: bad noise (`sigma` or `nu` not one positive value per observation).
pub fn estimated_noise_bounds(
    fwd: &ForwardModel,
    theta: &[f64],
    jac: &[Complex64],
    sigma: &[f64],
    nu: &[f64],
) -> Result<Bounds, FisherError> {
    let n_obs = fwd.n_observations();
    Noise::PerObservation(sigma.to_vec()).check(n_obs)?;
    if nu.len() != n_obs || nu.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return Err(FisherError::Noise(format!(
            "{} degrees of freedom of the noise for {n_obs} observations, or one of them not positive",
            nu.len()
        )));
    }
    let free = fwd.free();
    let labels: Vec<String> = free.iter().map(|&k| fwd.label(k)).collect();
    let (cov, condition, dropped) =
        estimated_noise_covariance(jac, fwd.unknowns().len(), &free, (sigma, nu), &labels);
    Ok(bounds_from_covariance(
        fwd,
        theta,
        &free,
        cov,
        (condition, dropped),
        1,
    ))
}

/// The bounds the output-error standard errors are: with the noise from the shot scatter
/// (`pooled`), [`estimated_noise_bounds`] at the estimate `at` with each observation's
/// [`weight_dof`] (`shot_sigma` the lines' own noise, `sigma` the noise fitted with, wider
/// where an error floor was added); otherwise the Fisher `bounds` as they are.
pub(crate) fn stderr_bounds(
    fwd: &ForwardModel,
    at: &AtEstimate,
    pooled: &Pooled,
    shot_sigma: &[f64],
    sigma: &[f64],
    bounds: &Bounds,
) -> Result<Bounds, FisherError> {
    if !pooled.noise_from_shots() {
        return Ok(bounds.clone());
    }
    let nu = weight_dof(pooled, shot_sigma, sigma);
    estimated_noise_bounds(fwd, at.theta, at.jac, sigma, &nu)
}

#[cfg(test)]
mod tests;

//! Fisher information and Cramér–Rao bounds of a dataset's unknowns.
//!
//! With independent Gaussian noise of standard deviation `σ_o` on the real and on the
//! imaginary part of every observed complex amplitude `X_o` (per shot; `σ` may differ per line
//! and point), and `N` shots of the same steady state, the Fisher information of the free
//! unknowns `θ` is
//!
//! ```text
//! I_jk = N Σ_o Re[ conj(∂X_o/∂θ_j) ∂X_o/∂θ_k ] / σ_o²,
//! ```
//!
//! with `∂X/∂θ` from the forward model ([`crate::forward`], implicit differentiation of the
//! harmonic balance). The Cramér–Rao bound of an unbiased estimate of `θ_k` is
//! `√((I⁻¹)_kk)`; the full inverse profiles the nuisance unknowns (gains, forces) out.
//!
//! **Numerics.** Unknowns span ~25 decades (`ω²` ~ 1e12, couplings ~ 1e23, gains ~ 1), so `I`
//! is equilibrated first (`D I D` with `D = diag(1/√I_kk)`, unit diagonal), then decomposed
//! by a symmetric eigendecomposition. Its condition number is reported. An unknown with no
//! information, or one dominating an eigenvector whose eigenvalue is below `1e-12` of the
//! largest, is reported as not identifiable (with the unknowns it is collinear with) and left
//! out; the bounds of the others are computed without it.
//!
//! **Reported parametrisation:** `f_n = √(ω_n²)/2π` (Hz), `Q_n = √(ω_n²)/γ_n`, the model's
//! parameters; each with its absolute and relative bound (first-order propagation through the
//! covariance of `ω², γ`).

use crate::forward::{ForwardError, ForwardModel};
use crate::layout::Unknown;
use nalgebra::{DMatrix, SymmetricEigen};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Relative eigenvalue of the equilibrated information below which its direction counts as
/// not identifiable.
pub const SINGULAR_REL: f64 = 1e-12;

/// Errors of the Fisher-information computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FisherError {
    /// The forward model failed (names the measurement or the unknown).
    #[error(transparent)]
    Forward(#[from] ForwardError),
    /// A noise level that is not a positive finite number, or of the wrong length.
    #[error("noise: {0}")]
    Noise(String),
    /// Zero shots.
    #[error("the number of shots must be at least 1")]
    NoShots,
}

/// Per-quadrature noise of the observed amplitudes, m (standard deviation of the real part,
/// and of the imaginary part, of one shot's complex amplitude; independent).
#[derive(Debug, Clone, PartialEq)]
pub enum Noise {
    /// The same `σ` on every observation.
    Uniform(f64),
    /// One `σ` per observation, in [`ForwardModel`]'s order.
    PerObservation(Vec<f64>),
}

impl Noise {
    fn sigma(&self, o: usize) -> f64 {
        match self {
            Noise::Uniform(s) => *s,
            Noise::PerObservation(v) => v[o],
        }
    }

    pub(crate) fn check(&self, n_obs: usize) -> Result<(), FisherError> {
        let bad = |s: f64| !(s.is_finite() && s > 0.0);
        match self {
            Noise::Uniform(s) if bad(*s) => Err(FisherError::Noise(format!(
                "σ = {s:e} m; it must be a positive finite number"
            ))),
            Noise::PerObservation(v) if v.len() != n_obs => Err(FisherError::Noise(format!(
                "{} values of σ for {n_obs} observations",
                v.len()
            ))),
            Noise::PerObservation(v) => match v.iter().position(|&s| bad(s)) {
                Some(o) => Err(FisherError::Noise(format!(
                    "σ of observation {o} is {:e} m; it must be a positive finite number",
                    v[o]
                ))),
                None => Ok(()),
            },
            _ => Ok(()),
        }
    }
}

pub use crate::layout::Quantity;

/// The Cramér–Rao bound of one reported quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct Bound {
    /// Which quantity.
    pub quantity: Quantity,
    /// Readable name: `f_hz:q1`, `Q:q1`, or the parameter's name.
    pub name: String,
    /// Its value at `θ` (Hz for frequencies).
    pub value: f64,
    /// One-sigma bound, same unit (infinite when not identifiable).
    pub std: f64,
    /// `std / |value|` (infinite when the value is 0 or it is not identifiable).
    pub rel: f64,
}

/// An unknown the information cannot determine, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Unidentifiable {
    /// Index into [`ForwardModel::unknowns`].
    pub unknown: usize,
    /// Readable name.
    pub name: String,
    /// Why: no observation is sensitive to it, or which unknowns it is collinear with.
    pub reason: String,
}

/// Cramér–Rao bounds of a dataset's free unknowns at `θ`.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    /// Frequencies, quality factors and parameters that are free unknowns, in unknown order.
    pub quantities: Vec<Bound>,
    /// Free unknowns left out as not identifiable.
    pub unidentifiable: Vec<Unidentifiable>,
    /// Condition number of the equilibrated information (of the unknowns kept).
    pub condition: f64,
    /// Free unknowns (indices into [`ForwardModel::unknowns`]) of `covariance`.
    pub free: Vec<usize>,
    /// Covariance bound `I⁻¹` of `free` (row-major; rows and columns of unidentifiable
    /// unknowns are infinite on the diagonal, zero elsewhere), units of `θ`.
    pub covariance: Vec<f64>,
    /// Shots the bound is for.
    pub shots: usize,
}

impl Bounds {
    /// The bound of the quantity called `name` (`f_hz:q1`, `Q:q2`, `beta1`).
    pub fn get(&self, name: &str) -> Option<&Bound> {
        self.quantities.iter().find(|b| b.name == name)
    }

    /// The largest relative bound and its quantity.
    pub fn worst(&self) -> Option<&Bound> {
        self.quantities
            .iter()
            .max_by(|a, b| a.rel.total_cmp(&b.rel))
    }
}

/// Fisher information of the unknowns `cols` from a Jacobian `jac[o·K + k] = ∂X_o/∂θ_k`
/// (`K` unknowns): `I[i·C + j]` for `cols[i]`, `cols[j]`, per the module's formula.
pub fn information(
    jac: &[Complex64],
    n_unknowns: usize,
    cols: &[usize],
    noise: &Noise,
    shots: usize,
) -> Vec<f64> {
    let c = cols.len();
    let n_obs = jac.len() / n_unknowns.max(1);
    let mut info = vec![0.0; c * c];
    for o in 0..n_obs {
        let w = shots as f64 / noise.sigma(o).powi(2);
        let row = &jac[o * n_unknowns..(o + 1) * n_unknowns];
        for i in 0..c {
            let a = row[cols[i]];
            if a == Complex64::new(0.0, 0.0) {
                continue;
            }
            for j in i..c {
                let b = row[cols[j]];
                info[i * c + j] += w * (a.re * b.re + a.im * b.im);
            }
        }
    }
    for i in 0..c {
        for j in 0..i {
            info[i * c + j] = info[j * c + i];
        }
    }
    info
}

/// Inverts a Fisher information `info` (row-major, `labels.len()` square) as the module
/// describes: equilibrated, eigendecomposed, singular directions dropped one unknown at a
/// time. Returns the covariance (infinite variance for dropped unknowns), the condition
/// number of what was kept, and the dropped unknowns (local index, reason).
pub fn invert(info: &[f64], labels: &[String]) -> (Vec<f64>, f64, Vec<(usize, String)>) {
    let c = labels.len();
    let mut keep: Vec<usize> = (0..c).collect();
    let mut dropped = Vec::new();
    for i in 0..c {
        let d = info[i * c + i];
        if !(d.is_finite() && d > 0.0) {
            dropped.push((
                i,
                "no observation is sensitive to it (zero information)".to_string(),
            ));
        }
    }
    keep.retain(|i| !dropped.iter().any(|(j, _)| j == i));
    loop {
        let k = keep.len();
        if k == 0 {
            let mut cov = vec![0.0; c * c];
            for i in 0..c {
                cov[i * c + i] = f64::INFINITY;
            }
            return (cov, f64::INFINITY, dropped);
        }
        let scale: Vec<f64> = keep.iter().map(|&i| 1.0 / info[i * c + i].sqrt()).collect();
        let (values, vectors) =
            symmetric_eigen(k, |a, b| info[keep[a] * c + keep[b]] * scale[a] * scale[b]);
        let (mut imin, mut imax) = (0, 0);
        for i in 0..k {
            if values[i] < values[imin] {
                imin = i;
            }
            if values[i] > values[imax] {
                imax = i;
            }
        }
        let (lmin, lmax) = (values[imin], values[imax]);
        if lmin <= SINGULAR_REL * lmax {
            let v = vectors.col(imin);
            let j = (0..k)
                .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
                .unwrap_or(0);
            let partners: Vec<&str> = (0..k)
                .filter(|&i| i != j && v[i].abs() > 0.1 * v[j].abs())
                .map(|i| labels[keep[i]].as_str())
                .collect();
            let reason = if partners.is_empty() {
                format!("its information is {lmin:.1e} of the largest (relative), below {SINGULAR_REL:.0e}")
            } else {
                format!(
                    "its effect on the observations is collinear with that of {} (relative eigenvalue {:.1e})",
                    partners.join(", "),
                    lmin / lmax
                )
            };
            dropped.push((keep[j], reason));
            keep.remove(j);
            continue;
        }
        let mut cov = vec![0.0; c * c];
        let mut kept = vec![false; c];
        keep.iter().for_each(|&i| kept[i] = true);
        for i in 0..c {
            if !kept[i] {
                cov[i * c + i] = f64::INFINITY;
            }
        }
        // V Λ⁻¹ Vᵀ as W Wᵀ with W = V Λ^{-1/2}: one matrix product (k³), not k³ strided sums.
        let w = faer::Mat::<f64>::from_fn(k, k, |a, e| vectors[(a, e)] / values[e].sqrt());
        let inv = &w * w.transpose();
        for a in 0..k {
            for b in 0..k {
                cov[keep[a] * c + keep[b]] = inv[(a, b)] * scale[a] * scale[b];
            }
        }
        return (cov, lmax / lmin, dropped);
    }
}

/// The eigenvalues and eigenvectors (columns) of the symmetric `k × k` matrix `at(a, b)`:
/// by faer's self-adjoint decomposition (the twenty-mode string's thousand unknowns in a
/// fraction of a second), by nalgebra's when that does not converge.
fn symmetric_eigen(k: usize, at: impl Fn(usize, usize) -> f64) -> (Vec<f64>, faer::Mat<f64>) {
    let s = faer::Mat::<f64>::from_fn(k, k, &at);
    if let Ok(eig) = s.self_adjoint_eigen(faer::Side::Lower) {
        let values: Vec<f64> = (0..k).map(|i| eig.S()[i]).collect();
        if values.iter().all(|v| v.is_finite()) {
            return (values, eig.U().to_owned());
        }
    }
    let eig = SymmetricEigen::new(DMatrix::from_fn(k, k, at));
    let vectors = faer::Mat::<f64>::from_fn(k, k, |a, b| eig.eigenvectors[(a, b)]);
    (eig.eigenvalues.iter().copied().collect(), vectors)
}

/// Cramér–Rao bounds of `fwd`'s free unknowns at `θ` (layout of
/// [`ForwardModel::unknowns`]) for `shots` shots with per-quadrature noise `noise` (m), in the
/// reported parametrisation (`f_n` Hz, `Q_n`, parameters); see the module documentation.
/// Errors: a failed harmonic balance (names the measurement), a bad `θ`, bad noise, no shots.
pub fn crlb(
    fwd: &mut ForwardModel,
    theta: &[f64],
    noise: &Noise,
    shots: usize,
) -> Result<Bounds, FisherError> {
    if shots == 0 {
        return Err(FisherError::NoShots);
    }
    let n_obs = fwd.n_observations();
    noise.check(n_obs)?;
    let nk = fwd.unknowns().len();
    let mut jac = vec![Complex64::new(0.0, 0.0); n_obs * nk];
    fwd.jacobian(theta, &mut jac)?;
    crlb_from_jacobian(fwd, theta, &jac, noise, shots)
}

/// As [`crlb`] with the Jacobian at `θ` already computed (`jac`, layout of
/// [`ForwardModel::evaluate`]; e.g. the one a fit ended with).
pub fn crlb_from_jacobian(
    fwd: &ForwardModel,
    theta: &[f64],
    jac: &[Complex64],
    noise: &Noise,
    shots: usize,
) -> Result<Bounds, FisherError> {
    if shots == 0 {
        return Err(FisherError::NoShots);
    }
    noise.check(fwd.n_observations())?;
    let nk = fwd.unknowns().len();
    let free = fwd.free();
    let info = information(jac, nk, &free, noise, shots);
    Ok(bounds_from_information(fwd, theta, &free, &info, shots))
}

/// Bounds from a Fisher information `info` of the unknowns `free` (indices into
/// [`ForwardModel::unknowns`], row-major `free.len()` square) at `θ`: inverted as `invert` does
/// does, then in the reported parametrisation (`fwd` gives the labels and the `γ` of modes
/// with fixed `Q`). Information added up over several forward models of the same model (a
/// planner's measurements) works the same, as long as `free` indexes the shared unknowns.
pub fn bounds_from_information(
    fwd: &ForwardModel,
    theta: &[f64],
    free: &[usize],
    info: &[f64],
    shots: usize,
) -> Bounds {
    let labels: Vec<String> = free.iter().map(|&k| fwd.label(k)).collect();
    let (cov, condition, dropped) = invert(info, &labels);
    bounds_from_covariance(fwd, theta, free, cov, (condition, dropped), shots)
}

/// Bounds from a covariance `cov` of the unknowns `free` (row-major, units of `θ`; infinite
/// on the diagonal of the unknowns `dropped` left out, with why) at `θ`, in the reported
/// parametrisation (`f_n` Hz, `Q_n`, parameters; first-order propagation), `condition` the
/// information's condition number as [`invert`] gives it.
pub(crate) fn bounds_from_covariance(
    fwd: &ForwardModel,
    theta: &[f64],
    free: &[usize],
    cov: Vec<f64>,
    (condition, dropped): (f64, Vec<(usize, String)>),
    shots: usize,
) -> Bounds {
    let labels: Vec<String> = free.iter().map(|&k| fwd.label(k)).collect();
    let c = free.len();
    let local = |u: &Unknown| free.iter().position(|&k| fwd.unknowns()[k] == *u);
    let var = |i: Option<usize>, j: Option<usize>| match (i, j) {
        (Some(i), Some(j)) => cov[i * c + j],
        _ => 0.0,
    };
    let mut quantities = Vec::new();
    for (n, name) in fwd.mode_names().iter().enumerate() {
        let (iw, ig) = (local(&Unknown::OmegaSq(n)), local(&Unknown::Gamma(n)));
        let w2 = theta[2 * n];
        let w = w2.sqrt();
        let g = fwd.gamma(theta, n);
        let (f, q) = (w / TAU, w / g);
        if iw.is_some() {
            let sf = var(iw, iw).sqrt() * f / (2.0 * w2);
            quantities.push(bound(Quantity::Frequency(n), format!("f_hz:{name}"), f, sf));
        }
        if ig.is_some() {
            // Q = √ω²/γ: ∂Q/∂ω² = Q/(2ω²), ∂Q/∂γ = −Q/γ.
            let (a, b) = (q / (2.0 * w2), -q / g);
            let vq = a * a * var(iw, iw) + b * b * var(ig, ig) + 2.0 * a * b * var(iw, ig);
            quantities.push(bound(
                Quantity::Q(n),
                format!("Q:{name}"),
                q,
                vq.max(0.0).sqrt(),
            ));
        }
    }
    for (i, &k) in free.iter().enumerate() {
        // Parameters and background terms are reported as they are fitted.
        if let Some(q @ (Quantity::Param(_) | Quantity::Background { .. })) =
            Quantity::of(&fwd.unknowns()[k])
        {
            quantities.push(bound(q, fwd.label(k), theta[k], cov[i * c + i].sqrt()));
        }
    }
    let unidentifiable = dropped
        .into_iter()
        .map(|(i, reason)| Unidentifiable {
            unknown: free[i],
            name: labels[i].clone(),
            reason,
        })
        .collect();
    Bounds {
        quantities,
        unidentifiable,
        condition,
        free: free.to_vec(),
        covariance: cov,
        shots,
    }
}

fn bound(quantity: Quantity, name: String, value: f64, std: f64) -> Bound {
    let std = if std.is_nan() { f64::INFINITY } else { std };
    Bound {
        quantity,
        name,
        value,
        std,
        rel: if value != 0.0 {
            std / value.abs()
        } else {
            f64::INFINITY
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("u{i}")).collect()
    }

    #[test]
    fn inverse_of_a_badly_scaled_matrix() {
        // I = diag(s) A diag(s) with A = [[2, 1], [1, 3]] and scales 25 decades apart.
        let s = [1e-12, 1e13];
        let a = [2.0, 1.0, 1.0, 3.0];
        let info: Vec<f64> = (0..4).map(|k| a[k] * s[k / 2] * s[k % 2]).collect();
        let (cov, cond, dropped) = invert(&info, &labels(2));
        assert!(dropped.is_empty());
        // A⁻¹ = [[3, −1], [−1, 2]] / 5.
        let want = [0.6, -0.2, -0.2, 0.4];
        for k in 0..4 {
            let w = want[k] / (s[k / 2] * s[k % 2]);
            assert!(
                (cov[k] - w).abs() < 1e-12 * w.abs(),
                "{k}: {} vs {w}",
                cov[k]
            );
        }
        // Condition of the equilibrated matrix [[1, 1/√6], [1/√6, 1]].
        let r = 1.0 / 6f64.sqrt();
        assert!((cond - (1.0 + r) / (1.0 - r)).abs() < 1e-12);
    }

    #[test]
    fn collinear_and_blind_unknowns_are_named() {
        // u1 = 2 u0 in every observation; u2 unseen; u3 independent.
        let jac = [
            Complex64::new(1.0, 0.0),
            Complex64::new(2.0, 0.0),
            Complex64::new(0.0, 0.0),
            Complex64::new(0.0, 1.0),
            Complex64::new(0.5, 0.3),
            Complex64::new(1.0, 0.6),
            Complex64::new(0.0, 0.0),
            Complex64::new(1.0, 0.0),
        ];
        let info = information(&jac, 4, &[0, 1, 2, 3], &Noise::Uniform(0.1), 3);
        // N/σ² Σ Re(conj a b): u3 with itself = 300 · (1 + 1).
        assert!((info[15] - 600.0).abs() < 1e-9);
        let (cov, _, dropped) = invert(&info, &labels(4));
        assert_eq!(dropped.len(), 2, "{dropped:?}");
        assert!(dropped[0].0 == 2 && dropped[0].1.contains("zero information"));
        assert!(dropped[1].0 <= 1 && dropped[1].1.contains("collinear with that of u"));
        assert!(cov[2 * 4 + 2].is_infinite());
        // Kept: u3 and one of u0, u1. With u0: I/300 = [[1.34, 0.5], [0.5, 2]].
        let want = if dropped[1].0 == 1 {
            1.34 / (1.34 * 2.0 - 0.25) / 300.0
        } else {
            // u1 = 2 u0: I/300 = [[5.36, 1], [1, 2]].
            5.36 / (5.36 * 2.0 - 1.0) / 300.0
        };
        assert!(
            (cov[15] - want).abs() < 1e-9 * want,
            "{} vs {want}",
            cov[15]
        );
    }
}

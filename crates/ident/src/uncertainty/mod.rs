//! The uncertainty of the output-error estimate: Cramér–Rao bounds from the Fisher
//! information ([`fisher`]), the noise expectation of a correct model's χ², a linearised
//! jackknife, a drift check over the shots, the comparison of quantities between
//! measurements ([`consistency`]) and the verdict on whether the model fits at all
//! ([`GoodnessOfFit`]).

pub mod consistency;
mod drift;
pub mod estimated_noise;
pub mod fisher;
mod goodness;
mod jackknife;

pub(crate) use drift::drift_warnings;
pub use drift::{check as drift_check, Drift};
pub(crate) use estimated_noise::stderr_bounds;
pub use fisher::{
    bounds_from_information, crlb, crlb_from_jacobian, information, Bound, Bounds, FisherError,
    Noise, Unidentifiable,
};
pub(crate) use goodness::{chi2_tail, goodness_of_fit, p_text};
pub use goodness::{GoodnessOfFit, LineResidual, MeasurementFit, P_DOES_NOT_FIT};
pub(crate) use jackknife::jackknife;

use crate::shots::Pooled;
use harmonid_data::Dataset;
use num_complex::Complex64;

/// The output-error fit at its estimate, as the linearised checks ([`jackknife`] and
/// [`drift_warnings`]) read it: they step from the estimate, they do not refit.
pub(crate) struct AtEstimate<'a> {
    /// Every unknown of the forward model (fixed ones included).
    pub theta: &'a [f64],
    /// Predictions, m, in the layout of [`crate::ForwardModel::evaluate`].
    pub x: &'a [Complex64],
    /// Jacobian, `jac[o·K + k]`.
    pub jac: &'a [Complex64],
    /// Unknowns held at a bound (left out of every step).
    pub at_bound: &'a [usize],
}

/// The factor the standard errors are widened by when the fit `g` is worse than the noise:
/// `√max(1, (χ²/dof − s)/E₀)`, `E₀` a correct model's expected `χ²/dof` and `s` its spread
/// (standard deviation), both from `g`. `None` unless the noise came from the shot scatter
/// (`from_shots`; otherwise nothing can be judged). A correct model's `χ²/dof` exceeds `E₀` in
/// half the fits; widening by `√(χ²/(dof·E₀))` whenever it did (as before) made correct
/// standard errors a few per cent too large on average where the spread is large (few
/// lines). Only the excess beyond one spread counts now (about one correct fit in six is
/// widened, and little: 1.003–1.005 on average over the stepped sweeps of
/// `tests/it/background.rs` and `nonsmooth_identify.rs`, against 1.013–1.020 before); a misfit
/// of `χ²/dof = R·E₀` widens by `√(R − s/E₀)`, within a few per cent of `√R` once it matters.
pub(crate) fn misfit_inflation(g: &GoodnessOfFit, from_shots: bool) -> Option<f64> {
    from_shots.then(|| {
        misfit_factor(
            g.chi2_per_dof,
            g.expected_chi2_per_dof,
            g.spread_chi2_per_dof,
        )
    })
}

/// `√max(1, (χ²/dof − s)/E₀)` of [`misfit_inflation`].
fn misfit_factor(chi2_per_dof: f64, expected: f64, spread: f64) -> f64 {
    ((chi2_per_dof - spread) / expected).max(1.0).sqrt()
}

/// `E[σ²/σ̂²] = ν/(ν − 2)` of one real residual whose noise `σ̂` is estimated with `ν` degrees
/// of freedom: a correct model's `χ²` per real degree of freedom. [`expected_reduced_chi2`]
/// averages it, and the goodness-of-fit law takes it as its mean. `ν = 2(n − 1)` is even: 3
/// shots give `ν = 4` and 2; 2 shots give `ν = 2`, whose expectation is infinite (`σ̂²` near
/// zero is too likely), and there the value at `ν = 4`, 2, is used: a lower bound, so a fit
/// to two shots may be judged worse than it is, never better. (This returned 1 for `ν ≤ 4`,
/// half the expectation at three shots.)
pub(crate) fn expected_per_real_dof(nu: f64) -> f64 {
    let nu = nu.max(4.0);
    nu / (nu - 2.0)
}

/// `E₀`, the expected `χ²/dof` of a correct model when every line's noise is its sample
/// standard deviation over the kept shots (as [`crate::shots::pool`] estimates it): `σ̂²` has
/// `ν = 2(n − 1)` degrees of freedom (real and imaginary parts of `n` shots) and is
/// independent of the mean, so `E[σ²/σ̂²] = ν/(ν − 2)`, averaged over the observations (2
/// for two shots, see [`expected_per_real_dof`]). The fit is worse than the noise
/// when `χ²/dof` exceeds this, not 1: 20 shots give 1.056, and comparing with 1 inflated the
/// standard errors of a correct model by 5 % on average (two-mode nanostring, 1600
/// realisations: ±1 stderr held the truth in 70.6 %, not 68.3 %).
pub(crate) fn expected_reduced_chi2(ds: &Dataset, pooled: &Pooled) -> f64 {
    let (mut sum, mut count) = (0.0, 0.0);
    for (m, &n) in ds.measurements.iter().zip(&pooled.used) {
        let obs = (m.freqs_hz.len() * m.points.len()) as f64;
        sum += obs * expected_per_real_dof(2.0 * (n as f64 - 1.0));
        count += obs;
    }
    if count > 0.0 {
        sum / count
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_data::{Manifest, Measurement, MeasurementSpec};

    fn measurement(name: &str, lines: usize, shots: usize) -> Measurement {
        let spec = MeasurementSpec::new(name, vec![1000.0]);
        let freqs = (0..lines).map(|k| 1000.0 + 10.0 * k as f64).collect();
        Measurement::zeros(spec, freqs, vec![], shots)
    }

    #[test]
    fn expected_reduced_chi2_with_noise_from_the_shots() {
        // 20 shots: ν = 38, E[σ²/σ̂²] = 38/36 on two lines; 3 shots (ν = 4): 2 on one line.
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
        let want = (2.0 * 38.0 / 36.0 + 2.0) / 3.0;
        assert!((expected_reduced_chi2(&ds, &pooled) - want).abs() < 1e-15);
        // Shots rejected: the kept ones count (18 of 20: ν = 34).
        let pooled = Pooled {
            used: vec![18, 3],
            ..pooled
        };
        let want = (2.0 * 34.0 / 32.0 + 2.0) / 3.0;
        assert!((expected_reduced_chi2(&ds, &pooled) - want).abs() < 1e-15);
        // Two shots (ν = 2, an infinite expectation): the value at ν = 4.
        assert_eq!(expected_per_real_dof(2.0), 2.0);
        assert_eq!(expected_per_real_dof(4.0), 2.0);
    }

    #[test]
    fn the_inflation_counts_only_the_excess_beyond_the_spread() {
        // χ²/dof within one spread of its expectation: no widening.
        assert_eq!(misfit_factor(1.2, 1.125, 0.1), 1.0);
        assert_eq!(misfit_factor(0.5, 1.125, 0.1), 1.0);
        // Beyond: √((χ²/dof − s)/E₀).
        let x = misfit_factor(4.6, 1.125, 0.1);
        assert!((x - 2.0).abs() < 1e-15, "{x}");
    }
}

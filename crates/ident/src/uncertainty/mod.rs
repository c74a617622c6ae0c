//! The uncertainty of the output-error estimate: Cramér–Rao bounds from the Fisher
//! information ([`fisher`]), the noise expectation of a correct model's χ², a linearised
//! jackknife, a drift check over the shots, the comparison of quantities between
//! measurements ([`consistency`]) and the verdict on whether the model fits at all
//! ([`GoodnessOfFit`]).

pub mod consistency;
mod drift;
pub mod fisher;
mod goodness;
mod jackknife;

pub(crate) use drift::drift_warnings;
pub use drift::{check as drift_check, Drift};
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

/// `E[σ²/σ̂²] = ν/(ν − 2)` of one real residual whose noise `σ̂` is estimated with `ν` degrees
/// of freedom (1 where `ν ≤ 4`, whose expectation is unbounded or large): a correct model's
/// `χ²` per real degree of freedom. [`expected_reduced_chi2`] averages it, and the
/// goodness-of-fit law takes it as its mean.
pub(crate) fn expected_per_real_dof(nu: f64) -> f64 {
    if nu > 4.0 {
        nu / (nu - 2.0)
    } else {
        1.0
    }
}

/// `E₀`, the expected `χ²/dof` of a correct model when every line's noise is its sample
/// standard deviation over the kept shots (as [`crate::shots::pool`] estimates it): `σ̂²` has
/// `ν = 2(n − 1)` degrees of freedom (real and imaginary parts of `n` shots) and is
/// independent of the mean, so `E[σ²/σ̂²] = ν/(ν − 2)`, averaged over the observations (1
/// where `ν ≤ 4`, whose expectation is unbounded or large). The fit is worse than the noise
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

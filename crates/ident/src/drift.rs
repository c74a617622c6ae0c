//! Drift check: pooling assumes every shot observes the same steady state. A quantity
//! estimated per shot with everything else fixed (one Gauss–Newton step from the pooled
//! estimate) should scatter as the noise predicts and show no trend over the shots.
//!
//! With per-shot deviations `δ_s` (shot order) of known noise variance `v` each:
//! - **trend**: the least-squares slope over the shot index, `t = slope / se(slope)`,
//!   `se² = v / Σ(s − s̄)²`; flagged when `|t| > 5`;
//! - **excess scatter**: `χ² = Σ(δ_s − δ̄)²/v` over `n − 1` degrees of freedom; flagged when
//!   `χ²/(n−1) > 1 + 5·√(2/(n−1))` (five standard deviations of the ratio).
//!
//! Needs at least 5 shots.

/// What the check found for one quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct Drift {
    /// Slope per shot, units of `δ`.
    pub slope: f64,
    /// Its t statistic.
    pub t: f64,
    /// `χ²/(n−1)` of the scatter about the mean (1 when the scatter is the noise's).
    pub scatter_ratio: f64,
    /// Whether the trend is significant (`|t| > 5`).
    pub trend: bool,
    /// Whether the scatter exceeds the noise's (see the module documentation).
    pub excess: bool,
}

/// Checks per-shot deviations `delta` (shot order) of noise variance `var` each; `None` with
/// fewer than 5 shots or a variance that is not positive.
pub fn check(delta: &[f64], var: f64) -> Option<Drift> {
    let n = delta.len();
    if n < 5 || !(var > 0.0 && var.is_finite()) {
        return None;
    }
    let nf = n as f64;
    let mean = delta.iter().sum::<f64>() / nf;
    let smean = (nf - 1.0) / 2.0;
    let sxx: f64 = (0..n).map(|s| (s as f64 - smean).powi(2)).sum();
    let sxy: f64 = delta
        .iter()
        .enumerate()
        .map(|(s, d)| (s as f64 - smean) * (d - mean))
        .sum();
    let slope = sxy / sxx;
    let t = slope / (var / sxx).sqrt();
    let chi2: f64 = delta.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / var;
    let scatter_ratio = chi2 / (nf - 1.0);
    Some(Drift {
        slope,
        t,
        scatter_ratio,
        trend: t.abs() > 5.0,
        excess: scatter_ratio > 1.0 + 5.0 * (2.0 / (nf - 1.0)).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::check;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, 2.0).expect("normal");
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    #[test]
    fn stationary_noise_is_not_flagged() {
        for seed in 0..50 {
            let d = check(&noise(30, seed), 4.0).expect("30 shots");
            assert!(!d.trend && !d.excess, "seed {seed}: {d:?}");
        }
    }

    #[test]
    fn a_trend_and_excess_scatter_are_flagged() {
        let mut v = noise(30, 1);
        for (s, x) in v.iter_mut().enumerate() {
            *x += 0.5 * s as f64;
        }
        let d = check(&v, 4.0).expect("30 shots");
        assert!(d.trend, "{d:?}");
        assert!((d.slope - 0.5).abs() < 0.15, "{d:?}");
        let d = check(&noise(30, 2), 0.25).expect("30 shots");
        assert!(d.excess && !d.trend, "{d:?}");
        assert!((d.scatter_ratio - 16.0).abs() < 8.0, "{d:?}");
        assert!(check(&noise(4, 1), 4.0).is_none());
    }
}

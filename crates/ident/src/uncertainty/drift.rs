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

use super::AtEstimate;
use crate::forward::ForwardModel;
use crate::layout::Unknown;
use crate::shots::Pooled;
use harmonid_data::Dataset;
use std::f64::consts::TAU;

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

/// Drift check of every identified resonance frequency: per shot, `ω_n²` with everything else
/// fixed at the estimate (one Gauss–Newton step on that shot's residual, per-line weights of
/// one shot), tested for a trend and excess scatter ([`check`]). Shot `g` is the `g`-th
/// kept shot of every measurement.
pub(crate) fn drift_warnings(
    fwd: &ForwardModel,
    fit: &AtEstimate<'_>,
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
        if let Some(d) = check(&delta, 1.0 / info) {
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

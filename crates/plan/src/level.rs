//! The strongest drive a candidate takes: a first guess from the Duffing fold of the guessed
//! values, bracketed by factors of two and bisected on the simulated steady state.

use crate::PlanError;
use harmonid_sim::NumericModel;

/// Bisections after the bracket: the level is found within a factor `2^(1/8)` ≈ 1.09.
const BISECTIONS: usize = 3;
/// Most factor-two steps while bracketing.
const MAX_STEPS: usize = 24;

/// Force per tone (N/kg) near which a tone pair on mode `n`, `spacing` linewidths apart and
/// centred on its resonance, drives it into a fold; `None` when the mode has no cubic
/// self-term `b q_n³` (then nothing predicts a fold and the search starts from its weakest
/// useful level).
///
/// A single tone folds first at the cusp of the Duffing response `A²[(σ − κA²)² + h²] =
/// F²/4ω₀²` (`κ = 3|b|/8ω₀`, half-width `h = ω₀/2Q`): at detuning `σ = √3 h`, force
/// `F_c = 2ω₀ √(8h³/(3√3 κ))`; a tone at detuning `σ ≫ h` folds at `F ≈ 2ω₀ √(4σ³/27κ)`,
/// which is `F_c √(0.096 (σ/h)³)`. The upper tone of the pair sits at `σ/h = spacing`; the
/// other tone adds to the response, so the estimate is doubled. It is only a starting point:
/// [`strongest`] brackets the real fold on the simulation, a good guess saves it steps.
pub(crate) fn pair_fold_estimate(num: &NumericModel, n: usize, spacing: f64) -> Option<f64> {
    let b = num
        .eq_terms(n)
        .iter()
        .filter(|t| t.factors == [(n, 3)])
        .map(|t| t.coef)
        .sum::<f64>()
        .abs();
    let w0 = num.omega(n);
    let h = 0.5 * w0 / num.q_factor[n];
    let kappa = 3.0 * b / (8.0 * w0);
    if !(kappa > 0.0 && h > 0.0 && kappa.is_finite()) {
        return None;
    }
    let f_c = 2.0 * w0 * (8.0 * h.powi(3) / (3.0 * 3f64.sqrt() * kappa)).sqrt();
    Some(2.0 * f_c * (0.096 * spacing.powi(3)).sqrt().max(1.0))
}

/// The largest force in `[lo, hi]` (N/kg) at which `ok` holds, starting at `start`: doubled
/// while `ok`, halved while not, until bracketed, then bisected. Returns the force and
/// whether a failing force was met above it (`false`: `hi` itself is fine); `None` when even
/// `lo` fails. Assumes `ok` holds below some level and fails above it (a fold).
pub(crate) fn strongest(
    start: f64,
    lo: f64,
    hi: f64,
    mut ok: impl FnMut(f64) -> Result<bool, PlanError>,
) -> Result<Option<(f64, bool)>, PlanError> {
    let start = start.clamp(lo, hi);
    let (mut good, mut bad);
    if ok(start)? {
        good = start;
        bad = f64::INFINITY;
        for _ in 0..MAX_STEPS {
            let next = (2.0 * good).min(hi);
            if next <= good {
                break;
            }
            if ok(next)? {
                good = next;
            } else {
                bad = next;
                break;
            }
        }
    } else {
        bad = start;
        good = f64::NAN;
        for _ in 0..MAX_STEPS {
            let next = (0.5 * bad).max(lo);
            if ok(next)? {
                good = next;
                break;
            }
            bad = next;
            if next <= lo {
                return Ok(None);
            }
        }
        if good.is_nan() {
            return Ok(None);
        }
    }
    if bad.is_finite() {
        for _ in 0..BISECTIONS {
            let mid = (good * bad).sqrt();
            if ok(mid)? {
                good = mid;
            } else {
                bad = mid;
            }
        }
    }
    Ok(Some((good, bad.is_finite())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_search_finds_a_threshold_from_above_and_below() {
        for start in [0.01, 3.0, 500.0] {
            let mut calls = 0;
            let (f, folds) = strongest(start, 1e-3, 1e6, |x| {
                calls += 1;
                Ok(x < 7.0)
            })
            .expect("no error")
            .expect("found");
            assert!(folds);
            assert!(f < 7.0 && f > 7.0 / 2f64.powf(1.0 / 8.0) - 1e-12, "{f}");
            assert!(calls <= 16, "{calls}");
        }
        // Nothing fails below `hi`; nothing works above `lo`.
        let r = strongest(1.0, 0.1, 10.0, |_| Ok(true)).expect("ok");
        assert_eq!(r, Some((10.0, false)));
        let r = strongest(1.0, 0.1, 10.0, |_| Ok(false)).expect("ok");
        assert_eq!(r, None);
    }

    /// The single-tone cusp: at detuning `√3 h` the amplitude equation `F²(u)`, `u = A²`, has
    /// an inflection with zero slope at `u_c = 2σ/3κ`, and `F(u_c)` is the estimate's `F_c`.
    #[test]
    fn the_fold_estimate_is_the_duffing_cusp() {
        let num = NumericModel::new(
            vec!["q1".into()],
            vec![1e5],
            vec![1e4],
            vec![harmonid_sim::Term {
                eq: 0,
                coef: 1e20,
                factors: vec![(0, 3)],
            }],
        )
        .expect("Duffing");
        // spacing ≤ √(1/0.096)^(2/3): the estimate is 2 F_c.
        let est = pair_fold_estimate(&num, 0, 1.0).expect("cubic");
        let w0 = num.omega(0);
        let h = 0.5 * w0 / 1e4;
        let kappa = 3.0 * 1e20 / (8.0 * w0);
        let sigma = 3f64.sqrt() * h;
        // On the cusp, F²(u) = 4ω₀² u[(σ − κu)² + h²] has an inflection with zero slope.
        let f2 = |u: f64| 4.0 * w0 * w0 * u * ((sigma - kappa * u).powi(2) + h * h);
        let uc = 2.0 * sigma / (3.0 * kappa);
        let du = 1e-4 * uc;
        let slope = (f2(uc + du) - f2(uc - du)) / (2.0 * du);
        let scale = f2(uc) / uc;
        assert!(slope.abs() < 1e-6 * scale, "slope {slope:e} vs {scale:e}");
        assert!((f2(uc).sqrt() / (0.5 * est) - 1.0).abs() < 1e-9);
        // Far above the cusp: ∝ spacing^1.5.
        let e8 = pair_fold_estimate(&num, 0, 8.0).expect("cubic");
        let e16 = pair_fold_estimate(&num, 0, 16.0).expect("cubic");
        assert!((e16 / e8 - 2f64.powf(1.5)).abs() < 1e-9);
    }
}

//! Robust statistics of per-shot estimates: the median and the spread inside the
//! interquartile fences, as the method's paper reports its histograms.

/// Robust statistics of per-shot estimates.
#[derive(Debug, Clone, PartialEq)]
pub struct ShotStats {
    /// Median of the finite estimates.
    pub median: f64,
    /// Sample standard deviation of the estimates inside the IQR fences.
    pub std: f64,
    /// Shots outside the fences `[Q1 − 1.5 IQR, Q3 + 1.5 IQR]` (or not finite).
    pub outliers: Vec<usize>,
    /// Number of estimates used for `std`.
    pub n_used: usize,
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let j = (i + 1).min(sorted.len() - 1);
    let t = pos - i as f64;
    sorted[i] * (1.0 - t) + sorted[j] * t
}

/// Median, the standard deviation after rejecting outliers by the interquartile rule (the
/// method's paper discards estimates outside the IQR fences and fits a normal distribution to
/// the rest), and the outlier shots. With fewer than 4 estimates nothing is rejected.
pub fn shot_stats(values: &[f64]) -> ShotStats {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    finite.sort_by(f64::total_cmp);
    let median = quantile(&finite, 0.5);
    let (lo, hi) = if finite.len() >= 4 {
        let (q1, q3) = (quantile(&finite, 0.25), quantile(&finite, 0.75));
        let iqr = q3 - q1;
        (q1 - 1.5 * iqr, q3 + 1.5 * iqr)
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    };
    let mut outliers = Vec::new();
    let mut used = Vec::new();
    for (s, &v) in values.iter().enumerate() {
        if v.is_finite() && v >= lo && v <= hi {
            used.push(v);
        } else {
            outliers.push(s);
        }
    }
    let n = used.len();
    let std = if n >= 2 {
        let mean = used.iter().sum::<f64>() / n as f64;
        (used.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        f64::NAN
    };
    ShotStats {
        median,
        std,
        outliers,
        n_used: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iqr_rule_flags_outliers() {
        let mut v: Vec<f64> = (0..20).map(|i| 10.0 + 0.1 * f64::from(i % 5)).collect();
        v[7] = 100.0;
        v[13] = f64::NAN;
        let s = shot_stats(&v);
        assert_eq!(s.outliers, vec![7, 13]);
        assert_eq!(s.n_used, 18);
        assert!((s.median - 10.2).abs() < 1e-12);
        assert!(s.std < 0.2 && s.std > 0.1, "{}", s.std);
    }

    #[test]
    fn gaussian_std_is_recovered() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let d = Normal::new(5.0, 2.0).expect("normal");
        let v: Vec<f64> = (0..4000).map(|_| d.sample(&mut rng)).collect();
        let s = shot_stats(&v);
        // The IQR fences cut ~0.7 % of a normal sample: std shrinks by ~1-2 %.
        assert!((s.std / 2.0 - 1.0).abs() < 0.05, "{}", s.std);
        assert!((s.median - 5.0).abs() < 0.1);
    }
}

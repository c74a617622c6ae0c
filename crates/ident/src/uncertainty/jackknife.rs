//! The linearised delete-one-shot jackknife of the output-error estimate.

use super::AtEstimate;
use crate::forward::ForwardModel;
use crate::layout::{Quantity, Unknown};
use crate::shots::Pooled;
use harmonid_data::Dataset;
use nalgebra::DMatrix;
use std::f64::consts::TAU;

/// Linearised delete-one-shot jackknife: leaving shot `i` (of every measurement) out moves
/// the pooled mean by `δX = (X̄ − X_i)/(n − 1)` and the estimate by one Gauss–Newton step
/// `δθ = (AᵀA)⁻¹Aᵀ δX/σ`; the jackknife variance is `(n−1)/n Σ (δθ_i − mean)²`, propagated to
/// f and Q to first order. It checks the noise model (per-line σ, correlations between lines
/// that the diagonal weighting ignores) without refitting.
pub(crate) fn jackknife(
    fwd: &ForwardModel,
    fit: &AtEstimate<'_>,
    sigma: &[f64],
    ds: &Dataset,
    pooled: &Pooled,
    cols: &[usize],
) -> Vec<(Quantity, f64)> {
    let nk = fwd.unknowns().len();
    let n_obs = sigma.len();
    let free: Vec<usize> = cols
        .iter()
        .copied()
        .filter(|k| !fit.at_bound.contains(k))
        .collect();
    let nf = free.len();
    let kept = pooled.kept(ds);
    let groups = kept.iter().map(Vec::len).max().unwrap_or(0);
    if nf == 0 || groups < 3 {
        return Vec::new();
    }
    let mut a = DMatrix::<f64>::zeros(2 * n_obs, nf);
    for o in 0..n_obs {
        for (j, &k) in free.iter().enumerate() {
            let z = fit.jac[o * nk + k] / sigma[o];
            a[(2 * o, j)] = z.re;
            a[(2 * o + 1, j)] = z.im;
        }
    }
    let mut scale = vec![0.0; nf];
    for (j, s) in scale.iter_mut().enumerate() {
        let n = a.column(j).norm();
        *s = if n > 0.0 { 1.0 / n } else { 0.0 };
        a.column_mut(j).scale_mut(*s);
    }
    let mut b = DMatrix::<f64>::zeros(2 * n_obs, groups);
    let mut offset = 0;
    for (mi, m) in ds.measurements.iter().enumerate() {
        let per = m.freqs_hz.len() * m.points.len();
        let mean = &pooled.mean.measurements[mi].data;
        let n = kept[mi].len();
        for (g, &s) in kept[mi].iter().enumerate() {
            if n < 2 {
                break;
            }
            for o in 0..per {
                let d = (mean[o] - m.data[s * per + o]) / ((n - 1) as f64 * sigma[offset + o]);
                b[(2 * (offset + o), g)] = d.re;
                b[(2 * (offset + o) + 1, g)] = d.im;
            }
        }
        offset += per;
    }
    let Some(y) = crate::solve::tall_lstsq(a, b, 1e-14) else {
        return Vec::new();
    };
    // δθ per group for every unknown (zero for those not fitted).
    let delta = |g: usize, k: usize| -> f64 {
        free.iter()
            .position(|&x| x == k)
            .map_or(0.0, |j| y[(j, g)] * scale[j])
    };
    let col = |u: &Unknown| fwd.unknowns().iter().position(|x| x == u);
    let th = &fit.theta;
    let mut out = Vec::new();
    let mut push = |q: Quantity, samples: Vec<f64>| {
        let n = samples.len() as f64;
        let mean = samples.iter().sum::<f64>() / n;
        let var = (n - 1.0) / n * samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        out.push((q, var.sqrt()));
    };
    for n in 0..fwd.mode_names().len() {
        let (Some(iw), Some(ig)) = (col(&Unknown::OmegaSq(n)), col(&Unknown::Gamma(n))) else {
            continue;
        };
        let (w2, g) = (th[iw], fwd.gamma(th, n));
        let (f, q) = (w2.sqrt() / TAU, w2.sqrt() / g);
        if free.contains(&iw) {
            push(
                Quantity::Frequency(n),
                (0..groups).map(|s| f * delta(s, iw) / (2.0 * w2)).collect(),
            );
        }
        if free.contains(&ig) {
            push(
                Quantity::Q(n),
                (0..groups)
                    .map(|s| q * (delta(s, iw) / (2.0 * w2) - delta(s, ig) / g))
                    .collect(),
            );
        }
    }
    for (k, u) in fwd.unknowns().iter().enumerate() {
        if let Some(q @ (Quantity::Param(_) | Quantity::Background { .. })) = Quantity::of(u) {
            if free.contains(&k) {
                push(q, (0..groups).map(|s| delta(s, k)).collect());
            }
        }
    }
    out
}

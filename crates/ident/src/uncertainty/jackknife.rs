//! The linearised delete-one-shot jackknife of the output-error estimate.

use super::fisher::SINGULAR_REL;
use super::AtEstimate;
use crate::forward::ForwardModel;
use crate::layout::{Quantity, Unknown};
use crate::shots::Pooled;
use harmonid_data::Dataset;
use num_complex::Complex64;
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
    // Aᵀ A and Aᵀ B from each row's non-zero entries (A = J/σ, B: each group's δX/σ): a
    // measurement's lines depend on few unknowns, so this is Σ_rows nnz², not the QR of a
    // 2N × K matrix (the twenty-mode string: 25,200 × 1,050, seconds).
    let mut gram = vec![0.0; nf * nf];
    let mut atb = vec![0.0; nf * groups];
    let mut row: Vec<(usize, Complex64)> = Vec::with_capacity(nf);
    let mut delta_x = vec![Complex64::new(0.0, 0.0); groups];
    let mut offset = 0;
    for (mi, m) in ds.measurements.iter().enumerate() {
        let per = m.freqs_hz.len() * m.points.len();
        let mean = &pooled.mean.measurements[mi].data;
        let n = kept[mi].len();
        for o in offset..offset + per {
            let w = 1.0 / sigma[o];
            row.clear();
            row.extend(
                free.iter()
                    .enumerate()
                    .map(|(j, &k)| (j, fit.jac[o * nk + k] * w))
                    .filter(|(_, z)| z.re != 0.0 || z.im != 0.0),
            );
            for (a, &(i, zi)) in row.iter().enumerate() {
                for &(j, zj) in &row[a..] {
                    gram[i * nf + j] += zi.re * zj.re + zi.im * zj.im;
                }
            }
            delta_x.fill(Complex64::new(0.0, 0.0));
            if n >= 2 {
                for (g, &s) in kept[mi].iter().enumerate() {
                    delta_x[g] = (mean[o - offset] - m.data[s * per + o - offset])
                        / ((n - 1) as f64 * sigma[o]);
                }
            }
            for &(i, zi) in &row {
                for (g, d) in delta_x.iter().enumerate() {
                    atb[i * groups + g] += zi.re * d.re + zi.im * d.im;
                }
            }
        }
        offset += per;
    }
    let Some((y, scale)) = normal_solve(&gram, &atb, nf, groups) else {
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

/// `y = (D AᵀA D)⁺ D AᵀB` and `D` (`D = diag(1/‖A_j‖)`, the columns equilibrated as the
/// output-error step does) from the upper triangle of `AᵀA` (`gram`, row-major `nf` square)
/// and `AᵀB` (row-major `nf × groups`): by the symmetric
/// eigendecomposition, directions whose eigenvalue is below [`SINGULAR_REL`] of the largest
/// left out (the Fisher bounds call such unknowns not identifiable). `None` when nothing is
/// left or the decomposition fails.
fn normal_solve(
    gram: &[f64],
    atb: &[f64],
    nf: usize,
    groups: usize,
) -> Option<(faer::Mat<f64>, Vec<f64>)> {
    let scale: Vec<f64> = (0..nf)
        .map(|j| match gram[j * nf + j].sqrt() {
            n if n > 0.0 && n.is_finite() => 1.0 / n,
            _ => 0.0,
        })
        .collect();
    let g = faer::Mat::<f64>::from_fn(nf, nf, |a, b| {
        let (i, j) = (a.min(b), a.max(b));
        gram[i * nf + j] * scale[i] * scale[j]
    });
    let eig = g.self_adjoint_eigen(faer::Side::Lower).ok()?;
    let values: Vec<f64> = (0..nf).map(|i| eig.S()[i]).collect();
    let lmax = values.iter().copied().fold(0.0, f64::max);
    if !(lmax > 0.0 && lmax.is_finite()) {
        return None;
    }
    let u = eig.U();
    // U Λ⁺ Uᵀ D AᵀB.
    let b = faer::Mat::<f64>::from_fn(nf, groups, |j, g| atb[j * groups + g] * scale[j]);
    let mut c = u.transpose() * &b;
    for (e, &l) in values.iter().enumerate() {
        let inv = if l > SINGULAR_REL * lmax {
            1.0 / l
        } else {
            0.0
        };
        for g in 0..groups {
            c[(e, g)] *= inv;
        }
    }
    Some((u * &c, scale))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};

    /// The normal-equations solve equals the QR-and-SVD least squares of the rows
    /// ([`crate::solve::tall_lstsq`], what the jackknife used before) on a sparse problem
    /// whose columns span 16 decades, and leaves an unseen column at zero.
    #[test]
    fn normal_solve_equals_the_least_squares_of_the_rows() {
        let (rows, nf, groups) = (400, 24, 5);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut a = DMatrix::<f64>::zeros(rows, nf);
        for r in 0..rows {
            for _ in 0..4 {
                // Column nf − 1 is never seen.
                let j = rng.random_range(0..nf - 1);
                a[(r, j)] = rng.random_range(-1.0..1.0) * 10f64.powi(j as i32 % 17 - 8);
            }
        }
        let b = DMatrix::<f64>::from_fn(rows, groups, |_, _| rng.random_range(-1.0..1.0));
        let gram: Vec<f64> = (0..nf * nf)
            .map(|x| a.column(x / nf).dot(&a.column(x % nf)))
            .collect();
        let atb: Vec<f64> = (0..nf * groups)
            .map(|x| a.column(x / groups).dot(&b.column(x % groups)))
            .collect();
        let (y, scale) = normal_solve(&gram, &atb, nf, groups).expect("solve");
        // The rows' least squares, columns equilibrated the same way.
        let mut ae = a.clone();
        for (j, &s) in scale.iter().enumerate() {
            ae.column_mut(j).scale_mut(s);
        }
        let want = crate::solve::tall_lstsq(ae, b, 1e-14).expect("lstsq");
        for g in 0..groups {
            for j in 0..nf {
                let (got, w) = (y[(j, g)] * scale[j], want[(j, g)] * scale[j]);
                assert!(
                    (got - w).abs() <= 1e-10 * w.abs().max(1e-300),
                    "column {j}, group {g}: {got:e} vs {w:e}"
                );
            }
        }
        assert_eq!(scale[nf - 1], 0.0);
    }
}

//! Linear least squares with column equilibration, condition numbers, covariance and optional
//! bounds (clarabel QP when the unconstrained optimum violates a bound).
//!
//! Problem: minimise `‖A x − b‖²` (rows already weighted), optionally with `l_j ≤ x_j ≤ u_j`.
//! Columns of `A` span many decades (ω² ~ 10¹², couplings ~ 10²³, forces ~ 1), so every column
//! is scaled to unit 2-norm first: `A_s = A S`, `x = S y`. The condition number reported is that
//! of `A_s` (the one that limits the attainable accuracy); the solution comes from the SVD of
//! `A_s`, which also gives the covariance `σ² S (A_sᵀ A_s)⁻¹ S` with `σ² = RSS / (m − k)`.

use nalgebra::{DMatrix, DVector};

/// How a least-squares solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitStatus {
    /// Unconstrained optimum (no bound active).
    Solved,
    /// A bound was active: solved as a QP with clarabel.
    SolvedWithBounds,
    /// The bounded QP did not converge; the unconstrained solution is returned.
    BoundsFailed,
}

/// Solution of one least-squares problem.
#[derive(Debug, Clone)]
pub struct LsSolution {
    /// Estimates, in the units of the columns of `A`.
    pub x: Vec<f64>,
    /// Unscaled covariance `S (A_sᵀ A_s)⁻¹ S` (multiply by `sigma2` for the covariance of `x`),
    /// row-major `k × k`.
    pub cov_unit: Vec<f64>,
    /// Residual sum of squares `‖A x − b‖²`.
    pub rss: f64,
    /// Residual variance estimate `rss / (m − k)` (NaN when `m ≤ k`).
    pub sigma2: f64,
    /// 2-norm condition number of the column-equilibrated matrix.
    pub cond: f64,
    /// Singular values of the equilibrated matrix, descending.
    pub singular_values: Vec<f64>,
    /// Right singular vector of the smallest singular value (in scaled coordinates).
    pub weakest_direction: Vec<f64>,
    /// Columns whose norm is zero (they cannot be determined).
    pub zero_columns: Vec<usize>,
    /// How the solve ended.
    pub status: FitStatus,
}

/// Solves `min ‖A x − b‖²` subject to optional bounds `lower[j] ≤ x_j ≤ upper[j]`.
///
/// `a` is `m × k` with `m ≥ 1`; zero columns get `x_j = 0` and are listed in
/// [`LsSolution::zero_columns`]. Singular values below `1e-14 σ_max` are treated as zero in the
/// pseudo-inverse.
pub fn solve_ls(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    lower: &[Option<f64>],
    upper: &[Option<f64>],
) -> LsSolution {
    let (m, k) = a.shape();
    let mut scale = vec![0.0; k];
    let mut zero_columns = Vec::new();
    for (j, s) in scale.iter_mut().enumerate() {
        let n = a.column(j).norm();
        if n > 0.0 && n.is_finite() {
            *s = 1.0 / n;
        } else {
            zero_columns.push(j);
        }
    }
    // Equilibrated matrix of the nonzero columns only.
    let cols: Vec<usize> = (0..k).filter(|&j| scale[j] > 0.0).collect();
    let nz = cols.len();
    let a_s = DMatrix::from_fn(m, nz, |i, c| a[(i, cols[c])] * scale[cols[c]]);
    let mut y = DVector::<f64>::zeros(k);
    let mut cov = DMatrix::<f64>::zeros(k, k);
    let mut sorted = Vec::new();
    let mut weakest_direction = vec![0.0; k];
    let mut cond = f64::INFINITY;
    if nz > 0 {
        let svd = a_s.clone().svd(true, true);
        let (u, v_t) = match (svd.u, svd.v_t) {
            (Some(u), Some(v)) => (u, v),
            _ => return failed(k, zero_columns),
        };
        let sv = svd.singular_values;
        let smax = sv.iter().copied().fold(0.0, f64::max);
        let mut order: Vec<usize> = (0..sv.len()).collect();
        order.sort_by(|&i, &j| sv[j].total_cmp(&sv[i]));
        sorted = order.iter().map(|&i| sv[i]).collect();
        // With fewer rows than columns the missing singular values are zero.
        sorted.resize(nz, 0.0);
        let smin = sorted[nz - 1];
        cond = if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        };
        if sv.len() == nz {
            let weakest = order[nz - 1];
            for (c, &j) in cols.iter().enumerate() {
                weakest_direction[j] = v_t[(weakest, c)];
            }
        }
        let tol = 1e-14 * smax;
        let utb = u.transpose() * b;
        for i in 0..sv.len() {
            if sv[i] > tol {
                let coef = utb[i] / sv[i];
                for (c, &j) in cols.iter().enumerate() {
                    y[j] += v_t[(i, c)] * coef;
                    for (c2, &j2) in cols.iter().enumerate() {
                        cov[(j, j2)] += v_t[(i, c)] * v_t[(i, c2)] / (sv[i] * sv[i]);
                    }
                }
            }
        }
    }
    let mut status = FitStatus::Solved;
    let mut x: Vec<f64> = (0..k).map(|j| y[j] * scale[j]).collect();
    let violated = |j: usize| {
        lower.get(j).copied().flatten().is_some_and(|l| x[j] < l)
            || upper.get(j).copied().flatten().is_some_and(|u| x[j] > u)
    };
    if zero_columns.iter().any(|&j| violated(j)) {
        // A zero column's unknown is 0 whatever the data; a bound excluding 0 cannot be met
        // (and a problem with no free column is no QP).
        status = FitStatus::BoundsFailed;
    } else if cols.iter().any(|&j| violated(j)) {
        let sub = |v: &[Option<f64>]| -> Vec<Option<f64>> {
            cols.iter().map(|&j| v.get(j).copied().flatten()).collect()
        };
        let sc: Vec<f64> = cols.iter().map(|&j| scale[j]).collect();
        match bounded_qp(&a_s, b, &sc, &sub(lower), &sub(upper)) {
            Some(ys) => {
                x = vec![0.0; k];
                for (c, &j) in cols.iter().enumerate() {
                    x[j] = ys[c] * scale[j];
                }
                status = FitStatus::SolvedWithBounds;
            }
            None => status = FitStatus::BoundsFailed,
        }
    }
    let xv = DVector::from_column_slice(&x);
    let r = a * &xv - b;
    let rss = r.norm_squared();
    let sigma2 = if m > nz {
        rss / (m - nz) as f64
    } else {
        f64::NAN
    };
    let mut cov_unit = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..k {
            cov_unit[i * k + j] = cov[(i, j)] * scale[i] * scale[j];
        }
    }
    LsSolution {
        x,
        cov_unit,
        rss,
        sigma2,
        cond,
        singular_values: sorted,
        weakest_direction,
        zero_columns,
        status,
    }
}

fn failed(k: usize, zero_columns: Vec<usize>) -> LsSolution {
    LsSolution {
        x: vec![f64::NAN; k],
        cov_unit: vec![f64::NAN; k * k],
        rss: f64::NAN,
        sigma2: f64::NAN,
        cond: f64::INFINITY,
        singular_values: Vec::new(),
        weakest_direction: vec![0.0; k],
        zero_columns,
        status: FitStatus::BoundsFailed,
    }
}

/// `min ½‖A_s y − b‖²` with bounds on `x = S y`, as a clarabel QP in the scaled variables.
#[allow(non_snake_case)]
fn bounded_qp(
    a_s: &DMatrix<f64>,
    b: &DVector<f64>,
    scale: &[f64],
    lower: &[Option<f64>],
    upper: &[Option<f64>],
) -> Option<Vec<f64>> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
    };
    let k = a_s.ncols();
    let bn = b.norm().max(f64::MIN_POSITIVE);
    let p = a_s.transpose() * a_s;
    let q = -(a_s.transpose() * b) / bn;
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut rhs = Vec::new();
    for j in 0..k {
        if scale[j] == 0.0 {
            continue;
        }
        if let Some(l) = lower.get(j).copied().flatten() {
            let mut r = vec![0.0; k];
            r[j] = -1.0;
            rows.push(r);
            rhs.push(-l / scale[j] / bn);
        }
        if let Some(u) = upper.get(j).copied().flatten() {
            let mut r = vec![0.0; k];
            r[j] = 1.0;
            rows.push(r);
            rhs.push(u / scale[j] / bn);
        }
    }
    let p_rows: Vec<Vec<f64>> = (0..k)
        .map(|i| (0..k).map(|j| p[(i, j)]).collect())
        .collect();
    let P = CscMatrix::from(&p_rows).to_triu();
    let A = CscMatrix::from(&rows);
    let cones = [NonnegativeConeT(rows.len())];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .ok()?;
    let mut solver = DefaultSolver::new(&P, q.as_slice(), &A, &rhs, &cones, settings).ok()?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            Some(solver.solution.x.iter().map(|y| y * bn).collect())
        }
        _ => None,
    }
}

/// `argmin ‖A Y − B‖` for a tall `A` (`m ≥ n` rows), column by column, with the SVD's
/// treatment of small singular values (those at or below `eps` are dropped, as
/// `nalgebra::SVD::solve` does), but the SVD taken of `R` of `A = QR` (`n × n`) with `QᵀB`
/// applied by the Householder reflections, never forming `U`: for the `2N × k` systems of an
/// output-error step (thousands of rows, a hundred unknowns) several times cheaper than the
/// SVD of `A` with its `U`. The singular values and the solution are those of `A`'s SVD up
/// to rounding. `None` when the SVD fails. A wide `A` falls back to the SVD of `A`.
pub(crate) fn tall_lstsq(a: DMatrix<f64>, b: DMatrix<f64>, eps: f64) -> Option<DMatrix<f64>> {
    let (m, n) = a.shape();
    if m < n {
        return a.svd(true, true).solve(&b, eps).ok();
    }
    let qr = a.qr();
    let mut c = b;
    qr.q_tr_mul(&mut c);
    let r = qr.r();
    let top = c.rows(0, n).into_owned();
    r.svd(true, true).solve(&top, eps).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_problem(m: usize, k: usize, seed: u64) -> (DMatrix<f64>, DVector<f64>, Vec<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        // Columns spanning 20 decades.
        let a = DMatrix::from_fn(m, k, |_, j| {
            rng.random_range(-1.0..1.0) * 10f64.powi(2 * j as i32 - 10)
        });
        let x: Vec<f64> = (0..k)
            .map(|j| rng.random_range(0.5..2.0) * 10f64.powi(10 - 2 * j as i32))
            .collect();
        let b = &a * DVector::from_column_slice(&x);
        (a, b, x)
    }

    #[test]
    fn recovers_exact_solution_across_decades() {
        for (m, k, seed) in [(10, 3, 1), (40, 8, 2), (80, 11, 3)] {
            let (a, b, x) = random_problem(m, k, seed);
            let s = solve_ls(&a, &b, &vec![None; k], &vec![None; k]);
            for (j, (&got, &want)) in s.x.iter().zip(&x).enumerate() {
                assert!(((got - want) / want).abs() < 1e-10, "{j}: {got} vs {want}");
            }
            assert!(s.cond < 1e3, "equilibrated condition {}", s.cond);
            assert_eq!(s.status, FitStatus::Solved);
        }
    }

    #[test]
    fn matches_faer_qr_on_noisy_data() {
        use faer::prelude::*;
        let (a, mut b, _) = random_problem(30, 5, 7);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let bn = b.norm();
        for v in b.iter_mut() {
            *v += 1e-3 * bn * rng.random_range(-1.0..1.0);
        }
        let s = solve_ls(&a, &b, &[None; 5], &[None; 5]);
        // faer: QR least squares on the equilibrated matrix.
        let scale: Vec<f64> = (0..5).map(|j| 1.0 / a.column(j).norm()).collect();
        let af = faer::Mat::<f64>::from_fn(30, 5, |i, j| a[(i, j)] * scale[j]);
        let bf = faer::Mat::<f64>::from_fn(30, 1, |i, _| b[i]);
        let y = af.qr().solve_lstsq(&bf);
        for j in 0..5 {
            let xf = y[(j, 0)] * scale[j];
            assert!(((s.x[j] - xf) / xf).abs() < 1e-9, "{j}: {} vs {xf}", s.x[j]);
        }
        // Covariance: for y = A x + e with unit-variance e, cov = (AᵀA)⁻¹.
        let ata = a.transpose() * &a;
        let inv = ata.try_inverse().expect("invertible");
        for i in 0..5 {
            let r = s.cov_unit[i * 5 + i] / inv[(i, i)];
            assert!((r - 1.0).abs() < 1e-6, "cov ratio {r}");
        }
    }

    #[test]
    fn bounds_are_enforced_with_clarabel() {
        // Fit y = x0 + x1 t to data from x1 = -1; with x1 >= 0 the optimum is x1 = 0, x0 = mean.
        let t: Vec<f64> = (0..10).map(f64::from).collect();
        let a = DMatrix::from_fn(10, 2, |i, j| if j == 0 { 1.0 } else { t[i] * 1e6 });
        let b = DVector::from_fn(10, |i, _| 3.0 - t[i]);
        let s = solve_ls(&a, &b, &[None, Some(0.0)], &[None, None]);
        assert_eq!(s.status, FitStatus::SolvedWithBounds);
        let mean = b.mean();
        assert!((s.x[0] - mean).abs() < 1e-6, "{}", s.x[0]);
        assert!(s.x[1].abs() < 1e-12, "{}", s.x[1]);
    }

    #[test]
    fn zero_and_collinear_columns_are_reported() {
        let a = DMatrix::from_row_slice(4, 3, &[1., 0., 2., 2., 0., 4., 3., 0., 6., 1., 0., 2.0]);
        let b = DVector::from_row_slice(&[1., 2., 3., 1.]);
        let s = solve_ls(&a, &b, &[None; 3], &[None; 3]);
        assert_eq!(s.zero_columns, vec![1]);
        assert!(s.cond > 1e12, "cond {}", s.cond);
        let w = &s.weakest_direction;
        assert!(w[0].abs() > 0.5 && w[2].abs() > 0.5, "{w:?}");
    }

    #[test]
    fn a_bound_on_a_zero_column_fails_without_a_panic() {
        // Found by tests/it/finite_inputs.rs: an all-zero matrix with a bound excluding 0 sent an
        // empty problem to clarabel, which panicked.
        let a = DMatrix::from_row_slice(1, 1, &[0.0]);
        let b = DVector::from_row_slice(&[0.0]);
        let s = solve_ls(&a, &b, &[Some(1.0)], &[None]);
        assert_eq!(s.status, FitStatus::BoundsFailed);
        assert_eq!(s.zero_columns, vec![0]);
        // A bound on another, nonzero column still goes through the QP.
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, 1.0]);
        let b = DVector::from_row_slice(&[2.0, 2.0]);
        let s = solve_ls(&a, &b, &[None, None], &[None, Some(1.0)]);
        assert_eq!(s.status, FitStatus::SolvedWithBounds);
        assert!((s.x[1] - 1.0).abs() < 1e-6, "{:?}", s.x);
    }
}

#[cfg(test)]
mod tall_tests {
    use super::*;

    #[test]
    fn tall_lstsq_matches_the_svd_of_a_including_rank_deficiency() {
        // A 40 × 5 matrix with a repeated column (rank 4) and two right-hand sides.
        let a = DMatrix::from_fn(40, 5, |i, j| {
            let x = i as f64 / 7.0;
            match j {
                4 => (x).sin(),
                _ => (x * (j + 1) as f64).sin() + 0.1 * j as f64,
            }
        });
        let mut a = a;
        let c0 = a.column(0).into_owned();
        a.set_column(3, &c0);
        let b = DMatrix::from_fn(40, 2, |i, j| (i as f64 * 0.3 + j as f64).cos());
        let want = a.clone().svd(true, true).solve(&b, 1e-12).expect("svd");
        let got = tall_lstsq(a, b, 1e-12).expect("qr");
        assert!(
            (&got - &want).norm() <= 1e-10 * want.norm(),
            "{got} vs {want}"
        );
    }
}

//! Weighting: the covariance of the equation errors that noise on the measured amplitudes causes.

use super::{FitGroup, MeasRows, Problem, Unknown};
use harmonid_data::Dataset;
use harmonid_spectral::{monomial_jacobian, velocity_to_amplitude, ProductScratch};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::PI;

impl Problem {
    /// Relative noise variance of every modal amplitude, `var[mi][r]`: equal noise on every
    /// measured amplitude, propagated through the modal conversion (`Σ_p w_p²`).
    pub(super) fn relative_variances(&self) -> Vec<Vec<f64>> {
        self.meas
            .iter()
            .map(|m| {
                m.weights
                    .iter()
                    .map(|w| w.iter().map(|x| x * x).sum())
                    .collect()
            })
            .collect()
    }

    /// Noise variance per quadrature of every modal amplitude, `var[mi][r]` (m²), from the
    /// scatter across `nshots` shots, and `true`; the relative variances and `false` when some
    /// amplitude does not scatter (noise-free data).
    pub(super) fn amplitude_variances(&self, ds: &Dataset, nshots: usize) -> (Vec<Vec<f64>>, bool) {
        let mut data_var = self.relative_variances();
        let mut all_positive = true;
        for (mi, dv) in data_var.iter_mut().enumerate() {
            let spectra: Vec<Vec<Vec<Complex64>>> =
                (0..nshots).map(|s| self.modal_spectra(ds, mi, s)).collect();
            for (r, v) in dv.iter_mut().enumerate() {
                let n = self.meas[mi].mode_of[r];
                let mean: Complex64 =
                    spectra.iter().map(|x| x[n][r]).sum::<Complex64>() / nshots as f64;
                let var = spectra
                    .iter()
                    .map(|x| (x[n][r] - mean).norm_sqr())
                    .sum::<f64>()
                    / (2.0 * (nshots as f64 - 1.0));
                *v = var;
                all_positive &= var > 0.0;
            }
        }
        if all_positive {
            (data_var, true)
        } else {
            (self.relative_variances(), false)
        }
    }

    /// Covariance of the group's real equation errors caused by noise on the measured modal
    /// amplitudes, linearised at the current estimate, one block per measurement of the group
    /// in its order (measurements are independent acquisitions: `Σ` is block-diagonal, and
    /// only the blocks are formed, so the cost is linear in the number of measurements):
    /// `Σ = J D Jᵀ`, where `J` is the derivative
    /// of every equation (real, imaginary rows) with respect to the real and imaginary parts of
    /// every modal amplitude (through the linear term and, via the products ĝ, the nonlinear
    /// terms), and `D` the amplitudes' noise variances. Row order as in `assemble`.
    ///
    /// Whitening with `Σ` makes the least squares a generalised (Gauss-Markov) fit that accounts
    /// for noise in the regressors to first order, and gives covariances that match the scatter.
    pub(super) fn equation_cov(
        &self,
        ds: &Dataset,
        g: &FitGroup,
        shot: usize,
        values: &[f64],
        data_var: &[Vec<f64>],
        scratch: &mut [ProductScratch],
    ) -> Vec<DMatrix<f64>> {
        let mut blocks = Vec::with_capacity(g.measurements.len());
        let val = |u: &Unknown| -> f64 {
            self.index_of(u)
                .map_or(0.0, |i| self.known_value(values, i))
        };
        for &mi in &g.measurements {
            let prep = &self.meas[mi];
            let m = &ds.measurements[mi];
            let nf = prep.mode_of.len();
            let modal = self.variable_spectra(ds, mi, shot);
            let modal_ref: Vec<&[Complex64]> = modal.iter().map(|v| v.as_slice()).collect();
            let nm = self.mode_names.len();
            // J[o][2s + quad], complex.
            let mut jac = vec![Complex64::new(0.0, 0.0); nf * 2 * nf];
            for r in 0..nf {
                let n = prep.mode_of[r];
                let om = 2.0 * PI * m.freqs_hz[r];
                let lin = Complex64::new(
                    val(&Unknown::OmegaSq(n)) - om * om,
                    om * val(&Unknown::Gamma(n)),
                );
                jac[r * 2 * nf + 2 * r] += lin;
                jac[r * 2 * nf + 2 * r + 1] += lin * Complex64::i();
            }
            let n_in = prep.input_hz.len();
            let mut jr = vec![Complex64::new(0.0, 0.0); nf * n_in];
            let mut ji = vec![Complex64::new(0.0, 0.0); nf * n_in];
            for &n in &prep.active {
                for t in &self.eqs[n] {
                    let b = t.konst
                        + t.params
                            .iter()
                            .map(|&(p, f)| f * val(&Unknown::Param(p)))
                            .sum::<f64>();
                    if b == 0.0 || !b.is_finite() {
                        continue;
                    }
                    if let Some(ns) = &self.ns[t.monomial] {
                        let mut modes = self.nonsmooth_modes(ns);
                        modes.sort_unstable();
                        modes.dedup();
                        for mode in modes {
                            for s in (0..nf).filter(|&s| prep.mode_of[s] == mode) {
                                let at = (mode, prep.input_of[s], m.freqs_hz[s]);
                                let (dre, dim) = self.nonsmooth_column_jacobian(mi, ns, &modal, at);
                                for o in (0..nf).filter(|&o| prep.mode_of[o] == n) {
                                    jac[o * 2 * nf + 2 * s] += dre[o] * b;
                                    jac[o * 2 * nf + 2 * s + 1] += dim[o] * b;
                                }
                            }
                        }
                        continue;
                    }
                    let mono = &self.monomials[t.monomial];
                    for &(v, _) in mono.factors() {
                        // The pump is given, without noise.
                        if v.index() >= 2 * nm {
                            continue;
                        }
                        monomial_jacobian(
                            &prep.plan,
                            mono,
                            &modal_ref,
                            v,
                            &mut jr,
                            &mut ji,
                            &mut scratch[mi],
                        );
                        // A velocity's derivative carries back onto its mode's amplitude.
                        let (mode, velocity) = (v.index() % nm, v.index() >= nm);
                        for o in (0..nf).filter(|&o| prep.mode_of[o] == n) {
                            for s in (0..nf).filter(|&s| prep.mode_of[s] == mode) {
                                let si = prep.input_of[s];
                                let (mut dre, mut dim) = (jr[o * n_in + si], ji[o * n_in + si]);
                                if velocity {
                                    (dre, dim) = velocity_to_amplitude(dre, dim, m.freqs_hz[s]);
                                }
                                jac[o * 2 * nf + 2 * s] += dre * b;
                                jac[o * 2 * nf + 2 * s + 1] += dim * b;
                            }
                        }
                    }
                }
            }
            // Σ_block = Jr D Jrᵀ with real rows (2o: re, 2o+1: im).
            let real = |row: usize, c: usize| -> f64 {
                let z = jac[(row / 2) * 2 * nf + c];
                if row.is_multiple_of(2) {
                    z.re
                } else {
                    z.im
                }
            };
            let mut sigma = DMatrix::<f64>::zeros(2 * nf, 2 * nf);
            for r1 in 0..2 * nf {
                for r2 in r1..2 * nf {
                    let mut acc = 0.0;
                    for c in 0..2 * nf {
                        let a = real(r1, c);
                        if a != 0.0 {
                            acc += a * real(r2, c) * data_var[mi][c / 2];
                        }
                    }
                    sigma[(r1, r2)] = acc;
                    sigma[(r2, r1)] = acc;
                }
            }
            blocks.push(sigma);
        }
        blocks
    }

    /// Cholesky factors `L` (`L Lᵀ = Σ`) of the sample covariance of the group's real rows, where `Σ` is the covariance
    /// across shots of the equation residuals evaluated at the median estimate (held fixed):
    /// the equation error the data noise makes, correlations between rows included (the same
    /// noisy amplitude enters several rows through the products). `Σ` is shrunk towards its
    /// diagonal by `shrinkage` (the sample covariance of few shots is noisy). Residuals of
    /// per-shot fits would understate the noise where a row's own unknowns absorb it. One
    /// block per measurement: the shots of two measurements are separate acquisitions, so
    /// their sample cross-covariance is noise only, and leaving it out keeps the cost linear
    /// in the number of measurements.
    pub(super) fn whitening(
        &self,
        rows: &[Vec<MeasRows>],
        g: &FitGroup,
        values: &[Vec<f64>],
        shrinkage: f64,
    ) -> Option<BlockWhitening> {
        let nshots = rows.len();
        let mut xbar = values.first()?.clone();
        for &u in &g.unknowns {
            let mut v: Vec<f64> = values.iter().map(|x| x[u]).collect();
            v.sort_by(f64::total_cmp);
            xbar[u] = v[v.len() / 2];
        }
        let xv = DVector::from_iterator(g.unknowns.len(), g.unknowns.iter().map(|&u| xbar[u]));
        let mut res: Vec<DVector<f64>> = Vec::with_capacity(nshots);
        for shot_rows in rows {
            let (a, b, _) = self.assemble(shot_rows, &g.measurements, &g.unknowns, &xbar, None);
            res.push(&a * &xv - &b);
        }
        let sizes: Vec<usize> = g
            .measurements
            .iter()
            .map(|&mi| 2 * rows[0][mi].rows.len())
            .collect();
        let mean = res
            .iter()
            .fold(DVector::zeros(res[0].len()), |acc, r| acc + r)
            / nshots as f64;
        let mut blocks = Vec::with_capacity(sizes.len());
        let mut offset = 0;
        for &m in &sizes {
            let mut cov = DMatrix::<f64>::zeros(m, m);
            for r in &res {
                let d = r.rows(offset, m) - mean.rows(offset, m);
                cov += &d * d.transpose();
            }
            cov /= (nshots as f64 - 1.0).max(1.0);
            blocks.push(cov);
            offset += m;
        }
        // The floor and the shrinkage as over the whole group's covariance.
        let dmax = blocks
            .iter()
            .map(|c| c.diagonal().max())
            .fold(f64::NEG_INFINITY, f64::max);
        if !(dmax > 0.0 && dmax.is_finite()) {
            return None;
        }
        for cov in &mut blocks {
            let m = cov.nrows();
            for i in 0..m {
                // Floor: rows whose residual never moves get the smallest nonzero variance.
                if cov[(i, i)] <= 1e-300 {
                    cov[(i, i)] = dmax * 1e-12;
                }
                for j in 0..m {
                    if i != j {
                        cov[(i, j)] *= 1.0 - shrinkage;
                    }
                }
            }
        }
        BlockWhitening::factor(blocks)
    }
}

/// A block-diagonal whitening `L⁻¹` of a group's rows: the lower Cholesky factor of each
/// measurement's block of the covariance, in row order.
#[derive(Debug, Clone)]
pub(super) struct BlockWhitening {
    blocks: Vec<DMatrix<f64>>,
}

impl BlockWhitening {
    /// Factors every block (`L Lᵀ = Σ_block`); `None` when a block is not positive definite.
    pub(super) fn factor(blocks: Vec<DMatrix<f64>>) -> Option<Self> {
        let blocks = blocks
            .into_iter()
            .map(|c| c.cholesky().map(|c| c.l()))
            .collect::<Option<Vec<_>>>()?;
        Some(Self { blocks })
    }

    /// `(L⁻¹ a, L⁻¹ b)` block by block, or `None` when the rows do not match the blocks or a
    /// triangular solve fails.
    pub(super) fn whiten(
        &self,
        a: &DMatrix<f64>,
        b: &DVector<f64>,
    ) -> Option<(DMatrix<f64>, DVector<f64>)> {
        let total: usize = self.blocks.iter().map(|l| l.nrows()).sum();
        if total != a.nrows() || total != b.len() {
            return None;
        }
        let (mut wa, mut wb) = (a.clone(), b.clone());
        let mut offset = 0;
        for l in &self.blocks {
            let m = l.nrows();
            let ok = l.solve_lower_triangular_mut(&mut wa.rows_mut(offset, m))
                && l.solve_lower_triangular_mut(&mut wb.rows_mut(offset, m));
            if !ok {
                return None;
            }
            offset += m;
        }
        Some((wa, wb))
    }
}

/// The dataset with every measurement's shots averaged into one shot.
pub(super) fn shot_mean(ds: &Dataset) -> Dataset {
    let mut mean_ds = ds.clone();
    for m in &mut mean_ds.measurements {
        let per = m.freqs_hz.len() * m.points.len();
        let mut mean = vec![Complex64::new(0.0, 0.0); per];
        for s in 0..m.n_shots {
            for (i, x) in mean.iter_mut().enumerate() {
                *x += m.data[s * per + i] / m.n_shots as f64;
            }
        }
        m.data = mean;
        m.n_shots = 1;
    }
    mean_ds
}

#[cfg(test)]
mod tests {
    use super::super::testkit::{self, SHAPE};
    use super::super::{Problem, Settings};
    use super::shot_mean;

    #[test]
    fn amplitude_noise_comes_from_the_shot_scatter() {
        let sigma = 1e-9;
        let ds = testkit::dataset(false, 400, sigma, 7);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let (var, absolute) = p.amplitude_variances(&ds, 400);
        assert!(absolute);
        for (mi, v) in var.iter().enumerate() {
            // Modal amplitude = x / shape: its variance per quadrature is σ²/shape².
            let expect = (sigma / SHAPE[mi]).powi(2);
            for x in v {
                assert!((x / expect - 1.0).abs() < 0.15, "{x:e} vs {expect:e}");
            }
        }
        let rel = p.relative_variances();
        assert!((rel[0][0] - 4.0).abs() < 1e-12);
        let clean = testkit::dataset(false, 5, 0.0, 7);
        let (v, absolute) = p.amplitude_variances(&clean, 5);
        assert!(!absolute);
        assert_eq!(v, rel);
    }

    #[test]
    fn the_shot_mean_averages_every_amplitude() {
        let ds = testkit::dataset(false, 3, 1e-9, 7);
        let m = shot_mean(&ds);
        assert_eq!(m.measurements[0].n_shots, 1);
        let x = &ds.measurements[1];
        let mean = (x.amplitude(0, 2, 0) + x.amplitude(1, 2, 0) + x.amplitude(2, 2, 0)) / 3.0;
        assert!((m.measurements[1].amplitude(0, 2, 0) - mean).norm() < 1e-24);
    }

    #[test]
    fn the_equation_covariance_of_a_linear_row_is_its_gain_squared() {
        let ds = testkit::dataset(false, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let t = testkit::truth(&p);
        let g = &p.groups[0];
        let var = p.relative_variances();
        let mut scratch: Vec<_> = p.meas.iter().map(|m| m.plan.scratch()).collect();
        let blocks = p.equation_cov(&ds, g, 0, &t, &var, &mut scratch);
        assert_eq!(blocks.len(), g.measurements.len());
        let sigma = &blocks[0];
        // beta = 0: each row depends on its own amplitude only, through ω² − Ω² + iΩγ.
        let om = 2.0 * std::f64::consts::PI * 985.0;
        let lin = num_complex::Complex64::new(t[0] - om * om, om * t[1]);
        assert!((sigma[(0, 0)] / (lin.norm_sqr() * var[0][0]) - 1.0).abs() < 1e-12);
        assert!(sigma[(0, 2)].abs() < 1e-12 * sigma[(0, 0)]);
        assert!((sigma[(0, 1)] - sigma[(1, 0)]).abs() <= 1e-12 * sigma[(0, 0)]);
    }

    #[test]
    fn block_whitening_equals_the_dense_whitening_of_the_block_diagonal_covariance() {
        use super::BlockWhitening;
        use nalgebra::{DMatrix, DVector};
        // Two blocks (2 and 4 rows), positive definite, with correlations inside each.
        let spd = |n: usize, seed: f64| {
            let m = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) as f64 + seed).sin());
            &m * m.transpose() + DMatrix::identity(n, n) * 0.5
        };
        let (s1, s2) = (spd(2, 0.3), spd(4, 1.7));
        let mut dense = DMatrix::zeros(6, 6);
        dense.view_mut((0, 0), (2, 2)).copy_from(&s1);
        dense.view_mut((2, 2), (4, 4)).copy_from(&s2);
        let a = DMatrix::from_fn(6, 3, |i, j| {
            (i as f64 + 1.0) * (j as f64 - 0.5) + 0.1 * i as f64
        });
        let b = DVector::from_fn(6, |i, _| (i as f64).cos());
        let l = dense.cholesky().expect("spd").l();
        let (da, db) = (
            l.solve_lower_triangular(&a).expect("solve"),
            l.solve_lower_triangular(&b).expect("solve"),
        );
        let w = BlockWhitening::factor(vec![s1, s2]).expect("blocks");
        let (wa, wb) = w.whiten(&a, &b).expect("whiten");
        assert!((wa - da).amax() < 1e-12 && (wb - db).amax() < 1e-12);
        // Rows that do not match the blocks are refused, not whitened in part.
        assert!(w
            .whiten(&a.rows(0, 5).into_owned(), &b.rows(0, 5).into_owned())
            .is_none());
        // A block that is not positive definite gives no whitening.
        assert!(BlockWhitening::factor(vec![DMatrix::from_element(2, 2, 1.0)]).is_none());
    }
}

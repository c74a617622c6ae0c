//! Per-shot fits of every group, stage by stage.

use super::weighting::{shot_mean, BlockWhitening};
use super::{FitGroup, IdentError, MeasRows, Problem, Unknown};
use crate::solve::{solve_ls, FitStatus, LsSolution};
use harmonid_data::Dataset;
use harmonid_spectral::ProductScratch;
use std::collections::BTreeMap;

/// Diagnostics of one fit group.
#[derive(Debug, Clone)]
pub struct GroupDiagnostics {
    /// Stage (0 for joint).
    pub stage: usize,
    /// Measurement indices.
    pub measurements: Vec<usize>,
    /// Unknown indices fitted.
    pub unknowns: Vec<usize>,
    /// Median over shots of the condition number of the equilibrated matrix.
    pub cond: f64,
    /// `sqrt(Σ RSS / Σ ‖b‖²)` over shots: relative residual of the fit.
    pub rms_residual: f64,
    /// `Σ ‖b‖²` over shots (for reference).
    pub rms_rhs: f64,
    /// Whether the fit is a generalised least squares (equations weighted by the covariance
    /// of their errors).
    pub weighted: bool,
    /// Whether the amplitudes' noise came from the scatter across shots (else: equal noise on
    /// every measured amplitude, scale from the residuals).
    pub noise_from_shots: bool,
    /// Number of shots in which a bound was active (or the bounded solve failed).
    pub status_bounds: usize,
    /// How every shot's solve ended, `status[shot]`.
    pub status: Vec<FitStatus>,
    /// Real rows of the fit.
    pub rows: usize,
}

/// Per-shot results of [`Problem::fit`].
#[derive(Debug, Clone)]
pub struct Fit {
    /// `values[shot][unknown]`.
    pub values: Vec<Vec<f64>>,
    /// Variance of each unknown from the single-shot residuals, `cov_diag[shot][unknown]`.
    pub cov_diag: Vec<Vec<f64>>,
    /// Per shot and mode: covariance of (ω², γ) as `[var ω², cov, cov, var γ]`.
    pub cov_lin: Vec<BTreeMap<usize, [f64; 4]>>,
    /// Per group diagnostics.
    pub groups: Vec<GroupDiagnostics>,
}

impl Problem {
    /// Fits every shot of the dataset: returns per-shot values of every unknown (NaN where not
    /// determined) and the per-group diagnostics.
    pub fn fit(&self, ds: &Dataset) -> Result<Fit, IdentError> {
        self.check_shape(ds)?;
        let settings = &self.settings;
        let nshots = ds.measurements.iter().map(|m| m.n_shots).max().unwrap_or(1);
        let nu = self.table.len();
        let mut scratch: Vec<ProductScratch> = self.meas.iter().map(|m| m.plan.scratch()).collect();
        let rows: Vec<Vec<MeasRows>> = (0..nshots)
            .map(|s| {
                (0..self.meas.len())
                    .map(|mi| self.shot_rows(ds, mi, s, &mut scratch[mi]))
                    .collect()
            })
            .collect();
        // Fixed values in place; NaN marks what the fits fill in.
        let start: Vec<f64> = self
            .table
            .fixed()
            .iter()
            .map(|v| v.unwrap_or(f64::NAN))
            .collect();
        let mut values = vec![start; nshots];
        let mut cov_diag = vec![vec![f64::NAN; nu]; nshots];
        let mut cov_lin: Vec<BTreeMap<usize, [f64; 4]>> = vec![BTreeMap::new(); nshots];
        let mut groups = Vec::new();
        let weighted =
            settings.min_shots_for_weights > 0 && nshots >= settings.min_shots_for_weights;
        let (data_var, absolute) = if weighted {
            self.amplitude_variances(ds, nshots)
        } else {
            (self.relative_variances(), false)
        };
        let gls_iters = if settings.gls {
            settings.gls_iterations
        } else {
            0
        };
        // The shot-averaged dataset (for linearising the noise propagation).
        let mean_ds = shot_mean(ds);
        for g in &self.groups {
            let lower: Vec<Option<f64>> = g
                .unknowns
                .iter()
                .map(|&u| self.table.bounds()[u].0)
                .collect();
            let upper: Vec<Option<f64>> = g
                .unknowns
                .iter()
                .map(|&u| self.table.bounds()[u].1)
                .collect();
            let mut diag = GroupDiagnostics {
                stage: g.stage,
                measurements: g.measurements.clone(),
                unknowns: g.unknowns.clone(),
                cond: 0.0,
                rms_residual: 0.0,
                rms_rhs: 0.0,
                weighted: settings.gls,
                noise_from_shots: settings.gls && absolute,
                status_bounds: 0,
                status: vec![FitStatus::Solved; nshots],
                rows: 0,
            };
            // Fixed-Q modes: iterate γ = ω/Q with the fitted ω.
            let iters = (1 + gls_iters).max(
                if (0..self.mode_names.len()).any(|n| self.table.fixed_q(n).is_some()) {
                    3
                } else {
                    1
                },
            );
            let mut sols: Vec<Option<(LsSolution, usize, f64, bool)>> = vec![None; nshots];
            for it in 0..iters {
                let gls_now = it > 0 && it <= gls_iters;
                // With many noisy shots: one weighting for all shots, linearised at the median
                // estimate and the shot-averaged spectra (much less noisy than one shot's).
                let shared_l = if gls_now && absolute && settings.sample_covariance && nshots >= 20
                {
                    self.whitening(&rows, g, &values, 0.2)
                } else if gls_now && absolute {
                    let mut xbar = values[0].clone();
                    for (u, xb) in xbar.iter_mut().enumerate() {
                        let mut v: Vec<f64> = values.iter().map(|x| x[u]).collect();
                        v.sort_by(f64::total_cmp);
                        *xb = v[v.len() / 2];
                    }
                    let blocks = self.equation_cov(&mean_ds, g, 0, &xbar, &data_var, &mut scratch);
                    BlockWhitening::factor(blocks)
                } else {
                    None
                };
                for s in 0..nshots {
                    let (mut a, mut b, _) =
                        self.assemble(&rows[s], &g.measurements, &g.unknowns, &values[s], None);
                    let mut whitened = false;
                    let own_l = if gls_now && shared_l.is_none() {
                        BlockWhitening::factor(self.equation_cov(
                            ds,
                            g,
                            s,
                            &values[s],
                            &data_var,
                            &mut scratch,
                        ))
                    } else {
                        None
                    };
                    if let Some(l) = shared_l.as_ref().or(own_l.as_ref()) {
                        if let Some((wa, wb)) = l.whiten(&a, &b) {
                            a = wa;
                            b = wb;
                            whitened = true;
                        }
                    }
                    let so = solve_ls(&a, &b, &lower, &upper);
                    if so.x.iter().all(|x| x.is_finite()) {
                        for (j, &u) in g.unknowns.iter().enumerate() {
                            values[s][u] = so.x[j];
                        }
                    }
                    self.update_fixed_q(&mut values[s]);
                    sols[s] = Some((so, a.nrows(), b.norm_squared(), whitened));
                }
            }
            self.record_group(g, sols, absolute, &mut cov_diag, &mut cov_lin, &mut diag);
            groups.push(diag);
        }
        Ok(Fit {
            values,
            cov_diag,
            cov_lin,
            groups,
        })
    }

    /// Records each shot's solution of group `g` (`sols[shot]`: solution, rows, `‖b‖²`,
    /// whether whitened): the unknowns' variances into `cov_diag` and each mode's (ω², γ)
    /// covariance into `cov_lin`, and the group's diagnostics (median condition number, relative residual, rows,
    /// every shot's status) into `diag`.
    fn record_group(
        &self,
        g: &FitGroup,
        sols: Vec<Option<(LsSolution, usize, f64, bool)>>,
        absolute: bool,
        cov_diag: &mut [Vec<f64>],
        cov_lin: &mut [BTreeMap<usize, [f64; 4]>],
        diag: &mut GroupDiagnostics,
    ) {
        let mut conds = Vec::new();
        let (mut rss_sum, mut rhs_sum) = (0.0, 0.0);
        for (s, sol) in sols.into_iter().enumerate() {
            let Some((so, nrows, bnorm2, whitened)) = sol else {
                continue;
            };
            diag.status[s] = so.status;
            if so.status != FitStatus::Solved {
                diag.status_bounds += 1;
            }
            // With known data noise the whitened problem has unit variance; otherwise the
            // scale comes from the residuals.
            let scale = if whitened && absolute { 1.0 } else { so.sigma2 };
            let k = g.unknowns.len();
            for (j, &u) in g.unknowns.iter().enumerate() {
                cov_diag[s][u] = so.cov_unit[j * k + j] * scale;
            }
            // ω², γ covariance per mode, for f and Q errors.
            for (j, &u) in g.unknowns.iter().enumerate() {
                if let Unknown::OmegaSq(n) = self.table.unknowns()[u] {
                    if let Some(j2) = g
                        .unknowns
                        .iter()
                        .position(|&v| self.table.unknowns()[v] == Unknown::Gamma(n))
                    {
                        let c = |x: usize, y: usize| so.cov_unit[x * k + y] * scale;
                        cov_lin[s].insert(n, [c(j, j), c(j, j2), c(j2, j), c(j2, j2)]);
                    }
                }
            }
            conds.push(so.cond);
            rss_sum += so.rss;
            rhs_sum += bnorm2;
            diag.rows = nrows;
        }
        conds.sort_by(f64::total_cmp);
        diag.cond = conds.get(conds.len() / 2).copied().unwrap_or(f64::NAN);
        diag.rms_residual = (rss_sum / rhs_sum.max(f64::MIN_POSITIVE)).sqrt();
        diag.rms_rhs = rhs_sum;
    }
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use super::super::{IdentError, Problem, Settings};
    use crate::solve::FitStatus;

    #[test]
    fn noise_free_data_give_the_truth_in_every_shot() {
        let ds = testkit::dataset(true, 3, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let fit = p.fit(&ds).expect("fit");
        let t = testkit::truth(&p);
        for v in &fit.values {
            for (i, (x, y)) in v.iter().zip(&t).enumerate() {
                // beta, g: the scale at which they matter is ω²/q² ~ 1e17 (q ~ 1e-5 m).
                let scale = if y.abs() > 0.0 { y.abs() } else { 1e17 };
                assert!(
                    (x - y).abs() <= 1e-8 * scale,
                    "{}: {x:e} vs {y:e}",
                    p.label(i)
                );
            }
        }
        assert_eq!(fit.groups.len(), 3);
        for g in &fit.groups {
            assert_eq!(g.status, vec![FitStatus::Solved; 3]);
        }
    }

    #[test]
    fn noisy_shots_scatter_and_keep_their_status() {
        let ds = testkit::dataset(true, 8, 1e-8, 2);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let fit = p.fit(&ds).expect("fit");
        assert_eq!(fit.values.len(), 8);
        assert!(fit.groups.iter().all(|g| g.weighted && g.noise_from_shots));
        assert!(fit.groups.iter().all(|g| g.status.len() == 8));
        let w2: Vec<f64> = fit.values.iter().map(|v| v[0]).collect();
        assert!(w2.windows(2).any(|w| w[0] != w[1]));
    }

    #[test]
    fn a_dataset_of_another_shape_is_refused() {
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let other = testkit::dataset(false, 1, 0.0, 1);
        assert!(matches!(
            p.fit(&other),
            Err(IdentError::ShapeMismatch { .. })
        ));
    }
}

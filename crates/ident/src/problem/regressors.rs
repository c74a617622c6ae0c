//! Regressors: the complex equations of one shot and the real least-squares system of a group.

use super::{ForceModel, Problem, Unknown};
use harmonid_data::Dataset;
use harmonid_spectral::{monomial_amplitudes, ProductScratch};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::PI;

/// One complex equation: sparse coefficients on unknowns, and the right-hand side.
#[derive(Debug, Clone)]
pub(super) struct Row {
    pub(super) coefs: Vec<(usize, Complex64)>,
    pub(super) rhs: Complex64,
}

#[derive(Debug, Clone)]
pub(super) struct MeasRows {
    pub(super) rows: Vec<Row>,
}

impl Problem {
    /// Complex equations of every measurement for one shot.
    pub(super) fn shot_rows_all(&self, ds: &Dataset, shot: usize) -> Vec<MeasRows> {
        let mut scratch: Vec<ProductScratch> = self.meas.iter().map(|m| m.plan.scratch()).collect();
        (0..self.meas.len())
            .map(|mi| self.shot_rows(ds, mi, shot, &mut scratch[mi]))
            .collect()
    }

    pub(super) fn shot_rows(
        &self,
        ds: &Dataset,
        mi: usize,
        shot: usize,
        scratch: &mut ProductScratch,
    ) -> MeasRows {
        let m = &ds.measurements[mi];
        let prep = &self.meas[mi];
        let nf = m.freqs_hz.len();
        let modal = self.variable_spectra(ds, mi, shot);
        let modal_ref: Vec<&[Complex64]> = modal.iter().map(|v| v.as_slice()).collect();
        // Which monomials are needed: those of active equations.
        let mut g: Vec<Vec<Complex64>> = vec![Vec::new(); self.monomials.len()];
        for &n in &prep.active {
            for t in &self.eqs[n] {
                if g[t.monomial].is_empty() {
                    let mut out = vec![Complex64::new(0.0, 0.0); nf];
                    match &self.ns[t.monomial] {
                        Some(ns) => self.nonsmooth_column(mi, ns, &modal_ref, &mut out),
                        None => monomial_amplitudes(
                            &prep.plan,
                            &self.monomials[t.monomial],
                            &modal_ref,
                            &mut out,
                            scratch,
                        ),
                    }
                    g[t.monomial] = out;
                }
            }
        }
        let mut rows = Vec::with_capacity(nf);
        for r in 0..nf {
            let n = prep.mode_of[r];
            let om = 2.0 * PI * m.freqs_hz[r];
            let q = modal[n][prep.input_of[r]];
            let mut coefs: Vec<(Unknown, Complex64)> = vec![
                (Unknown::OmegaSq(n), q),
                (Unknown::Gamma(n), Complex64::new(0.0, om) * q),
            ];
            let mut rhs = q * (om * om);
            for t in &self.eqs[n] {
                let gm = g[t.monomial][r];
                rhs -= gm * t.konst;
                for &(p, f) in &t.params {
                    match coefs.iter_mut().find(|(u, _)| *u == Unknown::Param(p)) {
                        Some(c) => c.1 += gm * f,
                        None => coefs.push((Unknown::Param(p), gm * f)),
                    }
                }
            }
            for (tone, &i) in prep.drive_idx.iter().enumerate() {
                if i != r {
                    continue;
                }
                match self.table.force_model() {
                    ForceModel::Free | ForceModel::Auto => {
                        for quad in 0..2u8 {
                            let c = if quad == 0 {
                                Complex64::new(-1.0, 0.0)
                            } else {
                                Complex64::new(0.0, -1.0)
                            };
                            coefs.push((
                                Unknown::Force {
                                    meas: mi,
                                    tone,
                                    quad,
                                },
                                c,
                            ));
                        }
                    }
                    ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                        let d = prep
                            .drive_c
                            .as_ref()
                            .and_then(|v| v.get(tone).copied())
                            .unwrap_or_default();
                        let meas = (self.table.force_model() == ForceModel::GainPerMeasurement)
                            .then_some(mi);
                        for quad in 0..2u8 {
                            let c = if quad == 0 { -d } else { -d * Complex64::i() };
                            let u = Unknown::Gain {
                                meas,
                                mode: n,
                                quad,
                            };
                            match coefs.iter_mut().find(|(x, _)| *x == u) {
                                Some(e) => e.1 += c,
                                None => coefs.push((u, c)),
                            }
                        }
                    }
                }
            }
            let coefs = coefs
                .into_iter()
                .filter_map(|(u, c)| self.table.index_of(&u).map(|i| (i, c)))
                .collect();
            rows.push(Row { coefs, rhs });
        }
        MeasRows { rows }
    }

    /// Real least-squares matrix and right-hand side of a group: rows (re, im) per complex
    /// equation, columns = `unknowns`; known values from `values` (NaN: take `fixed`; both NaN:
    /// 0) moved to the right-hand side. `weights[mi][r]` divides each row. Returns also the
    /// (measurement, frequency) of each complex row.
    pub(super) fn assemble(
        &self,
        rows: &[MeasRows],
        measurements: &[usize],
        unknowns: &[usize],
        values: &[f64],
        weights: Option<&[Vec<f64>]>,
    ) -> (DMatrix<f64>, DVector<f64>, Vec<(usize, usize)>) {
        let nrow: usize = measurements.iter().map(|&m| rows[m].rows.len()).sum();
        let k = unknowns.len();
        let mut a = DMatrix::zeros(2 * nrow, k);
        let mut b = DVector::zeros(2 * nrow);
        let mut which = Vec::with_capacity(nrow);
        let mut col = vec![usize::MAX; self.table.len()];
        for (j, &u) in unknowns.iter().enumerate() {
            col[u] = j;
        }
        let mut i = 0;
        for &m in measurements {
            for (r, row) in rows[m].rows.iter().enumerate() {
                let w = weights.map_or(1.0, |w| w[m][r]);
                let mut rhs = row.rhs;
                for &(u, c) in &row.coefs {
                    if col[u] != usize::MAX {
                        a[(2 * i, col[u])] += c.re * w;
                        a[(2 * i + 1, col[u])] += c.im * w;
                    } else {
                        rhs -= c * self.known_value(values, u);
                    }
                }
                b[2 * i] = rhs.re * w;
                b[2 * i + 1] = rhs.im * w;
                which.push((m, r));
                i += 1;
            }
        }
        (a, b, which)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use super::super::{ForceModel, Problem, Settings};
    use nalgebra::DVector;

    #[test]
    fn equations_hold_exactly_at_the_truth() {
        for fm in [ForceModel::GainPerMeasurement, ForceModel::Free] {
            let ds = testkit::dataset(true, 1, 0.0, 1);
            let s = Settings {
                force_model: fm,
                ..Settings::default()
            };
            let p = Problem::new(&testkit::model(), &ds, &s).expect("problem");
            let rows = p.shot_rows_all(&ds, 0);
            let all: Vec<usize> = (0..p.table.len()).collect();
            let t = testkit::truth(&p);
            let (a, b, which) = p.assemble(&rows, &[0, 1, 2], &all, &t, None);
            assert_eq!(which.len(), 4 + 4 + 7);
            assert_eq!(a.nrows(), 30);
            let r = &a * DVector::from_vec(t.clone()) - &b;
            assert!(
                r.norm() <= 1e-12 * b.norm(),
                "{fm:?}: {:e} vs {:e}",
                r.norm(),
                b.norm()
            );
            // Known values move to the right-hand side: fitting only beta leaves the same
            // residual.
            let (a1, b1, _) = p.assemble(&rows, &[0, 1, 2], &[4], &t, None);
            assert!((&a1 * DVector::from_element(1, 0.0) - b1).norm() <= 1e-12 * b.norm());
        }
    }

    #[test]
    fn the_duffing_column_is_the_cube_of_the_measured_spectrum() {
        let ds = testkit::dataset(false, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let rows = p.shot_rows_all(&ds, 0);
        let q = p.modal_spectra(&ds, 0, 0);
        // a^3 at 985 Hz = 2*995 - 1005: (3/4) q995^2 conj(q1005).
        let expect = q[0][1] * q[0][1] * q[0][2].conj() * 0.75;
        let beta = rows[0].rows[0]
            .coefs
            .iter()
            .find(|c| c.0 == 4)
            .expect("beta")
            .1;
        assert!(
            (beta - expect).norm() <= 1e-12 * expect.norm(),
            "{beta} vs {expect}"
        );
    }
}

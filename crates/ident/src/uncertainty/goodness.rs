//! Does the model fit? The output-error fit's `χ²` judged against what a correct model gives
//! with the noise model actually used.
//!
//! With the noise of every line from the scatter of its `n` kept shots, a line's standardized
//! residual is `t = |X̄ − X|² / (σ̂²/n)` with `σ̂²` on `ν = 2(n − 1)` degrees of freedom,
//! independent of the mean: `t = 2·F(2, ν)` for a correct model, not `χ²₂`. Per real degree of
//! freedom its mean is `ν/(ν − 2)` ([`super::expected_reduced_chi2`]) and its variance
//! `2ν³/((ν − 2)²(ν − 4))` (2 for many shots). The cumulants of `χ²` are the lines' cumulants
//! summed, times `dof/N` (`N` real residuals: the fitted unknowns take their share), and the
//! p-value is the tail of the shifted, scaled `χ²` with the same first three cumulants
//! (a matched mean and variance alone underestimate the tail when the noise comes from a few
//! shots: at six shots their p-values were visibly not uniform). The third moment of `F(2, ν)`
//! needs `ν > 6`: the higher cumulants of lines with `ν < 10` (five shots or fewer) are those
//! of `ν = 10`, and their verdict is approximate. Without
//! a noise estimate (one shot, or shots that do not scatter) the noise is the fit's residual
//! and nothing can be judged: `p_value` is `None`.

pub use harmonid_data::result::{
    p_text, GoodnessOfFit, LineResidual, MeasurementFit, SweepFit, P_DOES_NOT_FIT,
};
use harmonid_data::Dataset;
use num_complex::Complex64;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The smallest shot-noise degrees of freedom the moments are computed with (see the module
/// documentation).
const MIN_NU: f64 = 10.0;

/// The verdict on the fit of predictions `x` to the pooled measurements `meas` with noise
/// `sigma` (the mean's, per quadrature), in the observation order of
/// [`crate::ForwardModel::evaluate`] over `ds`'s measurements (pooled: one shot each);
/// `used[m]`: shots averaged in measurement `m`; `dof`: real residuals minus fitted
/// unknowns. `from_shots`: whether `sigma` came from the shot scatter.
pub(crate) fn goodness_of_fit(
    ds: &Dataset,
    used: &[usize],
    (meas, x, sigma): (&[Complex64], &[Complex64], &[f64]),
    dof: usize,
    from_shots: bool,
) -> GoodnessOfFit {
    let n_real = 2 * meas.len();
    let dof_share = dof as f64 / n_real.max(1) as f64;
    let (mut chi2, mut cumulants) = (0.0, [0.0; 3]);
    let (mut total_miss2, mut total_meas2) = (0.0, 0.0);
    let mut measurements = Vec::with_capacity(ds.measurements.len());
    let mut lines = Vec::with_capacity(meas.len());
    let mut o = 0;
    for (m, &n) in ds.measurements.iter().zip(used) {
        let k = line_cumulants(2.0 * (n as f64 - 1.0));
        let per = m.freqs_hz.len() * m.points.len();
        let (mut c, mut miss2, mut meas2) = (0.0, 0.0, 0.0);
        for &freq_hz in &m.freqs_hz {
            for &p in &m.points {
                let r = (meas[o] - x[o]) / sigma[o];
                c += r.norm_sqr();
                miss2 += (meas[o] - x[o]).norm_sqr();
                meas2 += meas[o].norm_sqr();
                lines.push(LineResidual {
                    measurement: m.spec.name.clone(),
                    freq_hz,
                    point: ds.manifest.points.get(p).map(|pt| pt.name.clone()),
                    re: r.re,
                    im: r.im,
                    sigma: r.norm(),
                });
                o += 1;
            }
        }
        chi2 += c;
        total_miss2 += miss2;
        total_meas2 += meas2;
        for (sum, x) in cumulants.iter_mut().zip(k) {
            *sum += per as f64 * x;
        }
        let share = 2.0 * per as f64 * dof_share;
        let p_value = (from_shots && per > 0).then(|| {
            let [k1, k2, k3] = k.map(|x| x * per as f64 * dof_share);
            survival(c, [k1, k2, k3])
        });
        measurements.push(MeasurementFit {
            name: m.spec.name.clone(),
            lines: per,
            chi2: c,
            relative_rms: (miss2 / meas2).sqrt(),
            amplitude_rms: (meas2 / per.max(1) as f64).sqrt(),
            rms_residual_sigma: (c / (2 * per).max(1) as f64).sqrt(),
            chi2_per_dof: if share > 0.0 { c / share } else { f64::NAN },
            expected_chi2_per_dof: if from_shots { k[0] / 2.0 } else { 1.0 },
            p_value,
        });
    }
    let dof_f = dof.max(1) as f64;
    let (expected, spread, p_value) = if from_shots && n_real > 0 {
        let [k1, k2, k3] = cumulants.map(|k| k * dof_share);
        (
            k1 / dof_f,
            k2.sqrt() / dof_f,
            Some(survival(chi2, [k1, k2, k3])),
        )
    } else {
        (1.0, (2.0 / dof_f).sqrt(), None)
    };
    GoodnessOfFit {
        chi2,
        dof,
        chi2_per_dof: chi2 / dof_f,
        expected_chi2_per_dof: expected,
        spread_chi2_per_dof: spread,
        p_value,
        fits: p_value.map(|p| p >= P_DOES_NOT_FIT),
        rms_residual_sigma: (chi2 / n_real.max(1) as f64).sqrt(),
        relative_rms: (total_miss2 / total_meas2).sqrt(),
        stderr_inflation: 1.0,
        converged: true,
        sweeps: sweep_fits(ds, &measurements),
        measurements,
        lines,
        error_floor: None,
    }
}

/// Every stepped sweep's steps summed ([`SweepFit::of_steps`]), in the order of their first
/// step; `measurements` in `ds`'s order.
pub(crate) fn sweep_fits(ds: &Dataset, measurements: &[MeasurementFit]) -> Vec<SweepFit> {
    let mut order: Vec<&str> = Vec::new();
    let mut steps: std::collections::BTreeMap<&str, Vec<&MeasurementFit>> = Default::default();
    for (m, fit) in ds.measurements.iter().zip(measurements) {
        if let Some(s) = &m.spec.sweep {
            let list = steps.entry(s.sweep.as_str()).or_default();
            if list.is_empty() {
                order.push(s.sweep.as_str());
            }
            list.push(fit);
        }
    }
    order
        .into_iter()
        .map(|name| SweepFit::of_steps(name, &steps[name]))
        .collect()
}

/// The first three cumulants of one line's `t = |X̄ − X|²/s² = 2·F(2, ν)`: from the raw
/// moments `E[tʲ] = νʲ j! / Π_{i ≤ j} (ν/2 − i)`. The mean is two real residuals'
/// [`super::expected_per_real_dof`], the others use `max(ν, MIN_NU)`.
fn line_cumulants(nu: f64) -> [f64; 3] {
    let raw = |nu: f64, j: i32| {
        (1..=j).fold(1.0, |acc, i| {
            acc * nu * f64::from(i) / (nu / 2.0 - f64::from(i))
        })
    };
    let mean = 2.0 * super::expected_per_real_dof(nu);
    let nu = nu.max(MIN_NU);
    let (m1, m2, m3) = (raw(nu, 1), raw(nu, 2), raw(nu, 3));
    [mean, m2 - m1 * m1, m3 - 3.0 * m1 * m2 + 2.0 * m1.powi(3)]
}

/// `P(T ≥ t)` for `T = a + c·χ²_k` with the cumulants `[κ₁, κ₂, κ₃]` (`c = κ₃/(4κ₂)`,
/// `k = 8κ₂³/κ₃²`, `a = κ₁ − ck`).
fn survival(t: f64, [k1, k2, k3]: [f64; 3]) -> f64 {
    let c = k3 / (4.0 * k2);
    let k = 8.0 * k2.powi(3) / (k3 * k3);
    let a = k1 - c * k;
    if t.is_finite() && c > 0.0 {
        chi2_tail((t - a) / c, k)
    } else {
        f64::NAN
    }
}

/// `P(χ²_k ≥ x)`, 1 for `x ≤ 0` (NaN for `k` that is no degrees of freedom).
pub(crate) fn chi2_tail(x: f64, k: f64) -> f64 {
    match ChiSquared::new(k) {
        Ok(d) => d.sf(x.max(0.0)),
        Err(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_data::{Manifest, Measurement, MeasurementSpec};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn dataset(lines: &[usize]) -> Dataset {
        let ms = lines
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                let spec = MeasurementSpec::new(format!("m{i}"), vec![1000.0]);
                let freqs = (0..l).map(|k| 1000.0 + 10.0 * k as f64).collect();
                Measurement::zeros(spec, freqs, vec![], 1)
            })
            .collect();
        Dataset::from_parts("d", Manifest::new("t"), ms, None).expect("dataset")
    }

    #[test]
    fn survival_of_chi2_is_the_chi2_tail() {
        // χ²_k has cumulants k, 2k, 8k (k = 4: P(T ≥ t) = e^{-t/2}(1 + t/2)).
        let t: f64 = 9.0;
        let exact = (-t / 2.0).exp() * (1.0 + t / 2.0);
        assert!((survival(t, [4.0, 8.0, 32.0]) - exact).abs() < 1e-12);
        // Scaled and shifted: T = 1 + 2·χ²_4.
        assert!((survival(1.0 + 2.0 * t, [9.0, 32.0, 256.0]) - exact).abs() < 1e-12);
    }

    #[test]
    fn line_cumulants_tend_to_chi2_2_and_match_f_moments() {
        // Many shots: χ²₂ (2, 4, 16).
        let k = line_cumulants(1e9);
        assert!((k[0] - 2.0).abs() < 1e-6 && (k[1] - 4.0).abs() < 1e-6);
        assert!((k[2] - 16.0).abs() < 1e-5);
        // ν = 38 (20 shots): mean 2ν/(ν − 2), variance 4ν³/((ν − 2)²(ν − 4)).
        let nu: f64 = 38.0;
        let k = line_cumulants(nu);
        assert!((k[0] - 2.0 * nu / (nu - 2.0)).abs() < 1e-12);
        assert!((k[1] - 4.0 * nu.powi(3) / ((nu - 2.0).powi(2) * (nu - 4.0))).abs() < 1e-9);
    }

    #[test]
    fn residuals_are_standardized_and_shared_out_by_measurement() {
        let ds = dataset(&[2, 1]);
        let meas = [
            Complex64::new(30.0, 0.0),
            Complex64::new(0.0, -40.0),
            Complex64::new(1.0, 1.0),
        ];
        let x = [Complex64::new(0.0, 0.0); 3];
        let sigma = [1.0, 2.0, 1.0];
        let g = goodness_of_fit(&ds, &[20, 20], (&meas, &x, &sigma), 3, true);
        assert_eq!(g.lines[1].im, -20.0);
        assert_eq!(g.lines[0].sigma, 30.0);
        assert_eq!(g.chi2, 900.0 + 400.0 + 2.0);
        assert_eq!(g.chi2_per_dof, 434.0);
        // The model is zero: it misses everything, and m1 by 1 sigma per quadrature.
        assert_eq!((g.relative_rms, g.measurements[0].relative_rms), (1.0, 1.0));
        assert_eq!(g.measurements[1].rms_residual_sigma, 1.0);
        // m0 has 4 of the 6 real residuals: 2 of the 3 degrees of freedom.
        assert_eq!(g.measurements[0].chi2_per_dof, 1300.0 / 2.0);
        assert!((g.expected_chi2_per_dof - 38.0 / 36.0).abs() < 1e-12);
        assert_eq!(g.fits, Some(false));
        let text = g.headline().expect("does not fit");
        assert!(text.contains("Worst: \"m0\""), "{text}");
        assert!(
            text.contains("worst line 1000.000 Hz in \"m0\", 30.0 sigmas off"),
            "{text}"
        );
        // A fit that stopped early says so first, whatever its χ².
        let stopped = GoodnessOfFit {
            converged: false,
            ..g.clone()
        };
        let text = stopped.headline().expect("not converged");
        assert!(
            text.starts_with("THE OUTPUT-ERROR FIT DID NOT CONVERGE: it stopped at χ²/dof = 434 "),
            "{text}"
        );
        assert!(stopped
            .one_line()
            .ends_with("THE OUTPUT-ERROR FIT DID NOT CONVERGE (values are where it stopped)"));
        // Without shot noise nothing is judged.
        let g = goodness_of_fit(&ds, &[1, 1], (&meas, &x, &sigma), 3, false);
        assert_eq!((g.p_value, g.fits), (None, None));
        assert!(g.headline().is_none());
    }

    /// The p-value of a correct model's residuals (no fitted unknowns) with the noise
    /// estimated from n shots is uniform: brute force over 4000 draws at n = 20 and 10 (KS distance below its 1 % critical value); at n = 6 the upper tail (the verdict) holds, while fits better than the three-cumulant law's lower bound get p = 1 (4.5 % of draws instead of 1 % above 0.99).
    #[test]
    fn p_values_of_pure_noise_are_uniform() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for (shots, lines) in [(20usize, 30usize), (10, 12), (6, 12)] {
            let ds = dataset(&[lines]);
            let draws = 4000;
            let mut ps = Vec::with_capacity(draws);
            for _ in 0..draws {
                let mut meas = Vec::with_capacity(lines);
                let mut sigma = Vec::with_capacity(lines);
                for _ in 0..lines {
                    let shot: Vec<Complex64> = (0..shots)
                        .map(|_| {
                            Complex64::new(
                                StandardNormal.sample(&mut rng),
                                StandardNormal.sample(&mut rng),
                            )
                        })
                        .collect();
                    let mean = shot.iter().sum::<Complex64>() / shots as f64;
                    let ss: f64 = shot.iter().map(|s| (s - mean).norm_sqr()).sum();
                    let s1 = (ss / (2.0 * (shots as f64 - 1.0))).sqrt();
                    meas.push(mean);
                    sigma.push(s1 / (shots as f64).sqrt());
                }
                let x = vec![Complex64::new(0.0, 0.0); lines];
                let g = goodness_of_fit(&ds, &[shots], (&meas, &x, &sigma), 2 * lines, true);
                ps.push(g.p_value.expect("p"));
            }
            ps.sort_by(f64::total_cmp);
            // Kolmogorov–Smirnov distance from uniform; 1.63/√N is the 1 % critical value.
            let ks = ps
                .iter()
                .enumerate()
                .map(|(i, &p)| {
                    let lo = i as f64 / draws as f64;
                    let hi = (i + 1) as f64 / draws as f64;
                    (p - lo).abs().max((hi - p).abs())
                })
                .fold(0.0, f64::max);
            let below = |q: f64| ps.iter().filter(|&&p| p < q).count() as f64 / draws as f64;
            // The upper tail: p < 0.01 and p < 0.05 within 3.5 binomial standard errors.
            for q in [0.01, 0.05] {
                let tol = 3.5 * (q * (1.0 - q) / draws as f64).sqrt();
                assert!(
                    (below(q) - q).abs() < tol,
                    "{shots} shots: p < {q} in {:.4}",
                    below(q)
                );
            }
            if shots >= 10 {
                let limit = 1.63 / (draws as f64).sqrt();
                assert!(
                    ks < limit,
                    "{shots} shots: KS distance {ks:.4} (limit {limit:.4})"
                );
            }
        }
    }
}

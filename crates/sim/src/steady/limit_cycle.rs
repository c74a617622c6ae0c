//! Self-excited oscillation without a drive (a limit cycle, van der Pol's): autonomous harmonic
//! balance, the oscillation frequency an unknown and the phase fixed.

use super::aft::Aft;
use super::sweep::MAX_SWEEP_HARMONICS;
use crate::linalg::DenseLu;
use crate::{NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Smallest and largest fundamental amplitude (m) the start's scan of the effective damping
/// looks at, and its points per decade.
const SCAN_FROM_M: f64 = 1e-15;
const SCAN_TO_M: f64 = 1e3;
const SCAN_PER_DECADE: usize = 10;
/// Newton's tolerance: the residual's largest entry over `ω_n²` times the amplitude.
const TOL: f64 = 1e-12;
const MAX_NEWTON: usize = 60;

/// A limit cycle: a periodic oscillation the model sustains without a drive.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitCycle {
    /// The self-excited mode (its net linear damping is the most negative).
    pub mode: usize,
    /// Oscillation frequency, Hz.
    pub f_hz: f64,
    /// The harmonics of `f_hz` solved for (odd ones only when every term has odd degree).
    pub harmonics: Vec<usize>,
    /// `amplitudes[n][i]`: complex amplitude (m, peak) of mode `n` at harmonic
    /// `harmonics[i]`, phase fixed by a real fundamental of `mode`
    /// (`q_n(t) = Σ_i Re[X e^{i2π h_i f t}]`).
    pub amplitudes: Vec<Vec<Complex64>>,
    /// Whether the single-harmonic energy balance is stable there: the effective damping grows
    /// with the amplitude (a larger oscillation decays back, a smaller one grows).
    pub stable: bool,
}

impl LimitCycle {
    /// The fundamental amplitude of the self-excited mode, m.
    pub fn amplitude(&self) -> f64 {
        self.harmonics
            .iter()
            .position(|&h| h == 1)
            .map_or(0.0, |i| self.amplitudes[self.mode][i].norm())
    }

    /// The largest displacement of mode `n` over one period (m), from 4096 samples.
    pub fn peak(&self, n: usize) -> f64 {
        (0..4096)
            .map(|j| {
                let th = TAU * j as f64 / 4096.0;
                self.harmonics
                    .iter()
                    .zip(&self.amplitudes[n])
                    .map(|(&h, x)| (*x * Complex64::from_polar(1.0, h as f64 * th)).re)
                    .sum::<f64>()
                    .abs()
            })
            .fold(0.0, f64::max)
    }
}

/// The limit cycle of an undriven `model` (harmonics up to `harmonics`) from the mode whose net
/// linear damping ([`NumericModel::net_linear_damping`]) is the most negative.
///
/// Start: the fundamental amplitude where that mode's single-harmonic effective damping (the
/// quadrature part of its fundamental balance over `ω a`, at its own frequency, the other
/// modes at rest) changes sign from negative to positive, by a scan from 1e-15 m to 1e3 m and
/// bisection; in the weakly nonlinear van der Pol oscillator `q̈ + γq̇ + ω²q − μq̇ + νq²q̇ = 0`
/// that is `2√((μ − γ)/ν)`. Then Newton on every harmonic of every mode and the frequency, the
/// phase fixed by `Im X = 0` of the mode's fundamental (its column is the frequency's).
///
/// Errors: no mode is self-excited (every net damping positive: the undriven model decays to
/// rest); the effective damping stays negative up to 1e3 m (the oscillation grows without
/// bound); Newton does not converge; a harmonic count of 0 or above the sweeps' limit.
pub fn limit_cycle(model: &NumericModel, harmonics: usize) -> Result<LimitCycle, SimError> {
    if model.has_pump_terms() {
        return Err(SimError::PumpTerms {
            what: "the undriven limit cycle",
            terms: model.pump_term_names().join(", "),
            instead: "a pump fixes the oscillation's frequency at half its own: solve the pumped steady state (`harmonid simulate`) and check its stability",
        });
    }
    if harmonics == 0 || harmonics > MAX_SWEEP_HARMONICS {
        return Err(SimError::BadValue {
            what: "highest harmonic".into(),
            value: harmonics as f64,
            why: format!("give between 1 and {MAX_SWEEP_HARMONICS}"),
        });
    }
    let nm = model.n_modes();
    let (n, net) = (0..nm)
        .map(|n| (n, model.net_linear_damping(n)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .ok_or(SimError::BadValue {
            what: "modes".into(),
            value: 0.0,
            why: "the model has none".into(),
        })?;
    if net > 0.0 {
        return Err(SimError::NotSelfExcited {
            mode: model.mode_names[n].clone(),
            net_damping: net,
        });
    }
    let zero = vec![Complex64::new(0.0, 0.0); nm];
    let mut aft = Aft::new(model, &zero, harmonics);
    let nh = aft.harm.len();
    let nu = aft.n();
    let i1 = aft.harm.iter().position(|&h| h == 1).unwrap_or(0);
    let k_re = 2 * (n * nh + i1);
    let k_im = k_re + 1;
    let wn = model.omega(n);
    let mut res = vec![0.0; nu];
    let mut u = vec![0.0; nu];
    // The effective damping of a single harmonic of amplitude a at ω_n.
    let mut damping_at = |a: f64| -> f64 {
        u.fill(0.0);
        u[k_re] = a;
        aft.eval(&u, wn, 0.0, 1.0, &mut res, None);
        res[k_im] / (wn * a)
    };
    let decades = (SCAN_TO_M / SCAN_FROM_M).log10();
    let steps = (decades * SCAN_PER_DECADE as f64).ceil() as usize;
    let at = |k: usize| SCAN_FROM_M * 10f64.powf(k as f64 / SCAN_PER_DECADE as f64);
    let mut bracket = None;
    let mut last = damping_at(at(0));
    for k in 1..=steps {
        let d = damping_at(at(k));
        if last < 0.0 && d >= 0.0 {
            bracket = Some((at(k - 1), at(k)));
            break;
        }
        last = d;
    }
    let (mut lo, mut hi) = bracket.ok_or(SimError::NoLimitCycle {
        mode: model.mode_names[n].clone(),
        why: format!(
            "its single-harmonic damping stays negative up to {SCAN_TO_M:e} m: the oscillation grows without bound"
        ),
    })?;
    for _ in 0..100 {
        let mid = (lo * hi).sqrt();
        if damping_at(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a0 = (lo * hi).sqrt();
    let stable = damping_at(a0 * 1.01) > damping_at(a0 * 0.99);
    // Newton on (u without Im X1 of mode n, ω).
    let mut u = vec![0.0; nu];
    u[k_re] = a0;
    let mut w = wn;
    let mut ju = vec![0.0; nu * nu];
    let mut jw = vec![0.0; nu];
    let mut lu = DenseLu::dense(nu);
    let mut converged = false;
    for _ in 0..MAX_NEWTON {
        aft.eval(&u, w, 0.0, 1.0, &mut res, Some((&mut ju, &mut jw)));
        let scale = wn * wn * u[k_re].abs().max(f64::MIN_POSITIVE);
        let r = res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / scale;
        if !r.is_finite() {
            break;
        }
        if r < TOL {
            converged = true;
            break;
        }
        for i in 0..nu {
            ju[i * nu + k_im] = jw[i];
        }
        if !lu.factor(&ju) {
            break;
        }
        res.iter_mut().for_each(|v| *v = -*v);
        lu.solve(&mut res);
        for (i, d) in res.iter().enumerate() {
            if i == k_im {
                w += d;
            } else {
                u[i] += d;
            }
        }
        if !(w.is_finite() && w > 0.0) {
            break;
        }
    }
    if !converged {
        return Err(SimError::NoLimitCycle {
            mode: model.mode_names[n].clone(),
            why: format!(
                "Newton did not converge from the single-harmonic amplitude {a0:.3e} m; try fewer harmonics"
            ),
        });
    }
    let amplitudes = (0..nm)
        .map(|m| {
            (0..nh)
                .map(|i| Complex64::new(u[2 * (m * nh + i)], u[2 * (m * nh + i) + 1]))
                .collect()
        })
        .collect();
    Ok(LimitCycle {
        mode: n,
        f_hz: w / TAU,
        harmonics: aft.harm.clone(),
        amplitudes,
        stable,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Term;

    /// `q̈ + (ω/Q) q̇ + ω² q − μ q̇ + ν q² q̇ = 0` (variables: q, then q̇).
    fn van_der_pol(f_hz: f64, q: f64, mu: f64, nu: f64) -> NumericModel {
        NumericModel::new(
            vec!["q".into()],
            vec![f_hz],
            vec![q],
            vec![
                Term {
                    eq: 0,
                    coef: -mu,
                    factors: vec![(1, 1)],
                },
                Term {
                    eq: 0,
                    coef: nu,
                    factors: vec![(0, 2), (1, 1)],
                },
            ],
        )
        .expect("model")
    }

    #[test]
    fn weakly_nonlinear_van_der_pol_has_amplitude_two_root_mu_over_nu() {
        // ε = μ/ω = 1.6e-4: the single-harmonic amplitude 2√((μ − ω/Q)/ν), to O(ε²).
        let (f, q, mu, nu) = (1000.0, 1e4, 1.0, 1e8);
        let lc = limit_cycle(&van_der_pol(f, q, mu, nu), 7).expect("limit cycle");
        let net = mu - TAU * f / q;
        let want = 2.0 * (net / nu).sqrt();
        let a = lc.amplitude();
        println!("amplitude {a:.9e} vs {want:.9e}, f {:.9} Hz", lc.f_hz);
        assert!((a - want).abs() < 1e-6 * want, "{a:e} vs {want:e}");
        assert!((lc.f_hz - f).abs() < 1e-6 * f, "{} Hz", lc.f_hz);
        assert!(lc.stable);
        assert_eq!(lc.harmonics, [1, 3, 5, 7]);
        // The third harmonic is O(ε) of the fundamental.
        assert!(lc.amplitudes[0][1].norm() < 1e-3 * a);
    }

    #[test]
    fn strongly_nonlinear_van_der_pol_matches_its_known_period_and_peak() {
        // x'' − ε(1 − x²)x' + x = 0 at ε = 1 (ω = 1 rad/s): period 6.663286859, peak 2.008620
        // (the numerical literature's values for the van der Pol relaxation at ε = 1).
        let f = 1.0 / TAU;
        let lc = limit_cycle(&van_der_pol(f, 1e15, 1.0 + 1e-15, 1.0), 41).expect("limit cycle");
        let period = 1.0 / lc.f_hz;
        println!("period {period:.10}, peak {:.7}", lc.peak(0));
        assert!((period - 6.663_286_859).abs() < 1e-6, "period {period}");
        let peak = lc.peak(0);
        assert!((peak - 2.008_620).abs() < 1e-4, "peak {peak}");
    }

    #[test]
    fn a_model_without_self_excitation_is_refused_by_name() {
        let e = limit_cycle(&van_der_pol(1000.0, 100.0, 1.0, 1e8), 5).expect_err("damped");
        assert!(e.to_string().contains("q is not self-excited"), "{e}");
        // Negative damping at every amplitude: no cycle bounds it.
        let e = limit_cycle(&van_der_pol(1000.0, 1e4, 1.0, -1e8), 5).expect_err("unbounded");
        assert!(e.to_string().contains("grows without bound"), "{e}");
    }
}

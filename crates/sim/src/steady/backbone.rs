//! Backbone curves: the free, undamped oscillation frequency against the amplitude.

use super::aft::Aft;
use super::sweep::MAX_SWEEP_HARMONICS;
use crate::linalg::DenseLu;
use crate::{NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Backbone curve of mode `n`: the free, undamped oscillation frequency (Hz) at each
/// fundamental amplitude in `amplitudes` (m), other harmonics and modes solved for (other modes
/// start at rest and stay there unless coupled linearly in the oscillation). Returns `None` for
/// amplitudes where Newton fails.
pub fn backbone(
    model: &NumericModel,
    n: usize,
    amplitudes: &[f64],
    harmonics: usize,
) -> Result<Vec<Option<f64>>, SimError> {
    if model.has_nonsmooth() {
        return Err(SimError::NonSmooth {
            what: "the backbone",
            terms: model
                .rough_terms()
                .iter()
                .map(|t| format!("{} in the equation of {}", t.name, model.mode_names[t.eq]))
                .collect::<Vec<_>>()
                .join(", "),
            why: "its amplitude–frequency continuation runs on polynomial terms only; sweep the drive frequency at a small damping instead (harmonid sweep), or leave the non-smooth terms out for the backbone".into(),
        });
    }
    if model.has_velocity_terms() {
        return Err(SimError::VelocityTerms {
            what: "the backbone (a free, undamped oscillation)",
        });
    }
    if model.has_pump_terms() {
        return Err(SimError::PumpTerms {
            what: "the backbone (a free oscillation)",
            terms: model.pump_term_names().join(", "),
            instead: "leave the pump terms out of the model for its backbone",
        });
    }
    let nm = model.n_modes();
    if n >= nm {
        return Err(SimError::ModeIndex {
            index: n,
            n_modes: nm,
        });
    }
    if harmonics == 0 || harmonics > MAX_SWEEP_HARMONICS {
        return Err(SimError::BadValue {
            what: "highest harmonic".into(),
            value: harmonics as f64,
            why: format!("give between 1 and {MAX_SWEEP_HARMONICS}"),
        });
    }
    let zero = vec![Complex64::new(0.0, 0.0); nm];
    let mut aft = Aft::new(model, &zero, harmonics);
    let nh = aft.harm.len();
    let nu = aft.n();
    let i1 = aft
        .harm
        .iter()
        .position(|&h| h == 1)
        .ok_or(SimError::BadValue {
            what: "highest harmonic".into(),
            value: harmonics as f64,
            why: "the fundamental must be kept".into(),
        })?;
    let k_re = 2 * (n * nh + i1);
    let k_im = k_re + 1; // this unknown is replaced by ω
    let mut u = vec![0.0; nu];
    let mut w = model.omega(n);
    let mut res = vec![0.0; nu];
    let mut ju = vec![0.0; nu * nu];
    let mut jw = vec![0.0; nu];
    let mut lu = DenseLu::dense(nu);
    let mut out = Vec::with_capacity(amplitudes.len());
    // Continuation in amplitude from the last converged state: a step Newton cannot take is
    // halved (up to 2^-8 of it); an amplitude still not reached is `None`, and the next one
    // starts again from the last converged state (a failed Newton leaves no garbage behind).
    let (mut u_ok, mut w_ok, mut a_ok) = (u.clone(), w, 0.0f64);
    for &a in amplitudes {
        let mut step = a - a_ok;
        let mut reached = false;
        for _ in 0..200 {
            let target = if (a - a_ok).abs() <= step.abs() {
                a
            } else {
                a_ok + step
            };
            u.copy_from_slice(&u_ok);
            w = w_ok;
            let ok = backbone_newton(
                &mut aft,
                model,
                n,
                target,
                (k_re, k_im),
                &mut u,
                &mut w,
                &mut res,
                &mut ju,
                &mut jw,
                &mut lu,
            );
            if ok {
                u_ok.copy_from_slice(&u);
                (w_ok, a_ok) = (w, target);
                if target == a {
                    reached = true;
                    break;
                }
            } else {
                step *= 0.5;
                if step.abs() < (a - a_ok).abs() / 256.0 {
                    break;
                }
            }
        }
        out.push(reached.then_some(w_ok / TAU));
    }
    Ok(out)
}

/// Newton for the free oscillation of mode `n` at fundamental amplitude `a` from `(u, w)`:
/// `ω` takes the place of the fixed `Re X` (column `k_re`), `Im X = 0` fixes the phase (row
/// `k_im`; the free oscillation's sine balance holds by symmetry). True when converged (residual
/// below 1e-12 of `ω_n² a`) to a finite positive `ω`.
#[allow(clippy::too_many_arguments)]
fn backbone_newton(
    aft: &mut Aft,
    model: &NumericModel,
    n: usize,
    a: f64,
    (k_re, k_im): (usize, usize),
    u: &mut [f64],
    w: &mut f64,
    res: &mut [f64],
    ju: &mut [f64],
    jw: &mut [f64],
    lu: &mut DenseLu,
) -> bool {
    let nu = u.len();
    u[k_re] = a;
    u[k_im] = 0.0;
    for _ in 0..40 {
        aft.eval(u, *w, 0.0, 0.0, res, Some((&mut *ju, &mut *jw)));
        let scale = model.omega(n).powi(2) * a.abs().max(1e-300);
        let r = res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / scale;
        if r < 1e-12 {
            return w.is_finite() && *w > 0.0;
        }
        if !r.is_finite() {
            return false;
        }
        for i in 0..nu {
            ju[i * nu + k_re] = jw[i];
            ju[k_im * nu + i] = 0.0;
        }
        ju[k_im * nu + k_im] = 1.0;
        res[k_im] = u[k_im];
        if !lu.factor(ju) {
            return false;
        }
        for v in res.iter_mut() {
            *v = -*v;
        }
        lu.solve(res);
        for i in 0..nu {
            if i == k_re {
                *w += res[i];
            } else {
                u[i] += res[i];
            }
        }
        u[k_re] = a;
        if !(w.is_finite() && *w > 0.0) {
            return false;
        }
    }
    false
}

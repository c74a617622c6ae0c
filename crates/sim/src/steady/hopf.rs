//! Hopf points of a single-tone response curve: where a steady state loses or gains stability
//! through a complex pair of slow-flow eigenvalues (the state starts or stops a self-oscillation
//! beside the drive, a quasi-periodic response), as distinct from a fold, where one real
//! eigenvalue passes zero.

use super::{HbSettings, HbSolver, HbStatus, SteadyState, SweepPoint};
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// A Hopf point of a response curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hopf {
    /// Drive frequency of the Hopf point, Hz (located by bisection to `1e-9` relative).
    pub f_hz: f64,
    /// Index of the curve point before it (it lies between `index` and `index + 1`).
    pub index: usize,
    /// `|Im λ| / 2π` of the critical pair there, Hz: the self-oscillation starts at this
    /// offset from the drive's lines (a second base frequency of the response).
    pub offset_hz: f64,
    /// `true` where the state becomes stable along the curve (its arclength order), `false`
    /// where it becomes unstable.
    pub gains_stability: bool,
}

/// The largest real part over the complex pairs of slow-flow eigenvalues (1/s) and that
/// pair's `|Im λ|` (rad/s) of a curve point; `None` without a complex pair. A pair is complex
/// when `|Im λ|` exceeds `1e-6` of the slowest linear decay rate.
pub(super) fn critical_pair(
    model: &NumericModel,
    force: &[Complex64],
    harmonics: &[usize],
    point: &SweepPoint,
) -> Result<Option<(f64, f64)>, SimError> {
    let (mut solver, state) = solver_at(model, force, harmonics, point.f_hz)?;
    let state = SteadyState {
        amplitudes: point.amplitudes.clone(),
        ..state
    };
    let eig = solver.slow_flow_eigenvalues(&state)?;
    let decay = (0..model.n_modes())
        .map(|n| 0.5 * model.gamma(n))
        .fold(f64::INFINITY, f64::min);
    Ok(eig
        .iter()
        .filter(|z| z.im.abs() > 1e-6 * decay)
        .map(|z| (z.re, z.im.abs()))
        .max_by(|a, b| a.0.total_cmp(&b.0)))
}

/// The solver on the lattice of `harmonics` of `f_hz`, and an empty state on it.
pub(super) fn solver_at(
    model: &NumericModel,
    force: &[Complex64],
    harmonics: &[usize],
    f_hz: f64,
) -> Result<(HbSolver, SteadyState), SimError> {
    let drive = Excitation::new(vec![f_hz], force.iter().map(|&z| vec![z]).collect());
    let lattice: Vec<f64> = harmonics.iter().map(|&h| h as f64 * f_hz).collect();
    let solver = HbSolver::single(model, &drive, lattice.clone())?;
    let nm = model.n_modes();
    let state = SteadyState {
        lattice_hz: lattice,
        amplitudes: vec![vec![Complex64::ZERO; harmonics.len()]; nm],
        status: HbStatus::Converged { iterations: 0 },
        residual: 0.0,
        ramp_steps: 0,
        drive_jumps: Vec::new(),
        pump_sustained: false,
    };
    Ok((solver, state))
}

/// The Hopf points between consecutive points of a curve whose critical pairs `pairs` (from
/// [`critical_pair`]) change the sign of their real part, each located by bisection on the
/// drive frequency: the state at each trial frequency by Newton from the amplitudes
/// interpolated between the two points. Where Newton fails, the linear interpolation of the
/// real parts (secant) gives the point.
pub(super) fn locate_hopf(
    model: &NumericModel,
    force: &[Complex64],
    harmonics: &[usize],
    points: &[SweepPoint],
    pairs: &[Option<(f64, f64)>],
    tol: f64,
) -> Vec<Hopf> {
    let mut out = Vec::new();
    for i in 0..points.len().saturating_sub(1) {
        let (Some(a), Some(b)) = (pairs[i], pairs[i + 1]) else {
            continue;
        };
        if (a.0 < 0.0) == (b.0 < 0.0) {
            continue;
        }
        let (p, q) = (&points[i], &points[i + 1]);
        let secant = a.0 / (a.0 - b.0);
        let at = bisect(model, force, harmonics, (p, q), (a.0, b.0), tol);
        let (s, im) = at.unwrap_or((secant, a.1 + secant * (b.1 - a.1)));
        out.push(Hopf {
            f_hz: p.f_hz + s * (q.f_hz - p.f_hz),
            index: i,
            offset_hz: im / TAU,
            gains_stability: b.0 < 0.0,
        });
    }
    out
}

/// Bisection on the fraction `s ∈ [0, 1]` of the way from `p` to `q` for the real part of the
/// critical pair crossing zero; `(s, |Im λ|)` at the end, `None` when a trial state does not
/// converge or loses its complex pair.
fn bisect(
    model: &NumericModel,
    force: &[Complex64],
    harmonics: &[usize],
    (p, q): (&SweepPoint, &SweepPoint),
    (ra, _rb): (f64, f64),
    tol: f64,
) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0, 1.0);
    let mut im = 0.0;
    let settings = HbSettings {
        tol,
        ..HbSettings::default()
    };
    for _ in 0..60 {
        let s = 0.5 * (lo + hi);
        let f = p.f_hz + s * (q.f_hz - p.f_hz);
        let guess: Vec<Vec<Complex64>> = p
            .amplitudes
            .iter()
            .zip(&q.amplitudes)
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect())
            .collect();
        let (mut solver, _) = solver_at(model, force, harmonics, f).ok()?;
        let st = solver.solve_from(&guess, &settings);
        if !st.converged() {
            return None;
        }
        let point = SweepPoint {
            f_hz: f,
            amplitudes: st.amplitudes,
            stable: true,
        };
        let (re, i) = critical_pair(model, force, harmonics, &point).ok()??;
        im = i;
        if (re < 0.0) == (ra < 0.0) {
            lo = s;
        } else {
            hi = s;
        }
        if (hi - lo) * (q.f_hz - p.f_hz).abs() <= 1e-9 * f {
            break;
        }
    }
    Some((0.5 * (lo + hi), im))
}

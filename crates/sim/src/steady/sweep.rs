//! Single-tone frequency responses with pseudo-arclength continuation through folds, their
//! stability, the jumps of up- and down-sweeps, and backbone curves.
//!
//! The response to one tone `Re[F_n e^{iΩt}]` is periodic, so it is solved by harmonic balance
//! with the alternating frequency–time method on harmonics `h = 0..=H` of the tone (odd ones only
//! for a model with only odd-degree terms; DC included otherwise): the nonlinear forces are
//! evaluated at `N ≥ (d+1)H + 1` samples of one period (no aliasing for degree `d`) and
//! transformed back. Unknowns `X_{n,h}` (complex, DC real) follow DATA_FORMAT:
//! `q_n(t) = Σ_h Re[X_{n,h} e^{i h Ω t}]`.
//!
//! Stability: a fold of the branch changes the sign of the Jacobian's determinant, so points are
//! classified by that sign relative to the small-amplitude (linear, stable) end of the curve.
//! This detects the saddle-node instability of the middle branch between folds (Duffing-type
//! responses). A complex pair of slow-flow eigenvalues ([`crate::HbSolver::slow_flow_eigenvalues`]
//! at each point) with a positive real part makes a point unstable too, and where that real part
//! changes sign between two points the curve has a Hopf point ([`Hopf`], located by bisection):
//! a self-oscillation beside the drive starts or stops there.

use super::aft::Aft;
use super::hopf::{critical_pair, locate_hopf, Hopf};
use super::Step;
use crate::linalg::DenseLu;
use crate::{NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Settings of a single-tone sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSettings {
    /// Start and end of the swept range, Hz (the curve is followed through folds in between).
    pub f_start_hz: f64,
    /// End of the range, Hz.
    pub f_stop_hz: f64,
    /// Resolution of the curve: the arclength predictor advances the frequency by at most
    /// `(f_stop − f_start)/points` (the corrector may carry a step a few per cent further),
    /// so the curve gets about `points + 1` points or more; folds and steep flanks add more
    /// (at most `8·points`).
    pub points: usize,
    /// Highest harmonic of the tone kept (`H`).
    pub harmonics: usize,
    /// Newton tolerance on `max |R| / max |F|`.
    pub tol: f64,
}

impl Default for SweepSettings {
    fn default() -> Self {
        Self {
            f_start_hz: 0.0,
            f_stop_hz: 0.0,
            points: 500,
            harmonics: 3,
            tol: 1e-10,
        }
    }
}

/// One point of a response curve.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPoint {
    /// Drive frequency, Hz.
    pub f_hz: f64,
    /// `amplitudes[n][i]`: complex amplitude of mode `n` at harmonic `harmonics[i]`, m.
    pub amplitudes: Vec<Vec<Complex64>>,
    /// Whether the steady state is stable (see the module docs for the criterion).
    pub stable: bool,
}

/// A fold of the response curve (a turning point in frequency).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fold {
    /// Frequency of the fold, Hz.
    pub f_hz: f64,
    /// Index of the curve point nearest to it.
    pub index: usize,
    /// `true` where the frequency reaches a local maximum along the curve (an up-sweep jumps
    /// there), `false` at a local minimum (a down-sweep jumps there).
    pub upper: bool,
}

/// A response curve.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    /// Harmonics of the tone solved for.
    pub harmonics: Vec<usize>,
    /// Points in arclength order.
    pub points: Vec<SweepPoint>,
    /// Turning points in frequency.
    pub folds: Vec<Fold>,
    /// Hopf points: where a complex pair of slow-flow eigenvalues crosses `Re λ = 0`.
    pub hopf: Vec<Hopf>,
    /// Whether the curve reached the end of the range (false: stopped, e.g. Newton failed).
    pub complete: bool,
}

impl SweepResult {
    /// Frequencies where an up-sweep (increasing frequency) and a down-sweep jump.
    pub fn jumps(&self) -> (Vec<f64>, Vec<f64>) {
        let up = self
            .folds
            .iter()
            .filter(|f| f.upper)
            .map(|f| f.f_hz)
            .collect();
        let down = self
            .folds
            .iter()
            .filter(|f| !f.upper)
            .map(|f| f.f_hz)
            .collect();
        (up, down)
    }

    /// How far the harmonic truncation is from converged: over every point and mode, the
    /// largest amplitude of the highest harmonic kept relative to that mode's largest harmonic
    /// amplitude at the point, with the point's frequency (Hz) and the harmonic. 0 for a curve
    /// with one harmonic only. Above ~1e-3 the curve (and its stability verdicts) depend on the
    /// truncation: raise `harmonics`.
    pub fn truncation(&self) -> (f64, f64, usize) {
        let Some(&h_top) = self.harmonics.last() else {
            return (0.0, 0.0, 0);
        };
        if self.harmonics.len() < 2 {
            return (0.0, 0.0, h_top);
        }
        let mut worst = (0.0, 0.0, h_top);
        for p in &self.points {
            for row in &p.amplitudes {
                let peak = row.iter().map(|z| z.norm()).fold(0.0, f64::max);
                let top = row.last().map_or(0.0, |z| z.norm());
                if peak > 0.0 && top / peak > worst.0 {
                    worst = (top / peak, p.f_hz, h_top);
                }
            }
        }
        worst
    }
}

/// Most curve points a sweep may ask for.
pub const MAX_SWEEP_POINTS: usize = 100_000;
/// Highest harmonic a sweep may keep.
pub const MAX_SWEEP_HARMONICS: usize = 63;
/// Highest frequency a sweep may reach, Hz.
pub const MAX_SWEEP_HZ: f64 = 1e15;

/// Checks a sweep's inputs: each end of the range a positive finite frequency (each named in
/// its own message), finite forces, and sizes within [`MAX_SWEEP_POINTS`] and
/// [`MAX_SWEEP_HARMONICS`].
fn check_settings(
    model: &NumericModel,
    force: &[Complex64],
    settings: &SweepSettings,
) -> Result<(), SimError> {
    for (what, f) in [
        ("sweep start frequency (Hz)", settings.f_start_hz),
        ("sweep stop frequency (Hz)", settings.f_stop_hz),
    ] {
        if !(f.is_finite() && f > 0.0 && f <= MAX_SWEEP_HZ) {
            return Err(SimError::BadValue {
                what: what.into(),
                value: f,
                why: format!("a frequency must be positive and at most {MAX_SWEEP_HZ:e} Hz"),
            });
        }
    }
    for (n, z) in force.iter().enumerate() {
        if !(z.re.is_finite() && z.im.is_finite()) {
            let name = model.mode_names.get(n).map_or("?", |s| s.as_str());
            return Err(SimError::BadValue {
                what: format!("force on {name} (N/kg)"),
                value: if z.re.is_finite() { z.im } else { z.re },
                why: "a force must be a finite number".into(),
            });
        }
    }
    if !force.iter().any(|z| z.norm() > 0.0) {
        return Err(SimError::BadValue {
            what: "force (N/kg)".into(),
            value: 0.0,
            why: "every force is zero: the response is zero; give a non-zero force".into(),
        });
    }
    if settings.points == 0 || settings.points > MAX_SWEEP_POINTS {
        return Err(SimError::BadValue {
            what: "number of sweep points".into(),
            value: settings.points as f64,
            why: format!("give between 1 and {MAX_SWEEP_POINTS}"),
        });
    }
    if settings.harmonics == 0 || settings.harmonics > MAX_SWEEP_HARMONICS {
        return Err(SimError::BadValue {
            what: "highest harmonic".into(),
            value: settings.harmonics as f64,
            why: format!("give between 1 and {MAX_SWEEP_HARMONICS}"),
        });
    }
    if !(settings.tol.is_finite() && settings.tol > 0.0) {
        return Err(SimError::BadValue {
            what: "Newton tolerance".into(),
            value: settings.tol,
            why: "give a small positive number, e.g. 1e-10".into(),
        });
    }
    Ok(())
}

/// Computes the single-tone response curve to the force `force[n]` (complex, N/kg, on each
/// mode) over `[f_start, f_stop]` by pseudo-arclength continuation, with stability and folds.
pub fn sweep(
    model: &NumericModel,
    force: &[Complex64],
    settings: &SweepSettings,
) -> Result<SweepResult, SimError> {
    let nm = model.n_modes();
    if model.has_pump_terms() {
        return Err(SimError::PumpTerms {
            what: "the single-tone arclength sweep",
            terms: model.pump_term_names().join(", "),
            instead: "sweep a pumped resonator step by step, as a stepped-sine experiment does (a plan with one measurement per step, each with its `pumps_hz`, for `harmonid simulate`; or harmonid_sim::stepped_sweep, which carries each step's state to the next)",
        });
    }
    if force.len() != nm {
        return Err(SimError::Length {
            what: "the sweep's forces",
            found: force.len(),
            expected: nm,
            per: "one per mode".into(),
        });
    }
    let (f0, f1) = (settings.f_start_hz, settings.f_stop_hz);
    check_settings(model, force, settings)?;
    if f0 == f1 {
        return Err(SimError::BadValue {
            what: "sweep stop frequency (Hz)".into(),
            value: f1,
            why: "it equals the start; give distinct start and stop frequencies".into(),
        });
    }
    let mut arc = Arclength::start(model, force, settings)?;
    let max_points = settings.points.max(10) * 8;
    let mut points = Vec::new();
    let mut signs = Vec::new();
    let mut complete = false;
    loop {
        let (point, sign) = arc.here();
        points.push(point);
        signs.push(sign);
        if complete || points.len() >= max_points {
            break;
        }
        match arc.step() {
            Step::Advanced => {}
            Step::Reached => complete = true,
            Step::Fold { .. } | Step::Jump { .. } | Step::Stuck => break,
        }
    }
    // Stability: the sign at the start (small amplitude, off resonance, no fold passed) is the
    // sign without a real eigenvalue past zero; a complex pair growing makes a point unstable.
    let s0 = signs.first().copied().unwrap_or(1.0);
    let harm = arc.aft.harm.clone();
    let pairs: Vec<Option<(f64, f64)>> = points
        .iter()
        .map(|p| critical_pair(model, force, &harm, p).ok().flatten())
        .collect();
    let decay = (0..nm)
        .map(|n| 0.5 * model.gamma(n))
        .fold(f64::INFINITY, f64::min);
    for ((p, &s), pair) in points.iter_mut().zip(&signs).zip(&pairs) {
        p.stable = s == s0 && pair.is_none_or(|(re, _)| re < 1e-6 * decay);
    }
    let hopf = locate_hopf(model, force, &harm, &points, &pairs, settings.tol);
    let mut folds = Vec::new();
    for i in 1..points.len().saturating_sub(1) {
        let (a, b, c) = (points[i - 1].f_hz, points[i].f_hz, points[i + 1].f_hz);
        if (b - a) * (c - b) < 0.0 {
            folds.push(Fold {
                f_hz: b,
                index: i,
                // A local maximum of the frequency along the curve, whichever way it was
                // followed (`(b − a)·dir` swapped the two for a curve followed downwards).
                upper: b > a,
            });
        }
    }
    Ok(SweepResult {
        harmonics: harm,
        points,
        folds,
        hopf,
        complete,
    })
}

/// Pseudo-arclength continuation of the single-tone response in the scaled variables
/// `z = (u / a_s, (ω − ω₀)/ω_s)`: the tangent from `[J_u  J_ω] t = 0` (bordered by the last
/// tangent), a predictor along it, and Newton on the residual plus the arclength condition.
/// Folds in frequency are passed, not stopped at: the curve turns.
struct Arclength {
    aft: Aft,
    tol: f64,
    /// Amplitude and frequency scales, the largest force, the sweep's direction (±1) and end.
    a_s: f64,
    w_s: f64,
    fmax: f64,
    dir: f64,
    w_end: f64,
    /// The curve's current point.
    u: Vec<f64>,
    w: f64,
    /// Arclength step (scaled units), its nominal size, and the tangent of the last step.
    ds: f64,
    ds0: f64,
    tangent: Vec<f64>,
    prev_t: Vec<f64>,
    /// Largest frequency advance of a step, scaled (`1/points` of the span).
    df_max: f64,
    /// `prev_t` holds a tangent (after the first step).
    has_prev: bool,
    /// Buffers: residual, `∂R/∂u` (`nu × nu`), `∂R/∂ω`, the bordered system, corrector state.
    res: Vec<f64>,
    ju: Vec<f64>,
    jw: Vec<f64>,
    big: Vec<f64>,
    rhs: Vec<f64>,
    un: Vec<f64>,
    up: Vec<f64>,
    lu_u: DenseLu,
    lu_big: DenseLu,
}

impl Arclength {
    /// The linear response at the start frequency, corrected by Newton at that frequency.
    fn start(
        model: &NumericModel,
        force: &[Complex64],
        settings: &SweepSettings,
    ) -> Result<Self, SimError> {
        let nm = model.n_modes();
        let (f0, f1) = (settings.f_start_hz, settings.f_stop_hz);
        let aft = Aft::new(model, force, settings.harmonics);
        let nu = aft.n();
        let na = nu + 1;
        // Scales: amplitude from the largest linear resonant response, frequency from the span.
        let a_s = (0..nm)
            .map(|n| force[n].norm() * model.q_factor[n] / model.omega(n).powi(2))
            .fold(0.0, f64::max)
            .max(1e-300);
        let fmax = force
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max)
            .max(1e-300);
        // The arclength of the curve: frequency span + amplitude excursions (scaled units).
        let total_len_est = 1.0 + 4.0;
        let ds0 = total_len_est / settings.points.max(10) as f64;
        let mut arc = Self {
            aft,
            tol: settings.tol,
            a_s,
            w_s: TAU * (f1 - f0).abs(),
            fmax,
            dir: if f1 > f0 { 1.0 } else { -1.0 },
            w_end: TAU * f1,
            u: vec![0.0; nu],
            w: TAU * f0,
            ds: ds0,
            ds0,
            tangent: vec![0.0; na],
            prev_t: vec![0.0; na],
            has_prev: false,
            df_max: 1.0 / settings.points.max(1) as f64,
            res: vec![0.0; nu],
            ju: vec![0.0; nu * nu],
            jw: vec![0.0; nu],
            big: vec![0.0; na * na],
            rhs: vec![0.0; na],
            un: vec![0.0; nu],
            up: vec![0.0; nu],
            lu_u: DenseLu::dense(nu),
            lu_big: DenseLu::dense(na),
        };
        let nh = arc.aft.harm.len();
        let i1 = arc.aft.harm.iter().position(|&h| h == 1).unwrap_or(0);
        for n in 0..nm {
            let k = 2 * (n * nh + i1);
            let z = crate::linear_response(model.omega(n), model.gamma(n), f0, force[n]);
            arc.u[k] = z.re;
            arc.u[k + 1] = z.im;
        }
        for _ in 0..50 {
            let w = arc.w;
            arc.aft.eval(
                &arc.u,
                w,
                1.0,
                1.0,
                &mut arc.res,
                Some((&mut arc.ju, &mut arc.jw)),
            );
            let r = arc.res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / fmax;
            if r < settings.tol {
                return Ok(arc);
            }
            if !arc.lu_u.factor(&arc.ju) {
                break;
            }
            arc.res.iter_mut().for_each(|v| *v = -*v);
            arc.lu_u.solve(&mut arc.res);
            for (u, d) in arc.u.iter_mut().zip(&arc.res) {
                *u += d;
            }
        }
        Err(no_start(model, force, f0))
    }

    /// The current point (stability not yet set) and the sign of `det J_u` there (`0.0`:
    /// singular); leaves the Jacobian at the point in `ju`, `jw` for [`Arclength::step`].
    fn here(&mut self) -> (SweepPoint, f64) {
        let w = self.w;
        self.aft.eval(
            &self.u,
            w,
            1.0,
            1.0,
            &mut self.res,
            Some((&mut self.ju, &mut self.jw)),
        );
        let sign = if self.lu_u.factor(&self.ju) {
            self.lu_u.det_sign()
        } else {
            0.0
        };
        let nm = self.aft.n_modes();
        let nh = self.aft.harm.len();
        let u = &self.u;
        let amplitudes = (0..nm)
            .map(|n| {
                (0..nh)
                    .map(|i| Complex64::new(u[2 * (n * nh + i)], u[2 * (n * nh + i) + 1]))
                    .collect()
            })
            .collect();
        let point = SweepPoint {
            f_hz: w / TAU,
            amplitudes,
            stable: true,
        };
        (point, sign)
    }

    /// One arclength step from the current point (after [`Arclength::here`]): the tangent, then
    /// predictor and corrector, the step halved up to 12 times until Newton converges.
    /// [`Step::Reached`] when the new point lies at or past the end of the range;
    /// [`Step::Stuck`] when no step converges or the tangent is singular.
    fn step(&mut self) -> Step {
        let nu = self.u.len();
        let na = nu + 1;
        let last = self.has_prev.then_some(&self.prev_t[..]);
        border(
            &mut self.big,
            (&self.ju, &self.jw),
            (self.a_s, self.w_s),
            last,
        );
        self.rhs.iter_mut().for_each(|v| *v = 0.0);
        self.rhs[nu] = 1.0;
        if !self.lu_big.factor(&self.big) {
            return Step::Stuck;
        }
        self.lu_big.solve(&mut self.rhs);
        let nrm = self.rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
        for j in 0..na {
            self.tangent[j] = self.rhs[j] / nrm;
        }
        if !self.has_prev && self.tangent[nu] * self.dir < 0.0 {
            self.tangent.iter_mut().for_each(|v| *v = -*v);
        }
        let (a_s, w_s) = (self.a_s, self.w_s);
        // The frequency spacing never exceeds span/points (the resolution asked for).
        self.ds = self
            .ds
            .min(self.df_max / self.tangent[nu].abs().max(1e-300));
        for _attempt in 0..12 {
            let ds = self.ds;
            for i in 0..nu {
                self.un[i] = self.u[i] + ds * self.tangent[i] * a_s;
            }
            let mut wn = self.w + ds * self.tangent[nu] * w_s;
            self.up.copy_from_slice(&self.un);
            let wp = wn;
            if let Some(its) = self.correct(&mut wn, wp) {
                std::mem::swap(&mut self.u, &mut self.un);
                self.w = wn;
                if its <= 2 {
                    self.ds = (ds * 1.5).min(self.ds0 * 2.0);
                }
                self.prev_t.copy_from_slice(&self.tangent);
                self.has_prev = true;
                let past =
                    (self.dir > 0.0 && wn >= self.w_end) || (self.dir < 0.0 && wn <= self.w_end);
                return if past { Step::Reached } else { Step::Advanced };
            }
            self.ds = ds * 0.5;
        }
        Step::Stuck
    }

    /// Newton on the residual and the arclength condition from the predictor `(up, wp)` (in
    /// `un`, `wn`): the iterations it took, `None` when it did not converge in 10.
    fn correct(&mut self, wn: &mut f64, wp: f64) -> Option<usize> {
        let nu = self.u.len();
        let (a_s, w_s) = (self.a_s, self.w_s);
        for it in 0..10 {
            self.aft.eval(
                &self.un,
                *wn,
                1.0,
                1.0,
                &mut self.res,
                Some((&mut self.ju, &mut self.jw)),
            );
            let r = self.res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / self.fmax;
            let arc: f64 = (0..nu)
                .map(|i| (self.un[i] - self.up[i]) / a_s * self.tangent[i])
                .sum::<f64>()
                + (*wn - wp) / w_s * self.tangent[nu];
            if r < self.tol && arc.abs() < 1e-12 {
                return Some(it);
            }
            let last = Some(&self.tangent[..]);
            border(&mut self.big, (&self.ju, &self.jw), (a_s, w_s), last);
            for i in 0..nu {
                self.rhs[i] = -self.res[i];
            }
            self.rhs[nu] = -arc;
            if !self.lu_big.factor(&self.big) {
                return None;
            }
            self.lu_big.solve(&mut self.rhs);
            for i in 0..nu {
                self.un[i] += self.rhs[i] * a_s;
            }
            *wn += self.rhs[nu] * w_s;
            if !wn.is_finite() || *wn <= 0.0 {
                return None;
            }
        }
        None
    }
}

/// Why a sweep could not start at `f_hz`: [`SimError::NoSliding`] for a model with Coulomb
/// friction (a term with `sign` or `tanh`), naming the terms and, for a mode whose friction is
/// `μ sign(q̇)` alone, the describing function's threshold `4|μ|/π` against the force on it
/// (below it the mode sticks); else [`SimError::NoStart`].
fn no_start(model: &NumericModel, force: &[Complex64], f_hz: f64) -> SimError {
    let nm = model.n_modes();
    let jumps: Vec<_> = model
        .rough_terms()
        .iter()
        .filter(|t| t.has_jump())
        .collect();
    if jumps.is_empty() {
        return SimError::NoStart { f_hz };
    }
    let mut why: Vec<String> = Vec::new();
    for t in &jumps {
        let mode = &model.mode_names[t.eq];
        let own_sign = t.factors.is_empty()
            && matches!(t.nonsmooth[..], [(harmonid_model::NonSmooth::Sign(v), 1)] if v.index() == nm + t.eq);
        let f = force.get(t.eq).map_or(0.0, |z| z.norm());
        why.push(if own_sign {
            let limit = 4.0 * t.coef.abs() / std::f64::consts::PI;
            let verdict = if f <= limit { "sticks" } else { "should slide" };
            format!(
                "{} in the equation of {mode}: 4|μ|/π = {limit:.4e} N/kg against the force {f:.4e} N/kg on it (it {verdict})",
                t.name
            )
        } else {
            format!("{} in the equation of {mode}", t.name)
        });
    }
    SimError::NoSliding {
        f_hz,
        why: format!("friction {}", why.join(", ")),
    }
}

/// Fills the bordered matrix `[J_u a_s, J_ω ω_s; last]` (`last`: the previous tangent, or the
/// frequency direction at the first point), row-major `(nu + 1)²`.
fn border(
    big: &mut [f64],
    (ju, jw): (&[f64], &[f64]),
    (a_s, w_s): (f64, f64),
    last: Option<&[f64]>,
) {
    let nu = jw.len();
    let na = nu + 1;
    for i in 0..nu {
        for j in 0..nu {
            big[i * na + j] = ju[i * nu + j] * a_s;
        }
        big[i * na + nu] = jw[i] * w_s;
    }
    for j in 0..na {
        big[nu * na + j] = match last {
            Some(t) => t[j],
            None if j == nu => 1.0,
            None => 0.0,
        };
    }
}

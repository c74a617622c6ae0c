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
//! responses); it does not detect secondary (Neimark–Sacker) instabilities.

use crate::linalg::{lu_factor, lu_solve};
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
    /// Roughly how many points the curve gets (arclength steps).
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

/// Alternating frequency–time harmonic balance for one tone.
struct Aft {
    model: NumericModel,
    harm: Vec<usize>,
    nt: usize,
    cos: Vec<f64>,
    sin: Vec<f64>,
    /// Force on each mode at the fundamental (`[n]`).
    force: Vec<Complex64>,
    // Buffers.
    q: Vec<f64>,
    pows: Vec<f64>,
    fnl: Vec<f64>,
    fj: Vec<f64>,
    nl_t: Vec<f64>,
    jac_t: Vec<f64>,
}

impl Aft {
    fn new(model: &NumericModel, force: &[Complex64], hmax: usize) -> Self {
        let odd = model.terms().iter().all(|t| t.degree() % 2 == 1);
        let harm: Vec<usize> = (0..=hmax.max(1))
            .filter(|&h| if odd { h % 2 == 1 } else { true })
            .collect();
        let d = model.max_degree().max(1) as usize;
        let need = (d + 1) * hmax.max(1) + 1;
        let nt = need.next_power_of_two().max(16);
        let nh = harm.len();
        let mut cos = vec![0.0; nt * nh];
        let mut sin = vec![0.0; nt * nh];
        for j in 0..nt {
            for (i, &h) in harm.iter().enumerate() {
                let th = TAU * ((h * j) % nt) as f64 / nt as f64;
                cos[j * nh + i] = th.cos();
                sin[j * nh + i] = th.sin();
            }
        }
        let nm = model.n_modes();
        Self {
            model: model.clone(),
            harm,
            nt,
            cos,
            sin,
            force: force.to_vec(),
            q: vec![0.0; nm],
            pows: vec![0.0; model.pow_len()],
            fnl: vec![0.0; nm],
            fj: vec![0.0; nm * nm],
            nl_t: vec![0.0; nt * nm],
            jac_t: vec![0.0; nt * nm * nm],
        }
    }

    fn n(&self) -> usize {
        2 * self.model.n_modes() * self.harm.len()
    }

    /// Residual `res` (real, [2(n·H + i) + part]) at unknowns `u` and angular frequency `w`
    /// with drive scale `s`; if `jac` is given, also `∂R/∂u` (row-major n×n) and `∂R/∂w`.
    fn eval(
        &mut self,
        u: &[f64],
        w: f64,
        s: f64,
        damping: f64,
        res: &mut [f64],
        mut jac: Option<(&mut [f64], &mut [f64])>,
    ) {
        let nm = self.model.n_modes();
        let nh = self.harm.len();
        let nt = self.nt;
        // Time samples of q and the nonlinear forces.
        for j in 0..nt {
            for n in 0..nm {
                let mut v = 0.0;
                for i in 0..nh {
                    let k = 2 * (n * nh + i);
                    v += u[k] * self.cos[j * nh + i] - u[k + 1] * self.sin[j * nh + i];
                }
                self.q[n] = v;
            }
            self.model.forces(&self.q, &mut self.pows, &mut self.fnl);
            self.nl_t[j * nm..(j + 1) * nm].copy_from_slice(&self.fnl);
            if jac.is_some() {
                self.model
                    .force_jacobian(&self.q, &mut self.pows, &mut self.fj);
                self.jac_t[j * nm * nm..(j + 1) * nm * nm].copy_from_slice(&self.fj);
            }
        }
        let fmax = self.force.iter().map(|z| z.norm()).fold(0.0, f64::max) * s;
        let _ = fmax;
        for n in 0..nm {
            let (wn, g) = (self.model.omega(n), self.model.gamma(n) * damping);
            for (i, &h) in self.harm.iter().enumerate() {
                let k = 2 * (n * nh + i);
                let hw = h as f64 * w;
                let l = Complex64::new(wn * wn - hw * hw, hw * g);
                let x = Complex64::new(u[k], u[k + 1]);
                let mut r = l * x;
                if h == 1 {
                    r -= self.force[n] * s;
                }
                // DFT of the nonlinear force: (2/N) Σ f e^{-ihθ}; DC: (1/N) Σ f.
                let norm = if h == 0 {
                    1.0 / nt as f64
                } else {
                    2.0 / nt as f64
                };
                let mut acc = Complex64::new(0.0, 0.0);
                for j in 0..nt {
                    let f = self.nl_t[j * nm + n];
                    acc += Complex64::new(f * self.cos[j * nh + i], -f * self.sin[j * nh + i]);
                }
                r += acc * norm;
                res[k] = r.re;
                res[k + 1] = if h == 0 { u[k + 1] } else { r.im };
                if let Some((_, jw)) = jac.as_mut() {
                    let dl = Complex64::new(-2.0 * h as f64 * hw, h as f64 * g) * x;
                    jw[k] = dl.re;
                    jw[k + 1] = if h == 0 { 0.0 } else { dl.im };
                }
            }
        }
        if let Some((ju, _)) = jac {
            let nu = self.n();
            ju.iter_mut().for_each(|v| *v = 0.0);
            for n in 0..nm {
                let (wn, g) = (self.model.omega(n), self.model.gamma(n) * damping);
                for (i, &h) in self.harm.iter().enumerate() {
                    let row = 2 * (n * nh + i);
                    let hw = h as f64 * w;
                    let l = Complex64::new(wn * wn - hw * hw, hw * g);
                    if h == 0 {
                        ju[row * nu + row] = l.re;
                        ju[(row + 1) * nu + row + 1] = 1.0;
                    } else {
                        ju[row * nu + row] = l.re;
                        ju[row * nu + row + 1] = -l.im;
                        ju[(row + 1) * nu + row] = l.im;
                        ju[(row + 1) * nu + row + 1] = l.re;
                    }
                    let norm = if h == 0 {
                        1.0 / nt as f64
                    } else {
                        2.0 / nt as f64
                    };
                    for m in 0..nm {
                        for (i2, _) in self.harm.iter().enumerate() {
                            let col = 2 * (m * nh + i2);
                            // ∂q_m(t)/∂Re X = cos(h2 θ), ∂/∂Im X = −sin(h2 θ).
                            let mut a = Complex64::new(0.0, 0.0);
                            let mut b = Complex64::new(0.0, 0.0);
                            for j in 0..nt {
                                let d = self.jac_t[j * nm * nm + n * nm + m];
                                let e =
                                    Complex64::new(self.cos[j * nh + i], -self.sin[j * nh + i]) * d;
                                a += e * self.cos[j * nh + i2];
                                b -= e * self.sin[j * nh + i2];
                            }
                            a *= norm;
                            b *= norm;
                            ju[row * nu + col] += a.re;
                            ju[row * nu + col + 1] += b.re;
                            if h != 0 {
                                ju[(row + 1) * nu + col] += a.im;
                                ju[(row + 1) * nu + col + 1] += b.im;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Sign of the determinant from LU factors.
fn det_sign(lu: &[f64], n: usize, piv: &[usize]) -> f64 {
    let mut s = 1.0;
    for k in 0..n {
        if piv[k] != k {
            s = -s;
        }
        if lu[k * n + k] < 0.0 {
            s = -s;
        }
    }
    s
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
    let mut aft = Aft::new(model, force, settings.harmonics);
    let nu = aft.n();
    let na = nu + 1;
    // Scales: amplitude from the largest linear resonant response, frequency from the span.
    let a_s = (0..nm)
        .map(|n| force[n].norm() * model.q_factor[n] / model.omega(n).powi(2))
        .fold(0.0, f64::max)
        .max(1e-300);
    let w0 = TAU * f0;
    let w_s = TAU * (f1 - f0).abs();
    let dir = if f1 > f0 { 1.0 } else { -1.0 };
    let fmax = force
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
        .max(1e-300);
    let mut u = vec![0.0; nu];
    let mut res = vec![0.0; nu];
    let mut ju = vec![0.0; nu * nu];
    let mut jw = vec![0.0; nu];
    let mut big = vec![0.0; na * na];
    let mut piv = vec![0usize; na];
    let mut rhs = vec![0.0; na];
    // Start: linear response, then Newton at fixed frequency.
    for n in 0..nm {
        let i1 = aft.harm.iter().position(|&h| h == 1).unwrap_or(0);
        let k = 2 * (n * aft.harm.len() + i1);
        let z = crate::linear_response(model.omega(n), model.gamma(n), f0, force[n]);
        u[k] = z.re;
        u[k + 1] = z.im;
    }
    let mut w = w0;
    let mut ok = false;
    for _ in 0..50 {
        aft.eval(&u, w, 1.0, 1.0, &mut res, Some((&mut ju, &mut jw)));
        let r = res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / fmax;
        if r < settings.tol {
            ok = true;
            break;
        }
        let mut j2 = ju.clone();
        if !lu_factor(&mut j2, nu, &mut piv[..nu]) {
            break;
        }
        let mut d: Vec<f64> = res.iter().map(|v| -v).collect();
        lu_solve(&j2, nu, &piv[..nu], &mut d);
        for i in 0..nu {
            u[i] += d[i];
        }
    }
    if !ok {
        return Err(SimError::NoStart { f_hz: f0 });
    }
    // Scaled variables z = (u / a_s, (w − w0)/w_s); tangent from [J_u  J_w] t = 0.
    let mut tangent = vec![0.0; na];
    let mut points = Vec::new();
    let mut signs = Vec::new();
    let total_len_est = 1.0 + 4.0; // frequency span + amplitude excursions (in scaled units)
    let ds0 = total_len_est / settings.points.max(10) as f64;
    let mut ds = ds0;
    let max_points = settings.points.max(10) * 8;
    let mut prev_t: Option<Vec<f64>> = None;
    let mut complete = false;
    let record = |u: &[f64], w: f64, aft: &Aft| -> SweepPoint {
        let nh = aft.harm.len();
        let amplitudes = (0..nm)
            .map(|n| {
                (0..nh)
                    .map(|i| Complex64::new(u[2 * (n * nh + i)], u[2 * (n * nh + i) + 1]))
                    .collect()
            })
            .collect();
        SweepPoint {
            f_hz: w / TAU,
            amplitudes,
            stable: true,
        }
    };
    while points.len() < max_points {
        // Jacobian at the current point; tangent.
        aft.eval(&u, w, 1.0, 1.0, &mut res, Some((&mut ju, &mut jw)));
        // Bordered matrix [J_u a_s, J_w w_s; t_prev^T] for the tangent.
        for i in 0..nu {
            for j in 0..nu {
                big[i * na + j] = ju[i * nu + j] * a_s;
            }
            big[i * na + nu] = jw[i] * w_s;
        }
        let last: Vec<f64> = match &prev_t {
            Some(t) => t.clone(),
            None => {
                let mut e = vec![0.0; na];
                e[nu] = 1.0;
                e
            }
        };
        for j in 0..na {
            big[nu * na + j] = last[j];
        }
        // Determinant sign of J_u (stability) from a separate factorisation.
        let mut j2 = ju.clone();
        let sign = if lu_factor(&mut j2, nu, &mut piv[..nu]) {
            det_sign(&j2, nu, &piv[..nu])
        } else {
            0.0
        };
        signs.push(sign);
        points.push(record(&u, w, &aft));
        let fw = w / TAU;
        if points.len() > 1 && ((dir > 0.0 && fw >= f1) || (dir < 0.0 && fw <= f1)) {
            complete = true;
            break;
        }
        rhs.iter_mut().for_each(|v| *v = 0.0);
        rhs[nu] = 1.0;
        if !lu_factor(&mut big, na, &mut piv) {
            break;
        }
        lu_solve(&big, na, &piv, &mut rhs);
        let nrm = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
        for j in 0..na {
            tangent[j] = rhs[j] / nrm;
        }
        if prev_t.is_none() && tangent[nu] * dir < 0.0 {
            tangent.iter_mut().for_each(|v| *v = -*v);
        }
        // Predictor–corrector with step control.
        let mut accepted = false;
        for _attempt in 0..12 {
            let mut un: Vec<f64> = (0..nu).map(|i| u[i] + ds * tangent[i] * a_s).collect();
            let mut wn = w + ds * tangent[nu] * w_s;
            let (up, wp) = (un.clone(), wn);
            let mut conv = false;
            let mut its = 0;
            for it in 0..10 {
                its = it;
                aft.eval(&un, wn, 1.0, 1.0, &mut res, Some((&mut ju, &mut jw)));
                let r = res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / fmax;
                let arc: f64 = (0..nu)
                    .map(|i| (un[i] - up[i]) / a_s * tangent[i])
                    .sum::<f64>()
                    + (wn - wp) / w_s * tangent[nu];
                if r < settings.tol && arc.abs() < 1e-12 {
                    conv = true;
                    break;
                }
                for i in 0..nu {
                    for j in 0..nu {
                        big[i * na + j] = ju[i * nu + j] * a_s;
                    }
                    big[i * na + nu] = jw[i] * w_s;
                    rhs[i] = -res[i];
                }
                for j in 0..na {
                    big[nu * na + j] = tangent[j];
                }
                rhs[nu] = -arc;
                if !lu_factor(&mut big, na, &mut piv) {
                    break;
                }
                lu_solve(&big, na, &piv, &mut rhs);
                for i in 0..nu {
                    un[i] += rhs[i] * a_s;
                }
                wn += rhs[nu] * w_s;
                if !wn.is_finite() || wn <= 0.0 {
                    break;
                }
            }
            if conv {
                u = un;
                w = wn;
                accepted = true;
                if its <= 2 {
                    ds = (ds * 1.5).min(ds0 * 2.0);
                }
                break;
            }
            ds *= 0.5;
        }
        if !accepted {
            break;
        }
        prev_t = Some(tangent.clone());
    }
    // Stability: the sign at the start (small amplitude, off resonance, stable) is the stable sign.
    let s0 = signs.first().copied().unwrap_or(1.0);
    for (p, &s) in points.iter_mut().zip(&signs) {
        p.stable = s == s0;
    }
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
        harmonics: aft.harm.clone(),
        points,
        folds,
        complete,
    })
}

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
    let mut piv = vec![0usize; nu];
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
                &mut piv,
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
    piv: &mut [usize],
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
        if !lu_factor(ju, nu, piv) {
            return false;
        }
        for v in res.iter_mut() {
            *v = -*v;
        }
        lu_solve(ju, nu, piv, res);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{linear_response, Term};

    fn duffing(beta: f64) -> NumericModel {
        NumericModel::new(
            vec!["q".into()],
            vec![1000.0],
            vec![200.0],
            vec![Term {
                eq: 0,
                coef: beta,
                factors: vec![(0, 3)],
            }],
        )
        .expect("model")
    }

    #[test]
    fn vanishing_drive_sweep_is_linear_frf() {
        let m = duffing(1e12);
        let f = [Complex64::new(1e-6, 0.0)];
        let s = SweepSettings {
            f_start_hz: 980.0,
            f_stop_hz: 1020.0,
            points: 200,
            ..Default::default()
        };
        let r = sweep(&m, &f, &s).expect("sweep");
        assert!(r.complete);
        assert!(r.folds.is_empty());
        assert!(r.points.len() > 50);
        for p in &r.points {
            let want = linear_response(m.omega(0), m.gamma(0), p.f_hz, f[0]);
            let got = p.amplitudes[0][0];
            assert!(
                (got - want).norm() <= 1e-8 * want.norm(),
                "{} Hz: {got} vs {want}",
                p.f_hz
            );
            assert!(p.stable);
        }
    }

    #[test]
    fn folds_are_named_the_same_followed_up_or_down() {
        // The upper fold (a local maximum of f, where an up-sweep jumps) is the one at the
        // higher frequency, whichever way the curve is followed.
        let m = duffing(1e14);
        let f = [Complex64::new(20.0, 0.0)];
        for (from, to) in [(990.0, 1030.0), (1030.0, 990.0)] {
            let s = SweepSettings {
                f_start_hz: from,
                f_stop_hz: to,
                points: 2000,
                ..Default::default()
            };
            let r = sweep(&m, &f, &s).expect("sweep");
            assert_eq!(r.folds.len(), 2, "{from} → {to}: {:?}", r.folds);
            let up = r.folds.iter().find(|x| x.upper).expect("an upper fold");
            let low = r.folds.iter().find(|x| !x.upper).expect("a lower fold");
            assert!(up.f_hz > low.f_hz, "{from} → {to}: {:?}", r.folds);
        }
    }

    #[test]
    fn backbone_reaches_large_amplitudes_in_big_steps() {
        // One harmonic: the balance is exactly ω² = ω0² + (3/4)·β·a². Amplitudes far apart
        // (the frequency grows 4× and 14×) and out of order: each is reached by continuation
        // from the last converged state, none is lost after a hard one.
        let beta = 1e14;
        let m = duffing(beta);
        let w0 = m.omega(0);
        let amps = [1e-6, 3e-3, 1e-2, 2e-4];
        let bb = backbone(&m, 0, &amps, 1).expect("backbone");
        for (&a, f) in amps.iter().zip(&bb) {
            let f = f.expect("converged");
            let want = (w0 * w0 + 0.75 * beta * a * a).sqrt() / TAU;
            assert!((f - want).abs() < 1e-9 * want, "a = {a}: {f} vs {want}");
        }
    }

    #[test]
    fn duffing_backbone_matches_analytic() {
        let beta = 1e14;
        let m = duffing(beta);
        let w = m.omega(0);
        let amps = [1e-5, 3e-5, 1e-4];
        let bb = backbone(&m, 0, &amps, 5).expect("backbone");
        for (&a, f) in amps.iter().zip(&bb) {
            let f = f.expect("converged");
            let want = 1000.0 * (1.0 + 3.0 * beta * a * a / (8.0 * w * w));
            let shift = want - 1000.0;
            assert!((f - want).abs() < 0.02 * shift, "a = {a}: {f} vs {want}");
        }
    }

    #[test]
    fn duffing_sweep_folds_and_peak_follow_backbone() {
        let beta = 1e14;
        let m = duffing(beta);
        let w = m.omega(0);
        let f = [Complex64::new(20.0, 0.0)];
        let s = SweepSettings {
            f_start_hz: 990.0,
            f_stop_hz: 1030.0,
            points: 2000,
            ..Default::default()
        };
        let r = sweep(&m, &f, &s).expect("sweep");
        assert!(
            r.complete,
            "stopped at {:?}",
            r.points.last().map(|p| p.f_hz)
        );
        assert_eq!(r.folds.len(), 2, "{:?}", r.folds);
        let (up, down) = r.jumps();
        assert!(up[0] > down[0]);
        // Peak amplitude and its frequency against the backbone ω(1 + 3βa²/(8ω²)).
        let (i, p) = r
            .points
            .iter()
            .enumerate()
            .max_by(|a, b| {
                a.1.amplitudes[0][0]
                    .norm()
                    .total_cmp(&b.1.amplitudes[0][0].norm())
            })
            .expect("points");
        let a = p.amplitudes[0][0].norm();
        let want = 1000.0 * (1.0 + 3.0 * beta * a * a / (8.0 * w * w));
        assert!(
            (p.f_hz - want).abs() < 0.02 * (want - 1000.0),
            "peak at {} Hz, backbone {want}",
            p.f_hz
        );
        // The peak lies on the stable upper branch; the middle branch is unstable.
        assert!(r.points[i].stable);
        assert!(r.points.iter().any(|p| !p.stable));
        // Peak amplitude ≈ F Q / ω² (damping balances drive at the peak).
        let a_lin = 20.0 * 200.0 / (w * w);
        assert!((a - a_lin).abs() < 0.02 * a_lin, "{a} vs {a_lin}");
    }
}

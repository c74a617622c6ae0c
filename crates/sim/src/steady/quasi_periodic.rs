//! The quasi-periodic branch born at a Hopf point of a driven response curve: beside the drive
//! the resonator self-oscillates at a second base frequency `f₂`, an unknown, and the response
//! lives on the lattice `k₁ f_d + k₂ f₂` (the two-frequency harmonic balance of
//! [`super::torus`]).
//!
//! Continued in the drive frequency by pseudo-arclength from the Hopf point: there the branch
//! leaves the periodic state along the critical eigenvector, the null vector of the Hill matrix
//! at `f₂ = f_d ± offset` (the torus Jacobian's block of the lines `(k₁, 1)` about the periodic
//! state, complex-linear and decoupled from the other lines there), so the first step
//! moves the self-oscillation's amplitude alone (no normal form needed) and Newton finds the
//! drive frequency and `f₂` that sustain it. The free phase of the second angle is fixed by
//! `Im X = 0` on the self-oscillating mode's line `(0,1)`, whose column then holds `f₂`.
//!
//! Stability: the slow flow of the two-frequency balance ([`HbSolver::slow_flow_eigenvalues`]
//! on the branch's lines at their frequencies), less its zero eigenvalue (the free phase).

use super::hopf::solver_at;
use super::torus::Torus;
use super::{HbSettings, HbSolver, HbStatus, Hopf, Stability, SteadyState, SweepResult};
use crate::lattice::LINE_TOL_HZ;
use crate::linalg::DenseLu;
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Settings of a quasi-periodic branch.
#[derive(Debug, Clone, PartialEq)]
pub struct QuasiPeriodicSettings {
    /// Highest order `|k₁| + |k₂|` of the lines kept.
    pub harmonics: usize,
    /// Most points of the branch.
    pub points: usize,
    /// The drive frequency stays within this range, Hz (the sweep's).
    pub f_range_hz: (f64, f64),
    /// Newton tolerance on `max |R| / max |F|`.
    pub tol: f64,
}

impl QuasiPeriodicSettings {
    /// The settings for the branches from a sweep's Hopf points (`harmonid sweep
    /// --limit-cycles`, Python `sweep(limit_cycles=True)`): lattice order `|k₁| + |k₂|` the
    /// sweep's highest harmonic, at least 5 and at most 15; about a quarter of the sweep's
    /// `points` (20 to 1000); the drive within the sweep's range `f_range_hz`.
    pub fn for_sweep(r: &SweepResult, f_range_hz: (f64, f64), points: usize) -> Self {
        Self {
            harmonics: r.harmonics.iter().copied().max().unwrap_or(1).clamp(5, 15),
            points: (points / 4).clamp(20, 1000),
            f_range_hz,
            ..Self::default()
        }
    }
}

impl Default for QuasiPeriodicSettings {
    fn default() -> Self {
        Self {
            harmonics: 5,
            points: 200,
            f_range_hz: (0.0, f64::INFINITY),
            tol: 1e-10,
        }
    }
}

/// One point of a quasi-periodic branch.
#[derive(Debug, Clone, PartialEq)]
pub struct QuasiPeriodicPoint {
    /// Drive frequency, Hz.
    pub f_hz: f64,
    /// Second base frequency (the self-oscillation's line `(0,1)`), Hz.
    pub f2_hz: f64,
    /// `amplitudes[n][l]`: complex amplitude (m, peak) of mode `n` on line
    /// [`QuasiPeriodicBranch::lines`]`[l] = (k₁, k₂)`, at `k₁ f_hz + k₂ f2_hz`
    /// (`q_n = Σ_l Re[X e^{i2π(k₁f + k₂f₂)t}]`; a negative total is the conjugate line).
    pub amplitudes: Vec<Vec<Complex64>>,
    /// The slow flow's verdict without its free-phase eigenvalue; `None` where the growth
    /// rate is within the slow flow's own error of zero (`2|f₂ − f|/f` of the linear decay
    /// rate: it neglects `Ẍ`, whose weight grows with a line's offset from the drive; near
    /// the Hopf point the branch is that close to neutral) and where two lines coincide
    /// (locking within the lattice's order).
    pub stability: Option<Stability>,
}

/// Why a branch ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BranchEnd {
    /// The drive frequency left the range.
    Range,
    /// The most points were reached.
    Points,
    /// The self-oscillation died out again near this drive frequency (Hz): another Hopf point.
    Hopf {
        /// Drive frequency, Hz.
        f_hz: f64,
    },
    /// No step converged after this drive frequency (Hz): the torus breaks up or locks, or
    /// the lattice is too short.
    Stuck {
        /// Drive frequency, Hz.
        f_hz: f64,
    },
}

/// The sentence `sweep --limit-cycles` and Python's `sweep(limit_cycles=True)` give for where
/// a branch ends.
impl std::fmt::Display for BranchEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            BranchEnd::Range => write!(f, "the end of the range"),
            BranchEnd::Points => write!(f, "the most points"),
            BranchEnd::Hopf { f_hz } => write!(f, "another Hopf point near {f_hz:.6} Hz"),
            BranchEnd::Stuck { f_hz } => write!(
                f,
                "no step converged after {f_hz:.6} Hz (the torus locks or breaks up, or needs more --harmonics)"
            ),
        }
    }
}

/// A quasi-periodic branch from a Hopf point.
#[derive(Debug, Clone, PartialEq)]
pub struct QuasiPeriodicBranch {
    /// The Hopf point it starts at.
    pub hopf: Hopf,
    /// The self-oscillating mode (the phase of its line `(0,1)` is fixed at 0).
    pub mode: usize,
    /// Lines `(k₁, k₂)`: `k₁ f_d + k₂ f₂`.
    pub lines: Vec<(i64, i64)>,
    /// Points in order from the Hopf point (which is not one of them: its frequencies are the
    /// sweep's slow-flow estimate, the branch's own start is where the amplitude at `f₂`
    /// extrapolates to zero).
    pub points: Vec<QuasiPeriodicPoint>,
    /// Why it ended.
    pub end: BranchEnd,
}

impl QuasiPeriodicBranch {
    /// Index of line `(k₁, k₂)`, if kept.
    pub fn line(&self, k: (i64, i64)) -> Option<usize> {
        self.lines.iter().position(|&x| x == k)
    }

    /// Physical frequency (Hz, ≥ 0) and amplitude (m, the DATA_FORMAT convention) of mode `n`
    /// on line `l` at point `i`: the conjugate amplitude where `k₁f + k₂f₂ < 0`.
    pub fn physical(&self, i: usize, n: usize, l: usize) -> (f64, Complex64) {
        let p = &self.points[i];
        let (k1, k2) = self.lines[l];
        let f = k1 as f64 * p.f_hz + k2 as f64 * p.f2_hz;
        let x = p.amplitudes[n][l];
        if f < 0.0 {
            (-f, x.conj())
        } else {
            (f, x)
        }
    }
}

/// The quasi-periodic branch of `model`, driven by the single tone of force `force` (N/kg on
/// each mode), from the Hopf point `sweep.hopf[hopf]` of its response curve `sweep`
/// ([`crate::sweep`] with that force), continued in the drive frequency (see the module docs).
///
/// Errors: no such Hopf point, pump terms, the periodic state at the Hopf point or the first
/// step not converging, a harmonic order of 0 or above 31.
pub fn quasi_periodic_branch(
    model: &NumericModel,
    force: &[Complex64],
    sweep: &SweepResult,
    hopf: usize,
    settings: &QuasiPeriodicSettings,
) -> Result<QuasiPeriodicBranch, SimError> {
    let h = *sweep.hopf.get(hopf).ok_or_else(|| SimError::BadValue {
        what: "Hopf point index".into(),
        value: hopf as f64,
        why: format!("the sweep has {} Hopf points", sweep.hopf.len()),
    })?;
    let torus = Torus::new(model, force, settings.harmonics)?;
    let start = Start::at_hopf(model, force, sweep, &h, &torus, settings.tol)?;
    let mut c = Continuation::new(torus, force, &start, settings);
    let mut points = Vec::new();
    let (lo, hi) = (
        settings.f_range_hz.0.min(settings.f_range_hz.1),
        settings.f_range_hz.0.max(settings.f_range_hz.1),
    );
    let end = loop {
        if points.len() >= settings.points.max(1) {
            break BranchEnd::Points;
        }
        let f_before = c.wd / TAU;
        if !c.step() {
            break BranchEnd::Stuck { f_hz: f_before };
        }
        let f = c.wd / TAU;
        if !(lo..=hi).contains(&f) {
            break BranchEnd::Range;
        }
        if c.u[c.cp - 1] <= 0.0 {
            break BranchEnd::Hopf { f_hz: f };
        }
        let st = torus_stability(model, force, &c);
        points.push(c.point(st));
    };
    Ok(QuasiPeriodicBranch {
        hopf: h,
        mode: start.mode,
        lines: c.torus.idx.clone(),
        points,
        end,
    })
}

/// Where the branch starts: the periodic state at the Hopf point on the torus's lines, the
/// critical eigenvector there, and `f₂`.
struct Start {
    u: Vec<f64>,
    dir: Vec<f64>,
    wd: f64,
    w2: f64,
    mode: usize,
    /// Column of `Im X` of `mode` on line `(0,1)`: it holds `ω₂` in Newton.
    cp: usize,
}

impl Start {
    fn at_hopf(
        model: &NumericModel,
        force: &[Complex64],
        sweep: &SweepResult,
        h: &Hopf,
        torus: &Torus,
        tol: f64,
    ) -> Result<Self, SimError> {
        let fail = |why: String| SimError::NoLimitCycle {
            mode: model.mode_names.first().cloned().unwrap_or_default(),
            why,
        };
        let (p, q) = (&sweep.points[h.index], &sweep.points[h.index + 1]);
        let s = (h.f_hz - p.f_hz) / (q.f_hz - p.f_hz);
        let guess: Vec<Vec<Complex64>> = p
            .amplitudes
            .iter()
            .zip(&q.amplitudes)
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect())
            .collect();
        let (mut solver, _) = solver_at(model, force, &sweep.harmonics, h.f_hz)?;
        let state = solver.solve_from(
            &guess,
            &HbSettings {
                tol,
                ..HbSettings::default()
            },
        );
        if !state.converged() {
            return Err(fail(format!(
                "the driven state at the Hopf point {:.6} Hz did not converge ({})",
                h.f_hz, state.status
            )));
        }
        let nm = model.n_modes();
        let nl = torus.idx.len();
        let mut u = vec![0.0; torus.n()];
        for n in 0..nm {
            for (i, &hh) in sweep.harmonics.iter().enumerate() {
                if let Some(l) = torus.line((hh as i64, 0)) {
                    u[2 * (n * nl + l)] = state.amplitudes[n][i].re;
                    u[2 * (n * nl + l) + 1] = state.amplitudes[n][i].im;
                }
            }
        }
        // The critical eigenvector: on the side of the drive where its own line dominates.
        let l01 = torus
            .line((0, 1))
            .ok_or_else(|| fail("the lattice has no line (0,1)".into()))?;
        let mut best: Option<(f64, f64, Vec<Complex64>)> = None;
        for sign in [1.0, -1.0] {
            let fp = h.f_hz + sign * h.offset_hz;
            let Some(v) = critical_vector(torus, &u, (TAU * h.f_hz, TAU * fp)) else {
                continue;
            };
            let own = (0..nm).map(|n| v[n * nl + l01].norm()).fold(0.0, f64::max);
            if best.as_ref().is_none_or(|b| own > b.0) {
                best = Some((own, fp, v));
            }
        }
        let (_, fp, v) =
            best.ok_or_else(|| fail("the Hill matrix at the Hopf point is singular".into()))?;
        let mode = (0..nm)
            .max_by(|&a, &b| v[a * nl + l01].norm().total_cmp(&v[b * nl + l01].norm()))
            .unwrap_or(0);
        let rot = v[mode * nl + l01].conj() / v[mode * nl + l01].norm();
        let mut dir = vec![0.0; torus.n()];
        for (i, z) in v.iter().enumerate() {
            let z = z * rot;
            dir[2 * i] = z.re;
            dir[2 * i + 1] = z.im;
        }
        let cp = 2 * (mode * nl + l01) + 1;
        dir[cp] = 0.0;
        Ok(Self {
            u,
            dir,
            wd: TAU * h.f_hz,
            w2: TAU * fp,
            mode,
            cp,
        })
    }
}

/// Pseudo-arclength continuation in `z = (u/a_s with ω₂/ω_s in column cp, ω_d/ω_s)`.
struct Continuation {
    torus: Torus,
    force: Vec<Complex64>,
    u: Vec<f64>,
    wd: f64,
    w2: f64,
    cp: usize,
    a_s: f64,
    w_s: f64,
    fmax: f64,
    tol: f64,
    ds: f64,
    ds0: f64,
    /// The last point's `z` and the tangent (the critical eigenvector first, then secants).
    z_last: Vec<f64>,
    tangent: Vec<f64>,
    lu: DenseLu,
}

impl Continuation {
    fn new(
        torus: Torus,
        force: &[Complex64],
        start: &Start,
        settings: &QuasiPeriodicSettings,
    ) -> Self {
        let nu = torus.n();
        let a_s = start
            .u
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        let (lo, hi) = settings.f_range_hz;
        let span = if (hi - lo).is_finite() && hi != lo {
            (hi - lo).abs()
        } else {
            1e-3 * start.wd / TAU
        };
        let ds0 = 2.0 / settings.points.max(10) as f64;
        let mut c = Self {
            torus,
            force: force.to_vec(),
            u: start.u.clone(),
            wd: start.wd,
            w2: start.w2,
            cp: start.cp,
            a_s,
            w_s: TAU * span,
            fmax: force
                .iter()
                .map(|z| z.norm())
                .fold(0.0, f64::max)
                .max(1e-300),
            tol: settings.tol,
            ds: ds0,
            ds0,
            z_last: Vec::new(),
            tangent: Vec::new(),
            lu: DenseLu::dense(nu + 1),
        };
        c.z_last = c.pack(&c.u, c.w2, c.wd);
        let nrm = start.dir.iter().map(|v| v * v).sum::<f64>().sqrt() / a_s;
        let mut t: Vec<f64> = start.dir.iter().map(|v| v / a_s / nrm).collect();
        t.push(0.0);
        c.tangent = t;
        c
    }

    fn pack(&self, u: &[f64], w2: f64, wd: f64) -> Vec<f64> {
        let mut z: Vec<f64> = u.iter().map(|v| v / self.a_s).collect();
        z[self.cp] = w2 / self.w_s;
        z.push(wd / self.w_s);
        z
    }

    fn unpack(&self, z: &[f64]) -> (Vec<f64>, f64, f64) {
        let nu = z.len() - 1;
        let mut u: Vec<f64> = z[..nu].iter().map(|v| v * self.a_s).collect();
        u[self.cp] = 0.0;
        (u, z[self.cp] * self.w_s, z[nu] * self.w_s)
    }

    /// The current point.
    fn point(&self, stability: Option<Stability>) -> QuasiPeriodicPoint {
        let nm = self.force.len();
        let nl = self.torus.idx.len();
        QuasiPeriodicPoint {
            f_hz: self.wd / TAU,
            f2_hz: self.w2 / TAU,
            amplitudes: (0..nm)
                .map(|n| {
                    (0..nl)
                        .map(|l| {
                            Complex64::new(self.u[2 * (n * nl + l)], self.u[2 * (n * nl + l) + 1])
                        })
                        .collect()
                })
                .collect(),
            stability,
        }
    }

    /// One step along the tangent, halved up to 10 times until Newton converges; `false` when
    /// none does.
    fn step(&mut self) -> bool {
        for _ in 0..10 {
            let zp: Vec<f64> = self
                .z_last
                .iter()
                .zip(&self.tangent)
                .map(|(z, t)| z + self.ds * t)
                .collect();
            if let Some((z, its)) = self.correct(&zp) {
                let d: Vec<f64> = z.iter().zip(&self.z_last).map(|(a, b)| a - b).collect();
                let nrm = d.iter().map(|v| v * v).sum::<f64>().sqrt();
                if nrm > 0.0 {
                    self.tangent = d.iter().map(|v| v / nrm).collect();
                }
                let (u, w2, wd) = self.unpack(&z);
                (self.u, self.w2, self.wd) = (u, w2, wd);
                self.z_last = z;
                if its <= 3 {
                    self.ds = (self.ds * 1.5).min(2.0 * self.ds0);
                }
                return true;
            }
            self.ds *= 0.5;
        }
        false
    }

    /// Newton on the residual and `t·(z − zp) = 0` from the predictor `zp`: the point and the
    /// iterations it took, `None` when it did not converge in 12.
    fn correct(&mut self, zp: &[f64]) -> Option<(Vec<f64>, usize)> {
        let nu = self.torus.n();
        let na = nu + 1;
        let mut z = zp.to_vec();
        let mut res = vec![0.0; nu];
        let mut ju = vec![0.0; nu * nu];
        let mut big = vec![0.0; na * na];
        for it in 0..12 {
            let (u, w2, wd) = self.unpack(&z);
            if !(w2 > 0.0 && wd > 0.0) {
                return None;
            }
            self.torus.eval(&u, (wd, w2), &mut res, Some(&mut ju));
            let r = res.iter().fold(0.0f64, |m, v| m.max(v.abs())) / self.fmax;
            let arc: f64 = (0..na).map(|i| (z[i] - zp[i]) * self.tangent[i]).sum();
            if !r.is_finite() {
                return None;
            }
            if r < self.tol && arc.abs() < 1e-12 {
                return Some((z, it));
            }
            let dw2 = self.d_dw(&u, (wd, w2), 1);
            let dwd = self.d_dw(&u, (wd, w2), 0);
            for i in 0..nu {
                for j in 0..nu {
                    big[i * na + j] = ju[i * nu + j] * self.a_s;
                }
                big[i * na + self.cp] = dw2[i] * self.w_s;
                big[i * na + nu] = dwd[i] * self.w_s;
            }
            big[nu * na..].copy_from_slice(&self.tangent);
            if !self.lu.factor(&big) {
                return None;
            }
            let mut rhs: Vec<f64> = res.iter().map(|v| -v).collect();
            rhs.push(-arc);
            self.lu.solve(&mut rhs);
            z.iter_mut().zip(&rhs).for_each(|(a, d)| *a += d);
        }
        None
    }

    /// `∂R/∂ω` of base frequency `which` (0: the drive, 1: the second) by central differences
    /// (the residual is a polynomial of degree 2 in it plus the velocity terms').
    fn d_dw(&self, u: &[f64], w: (f64, f64), which: usize) -> Vec<f64> {
        let nu = u.len();
        let h = 1e-6 * if which == 0 { w.0 } else { w.1 };
        let shift = |s: f64| {
            if which == 0 {
                (w.0 + s, w.1)
            } else {
                (w.0, w.1 + s)
            }
        };
        let (mut a, mut b) = (vec![0.0; nu], vec![0.0; nu]);
        self.torus.eval(u, shift(h), &mut a, None);
        self.torus.eval(u, shift(-h), &mut b, None);
        a.iter().zip(&b).map(|(x, y)| (x - y) / (2.0 * h)).collect()
    }
}

/// The slow flow's verdict at the current point of `c`: the branch's lines at their
/// frequencies on an [`HbSolver`] lattice (conjugated where negative), its eigenvalues less
/// the one nearest zero (the free phase of the second angle). `None` when two lines coincide
/// or the solver cannot be set up.
fn torus_stability(
    model: &NumericModel,
    force: &[Complex64],
    c: &Continuation,
) -> Option<Stability> {
    let p = c.point(None);
    let nm = model.n_modes();
    let mut lines: Vec<(f64, usize, bool)> = c
        .torus
        .idx
        .iter()
        .enumerate()
        .map(|(l, &(k1, k2))| {
            let f = k1 as f64 * p.f_hz + k2 as f64 * p.f2_hz;
            (f.abs(), l, f < 0.0)
        })
        .collect();
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gap = lines
        .windows(2)
        .map(|w| w[1].0 - w[0].0)
        .fold(f64::INFINITY, f64::min);
    if gap < 1e3 * LINE_TOL_HZ {
        return None;
    }
    let lattice: Vec<f64> = lines.iter().map(|l| l.0).collect();
    let amplitudes: Vec<Vec<Complex64>> = (0..nm)
        .map(|n| {
            lines
                .iter()
                .map(|&(_, l, neg)| {
                    let x = p.amplitudes[n][l];
                    if neg {
                        x.conj()
                    } else {
                        x
                    }
                })
                .collect()
        })
        .collect();
    let drive = Excitation::new(vec![p.f_hz], force.iter().map(|&z| vec![z]).collect());
    let mut solver = HbSolver::with_lattice(model, &drive, lattice.clone()).ok()?;
    let state = SteadyState {
        lattice_hz: lattice,
        amplitudes,
        status: HbStatus::Converged { iterations: 0 },
        residual: 0.0,
        ramp_steps: 0,
        drive_jumps: Vec::new(),
        pump_sustained: false,
    };
    let mut eig = solver.slow_flow_eigenvalues(&state).ok()?;
    let zero = (0..eig.len()).min_by(|&a, &b| eig[a].norm().total_cmp(&eig[b].norm()))?;
    eig.remove(zero);
    let growth = eig.iter().map(|z| z.re).fold(f64::NEG_INFINITY, f64::max);
    let decay = (0..nm)
        .map(|n| 0.5 * model.gamma(n))
        .fold(f64::INFINITY, f64::min);
    if growth.abs() < 2.0 * (p.f2_hz - p.f_hz).abs() / p.f_hz * decay {
        return None;
    }
    Some(Stability {
        stable: growth < 1e-6 * decay,
        growth_rate: growth,
        linear_decay_rate: decay,
    })
}

/// The near-null vector of the torus Jacobian's block of the lines `(k₁, 1)` at the periodic
/// state `u` (only `k₂ = 0` lines set) and `(ω_d, ω₂)`, by inverse iteration: `[n·L + l]`,
/// complex, zero off that block, largest entry 1. About a periodic state that block does not
/// mix `X` with `X̄` (the coefficients vary with `θ₁` alone), so it is the Hill matrix of the
/// linear response at `f₂`; singular at a Hopf point. `None` when it cannot be factorised.
fn critical_vector(torus: &Torus, u: &[f64], w: (f64, f64)) -> Option<Vec<Complex64>> {
    let nu = torus.n();
    let mut res = vec![0.0; nu];
    let mut jac = vec![0.0; nu * nu];
    torus.eval(u, w, &mut res, Some(&mut jac));
    let nl = torus.idx.len();
    let cols: Vec<usize> = (0..nu)
        .filter(|&c| torus.idx[(c / 2) % nl].1 == 1)
        .collect();
    let nb = cols.len();
    let block: Vec<f64> = cols
        .iter()
        .flat_map(|&r| cols.iter().map(move |&c| (r, c)))
        .map(|(r, c)| jac[r * nu + c])
        .collect();
    let mut lu = DenseLu::dense(nb);
    if !lu.factor(&block) {
        return None;
    }
    let mut v: Vec<f64> = (0..nb).map(|i| (0.7 * i as f64 + 0.3).sin()).collect();
    for _ in 0..4 {
        lu.solve(&mut v);
        let top = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if !(top.is_finite() && top > 0.0) {
            return None;
        }
        v.iter_mut().for_each(|x| *x /= top);
    }
    let mut out = vec![Complex64::ZERO; nu / 2];
    for (i, &c) in cols.iter().enumerate().step_by(2) {
        out[c / 2] = Complex64::new(v[i], v[i + 1]);
    }
    Some(out)
}

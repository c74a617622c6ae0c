//! Time-domain simulation and lock-in emulation.
//!
//! The equations of motion are integrated with an integrating-factor (Lawson) Dormand–Prince
//! 5(4) scheme: the linear part of each mode, `q̈ + γ q̇ + ω² q`, is propagated exactly (no
//! numerical dispersion, which at `Q ~ 10⁵` would otherwise detune the resonance by more than
//! its linewidth), the linear steady-state response to the drive is subtracted analytically, and
//! only the nonlinear forces are integrated numerically. The step is fixed and aligned with the
//! lock-in's sampling so that a window holds an exact integer number of periods of every tone
//! and measured frequency (a multi-frequency lock-in tunes its frequencies the same way); the
//! embedded 4th-order solution gives a local error estimate per step, and the run is repeated
//! with a halved step when that estimate exceeds the tolerance.
//!
//! Demodulation is what a lock-in does: `X_k = (2/N) Σ_j x(t_j) e^{−i 2π f_k t_j}` over the `N`
//! samples of a window of length `T` with `f_k T` integer, `t` the absolute time of the drive
//! (DATA_FORMAT: `x(t) = Re[X e^{i2πft}]`, peak amplitude; a DC component is returned as the mean).

use crate::excitation::{common_grid, linear_response};
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

/// Settings of a time-domain run.
#[derive(Debug, Clone, PartialEq)]
pub struct TdSettings {
    /// Integration steps per period of the highest tone or measured frequency (≥ 4). When the
    /// error estimate exceeds `rtol` in a demodulated window the run is abandoned and restarted
    /// with the step refined by the factor the estimate asks for.
    pub steps_per_period: usize,
    /// Largest `steps_per_period` the automatic refinement may reach.
    pub max_steps_per_period: usize,
    /// Local error tolerance per step, relative to the linear response amplitude of each mode.
    /// The local errors oscillate and largely cancel over a lock-in window: on the two-mode
    /// nanostring the demodulated amplitudes' integration error is about `10 · rtol`.
    pub rtol: f64,
    /// Settling time before the first window, in units of the longest decay time `2Q/ω`;
    /// `None`: 12 from rest, 1 from a given state.
    pub settle_tau: Option<f64>,
    /// Relative change of the demodulated amplitudes between consecutive windows below which the
    /// response counts as settled (relative to the largest amplitude).
    pub settle_tol: f64,
    /// At most this many windows after the settling time before giving up ([`SimError::NotSettled`]).
    pub max_windows: usize,
    /// Lock-in window length in units of the shortest window with integer periods of every
    /// frequency (1 = that period).
    pub window_periods: usize,
    /// RMS of the white noise added to each sample of each measurement point's signal (same unit
    /// as `q`, m); 0 for none.
    pub noise_rms: f64,
    /// Seed of the noise generator.
    pub seed: u64,
    /// Lock-in samples per period of the highest frequency (aliasing guard; ≥ 4).
    pub samples_per_period: usize,
}

impl Default for TdSettings {
    fn default() -> Self {
        Self {
            steps_per_period: 32,
            max_steps_per_period: 512,
            rtol: 1e-9,
            settle_tau: None,
            settle_tol: 1e-6,
            max_windows: 64,
            window_periods: 1,
            noise_rms: 0.0,
            seed: 0,
            samples_per_period: 8,
        }
    }
}

/// Where the integration starts.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    /// From rest, `q = q̇ = 0` at `t = 0`.
    Rest,
    /// From displacements `q` (m) and velocities `v` (m/s) at `t = 0`, e.g. a harmonic-balance
    /// state ([`crate::SteadyState::state_at`]).
    State {
        /// Modal displacements.
        q: Vec<f64>,
        /// Modal velocities.
        v: Vec<f64>,
    },
}

/// Result of a lock-in emulation.
#[derive(Debug, Clone, PartialEq)]
pub struct LockinResult {
    /// Demodulated frequencies, Hz (as asked).
    pub freqs_hz: Vec<f64>,
    /// `modal[n][k]`: complex amplitude of mode `n` at `freqs_hz[k]` (m), noise-free.
    pub modal: Vec<Vec<Complex64>>,
    /// `points[p][k]`: complex amplitude of the signal `Σ_n shape[p][n] q_n + noise` at each
    /// frequency.
    pub points: Vec<Vec<Complex64>>,
    /// Window length, s.
    pub window_s: f64,
    /// Start of the last (reported) window, s.
    pub window_start_s: f64,
    /// Relative change of the modal amplitudes between the last two windows.
    pub settle_change: f64,
    /// Steps per period used.
    pub steps_per_period: usize,
    /// Lock-in samples per window (white noise of RMS `r` per sample gives a per-quadrature
    /// std of `r·sqrt(2/samples)` in each amplitude, [`crate::lockin_noise_sigma`]).
    pub samples: u64,
    /// Total integration steps.
    pub steps: u64,
    /// Largest local error estimate over the run, relative to the tolerance (≤ 1 when met).
    pub max_error_ratio: f64,
}

// Dormand–Prince 5(4) tableau.
const C: [f64; 7] = [0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0];
const A: [[f64; 6]; 7] = [
    [0.0; 6],
    [0.2, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];
const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// `e^{A s}` for `A = [[0, 1], [−ω², −γ]]` (underdamped, `γ < 2ω`), row-major.
fn propagator(omega: f64, gamma: f64, s: f64) -> [f64; 4] {
    let a = 0.5 * gamma;
    let wd = (omega * omega - a * a).sqrt();
    let (sn, cs) = (wd * s).sin_cos();
    let e = (-a * s).exp();
    [
        e * (cs + a / wd * sn),
        e * sn / wd,
        -e * omega * omega / wd * sn,
        e * (cs - a / wd * sn),
    ]
}

/// Per-mode precomputed propagators of one step size, flat (`nm` modes per row).
struct Lawson {
    /// `p[i·nm + n]`: `Φ_n(c_i h)`.
    p: Vec<[f64; 4]>,
    /// `acol[(i·7 + j)·nm + n]`: `h a_ij Φ_n((c_i − c_j) h) e₂` (zero for `j ≥ i`).
    acol: Vec<[f64; 2]>,
    /// `ecol[j·nm + n]`: `h e_j Φ_n((1 − c_j) h) e₂`.
    ecol: Vec<[f64; 2]>,
}

impl Lawson {
    fn new(model: &NumericModel, h: f64) -> Self {
        let nm = model.n_modes();
        let col = |n: usize, s: f64| {
            let p = propagator(model.omega(n), model.gamma(n), s);
            [p[1], p[3]]
        };
        let mut p = Vec::with_capacity(7 * nm);
        let mut acol = vec![[0.0; 2]; 49 * nm];
        let mut ecol = Vec::with_capacity(7 * nm);
        for i in 0..7 {
            for n in 0..nm {
                p.push(propagator(model.omega(n), model.gamma(n), C[i] * h));
                ecol.push({
                    let c = col(n, (1.0 - C[i]) * h);
                    [h * E[i] * c[0], h * E[i] * c[1]]
                });
            }
            for j in 0..i.min(6) {
                for n in 0..nm {
                    let c = col(n, (C[i] - C[j]) * h);
                    acol[(i * 7 + j) * nm + n] = [h * A[i][j] * c[0], h * A[i][j] * c[1]];
                }
            }
        }
        Self { p, acol, ecol }
    }
}

/// Simulates the model under `drive` and demodulates `measure_hz` like a multi-frequency
/// lock-in, for the modal coordinates and for each measurement point `shapes[p]` (signal
/// `Σ_n shapes[p][n] q_n`, plus white noise of RMS `settings.noise_rms` when nonzero).
///
/// The first demodulated window ends at the settling time (`settings.settle_tau` decay times
/// `2Q/ω`; windows need not start at multiples of their length, since any run of whole periods
/// of every frequency demodulates exactly); windows follow until two consecutive ones agree to
/// `settings.settle_tol`, and the last is reported (it starts at or after the settling time).
/// Errors: blow-up, not settling, no common period of the frequencies.
pub fn simulate_lockin(
    model: &NumericModel,
    drive: &Excitation,
    measure_hz: &[f64],
    shapes: &[Vec<f64>],
    start: &Start,
    settings: &TdSettings,
) -> Result<LockinResult, SimError> {
    if !(settings.rtol.is_finite() && settings.rtol > 0.0) {
        return Err(SimError::BadValue {
            what: "time-domain tolerance rtol".into(),
            value: settings.rtol,
            why: "it must be finite and > 0 (1e-9 gives about 1e-8 on the lock-in outputs)".into(),
        });
    }
    let mut s = settings.clone();
    loop {
        let refinable = s.steps_per_period < s.max_steps_per_period;
        match run(model, drive, measure_hz, shapes, start, &s, refinable)? {
            Run::Done(r) => return Ok(r),
            Run::TooCoarse { error_ratio } => {
                // Dormand–Prince 5(4): the local error scales as h⁵.
                let f = (1.25 * error_ratio).powf(0.2).max(1.25);
                s.steps_per_period =
                    ((s.steps_per_period as f64 * f).ceil() as usize).min(s.max_steps_per_period);
            }
        }
    }
}

/// How one run at a fixed step ended.
enum Run {
    Done(LockinResult),
    /// The error estimate exceeded the tolerance in a demodulated window (by this ratio so
    /// far); the run was abandoned for a finer step.
    TooCoarse {
        error_ratio: f64,
    },
}

fn run(
    model: &NumericModel,
    drive: &Excitation,
    measure_hz: &[f64],
    shapes: &[Vec<f64>],
    start: &Start,
    st: &TdSettings,
    abandon_when_coarse: bool,
) -> Result<Run, SimError> {
    check_inputs(model, drive, measure_hz, shapes, start)?;
    let nm = model.n_modes();
    let clock = Clock::new(drive, measure_hz, st)?;
    let h = clock.h;
    let lin = LinearDrive::new(model, drive);
    let mut stepper = Stepper::new(model, &lin, &clock, start);
    let mut lockin = LockIn::new(&clock, nm, shapes.len(), st)?;

    let tau_max = (0..nm).map(|n| 2.0 / model.gamma(n)).fold(0.0, f64::max);
    let settle_tau = st.settle_tau.unwrap_or(match start {
        Start::Rest => 12.0,
        Start::State { .. } => 1.0,
    });
    // Windows need not start at multiples of the window length: every frequency has whole
    // periods in any `n_win` consecutive steps. The first demodulated window ends at the
    // settling time (it is compared with the next one), after a pre-roll of `pre` steps.
    let settle_steps = (settle_tau * tau_max / h).ceil().max(0.0) as u64;
    let pre = settle_steps.saturating_sub(clock.n_win);
    let err_tol: Vec<f64> = lin.scale.iter().map(|&s| st.rtol * s).collect();

    let mut step: u64 = 0;
    let mut max_err: f64 = 0.0;
    let mut win: u64 = 0;
    let mut demod_windows: usize = 0;
    let mut prev_modal: Option<Vec<Complex64>> = None;
    let mut settle_change = f64::INFINITY;
    loop {
        let (demod, len) = if win == 0 && pre > 0 {
            (false, pre)
        } else {
            (true, clock.n_win)
        };
        if demod {
            lockin.start_window(&clock, step);
        }
        for j in 0..len {
            let err = stepper.stages(model, &lin, &err_tol);
            if err > max_err {
                max_err = err;
            }
            if demod && abandon_when_coarse && max_err > 1.0 {
                return Ok(Run::TooCoarse {
                    error_ratio: max_err,
                });
            }
            step += 1;
            let n_in = step % clock.n_win;
            stepper.commit(&clock, n_in);
            stepper.check_blow_up(&lin.scale, step as f64 * h)?;
            if demod && (j + 1) % clock.m_dec == 0 {
                // Sample at the end of this step: t = (win * n_win + j + 1) h; the phasor zk
                // refers to that time.
                lin.q_total(&stepper.z, &stepper.u, &mut stepper.qtot);
                lockin.sample(&clock, (j + 1) / clock.m_dec, n_in, &stepper.qtot[..nm]);
            }
        }
        win += 1;
        if demod {
            let cur = lockin.modal(measure_hz, clock.n_samp);
            let biggest = cur.iter().map(|z| z.norm()).fold(0.0, f64::max).max(1e-300);
            if let Some(prev) = &prev_modal {
                settle_change = cur
                    .iter()
                    .zip(prev)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max)
                    / biggest;
            }
            let start_step = step - clock.n_win;
            let done = start_step >= settle_steps && settle_change <= st.settle_tol;
            if start_step >= settle_steps {
                demod_windows += 1;
            }
            if done {
                let nk = measure_hz.len();
                return Ok(Run::Done(LockinResult {
                    freqs_hz: measure_hz.to_vec(),
                    modal: (0..nm)
                        .map(|n| cur[n * nk..(n + 1) * nk].to_vec())
                        .collect(),
                    points: lockin.points(&cur, shapes, measure_hz, clock.n_samp),
                    window_s: clock.window_s,
                    window_start_s: start_step as f64 * h,
                    settle_change,
                    steps_per_period: st.steps_per_period,
                    samples: clock.n_samp,
                    steps: step,
                    max_error_ratio: max_err,
                }));
            }
            if demod_windows > st.max_windows {
                return Err(SimError::NotSettled {
                    t_s: step as f64 * h,
                    change: settle_change,
                    tol: st.settle_tol,
                });
            }
            prev_modal = Some(cur);
            lockin.clear();
        }
        // Max error counts only over the windows that matter (after the first transient).
        if !demod {
            max_err = 0.0;
        }
    }
}

/// Checks what a run cannot repair: the drive's shapes, one mode-shape entry per mode,
/// finite measured frequencies ≥ 0, a finite start state of one entry per mode.
fn check_inputs(
    model: &NumericModel,
    drive: &Excitation,
    measure_hz: &[f64],
    shapes: &[Vec<f64>],
    start: &Start,
) -> Result<(), SimError> {
    let nm = model.n_modes();
    drive.check(nm)?;
    if let Some(s) = shapes.iter().find(|s| s.len() != nm) {
        return Err(SimError::Length {
            what: "a point's mode shape",
            found: s.len(),
            expected: nm,
            per: "one per mode".into(),
        });
    }
    if let Some(&f) = measure_hz.iter().find(|f| !(f.is_finite() && **f >= 0.0)) {
        return Err(SimError::BadValue {
            what: "a measured frequency (Hz)".into(),
            value: f,
            why: "measured frequencies must be finite and ≥ 0".into(),
        });
    }
    if let Start::State { q, v } = start {
        if q.len() != nm || v.len() != nm {
            return Err(SimError::Length {
                what: "the start state's q and v",
                found: q.len().min(v.len()),
                expected: nm,
                per: "one each per mode".into(),
            });
        }
        if let Some(&x) = q.iter().chain(v).find(|x| !x.is_finite()) {
            return Err(SimError::BadValue {
                what: "the start state".into(),
                value: x,
                why: "its q and v must be finite".into(),
            });
        }
    }
    Ok(())
}

/// The run's time base: a lock-in window holding whole periods of every tone and measured
/// frequency, the step, and exact phasors from integer cycle counts per window.
struct Clock {
    /// Window length, s.
    window_s: f64,
    /// Lock-in samples per window, steps per sample, steps per window.
    n_samp: u64,
    m_dec: u64,
    n_win: u64,
    /// Integration step, s.
    h: f64,
    /// Cycles per window of each tone and each measured frequency.
    tone_cyc: Vec<u64>,
    meas_cyc: Vec<u64>,
}

impl Clock {
    fn new(drive: &Excitation, measure_hz: &[f64], st: &TdSettings) -> Result<Self, SimError> {
        // Window: integer periods of every tone and measured frequency.
        let max_window_s = 100.0;
        let tones = all_tones_hz(drive);
        let all: Vec<f64> = tones
            .iter()
            .chain(measure_hz.iter().filter(|&&f| f > 0.0))
            .copied()
            .collect();
        let grid = common_grid(&all, 1e-7, 1.0 / max_window_s).ok_or(SimError::NoCommonPeriod {
            max_s: max_window_s,
        })?;
        let window_s = st.window_periods.max(1) as f64 / grid;
        // The linear part is exact, so the step only has to resolve the response's
        // frequencies (combinations of the tones, which the measured frequencies cover), not
        // every mode's.
        let f_hi = all.iter().copied().fold(0.0, f64::max);
        let spp = st.steps_per_period.max(4);
        let m_dec = (spp / st.samples_per_period.max(4)).max(1);
        let n_samp = ((window_s * f_hi * spp as f64 / m_dec as f64).ceil() as u64).max(16);
        let n_win = n_samp * m_dec as u64;
        let cyc = |f: f64| (f * window_s).round() as u64;
        Ok(Self {
            window_s,
            n_samp,
            m_dec: m_dec as u64,
            n_win,
            h: window_s / n_win as f64,
            tone_cyc: tones.iter().map(|&f| cyc(f)).collect(),
            meas_cyc: measure_hz.iter().map(|&f| cyc(f)).collect(),
        })
    }

    /// `e^{i 2π c n / n_win}`: the phase after `n` steps of a frequency of `c` cycles per
    /// window, exact (integer arithmetic modulo the window).
    fn phasor(&self, c: u64, n: u64) -> Complex64 {
        let ph = ((c as u128 * n as u128) % self.n_win as u128) as f64 / self.n_win as f64;
        let (s, c) = (TAU * ph).sin_cos();
        Complex64::new(c, s)
    }
}

/// Every tone the integrator keeps a phasor of: the drive tones, then the pump tones.
fn all_tones_hz(drive: &Excitation) -> Vec<f64> {
    drive
        .tones_hz
        .iter()
        .copied()
        .chain(drive.pumps.iter().map(|p| p.hz))
        .collect()
}

/// The drive's linear steady-state response, which the integrator leaves out: it propagates
/// only the deviation `w = q − q_lin`, driven by the nonlinear forces. Pump tones are tones
/// with no force (their phasors give the pump signal).
struct LinearDrive {
    nd: usize,
    /// Complex amplitude of each pump tone; its phasor is tone `nd − pump.len() + k`.
    pump: Vec<Complex64>,
    /// `y[n·nd + d]`: linear response of mode `n` to tone `d`.
    y: Vec<Complex64>,
    /// Angular frequencies of the tones.
    wdr: Vec<f64>,
    /// Amplitude scale of each mode (its linear response, at least 1e-3 of the largest): the
    /// error tolerance and the blow-up check are relative to it.
    scale: Vec<f64>,
}

impl LinearDrive {
    fn new(model: &NumericModel, drive: &Excitation) -> Self {
        let nm = model.n_modes();
        let tones = all_tones_hz(drive);
        let (nd, n_drive) = (tones.len(), drive.tones_hz.len());
        let y: Vec<Complex64> = (0..nm)
            .flat_map(|n| {
                (0..nd).map(move |d| {
                    if d < n_drive {
                        linear_response(
                            model.omega(n),
                            model.gamma(n),
                            drive.tones_hz[d],
                            drive.force[n][d],
                        )
                    } else {
                        Complex64::new(0.0, 0.0)
                    }
                })
            })
            .collect();
        let y_scale: Vec<f64> = (0..nm)
            .map(|n| {
                y[n * nd..(n + 1) * nd]
                    .iter()
                    .map(|z| z.norm())
                    .sum::<f64>()
            })
            .collect();
        let all_scale = y_scale
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        Self {
            nd,
            pump: drive.pumps.iter().map(|p| p.amplitude).collect(),
            scale: y_scale.iter().map(|&s| s.max(1e-3 * all_scale)).collect(),
            y,
            wdr: tones.iter().map(|&f| TAU * f).collect(),
        }
    }

    /// Linear displacement and velocity of mode `n` at tone phasors `z`.
    fn at(&self, z: &[Complex64], n: usize) -> (f64, f64) {
        let mut q = 0.0;
        let mut v = 0.0;
        for d in 0..self.nd {
            let a = self.y[n * self.nd + d] * z[d];
            q += a.re;
            v -= self.wdr[d] * a.im;
        }
        (q, v)
    }

    /// Total displacements into `qtot`: the linear response at tone phasors `t_z` plus the
    /// deviations `us`; then, when `qtot` has room (a model with velocity terms), the total
    /// velocities, and the pump signal after them (a model with pump terms).
    fn q_total(&self, t_z: &[Complex64], us: &[[f64; 2]], qtot: &mut [f64]) {
        let nm = us.len();
        if let Some(p) = qtot.get_mut(2 * nm) {
            let first = self.nd - self.pump.len();
            *p = self
                .pump
                .iter()
                .zip(&t_z[first..])
                .map(|(a, b)| a.re * b.re - a.im * b.im)
                .sum();
        }
        let (q_part, v_part) = qtot.split_at_mut(nm);
        let mut k = 0;
        for (q, un) in q_part.iter_mut().zip(us) {
            let mut ql = un[0];
            for b in t_z {
                let a = self.y[k];
                ql += a.re * b.re - a.im * b.im;
                k += 1;
            }
            *q = ql;
        }
        for (n, (v, un)) in v_part.iter_mut().take(nm).zip(us).enumerate() {
            let mut vl = un[1];
            for (d, b) in t_z.iter().enumerate() {
                let a = self.y[n * self.nd + d];
                vl -= self.wdr[d] * (a.re * b.im + a.im * b.re);
            }
            *v = vl;
        }
    }
}

/// The Lawson Dormand–Prince stepper: the deviation `u[n] = (w, ẇ)`, the tone phasors `z` at
/// the current step, the stage forces (first same as last), and scratch.
struct Stepper {
    lw: Lawson,
    /// Stage rotations `e^{i ω_d c_i h}`, `[i·nd + d]`, and the one-step rotation of each tone.
    rot: Vec<Complex64>,
    zstep: Vec<Complex64>,
    u: Vec<[f64; 2]>,
    z: Vec<Complex64>,
    /// Stage forces `g[j·nm + n]`.
    g: Vec<f64>,
    ust: Vec<[f64; 2]>,
    zst: Vec<Complex64>,
    qtot: Vec<f64>,
    pows: Vec<f64>,
}

impl Stepper {
    fn new(model: &NumericModel, lin: &LinearDrive, clock: &Clock, start: &Start) -> Self {
        let nm = model.n_modes();
        let h = clock.h;
        let rot = (0..7)
            .flat_map(|i| {
                lin.wdr
                    .iter()
                    .map(move |&w| Complex64::from_polar(1.0, w * C[i] * h))
            })
            .collect();
        let z: Vec<Complex64> = clock.tone_cyc.iter().map(|&c| clock.phasor(c, 0)).collect();
        let mut u = vec![[0.0f64; 2]; nm];
        for n in 0..nm {
            let (ql, vl) = lin.at(&z, n);
            let (q0, v0) = match start {
                Start::Rest => (0.0, 0.0),
                Start::State { q, v } => (q[n], v[n]),
            };
            u[n] = [q0 - ql, v0 - vl];
        }
        let mut stepper = Self {
            lw: Lawson::new(model, h),
            rot,
            zstep: clock.tone_cyc.iter().map(|&c| clock.phasor(c, 1)).collect(),
            u,
            zst: vec![Complex64::new(0.0, 0.0); z.len()],
            z,
            g: vec![0.0f64; 7 * nm],
            ust: vec![[0.0f64; 2]; nm],
            // The displacements, then the velocities when a term holds one.
            qtot: vec![0.0f64; model.n_vars()],
            pows: vec![0.0f64; model.pow_len()],
        };
        let Self {
            z,
            u,
            qtot,
            pows,
            g,
            ..
        } = &mut stepper;
        stage_forces(model, lin, z, u, qtot, pows, &mut g[..nm]);
        stepper
    }

    /// Stages 1..6 of the next step (stage 0 is the last step's stage 6) into `g` and the
    /// step's end state into `ust`; returns the largest local error estimate of the step
    /// relative to `err_tol` (per mode).
    fn stages(&mut self, model: &NumericModel, lin: &LinearDrive, err_tol: &[f64]) -> f64 {
        let nm = self.u.len();
        let nd = self.z.len();
        for i in 1..7 {
            let (done, rest) = self.g.split_at_mut(i * nm);
            let p = &self.lw.p[i * nm..(i + 1) * nm];
            for (n, (us, un)) in self.ust.iter_mut().zip(&self.u).enumerate() {
                let pn = &p[n];
                let mut a = pn[0] * un[0] + pn[1] * un[1];
                let mut b = pn[2] * un[0] + pn[3] * un[1];
                for jj in 0..i {
                    let c = &self.lw.acol[(i * 7 + jj) * nm + n];
                    let gj = done[jj * nm + n];
                    a += c[0] * gj;
                    b += c[1] * gj;
                }
                *us = [a, b];
            }
            let rot = &self.rot[i * nd..(i + 1) * nd];
            for ((zs, zd), r) in self.zst.iter_mut().zip(&self.z).zip(rot) {
                *zs = zd * r;
            }
            let out = &mut rest[..nm];
            stage_forces(
                model,
                lin,
                &self.zst,
                &self.ust,
                &mut self.qtot,
                &mut self.pows,
                out,
            );
        }
        let mut max_err: f64 = 0.0;
        for n in 0..nm {
            let mut e0 = 0.0;
            for jj in 0..7 {
                e0 += self.lw.ecol[jj * nm + n][0] * self.g[jj * nm + n];
            }
            let r = e0.abs() / err_tol[n];
            if r > max_err {
                max_err = r;
            }
        }
        max_err
    }

    /// Takes the step computed by [`Stepper::stages`] and moves the tone phasors to step
    /// `n_in` of the window (recomputed exactly every 256 steps, rotated in between).
    fn commit(&mut self, clock: &Clock, n_in: u64) {
        let nm = self.u.len();
        self.u.copy_from_slice(&self.ust);
        self.g.copy_within(6 * nm..7 * nm, 0);
        if n_in.is_multiple_of(256) {
            for (z, &c) in self.z.iter_mut().zip(&clock.tone_cyc) {
                *z = clock.phasor(c, n_in);
            }
        } else {
            for (z, r) in self.z.iter_mut().zip(&self.zstep) {
                *z *= r;
            }
        }
    }

    /// Blow-up check on the total displacement of the last stage (the step's end).
    fn check_blow_up(&self, scale: &[f64], t_s: f64) -> Result<(), SimError> {
        let blow = 1e3;
        for (&q, &s) in self.qtot.iter().zip(scale) {
            if !q.is_finite() || q.abs() > blow * s.max(1e-30) * 1e3 {
                return Err(SimError::BlowUp {
                    t_s,
                    amplitude: q.abs(),
                    scale: s,
                });
            }
        }
        Ok(())
    }
}

/// The nonlinear forces, negated (they enter the right-hand side), at the total displacement
/// of tone phasors `t_z` and deviations `us`.
fn stage_forces(
    model: &NumericModel,
    lin: &LinearDrive,
    t_z: &[Complex64],
    us: &[[f64; 2]],
    qtot: &mut [f64],
    pows: &mut [f64],
    out: &mut [f64],
) {
    lin.q_total(t_z, us, qtot);
    model.forces(qtot, pows, out);
    out.iter_mut().for_each(|v| *v = -*v);
}

/// The multi-frequency lock-in: the phasors `e^{−i2πf_k t}` of the measured frequencies,
/// the sums over a window of the modal signals and of each point's noise, the noise source.
struct LockIn {
    zk: Vec<Complex64>,
    /// Rotation of each `zk` over one sample.
    rot_k: Vec<Complex64>,
    /// `acc_modal[n·nk + k]`, `acc_point[p·nk + k]`.
    acc_modal: Vec<Complex64>,
    acc_point: Vec<Complex64>,
    /// Measurement points.
    np: usize,
    noise: Option<Normal<f64>>,
    rng: rand_chacha::ChaCha8Rng,
}

impl LockIn {
    fn new(clock: &Clock, nm: usize, np: usize, st: &TdSettings) -> Result<Self, SimError> {
        let nk = clock.meas_cyc.len();
        let noise = if st.noise_rms > 0.0 {
            Some(
                Normal::new(0.0, st.noise_rms).map_err(|_| SimError::BadValue {
                    what: "noise RMS".into(),
                    value: st.noise_rms,
                    why: "it must be finite and ≥ 0".into(),
                })?,
            )
        } else {
            None
        };
        Ok(Self {
            zk: clock
                .meas_cyc
                .iter()
                .map(|&c| clock.phasor(c, 0).conj())
                .collect(),
            rot_k: clock
                .meas_cyc
                .iter()
                .map(|&c| clock.phasor(c, clock.m_dec).conj())
                .collect(),
            acc_modal: vec![Complex64::new(0.0, 0.0); nm * nk],
            acc_point: vec![Complex64::new(0.0, 0.0); np * nk],
            np,
            noise,
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(st.seed),
        })
    }

    /// Phasors for a window starting after `step` steps.
    fn start_window(&mut self, clock: &Clock, step: u64) {
        for (z, &c) in self.zk.iter_mut().zip(&clock.meas_cyc) {
            *z = clock.phasor(c, step % clock.n_win).conj();
        }
    }

    /// Adds sample `sidx` of the window (taken at step `n_in` of it) of the modal
    /// displacements `q`, and a noise sample per point.
    fn sample(&mut self, clock: &Clock, sidx: u64, n_in: u64, q: &[f64]) {
        let nk = self.zk.len();
        if sidx.is_multiple_of(256) {
            for (z, &c) in self.zk.iter_mut().zip(&clock.meas_cyc) {
                *z = clock.phasor(c, n_in).conj();
            }
        } else {
            for k in 0..nk {
                self.zk[k] *= self.rot_k[k];
            }
        }
        for (n, &x) in q.iter().enumerate() {
            for k in 0..nk {
                self.acc_modal[n * nk + k] += self.zk[k] * x;
            }
        }
        // The points' signals are linear in the modal ones: only their noise needs its own
        // demodulation (the rest is combined once per window).
        if let Some(nz) = &self.noise {
            for p in 0..self.np {
                let x = nz.sample(&mut self.rng);
                for k in 0..nk {
                    self.acc_point[p * nk + k] += self.zk[k] * x;
                }
            }
        }
    }

    /// The window's modal amplitudes `[n·nk + k]` (peak; a 0 Hz line is the mean).
    fn modal(&self, measure_hz: &[f64], n_samp: u64) -> Vec<Complex64> {
        let nk = measure_hz.len();
        (0..self.acc_modal.len())
            .map(|i| self.acc_modal[i] * window_norm(measure_hz[i % nk], n_samp))
            .collect()
    }

    /// Each point's amplitudes: its mode-shape combination of `modal` plus its noise.
    fn points(
        &self,
        modal: &[Complex64],
        shapes: &[Vec<f64>],
        measure_hz: &[f64],
        n_samp: u64,
    ) -> Vec<Vec<Complex64>> {
        let nk = measure_hz.len();
        shapes
            .iter()
            .enumerate()
            .map(|(p, shape)| {
                (0..nk)
                    .map(|k| {
                        let signal: Complex64 = shape
                            .iter()
                            .enumerate()
                            .map(|(n, &s)| modal[n * nk + k] * s)
                            .sum();
                        signal + self.acc_point[p * nk + k] * window_norm(measure_hz[k], n_samp)
                    })
                    .collect()
            })
            .collect()
    }

    fn clear(&mut self) {
        let zero = Complex64::new(0.0, 0.0);
        self.acc_modal.iter_mut().for_each(|a| *a = zero);
        self.acc_point.iter_mut().for_each(|a| *a = zero);
    }
}

/// The lock-in's normalisation of a window of `n_samp` samples: `2/N` (peak amplitude), `1/N`
/// at 0 Hz (the mean).
fn window_norm(f: f64, n_samp: u64) -> f64 {
    if f > 0.0 {
        2.0 / n_samp as f64
    } else {
        1.0 / n_samp as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::Term;

    #[test]
    fn propagator_matches_series() {
        let (w, g, s) = (3.0, 0.4, 0.37);
        let p = propagator(w, g, s);
        // Taylor series of e^{As}.
        let a = [0.0, 1.0, -w * w, -g];
        let mut term = [1.0, 0.0, 0.0, 1.0];
        let mut sum = term;
        for k in 1..40 {
            let t = [
                term[0] * a[0] + term[1] * a[2],
                term[0] * a[1] + term[1] * a[3],
                term[2] * a[0] + term[3] * a[2],
                term[2] * a[1] + term[3] * a[3],
            ];
            term = t.map(|x| x * s / k as f64);
            for i in 0..4 {
                sum[i] += term[i];
            }
        }
        for i in 0..4 {
            assert!((p[i] - sum[i]).abs() < 1e-12, "{i}: {} vs {}", p[i], sum[i]);
        }
    }

    #[test]
    fn linear_model_gives_linear_response() {
        let m =
            NumericModel::new(vec!["q".into()], vec![1000.0], vec![50.0], vec![]).expect("model");
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![990.0, 1010.0],
            force: vec![vec![Complex64::new(1.0, 0.5), Complex64::new(-0.3, 0.2)]],
        };
        let r = simulate_lockin(
            &m,
            &drive,
            &[990.0, 1010.0, 1030.0],
            &[vec![0.5]],
            &Start::Rest,
            &TdSettings::default(),
        )
        .expect("runs");
        for (k, &f) in [990.0, 1010.0].iter().enumerate() {
            let want = linear_response(m.omega(0), m.gamma(0), f, drive.force[0][k]);
            assert!(
                (r.modal[0][k] - want).norm() < 1e-6 * want.norm(),
                "{} vs {want}",
                r.modal[0][k]
            );
            assert!((r.points[0][k] - want * 0.5).norm() < 1e-6 * want.norm());
        }
        assert!(r.modal[0][2].norm() < 1e-9 * r.modal[0][0].norm());
    }

    #[test]
    fn blow_up_is_reported() {
        // Softening Duffing driven far beyond its escape amplitude.
        let t = Term {
            eq: 0,
            coef: -1.0e6,
            factors: vec![(0, 3)],
        };
        let m = NumericModel::new(vec!["q".into()], vec![1.0], vec![20.0], vec![t]).expect("model");
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1.0],
            force: vec![vec![Complex64::new(50.0, 0.0)]],
        };
        let r = simulate_lockin(
            &m,
            &drive,
            &[1.0],
            &[],
            &Start::Rest,
            &TdSettings::default(),
        );
        assert!(matches!(r, Err(SimError::BlowUp { .. })), "{r:?}");
    }

    #[test]
    fn coarse_step_is_refined_to_the_tolerance() {
        // A strongly driven Duffing oscillator: 4 steps per period is far too coarse for
        // rtol = 1e-9; the run is abandoned and refined by the estimate's factor.
        let m = NumericModel::new(
            vec!["q".into()],
            vec![1000.0],
            vec![50.0],
            vec![Term {
                eq: 0,
                coef: 1e13,
                factors: vec![(0, 3)],
            }],
        )
        .expect("model");
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1000.0, 1010.0],
            force: vec![vec![Complex64::new(30.0, 0.0), Complex64::new(10.0, 0.0)]],
        };
        let measure = [990.0, 1000.0, 1010.0, 1020.0];
        let run = |spp: usize, max: usize| {
            let s = TdSettings {
                steps_per_period: spp,
                max_steps_per_period: max,
                ..TdSettings::default()
            };
            simulate_lockin(&m, &drive, &measure, &[vec![1.0]], &Start::Rest, &s).expect("runs")
        };
        let coarse = run(4, 4);
        assert!(coarse.max_error_ratio > 1.0, "{}", coarse.max_error_ratio);
        let refined = run(4, 512);
        assert!(
            refined.max_error_ratio <= 1.0,
            "{}",
            refined.max_error_ratio
        );
        assert!(refined.steps_per_period > 4 && refined.steps_per_period < 64);
        // The refined run is accurate: it agrees with a much finer one.
        let fine = run(64, 64);
        let big = fine.modal[0].iter().map(|z| z.norm()).fold(0.0, f64::max);
        let err = |r: &LockinResult| {
            r.modal[0]
                .iter()
                .zip(&fine.modal[0])
                .map(|(a, b)| (a - b).norm() / big)
                .fold(0.0, f64::max)
        };
        eprintln!(
            "errors: coarse {:e}, refined {:e}",
            err(&coarse),
            err(&refined)
        );
        assert!(err(&refined) < 1e-7, "{}", err(&refined));
        assert!(err(&coarse) > 3.0 * err(&refined));
    }

    #[test]
    fn point_signals_are_the_shape_combination_plus_their_own_noise() {
        let m = NumericModel::new(
            vec!["a".into(), "b".into()],
            vec![1000.0, 1500.0],
            vec![50.0, 60.0],
            vec![],
        )
        .expect("model");
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1000.0, 1500.0],
            force: vec![
                vec![Complex64::new(1.0, 0.0), Complex64::new(0.0, 0.0)],
                vec![Complex64::new(0.0, 0.0), Complex64::new(0.5, 0.0)],
            ],
        };
        let shapes = [vec![0.3, 0.7], vec![1.0, -1.0]];
        let quiet = simulate_lockin(
            &m,
            &drive,
            &[1000.0, 1500.0],
            &shapes,
            &Start::Rest,
            &TdSettings::default(),
        )
        .expect("runs");
        for (p, shape) in shapes.iter().enumerate() {
            for k in 0..2 {
                let want = quiet.modal[0][k] * shape[0] + quiet.modal[1][k] * shape[1];
                assert!((quiet.points[p][k] - want).norm() <= 1e-12 * want.norm());
            }
        }
        // With noise, each point gets its own realisation, of the documented size.
        let noisy = simulate_lockin(
            &m,
            &drive,
            &[1000.0, 1500.0],
            &shapes,
            &Start::Rest,
            &TdSettings {
                noise_rms: 1e-9,
                ..TdSettings::default()
            },
        )
        .expect("runs");
        let sigma = crate::lockin_noise_sigma(1e-9, noisy.samples as f64);
        let d0 = noisy.points[0][0] - quiet.points[0][0];
        let d1 = noisy.points[1][0] - quiet.points[1][0];
        assert!(
            d0.norm() > 0.0 && d0.norm() < 6.0 * sigma,
            "{d0} vs sigma {sigma}"
        );
        assert!((d0 - d1).norm() > 1e-3 * sigma);
    }
}

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
    let nd = drive.tones_hz.len();
    let nk = measure_hz.len();
    let np = shapes.len();
    // Window: integer periods of every tone and measured frequency.
    let max_window_s = 100.0;
    let all: Vec<f64> = drive
        .tones_hz
        .iter()
        .chain(measure_hz.iter().filter(|&&f| f > 0.0))
        .copied()
        .collect();
    let grid = common_grid(&all, 1e-7, 1.0 / max_window_s).ok_or(SimError::NoCommonPeriod {
        max_s: max_window_s,
    })?;
    let window_s = st.window_periods.max(1) as f64 / grid;
    // The linear part is exact, so the step only has to resolve the response's frequencies
    // (combinations of the tones, which the measured frequencies cover), not every mode's.
    let f_hi = all.iter().copied().fold(0.0, f64::max);
    let spp = st.steps_per_period.max(4);
    let m_dec = (spp / st.samples_per_period.max(4)).max(1);
    let n_samp = ((window_s * f_hi * spp as f64 / m_dec as f64).ceil() as u64).max(16);
    let n_win = n_samp * m_dec as u64; // steps per window
    let h = window_s / n_win as f64;
    // Integer cycles per window, for exact phases.
    let cyc = |f: f64| (f * window_s).round() as u64;
    let tone_cyc: Vec<u64> = drive.tones_hz.iter().map(|&f| cyc(f)).collect();
    let meas_cyc: Vec<u64> = measure_hz.iter().map(|&f| cyc(f)).collect();
    let phasor = |c: u64, n: u64| {
        let ph = ((c as u128 * n as u128) % n_win as u128) as f64 / n_win as f64;
        let (s, c) = (TAU * ph).sin_cos();
        Complex64::new(c, s)
    };

    // Linear steady-state response `y[n·nd + d]` and the scale of each mode.
    let y: Vec<Complex64> = (0..nm)
        .flat_map(|n| {
            (0..nd).map(move |d| {
                linear_response(
                    model.omega(n),
                    model.gamma(n),
                    drive.tones_hz[d],
                    drive.force[n][d],
                )
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
    let scale: Vec<f64> = y_scale.iter().map(|&s| s.max(1e-3 * all_scale)).collect();
    let wdr: Vec<f64> = drive.tones_hz.iter().map(|&f| TAU * f).collect();
    // Stage rotations e^{i ω_d c_i h}, `rot[i·nd + d]`.
    let rot: Vec<Complex64> = (0..7)
        .flat_map(|i| {
            wdr.iter()
                .map(move |&w| Complex64::from_polar(1.0, w * C[i] * h))
        })
        .collect();
    let lw = Lawson::new(model, h);

    // State w = q − q_lin, per mode (w, ẇ).
    let q_lin_at = |z: &[Complex64], n: usize| -> (f64, f64) {
        let mut q = 0.0;
        let mut v = 0.0;
        for d in 0..nd {
            let a = y[n * nd + d] * z[d];
            q += a.re;
            v -= wdr[d] * a.im;
        }
        (q, v)
    };
    let mut z: Vec<Complex64> = tone_cyc.iter().map(|&c| phasor(c, 0)).collect();
    let mut u = vec![[0.0f64; 2]; nm];
    for n in 0..nm {
        let (ql, vl) = q_lin_at(&z, n);
        let (q0, v0) = match start {
            Start::Rest => (0.0, 0.0),
            Start::State { q, v } => (q[n], v[n]),
        };
        u[n] = [q0 - ql, v0 - vl];
    }

    // Scratch.
    // Stage forces, `g[j·nm + n]`.
    let mut g = vec![0.0f64; 7 * nm];
    let mut ust = vec![[0.0f64; 2]; nm];
    let mut qtot = vec![0.0f64; nm];
    let mut pows = vec![0.0f64; model.pow_len()];
    let mut zst = vec![Complex64::new(0.0, 0.0); nd];
    let mut acc_modal = vec![Complex64::new(0.0, 0.0); nm * nk];
    let mut acc_point = vec![Complex64::new(0.0, 0.0); np * nk];
    let mut prev_modal: Option<Vec<Complex64>> = None;
    let mut zk: Vec<Complex64> = meas_cyc.iter().map(|&c| phasor(c, 0).conj()).collect();
    let rot_k: Vec<Complex64> = meas_cyc
        .iter()
        .map(|&c| phasor(c, m_dec as u64).conj())
        .collect();
    let zstep: Vec<Complex64> = tone_cyc.iter().map(|&c| phasor(c, 1)).collect();
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
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(st.seed);

    let tau_max = (0..nm).map(|n| 2.0 / model.gamma(n)).fold(0.0, f64::max);
    let settle_tau = st.settle_tau.unwrap_or(match start {
        Start::Rest => 12.0,
        Start::State { .. } => 1.0,
    });
    // Windows need not start at multiples of the window length: every frequency has whole
    // periods in any `n_win` consecutive steps. The first demodulated window ends at the
    // settling time (it is compared with the next one), after a pre-roll of `pre` steps.
    let settle_steps = (settle_tau * tau_max / h).ceil().max(0.0) as u64;
    let pre = settle_steps.saturating_sub(n_win);
    let err_tol: Vec<f64> = scale.iter().map(|&s| st.rtol * s).collect();
    let blow = 1e3;

    // Total displacement: the linear response at tone phasors `t_z` plus the state `us`.
    let q_total = |t_z: &[Complex64], us: &[[f64; 2]], qtot: &mut [f64]| {
        let mut k = 0;
        for (q, un) in qtot.iter_mut().zip(us) {
            let mut ql = un[0];
            for b in t_z {
                let a = y[k];
                ql += a.re * b.re - a.im * b.im;
                k += 1;
            }
            *q = ql;
        }
    };
    let eval_g = |t_z: &[Complex64],
                  us: &[[f64; 2]],
                  qtot: &mut [f64],
                  pows: &mut [f64],
                  out: &mut [f64]| {
        q_total(t_z, us, qtot);
        model.forces(qtot, pows, out);
        out.iter_mut().for_each(|v| *v = -*v);
    };

    let mut step: u64 = 0;
    let mut max_err: f64 = 0.0;
    let mut win: u64 = 0;
    let mut demod_windows: usize = 0;
    eval_g(&z, &u, &mut qtot, &mut pows, &mut g[..nm]);
    let mut settle_change = f64::INFINITY;
    loop {
        let (demod, len) = if win == 0 && pre > 0 {
            (false, pre)
        } else {
            (true, n_win)
        };
        if demod {
            for (k, &c) in meas_cyc.iter().enumerate() {
                zk[k] = phasor(c, step % n_win).conj();
            }
        }
        for j in 0..len {
            // Stages 1..6 (stage 0 is FSAL).
            for i in 1..7 {
                let (done, rest) = g.split_at_mut(i * nm);
                let p = &lw.p[i * nm..(i + 1) * nm];
                for (n, (us, un)) in ust.iter_mut().zip(&u).enumerate() {
                    let pn = &p[n];
                    let mut a = pn[0] * un[0] + pn[1] * un[1];
                    let mut b = pn[2] * un[0] + pn[3] * un[1];
                    for jj in 0..i {
                        let c = &lw.acol[(i * 7 + jj) * nm + n];
                        let gj = done[jj * nm + n];
                        a += c[0] * gj;
                        b += c[1] * gj;
                    }
                    *us = [a, b];
                }
                for ((zs, zd), r) in zst.iter_mut().zip(&z).zip(&rot[i * nd..(i + 1) * nd]) {
                    *zs = zd * r;
                }
                eval_g(&zst, &ust, &mut qtot, &mut pows, &mut rest[..nm]);
            }
            // Error estimate.
            for n in 0..nm {
                let mut e0 = 0.0;
                for jj in 0..7 {
                    e0 += lw.ecol[jj * nm + n][0] * g[jj * nm + n];
                }
                let r = e0.abs() / err_tol[n];
                if r > max_err {
                    max_err = r;
                }
            }
            if demod && abandon_when_coarse && max_err > 1.0 {
                return Ok(Run::TooCoarse {
                    error_ratio: max_err,
                });
            }
            u.copy_from_slice(&ust);
            g.copy_within(6 * nm..7 * nm, 0);
            step += 1;
            let n_in = step % n_win;
            if n_in % 256 == 0 {
                for d in 0..nd {
                    z[d] = phasor(tone_cyc[d], n_in);
                }
            } else {
                for d in 0..nd {
                    z[d] *= zstep[d];
                }
            }
            // Blow-up check on the total displacement.
            for n in 0..nm {
                let q = qtot[n];
                if !q.is_finite() || q.abs() > blow * scale[n].max(1e-30) * 1e3 {
                    return Err(SimError::BlowUp {
                        t_s: step as f64 * h,
                        amplitude: q.abs(),
                        scale: scale[n],
                    });
                }
            }
            if demod && (j + 1) % m_dec as u64 == 0 {
                // Sample at the end of this step: t = (win * n_win + j + 1) h; the phasor zk
                // refers to that time.
                q_total(&z, &u, &mut qtot);
                let sidx = (j + 1) / m_dec as u64;
                if sidx % 256 == 0 {
                    for (k, &c) in meas_cyc.iter().enumerate() {
                        zk[k] = phasor(c, n_in).conj();
                    }
                } else {
                    for k in 0..nk {
                        zk[k] *= rot_k[k];
                    }
                }
                for n in 0..nm {
                    let x = qtot[n];
                    for k in 0..nk {
                        acc_modal[n * nk + k] += zk[k] * x;
                    }
                }
                // The points' signals are linear in the modal ones: only their noise needs
                // its own demodulation (the rest is combined once per window).
                if let Some(nz) = &noise {
                    for p in 0..np {
                        let x = nz.sample(&mut rng);
                        for k in 0..nk {
                            acc_point[p * nk + k] += zk[k] * x;
                        }
                    }
                }
            }
        }
        win += 1;
        if demod {
            let norm = |f: f64| {
                if f > 0.0 {
                    2.0 / n_samp as f64
                } else {
                    1.0 / n_samp as f64
                }
            };
            let cur: Vec<Complex64> = (0..nm * nk)
                .map(|i| acc_modal[i] * norm(measure_hz[i % nk]))
                .collect();
            let biggest = cur.iter().map(|z| z.norm()).fold(0.0, f64::max).max(1e-300);
            if let Some(prev) = &prev_modal {
                settle_change = cur
                    .iter()
                    .zip(prev)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max)
                    / biggest;
            }
            let start_step = step - n_win;
            let done = start_step >= settle_steps && settle_change <= st.settle_tol;
            if start_step >= settle_steps {
                demod_windows += 1;
            }
            if done || demod_windows > st.max_windows {
                if !done {
                    return Err(SimError::NotSettled {
                        t_s: step as f64 * h,
                        change: settle_change,
                        tol: st.settle_tol,
                    });
                }
                let modal = (0..nm)
                    .map(|n| cur[n * nk..(n + 1) * nk].to_vec())
                    .collect();
                let points = (0..np)
                    .map(|p| {
                        (0..nk)
                            .map(|k| {
                                let signal: Complex64 =
                                    (0..nm).map(|n| cur[n * nk + k] * shapes[p][n]).sum();
                                signal + acc_point[p * nk + k] * norm(measure_hz[k])
                            })
                            .collect()
                    })
                    .collect();
                return Ok(Run::Done(LockinResult {
                    freqs_hz: measure_hz.to_vec(),
                    modal,
                    points,
                    window_s,
                    window_start_s: start_step as f64 * h,
                    settle_change,
                    steps_per_period: st.steps_per_period,
                    samples: n_samp,
                    steps: step,
                    max_error_ratio: max_err,
                }));
            }
            prev_modal = Some(cur);
            acc_modal
                .iter_mut()
                .for_each(|a| *a = Complex64::new(0.0, 0.0));
            acc_point
                .iter_mut()
                .for_each(|a| *a = Complex64::new(0.0, 0.0));
        }
        // Max error counts only over the windows that matter (after the first transient).
        if !demod {
            max_err = 0.0;
        }
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

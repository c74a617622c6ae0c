//! What a harmonic-balance solve is asked ([`HbSettings`]) and what it returns
//! ([`SteadyState`], [`HbStatus`], [`Stability`]).

use super::Z;
use crate::lattice::{LatticeSettings, LINE_TOL_HZ};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Settings of a harmonic-balance solve.
#[derive(Debug, Clone, PartialEq)]
pub struct HbSettings {
    /// How the lattice is chosen.
    pub lattice: LatticeSettings,
    /// Converged when `max |R| / max |F|` is below this.
    pub tol: f64,
    /// Newton iterations per drive level before the ramp step is halved.
    pub max_iter: usize,
    /// Ramp the drive up from `ramp_start` (fraction of the full drive); `false`: one Newton
    /// solve at full drive from the linear response.
    pub ramp: bool,
    /// First drive fraction of the ramp.
    pub ramp_start: f64,
    /// First ramp step (fraction of the full drive); grows when Newton converges fast.
    pub ramp_step: f64,
    /// Largest ramp step.
    pub ramp_step_max: f64,
    /// Most ramp steps before giving up (status [`HbStatus::NotConverged`]).
    pub max_ramp_steps: usize,
    /// At a fold of the ramp, stop (status [`HbStatus::NotConverged`] at the fold, the fold
    /// in [`SteadyState::drive_jumps`]) instead of following the jump to the other branch,
    /// which costs far more: for callers that only need to know that the drive jumps (a
    /// planner looking for the strongest drive without one). Default `false`.
    pub stop_at_fold: bool,
}

impl Default for HbSettings {
    fn default() -> Self {
        Self {
            lattice: LatticeSettings::default(),
            tol: 1e-11,
            max_iter: 12,
            ramp: true,
            ramp_start: 0.01,
            ramp_step: 0.05,
            ramp_step_max: 0.25,
            max_ramp_steps: 2000,
            stop_at_fold: false,
        }
    }
}

/// Outcome of a harmonic-balance solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HbStatus {
    /// Newton converged at full drive.
    Converged {
        /// Jacobian evaluations of Newton at the last drive level (0 when the Jacobian of an
        /// earlier level served).
        iterations: usize,
    },
    /// Newton did not converge; the state is the last converged one (at `drive_fraction`).
    NotConverged {
        /// Fraction of the full drive reached.
        drive_fraction: f64,
    },
}

/// For messages: "converged in N iterations", "stopped at 90.0 % of the drive", or, when the
/// whole drive was reached but no state settled there (a stepped sweep's step, a landing past
/// a fold), "no steady state settled at the full drive".
impl std::fmt::Display for HbStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HbStatus::Converged { iterations } => write!(f, "converged in {iterations} iterations"),
            HbStatus::NotConverged { drive_fraction } if *drive_fraction >= 1.0 => {
                write!(f, "no steady state settled at the full drive")
            }
            HbStatus::NotConverged { drive_fraction } => {
                // Short of the full drive by less than rounding to 0.1 % shows: more digits.
                let pct = 100.0 * drive_fraction;
                let digits = if pct >= 99.95 { 3 } else { 1 };
                write!(f, "stopped at {pct:.digits$} % of the drive")
            }
        }
    }
}

/// A harmonic-balance steady state.
#[derive(Debug, Clone, PartialEq)]
pub struct SteadyState {
    /// Lattice frequencies, Hz (sorted, ≥ 0; a 0 Hz line is the static offset).
    pub lattice_hz: Vec<f64>,
    /// `amplitudes[n][r]`: complex amplitude of mode `n` at `lattice_hz[r]`, m (peak;
    /// `q_n(t) = Σ_r Re[X e^{i2π f_r t}]`).
    pub amplitudes: Vec<Vec<Complex64>>,
    /// Converged or not.
    pub status: HbStatus,
    /// `max |R| / max |F|` at the returned state (relative force balance error).
    pub residual: f64,
    /// Drive levels solved along the ramp.
    pub ramp_steps: usize,
    /// Drive fractions where the ramp met a fold (its branch ended) and the state jumped to
    /// the one the slow-flow dynamics reach, as a drive-up experiment would. With the status
    /// [`HbStatus::NotConverged`] at the last one, the ramp stopped there instead: asked to
    /// ([`HbSettings::stop_at_fold`]), or the slow flow after the jump settled on no steady
    /// state of the lattice.
    pub drive_jumps: Vec<f64>,
    /// The state is an oscillation a pump sustains above its parametric threshold: the state
    /// the drive ramp followed was unstable, and the resonator settled here from it.
    pub pump_sustained: bool,
}

impl SteadyState {
    /// Whether Newton converged at full drive.
    pub fn converged(&self) -> bool {
        matches!(self.status, HbStatus::Converged { .. })
    }

    /// Amplitude of mode `n` at `f_hz` (zero when `f_hz` is not on the lattice).
    pub fn amplitude(&self, n: usize, f_hz: f64) -> Complex64 {
        match self.index(f_hz) {
            Some(r) => self.amplitudes[n][r],
            None => Z,
        }
    }

    /// Lattice index of `f_hz`.
    pub fn index(&self, f_hz: f64) -> Option<usize> {
        let i = self.lattice_hz.partition_point(|&f| f < f_hz - LINE_TOL_HZ);
        match self.lattice_hz.get(i) {
            Some(&f) if (f - f_hz).abs() <= LINE_TOL_HZ => Some(i),
            _ => None,
        }
    }

    /// Amplitude of the signal `Σ_n shape[n] q_n` at `f_hz`.
    pub fn at_point(&self, shape: &[f64], f_hz: f64) -> Complex64 {
        (0..self.amplitudes.len())
            .map(|n| self.amplitude(n, f_hz) * shape.get(n).copied().unwrap_or(1.0))
            .sum()
    }

    /// Modal displacements (m) and velocities (m/s) at time `t_s`.
    pub fn state_at(&self, t_s: f64) -> (Vec<f64>, Vec<f64>) {
        let mut q = vec![0.0; self.amplitudes.len()];
        let mut v = vec![0.0; self.amplitudes.len()];
        for (n, row) in self.amplitudes.iter().enumerate() {
            for (&f, &x) in self.lattice_hz.iter().zip(row) {
                let ph = (f * t_s).fract();
                let e = Complex64::from_polar(1.0, TAU * ph) * x;
                q[n] += e.re;
                v[n] -= TAU * f * e.im;
            }
        }
        (q, v)
    }
}

/// Stability verdict of a steady state ([`crate::check_stability`], [`crate::HbSolver::stability`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stability {
    /// No perturbation grows: the largest growth rate is below `1e-6 ·` the slowest linear
    /// decay rate.
    pub stable: bool,
    /// Largest real part of the eigenvalues of the linearised slow flow on the lines near the
    /// resonances (the far ones condensed; see [`crate::HbSolver::stability`]), 1/s (negative: small
    /// perturbations decay at this rate; positive: they grow as `e^{growth_rate · t}`).
    pub growth_rate: f64,
    /// Slowest amplitude decay rate of the linear resonators, `min_n ω_n/(2 Q_n)`, 1/s (the
    /// scale of `growth_rate`; a linear resonator has `growth_rate = −linear_decay_rate`).
    pub linear_decay_rate: f64,
}

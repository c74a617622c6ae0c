//! Multi-tone harmonic-balance steady states: Newton with an analytic Jacobian on a frequency
//! lattice, nonlinear terms by exact sparse products ([`harmonid_spectral::ProductPlan`]), and a
//! drive ramp that follows the branch an experiment sweeping the drive up would see.
//!
//! Unknowns: `X_{n,r}`, the complex amplitude of mode `n` at lattice frequency `f_r`. Residual
//! (DATA_FORMAT conventions, `Ω_r = 2π f_r`):
//!
//! ```text
//! R_{n,r} = (ω_n² − Ω_r² + i Ω_r ω_n/Q_n) X_{n,r} + Σ_m b_m^(n) [m(q)]_r − F_{n,r}.
//! ```
//!
//! Static offset: models with even-degree terms have a 0 Hz line (see
//! [`crate::choose_lattice`]) whose amplitude is the real offset `X_{n,0} = q̄_n` (the mean of
//! `q_n`); there the linear part is `ω_n² X` and `[m(q)]_0` is the mean of the product. Its
//! imaginary part has no physical meaning: the products ignore it, so its residual row is
//! `ω_n² Im X_{n,0} = 0`, a decoupled diagonal entry that keeps the Jacobian nonsingular and
//! Newton leaves it at zero (it is set exactly to zero in the returned state).

use crate::lattice::{choose_lattice, low_order_lines, LatticeSettings, LINE_TOL_HZ};
use crate::linalg::{coupled_parts, DenseLu};
use crate::{Excitation, NumericModel, SimError};
use harmonid_poly::PowerProduct;
use harmonid_spectral::{ProductPlan, SystemPlan, SystemScratch};
use num_complex::Complex64;
use std::f64::consts::TAU;

const Z: Complex64 = Complex64::new(0.0, 0.0);
/// Most modes a harmonic-balance problem handles (fixed-size slice tables, no allocation).
pub const MAX_MODES: usize = 32;
/// A chord step (stale Jacobian) is kept when it shrinks the residual at least this much.
const CHORD_RATE: f64 = 0.25;
/// Residual tolerance at the intermediate levels of the drive ramp (they only serve the
/// predictor of the next level; the full drive is solved to [`HbSettings::tol`]).
const RAMP_TOL: f64 = 1e-7;
/// Intermodulation order of the coarse lattice the drive ramp runs on (see [`HbSolver::solve`]).
const RAMP_ORDER: usize = 5;
/// The coarse ramp is used when it leaves out at least this fraction of the lattice's lines.
const RAMP_MIN_SAVING: f64 = 0.25;
/// Most drive tones for which the coarse ramp lattice is enumerated (the count of
/// combinations grows as `tones^RAMP_ORDER`).
const RAMP_MAX_TONES: usize = 8;
/// A ramp step this small (fraction of the full drive) that still fails marks a fold in the
/// drive: the branch ends and the state jumps (see [`HbSolver::land`]).
const FOLD_STEP: f64 = 1e-4;
/// A converged ramp step continues the branch only if Newton moved the state at most this many
/// times as far from the tangent predictor as the predictor moved it from the last state, and
/// the tangent changed its size by at most this factor (see [`HbSolver::continues_branch`]).
const BRANCH_CORRECTION: f64 = 2.0;
/// Most pseudo-time steps of a landing.
const LAND_MAX_STEPS: usize = 400;

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

/// For messages: "converged in N iterations", "stopped at 90.0 % of the drive".
impl std::fmt::Display for HbStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HbStatus::Converged { iterations } => write!(f, "converged in {iterations} iterations"),
            HbStatus::NotConverged { drive_fraction } => {
                write!(f, "stopped at {:.1} % of the drive", 100.0 * drive_fraction)
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

/// Stability verdict of a steady state ([`check_stability`], [`HbSolver::stability`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stability {
    /// No perturbation grows: the largest growth rate is below `1e-6 ·` the slowest linear
    /// decay rate.
    pub stable: bool,
    /// Largest real part of the eigenvalues of the linearised slow flow, 1/s (negative: small
    /// perturbations decay at this rate; positive: they grow as `e^{growth_rate · t}`).
    pub growth_rate: f64,
    /// Slowest amplitude decay rate of the linear resonators, `min_n ω_n/(2 Q_n)`, 1/s (the
    /// scale of `growth_rate`; a linear resonator has `growth_rate = −linear_decay_rate`).
    pub linear_decay_rate: f64,
}

/// A harmonic-balance problem on a fixed lattice, with every table and buffer allocated once;
/// [`HbSolver::solve`] can then run many times (drive levels, noise studies) without allocating.
#[derive(Debug, Clone)]
pub struct HbSolver {
    model: NumericModel,
    lattice: Vec<f64>,
    /// The nonlinear forces of all equations, sharing partial products.
    system: SystemPlan,
    scratch: SystemScratch,
    /// `lin[n*R + r] = ω_n² − Ω_r² + iΩ_r γ_n`.
    lin: Vec<Complex64>,
    /// Full-drive forces on the lattice, `[n*R + r]`.
    force: Vec<Complex64>,
    force_max: f64,
    // Buffers.
    x: Vec<Complex64>,
    res: Vec<Complex64>,
    out: Vec<Complex64>,
    jre: Vec<Complex64>,
    jim: Vec<Complex64>,
    jac: Vec<f64>,
    lu: DenseLu,
    /// `[e·N + v]`: the Jacobian's block of equation `e`, mode `v` is not zero (assembly).
    coupled: Vec<bool>,
    step: Vec<f64>,
    x_try: Vec<Complex64>,
    /// `lu` holds a factorised Jacobian (of some earlier state).
    have_lu: bool,
    /// The factorised Jacobian is that of the current `x`.
    fresh: bool,
    /// The same problem on the lines of intermodulation order ≤ [`RAMP_ORDER`], where the drive
    /// ramp runs, and the index of each of its lines in `lattice`.
    coarse: Option<(Box<HbSolver>, Vec<usize>)>,
}

/// What the values of a problem (coefficients, `f`, `Q`, forces) set on a planned lattice.
struct Operators {
    system: SystemPlan,
    lin: Vec<Complex64>,
    force: Vec<Complex64>,
    force_max: f64,
}

impl Operators {
    fn new(
        model: &NumericModel,
        drive: &Excitation,
        lattice: &[f64],
        plan: ProductPlan,
    ) -> Result<Self, SimError> {
        let nm = model.n_modes();
        let nr = lattice.len();
        let terms: Vec<_> = model
            .terms()
            .iter()
            .map(|t| {
                let mut e = vec![0u32; nm];
                for &(m, k) in &t.factors {
                    e[m] += k;
                }
                (t.eq, PowerProduct::from_exponents(&e), t.coef)
            })
            .collect();
        let system = SystemPlan::new(plan, nm, nm, &terms)?;
        let mut lin = vec![Z; nm * nr];
        for n in 0..nm {
            let (w, g) = (model.omega(n), model.gamma(n));
            for (r, &f) in lattice.iter().enumerate() {
                let o = TAU * f;
                lin[n * nr + r] = Complex64::new(w * w - o * o, o * g);
            }
        }
        let mut force = vec![Z; nm * nr];
        for (d, &f) in drive.tones_hz.iter().enumerate() {
            let i = lattice.partition_point(|&x| x < f - LINE_TOL_HZ);
            if lattice.get(i).is_none_or(|&x| (x - f).abs() > LINE_TOL_HZ) {
                return Err(SimError::NotOnLattice { hz: f });
            }
            for n in 0..nm {
                force[n * nr + i] += drive.force[n][d];
            }
        }
        let force_max = force.iter().map(|z| z.norm()).fold(0.0, f64::max);
        Ok(Self {
            system,
            lin,
            force,
            force_max,
        })
    }
}

impl HbSolver {
    /// Sets the problem up: lattice from `settings.lattice`, product plan, linear operators and
    /// forces. Errors: bad drive shapes, too many modes, a lattice too large for the plan.
    pub fn new(
        model: &NumericModel,
        drive: &Excitation,
        settings: &LatticeSettings,
    ) -> Result<Self, SimError> {
        let lattice = choose_lattice(model, drive, settings)?;
        Self::with_lattice(model, drive, lattice)
    }

    /// As [`HbSolver::new`] with a given lattice (sorted distinct frequencies ≥ 0, Hz, holding
    /// every drive tone; a 0 Hz line is the static offset).
    pub fn with_lattice(
        model: &NumericModel,
        drive: &Excitation,
        lattice: Vec<f64>,
    ) -> Result<Self, SimError> {
        let mut solver = Self::single(model, drive, lattice)?;
        if drive.tones_hz.len() <= RAMP_MAX_TONES {
            let lines = low_order_lines(drive, &solver.lattice, RAMP_ORDER);
            let nr = solver.lattice.len();
            if (lines.len() as f64) <= (1.0 - RAMP_MIN_SAVING) * nr as f64 {
                let sub = lines.iter().map(|&i| solver.lattice[i]).collect();
                let coarse = Self::single(model, drive, sub)?;
                solver.coarse = Some((Box::new(coarse), lines));
            }
        }
        Ok(solver)
    }

    /// Sets new values of the same problem: `model` with the terms (equations and factors) of
    /// the set-up's, other coefficients, `f` and `Q`, and `drive` with the same tones and other
    /// forces. Keeps the lattice, its product plan and every buffer, so that a caller that
    /// re-solves one experiment at many parameter values (a fit, a planner) does not plan the
    /// lattice again. The next solve starts from the state given to it; a factorised Jacobian
    /// is kept only for [`HbSolver::solve_continued`]. Errors: another number of modes, other terms, other tones.
    pub fn set_values(&mut self, model: &NumericModel, drive: &Excitation) -> Result<(), SimError> {
        let nm = model.n_modes();
        let same_terms = nm == self.model.n_modes()
            && model.terms().len() == self.model.terms().len()
            && model
                .terms()
                .iter()
                .zip(self.model.terms())
                .all(|(a, b)| a.eq == b.eq && a.factors == b.factors);
        if !same_terms {
            return Err(SimError::SetUpFor { what: "set_values" });
        }
        drive.check(nm)?;
        let ops = Operators::new(model, drive, &self.lattice, self.system.plan().clone())?;
        self.model = model.clone();
        self.scratch = ops.system.scratch();
        self.system = ops.system;
        self.lin = ops.lin;
        self.force = ops.force;
        self.force_max = ops.force_max;
        // A factorised Jacobian stays for [`HbSolver::solve_continued`] (chord steps check
        // that it still contracts); it is no longer that of the current state.
        self.fresh = false;
        if let Some((coarse, _)) = self.coarse.as_mut() {
            coarse.set_values(model, drive)?;
        }
        Ok(())
    }

    /// The solver on exactly `lattice`, without a coarse ramp lattice.
    fn single(
        model: &NumericModel,
        drive: &Excitation,
        lattice: Vec<f64>,
    ) -> Result<Self, SimError> {
        let nm = model.n_modes();
        drive.check(nm)?;
        if nm > MAX_MODES {
            return Err(SimError::TooLarge {
                what: "modes",
                count: nm,
                limit: MAX_MODES,
                help: "split the model or keep the modes the measurement sees",
            });
        }
        let mut degrees: Vec<usize> = model.terms().iter().map(|t| t.degree() as usize).collect();
        degrees.sort_unstable();
        degrees.dedup();
        let plan = ProductPlan::for_degrees(&lattice, &lattice, &degrees)?;
        let nr = lattice.len();
        let ops = Operators::new(model, drive, &lattice, plan)?;
        let nu = 2 * nm * nr;
        Ok(Self {
            model: model.clone(),
            scratch: ops.system.scratch(),
            system: ops.system,
            lin: ops.lin,
            force: ops.force,
            force_max: ops.force_max,
            x: vec![Z; nm * nr],
            res: vec![Z; nm * nr],
            out: vec![Z; nm * nr],
            jre: vec![Z; nr * nr],
            jim: vec![Z; nr * nr],
            jac: vec![0.0; nu * nu],
            // A mode's lines are one group: modes the state does not couple factorise apart.
            lu: DenseLu::with_blocks(nu, 2 * nr),
            coupled: vec![true; nm * nm],
            step: vec![0.0; nu],
            x_try: vec![Z; nm * nr],
            have_lu: false,
            fresh: false,
            coarse: None,
            lattice,
        })
    }

    /// The lattice, Hz.
    pub fn lattice(&self) -> &[f64] {
        &self.lattice
    }

    /// Number of real unknowns.
    pub fn unknowns(&self) -> usize {
        2 * self.x.len()
    }

    /// Residual at `x` with drive fraction `s` into `res`; returns `max |R| / max |s F|`.
    fn residual(&mut self, use_try: bool, s: f64) -> f64 {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let x = if use_try { &self.x_try } else { &self.x };
        let mut refs: [&[Complex64]; MAX_MODES] = [&[]; MAX_MODES];
        for n in 0..nm {
            refs[n] = &x[n * nr..(n + 1) * nr];
        }
        self.system
            .forces(&refs[..nm], &mut self.out, &mut self.scratch);
        for i in 0..nm * nr {
            self.res[i] = self.lin[i] * x[i] - self.force[i] * s + self.out[i];
        }
        let fm = (self.force_max * s).max(f64::MIN_POSITIVE);
        let mut m: f64 = 0.0;
        for r in &self.res {
            let a = r.norm();
            if !a.is_finite() {
                return f64::INFINITY;
            }
            m = m.max(a);
        }
        m / fm
    }

    /// Assembles the real Jacobian at `self.x` and factorises it. `false` when singular.
    fn jacobian(&mut self) -> bool {
        self.assemble_jacobian();
        self.lu.factor_coupled(&self.jac, &self.coupled)
    }

    /// Assembles the real Jacobian `∂(Re R, Im R)/∂(Re X, Im X)` at `self.x` into `self.jac`
    /// (row-major, unknowns interleaved re/im).
    fn assemble_jacobian(&mut self) {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let nu = 2 * nm * nr;
        self.jac.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..nm * nr {
            let l = self.lin[i];
            self.jac[(2 * i) * nu + 2 * i] = l.re;
            self.jac[(2 * i) * nu + 2 * i + 1] = -l.im;
            self.jac[(2 * i + 1) * nu + 2 * i] = l.im;
            self.jac[(2 * i + 1) * nu + 2 * i + 1] = l.re;
        }
        let mut refs: [&[Complex64]; MAX_MODES] = [&[]; MAX_MODES];
        for n in 0..nm {
            refs[n] = &self.x[n * nr..(n + 1) * nr];
        }
        let jac = &mut self.jac;
        let coupled = &mut self.coupled;
        for (i, c) in coupled.iter_mut().enumerate() {
            *c = i / nm == i % nm;
        }
        self.system.jacobian(
            &refs[..nm],
            &mut self.jre,
            &mut self.jim,
            &mut self.scratch,
            |eq, j, jre, jim| {
                // A zero block (a factor of the derivative vanishes in this state: an undriven
                // mode) is skipped and leaves the modes uncoupled for the factorisation.
                if jre.iter().chain(jim).all(|z| *z == Z) {
                    return;
                }
                coupled[eq * nm + j] = true;
                for o in 0..nr {
                    let row0 = 2 * (eq * nr + o);
                    let (top, bottom) = jac[row0 * nu..(row0 + 2) * nu].split_at_mut(nu);
                    for r in 0..nr {
                        let col0 = 2 * (j * nr + r);
                        let (a, c) = (jre[o * nr + r], jim[o * nr + r]);
                        top[col0] += a.re;
                        bottom[col0] += a.im;
                        top[col0 + 1] += c.re;
                        bottom[col0 + 1] += c.im;
                    }
                }
            },
        );
    }

    /// Stability of the steady state `state` (amplitudes on this solver's lattice) by Hill's
    /// method in its slow-flow (first-order) form: with `X_{n,r}` slowly varying,
    /// `q̈` contributes `(2iΩ_r + γ_n) Ẋ_{n,r}` and the amplitudes obey
    /// `(2iΩ_r + γ_n) Ẋ = −R(X)`; the state is stable when every eigenvalue of the linearised
    /// flow `−(2iΩ + γ)⁻¹ ∂R/∂X` has a negative real part. The neglected `Ẍ` term is
    /// `O(λ/Ω)` relative, negligible for the high-Q resonators this crate is for (`Q ≫ 1`).
    pub fn stability(&mut self, state: &SteadyState) -> Result<Stability, SimError> {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        self.load_state(state)?;
        self.assemble_jacobian();
        self.have_lu = false;
        let nu = self.unknowns();
        let mut c = vec![Z; nm * nr];
        for n in 0..nm {
            let g = self.model.gamma(n);
            for (r, &f) in self.lattice.iter().enumerate() {
                c[n * nr + r] = Complex64::new(1.0, 0.0) / Complex64::new(g, 2.0 * TAU * f);
            }
        }
        // A = −C J with C the complex factors as real 2×2 blocks on the rows. C is diagonal
        // per mode, so A couples the modes as J does: modes J leaves uncoupled (an undriven
        // mode nothing forces) are blocks of their own, and the spectrum is the union of the
        // blocks' spectra (n³ → Σ nᵢ³).
        let mut parts: Vec<Vec<usize>> = Vec::new();
        coupled_parts(&self.coupled, nm, &mut [0; MAX_MODES], |n, first| {
            if first {
                parts.push(Vec::new());
            }
            if let Some(p) = parts.last_mut() {
                p.push(n);
            }
        });
        let mut growth = f64::NEG_INFINITY;
        for part in parts {
            let idx: Vec<usize> = part
                .iter()
                .flat_map(|&n| 2 * n * nr..2 * (n + 1) * nr)
                .collect();
            let a = faer::Mat::<f64>::from_fn(idx.len(), idx.len(), |i, j| {
                let (gi, gj) = (idx[i], idx[j]);
                let k = gi / 2;
                let (r0, r1) = (self.jac[(2 * k) * nu + gj], self.jac[(2 * k + 1) * nu + gj]);
                let z = c[k] * Complex64::new(r0, r1);
                -if gi % 2 == 0 { z.re } else { z.im }
            });
            if a.col_iter().any(|col| col.iter().any(|v| !v.is_finite())) {
                return Err(SimError::NonFiniteState);
            }
            let eig = a.eigenvalues().map_err(|_| SimError::NoEigenvalues)?;
            growth = eig.iter().map(|z| z.re).fold(growth, f64::max);
        }
        let decay = (0..nm)
            .map(|n| 0.5 * self.model.gamma(n))
            .fold(f64::INFINITY, f64::min);
        Ok(Stability {
            stable: growth < 1e-6 * decay,
            growth_rate: growth,
            linear_decay_rate: decay,
        })
    }

    /// Copies `state` (solved on this lattice) into the current amplitudes.
    fn load_state(&mut self, state: &SteadyState) -> Result<(), SimError> {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        if state.amplitudes.len() != nm
            || state.amplitudes.iter().any(|row| row.len() != nr)
            || state.lattice_hz.len() != nr
            || state
                .lattice_hz
                .iter()
                .zip(&self.lattice)
                .any(|(a, b)| (a - b).abs() > LINE_TOL_HZ)
        {
            return Err(SimError::OtherLattice);
        }
        for n in 0..nm {
            self.x[n * nr..(n + 1) * nr].copy_from_slice(&state.amplitudes[n]);
        }
        Ok(())
    }

    /// Loads `state` and factorises the Jacobian `∂(Re R, Im R)/∂(Re X, Im X)` there (unknowns
    /// interleaved re/im, `[n·R + r]` order), for [`HbSolver::solve_factored_columns`]. Errors: a
    /// state of another lattice, a singular Jacobian (a fold or bifurcation point).
    pub(crate) fn factor_at(&mut self, state: &SteadyState) -> Result<(), SimError> {
        self.load_state(state)?;
        self.have_lu = false;
        if !self.jacobian() {
            return Err(SimError::SingularJacobian);
        }
        self.have_lu = true;
        self.fresh = true;
        Ok(())
    }

    /// Scratch for [`HbSolver::solve_factored_columns`] with `k` right-hand sides.
    pub(crate) fn columns_scratch(&self, k: usize) -> crate::linalg::ColumnScratch {
        self.lu.columns_scratch(k)
    }

    /// Solves `J Y = B` in place for every column of `b` with the Jacobian factorised by
    /// [`HbSolver::factor_at`] (one blocked solve).
    pub(crate) fn solve_factored_columns(
        &self,
        b: faer::MatMut<'_, f64>,
        buf: &mut crate::linalg::ColumnScratch,
    ) {
        self.lu.solve_columns(b, buf);
    }

    /// The numeric model being solved.
    pub fn model(&self) -> &NumericModel {
        &self.model
    }

    /// The product plan of the lattice (input = output = the lattice).
    pub(crate) fn product_plan(&self) -> &ProductPlan {
        self.system.plan()
    }

    /// Newton at drive fraction `s` from the current `self.x`, reusing the factorised Jacobian
    /// of an earlier state while it contracts the residual by at least [`CHORD_RATE`] per step
    /// (chord/Shamanskii Newton: a refresh costs far more than a residual). `max_iter` bounds
    /// the Jacobian evaluations; `4 · max_iter` the chord steps. Returns `(converged,
    /// Jacobian evaluations, residual)`.
    fn newton(&mut self, s: f64, tol: f64, max_iter: usize) -> (bool, usize, f64) {
        let nu = self.unknowns();
        let mut r0 = self.residual(false, s);
        let mut evals = 0;
        let mut chord = 0;
        loop {
            if r0 <= tol {
                return (true, evals, r0);
            }
            if !self.have_lu {
                if evals >= max_iter {
                    return (false, evals, r0);
                }
                evals += 1;
                if !self.jacobian() {
                    self.residual(false, s);
                    return (false, evals, r0);
                }
                self.have_lu = true;
                self.fresh = true;
            }
            for i in 0..nu / 2 {
                self.step[2 * i] = -self.res[i].re;
                self.step[2 * i + 1] = -self.res[i].im;
            }
            self.lu.solve(&mut self.step);
            if !self.fresh {
                // Chord step with the stale Jacobian: keep it only if it contracts well.
                chord += 1;
                for i in 0..nu / 2 {
                    self.x_try[i] =
                        self.x[i] + Complex64::new(self.step[2 * i], self.step[2 * i + 1]);
                }
                let r1 = self.residual(true, s);
                if (r1 < CHORD_RATE * r0 || r1 <= tol) && chord <= 4 * max_iter {
                    std::mem::swap(&mut self.x, &mut self.x_try);
                    r0 = r1;
                } else {
                    // Refresh at the current state (restores self.res there first).
                    self.residual(false, s);
                    self.have_lu = false;
                }
                continue;
            }
            // Full Newton step with backtracking on the residual norm.
            let mut lam = 1.0;
            let mut accepted = false;
            for _ in 0..8 {
                for i in 0..nu / 2 {
                    self.x_try[i] =
                        self.x[i] + Complex64::new(self.step[2 * i], self.step[2 * i + 1]) * lam;
                }
                let r1 = self.residual(true, s);
                if r1 < r0 || r1 <= tol {
                    std::mem::swap(&mut self.x, &mut self.x_try);
                    r0 = r1;
                    accepted = true;
                    break;
                }
                lam *= 0.5;
            }
            self.fresh = false;
            if !accepted {
                self.residual(false, s);
                self.have_lu = false;
                return (false, evals, r0);
            }
        }
    }

    /// Solves for the steady state under the full drive (ramped up from a small fraction when
    /// `settings.ramp`), starting from the linear response. Never returns NaN: a failure is an
    /// [`HbStatus::NotConverged`] status with the last converged state and its residual.
    ///
    /// The ramp runs on the lattice's lines of intermodulation order ≤ 5 when they are
    /// markedly fewer: they carry the branch structure (folds, jumps), while the higher orders
    /// are corrections of relative size ~`(nonlinear shift / linewidth)^3` smaller. Newton then
    /// finishes at full drive on the whole lattice from the coarse state. Should that fail, the
    /// ramp is run again on the whole lattice.
    pub fn solve(&mut self, settings: &HbSettings) -> SteadyState {
        if settings.ramp {
            if let Some(state) = self.solve_via_coarse(settings) {
                return state;
            }
        }
        self.solve_ramp(settings)
    }

    /// The drive ramp on the coarse lattice, then Newton at full drive on the whole lattice;
    /// `None` when there is no coarse lattice or either step fails.
    fn solve_via_coarse(&mut self, settings: &HbSettings) -> Option<SteadyState> {
        let (coarse, lines) = self.coarse.as_mut()?;
        let loose = HbSettings {
            tol: settings.tol.max(RAMP_TOL),
            ..settings.clone()
        };
        let first = coarse.solve_ramp(&loose);
        if !first.converged() {
            return None;
        }
        let nr = self.lattice.len();
        let cr = lines.len();
        self.x.fill(Z);
        for n in 0..self.model.n_modes() {
            for (i, &r) in lines.iter().enumerate() {
                self.x[n * nr + r] = coarse.x[n * cr + i];
            }
        }
        self.have_lu = false;
        let (ok, it, res) = self.newton(1.0, settings.tol, settings.max_iter);
        ok.then(|| {
            self.finish(
                HbStatus::Converged { iterations: it },
                res,
                first.ramp_steps + 1,
                false,
                first.drive_jumps,
            )
        })
    }

    /// The drive ramp on this solver's own lattice (see [`HbSolver::solve`]).
    ///
    /// A step is kept only when the state it converged to continues the branch of the last
    /// one ([`HbSolver::continues_branch`]): Newton converges from a large step past a fold
    /// onto another branch as readily as onto the same one, and the ramp would then miss the
    /// jump an experiment driving up sees. A step that does not continue the branch is halved
    /// like one that fails; one of at most [`FOLD_STEP`] that still fails or leaves the branch
    /// is a fold.
    fn solve_ramp(&mut self, settings: &HbSettings) -> SteadyState {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let mut s0 = if settings.ramp {
            settings.ramp_start.clamp(1e-6, 1.0)
        } else {
            1.0
        };
        let mut steps = 0;
        let (mut iters, mut sign) = loop {
            for i in 0..nm * nr {
                self.x[i] = self.force[i] * s0 / self.lin[i];
            }
            self.have_lu = false;
            let tol0 = if s0 < 1.0 {
                settings.tol.max(RAMP_TOL)
            } else {
                settings.tol
            };
            let (ok, iters, res) = self.newton(s0, tol0, settings.max_iter * 2);
            steps += 1;
            if !ok {
                return self.finish(
                    HbStatus::NotConverged {
                        drive_fraction: 0.0,
                    },
                    res,
                    steps,
                    true,
                    Vec::new(),
                );
            }
            if s0 >= 1.0 {
                break (iters, 0.0);
            }
            // The branch of the linear response has det J > 0 (each line's 2×2 block
            // [[p, −q], [q, p]] has det p² + q²); a start on another sign is past a fold
            // already: start lower.
            let sign = self.branch_sign();
            if sign > 0.0 || s0 <= 1e-6 {
                break (iters, sign);
            }
            s0 = (0.1 * s0).max(1e-6);
        };
        let mut jumps = Vec::new();
        let mut s = s0;
        let mut ds = settings.ramp_step;
        let mut prev = self.x.clone();
        let mut prev_s = s;
        let mut good = self.x.clone();
        // The branch's tangent dx/ds at `good` (from the factorisation at hand).
        let mut tangent = self.x.clone();
        let mut tangent_new = self.x.clone();
        if s < 1.0 {
            self.tangent(&mut tangent);
        }
        // A fold whose landing failed: named if the ramp stops there.
        let mut unlanded = None;
        while s < 1.0 {
            if steps >= settings.max_ramp_steps || ds < 1e-7 {
                jumps.extend(unlanded);
                return self.stop_ramp(&good, s, steps, jumps);
            }
            let s_new = (s + ds).min(1.0);
            // Secant predictor.
            let secant = s > prev_s;
            let slope = if secant {
                (s_new - s) / (s - prev_s)
            } else {
                s_new / s - 1.0
            };
            for i in 0..nm * nr {
                let base = good[i];
                let d = if secant { base - prev[i] } else { base };
                self.x[i] = base + d * slope;
            }
            // Intermediate levels only feed the predictor: a loose tolerance there.
            let tol = if s_new < 1.0 {
                settings.tol.max(RAMP_TOL)
            } else {
                settings.tol
            };
            let (ok, it, _) = self.newton(s_new, tol, settings.max_iter);
            steps += 1;
            let (ok, sign_new) = if ok {
                self.continues_branch(&good, (&tangent, &mut tangent_new), s_new - s, sign)
            } else {
                (false, sign)
            };
            if ok {
                prev.copy_from_slice(&good);
                good.copy_from_slice(&self.x);
                prev_s = s;
                s = s_new;
                iters = it;
                sign = sign_new;
                std::mem::swap(&mut tangent, &mut tangent_new);
                if it <= 3 {
                    ds = (ds * 1.6).min(settings.ramp_step_max);
                }
            } else if ds <= FOLD_STEP && settings.stop_at_fold {
                // The branch ends between s and s + ds: a fold; the caller only wanted to know.
                jumps.push(s);
                return self.stop_ramp(&good, s, steps, jumps);
            } else if ds <= FOLD_STEP {
                // The branch ends between s and s + ds: a fold in the drive. An experiment
                // jumps there; follow the slow flow from the last state at the next level.
                self.x.copy_from_slice(&good);
                if self.land(s_new, tol) {
                    jumps.push(s);
                    unlanded = None;
                    good.copy_from_slice(&self.x);
                    prev.copy_from_slice(&self.x);
                    s = s_new;
                    prev_s = s;
                    ds = settings.ramp_step;
                    sign = self.branch_sign();
                    self.tangent(&mut tangent);
                } else {
                    // Closer to the fold the landing may succeed; if the ramp ends here, it
                    // ends at this fold.
                    unlanded = Some(s);
                    ds *= 0.5;
                }
            } else {
                ds *= 0.5;
            }
        }
        let r = self.residual(false, 1.0);
        self.finish(
            HbStatus::Converged { iterations: iters },
            r,
            steps,
            false,
            jumps,
        )
    }

    /// Whether the state Newton converged to at the next ramp level (`self.x`, `ds` above
    /// the last one) continues the branch of the last one (`good`, with tangent `tangent.0` =
    /// dx/ds and det J of sign `sign`; `0.0`: unknown), and the sign of det J at it; the
    /// tangent there into `tangent.1`. Newton converges from a step past a fold onto another
    /// branch as readily as onto the same one; the tests, none needing a factorisation
    /// unless the sign seems to change:
    /// - det J keeps its sign: along a branch parametrised by the drive it changes sign
    ///   exactly where the branch passes a fold (or a branch point), so a state of the other
    ///   sign lies past an odd number of them (the unstable middle branch of a hardening
    ///   resonance, typically). The sign is that of the last factorisation Newton used (near
    ///   the state: a chord step with a Jacobian of the other sign would not contract); a
    ///   change is confirmed on a factorisation at the state itself.
    /// - A step past two folds (from the low branch of a hardening resonance straight onto
    ///   the high one) keeps the sign, so steps larger than [`FOLD_STEP`] must also be
    ///   resolved: Newton moved the state at most [`BRANCH_CORRECTION`] times as far from the
    ///   tangent predictor `good + ds·tangent` as that predictor is from `good` (along a
    ///   branch the ratio is `O(ds·|x''|/|x'|)`), and the tangent's size changed by at most
    ///   that factor (it grows as `1/√δ` at a distance `δ` from a fold, and is far smaller on
    ///   the high branch than at the end of the low one).
    fn continues_branch(
        &mut self,
        good: &[Complex64],
        tangent: (&[Complex64], &mut [Complex64]),
        ds: f64,
        sign: f64,
    ) -> (bool, f64) {
        let (t0, t1) = tangent;
        let resolved = ds <= FOLD_STEP;
        if !resolved {
            let (mut moved, mut predicted) = (0.0f64, 0.0f64);
            for ((x, g), t) in self.x.iter().zip(good).zip(t0.iter()) {
                moved = moved.max((x - g - t * ds).norm());
                predicted = predicted.max((t * ds).norm());
            }
            // Written so that NaN fails.
            let near = moved <= BRANCH_CORRECTION * predicted;
            if !near {
                return (false, sign);
            }
        }
        let mut sign_new = self.branch_sign();
        if sign_new != sign && !self.fresh {
            self.have_lu = false;
            sign_new = self.branch_sign();
        }
        if sign_new == 0.0 || (sign != 0.0 && sign_new != sign) {
            return (false, sign_new);
        }
        self.tangent(t1);
        if !resolved {
            let size = |t: &[Complex64]| t.iter().map(|z| z.norm()).fold(0.0, f64::max);
            let ratio = size(t1) / size(t0);
            let similar = ratio <= BRANCH_CORRECTION && ratio * BRANCH_CORRECTION >= 1.0;
            if !similar {
                return (false, sign_new);
            }
        }
        (true, sign_new)
    }

    /// The tangent `dx/ds = J⁻¹ F` of the branch through the current state (`R = … − s F`),
    /// with the factorisation held (made at the state when none is; zero when singular).
    fn tangent(&mut self, out: &mut [Complex64]) {
        if self.branch_sign() == 0.0 {
            out.fill(Z);
            return;
        }
        for (i, f) in self.force.iter().enumerate() {
            self.step[2 * i] = f.re;
            self.step[2 * i + 1] = f.im;
        }
        self.lu.solve(&mut self.step);
        for (i, t) in out.iter_mut().enumerate() {
            *t = Complex64::new(self.step[2 * i], self.step[2 * i + 1]);
        }
    }

    /// Sign of det J: that of the factorisation held (the last one Newton used), or of one at
    /// the current state when none is held; `0.0` when singular.
    fn branch_sign(&mut self) -> f64 {
        if !self.have_lu {
            let regular = self.jacobian();
            self.have_lu = regular;
            self.fresh = regular;
            if !regular {
                return 0.0;
            }
        }
        self.lu.det_sign()
    }

    /// Ends a ramp that cannot go on: the last converged state `good`, at drive fraction `s`.
    fn stop_ramp(
        &mut self,
        good: &[Complex64],
        s: f64,
        steps: usize,
        jumps: Vec<f64>,
    ) -> SteadyState {
        self.x.copy_from_slice(good);
        let r = self.residual(false, s);
        self.finish(
            HbStatus::NotConverged { drive_fraction: s },
            r,
            steps,
            false,
            jumps,
        )
    }

    /// Newton at full drive from a given state (`amplitudes[n][r]` on this lattice), e.g. the
    /// previous point of a sweep or a noise study.
    pub fn solve_from(&mut self, start: &[Vec<Complex64>], settings: &HbSettings) -> SteadyState {
        self.have_lu = false;
        self.solve_continued(start, settings)
    }

    /// As [`HbSolver::solve_from`], but the first steps reuse the Jacobian factorised at the
    /// previous solve (or at the chosen start, `factor_at`) as chord steps while they contract the
    /// residual by at least a factor 4 each; a fresh factorisation follows only when they do
    /// not. For a problem whose values moved a little since ([`HbSolver::set_values`]: the next
    /// step of a fit) from that solve's state, this saves the factorisation, the dominant cost.
    /// The converged state is the same as `solve_from`'s to the tolerance.
    pub fn solve_continued(
        &mut self,
        start: &[Vec<Complex64>],
        settings: &HbSettings,
    ) -> SteadyState {
        let nr = self.lattice.len();
        for (n, row) in start.iter().enumerate().take(self.model.n_modes()) {
            self.x[n * nr..(n + 1) * nr].copy_from_slice(&row[..nr]);
        }
        self.fresh = false;
        let (ok, it, r) = self.newton(1.0, settings.tol, settings.max_iter * 2);
        let status = if ok {
            HbStatus::Converged { iterations: it }
        } else {
            HbStatus::NotConverged {
                drive_fraction: 1.0,
            }
        };
        self.finish(status, r, 1, false, Vec::new())
    }

    /// Lands at drive fraction `s` from the current state (beyond a fold, off any branch) the
    /// way the resonator does: the slow flow `(2iΩ_r + γ_n) Ẋ = −R(X)` (see
    /// [`HbSolver::stability`]) integrated by linearly implicit Euler,
    /// `(C/Δt + J) ΔX = −R`, from `Δt` a tenth of the fastest decay time, growing as the
    /// residual falls (switched evolution relaxation) until it is Newton. Small steps first
    /// keep the trajectory, so the state ends in the basin the physical transient reaches.
    /// Returns whether the residual met `tol`.
    fn land(&mut self, s: f64, tol: f64) -> bool {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let nu = self.unknowns();
        let g_max = (0..nm).map(|n| self.model.gamma(n)).fold(0.0, f64::max);
        let mut dt = 0.1 * 2.0 / g_max;
        let mut r0 = self.residual(false, s);
        for _ in 0..LAND_MAX_STEPS {
            if r0 <= tol {
                self.have_lu = false;
                return true;
            }
            self.assemble_jacobian();
            for n in 0..nm {
                let g = self.model.gamma(n);
                for (r, &f) in self.lattice.iter().enumerate() {
                    let c = Complex64::new(g, 2.0 * TAU * f) / dt;
                    let k = 2 * (n * nr + r);
                    self.jac[k * nu + k] += c.re;
                    self.jac[k * nu + k + 1] -= c.im;
                    self.jac[(k + 1) * nu + k] += c.im;
                    self.jac[(k + 1) * nu + k + 1] += c.re;
                }
            }
            if !self.lu.factor(&self.jac) {
                dt *= 0.25;
                continue;
            }
            for i in 0..nu / 2 {
                self.step[2 * i] = -self.res[i].re;
                self.step[2 * i + 1] = -self.res[i].im;
            }
            self.lu.solve(&mut self.step);
            for i in 0..nu / 2 {
                self.x_try[i] = self.x[i] + Complex64::new(self.step[2 * i], self.step[2 * i + 1]);
            }
            let r1 = self.residual(true, s);
            if r1.is_finite() {
                std::mem::swap(&mut self.x, &mut self.x_try);
                dt *= (r0 / r1).clamp(1.0, 2.0);
                r0 = r1;
            } else {
                self.residual(false, s);
                dt *= 0.25;
            }
        }
        self.have_lu = false;
        false
    }

    fn finish(
        &mut self,
        status: HbStatus,
        residual: f64,
        steps: usize,
        zero: bool,
        drive_jumps: Vec<f64>,
    ) -> SteadyState {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let lattice = &self.lattice;
        let amplitudes = (0..nm)
            .map(|n| {
                self.x[n * nr..(n + 1) * nr]
                    .iter()
                    .zip(lattice)
                    .map(|(&z, &f)| {
                        if zero || !(z.re.is_finite() && z.im.is_finite()) {
                            Z
                        } else if f <= LINE_TOL_HZ {
                            // The static offset is real.
                            Complex64::new(z.re, 0.0)
                        } else {
                            z
                        }
                    })
                    .collect()
            })
            .collect();
        SteadyState {
            lattice_hz: self.lattice.clone(),
            amplitudes,
            status,
            residual: if residual.is_finite() {
                residual
            } else {
                f64::MAX
            },
            ramp_steps: steps,
            drive_jumps,
        }
    }
}

/// Solves the steady state under `drive` with the lattice chosen by `settings.lattice`.
pub fn steady_state(
    model: &NumericModel,
    drive: &Excitation,
    settings: &HbSettings,
) -> Result<SteadyState, SimError> {
    let mut solver = HbSolver::new(model, drive, &settings.lattice)?;
    Ok(solver.solve(settings))
}

/// Stability of `state`, a steady state of `model` under `drive` (solved on its own lattice),
/// by Hill's method in slow-flow form (see [`HbSolver::stability`]).
pub fn check_stability(
    model: &NumericModel,
    drive: &Excitation,
    state: &SteadyState,
) -> Result<Stability, SimError> {
    let mut solver = HbSolver::with_lattice(model, drive, state.lattice_hz.clone())?;
    solver.stability(state)
}

/// What widening the lattice changes: the steady state with the given settings, the one with
/// the order raised by 2, the window by 1.5× and the direct harmonics added wherever they fall
/// ([`LatticeSettings::harmonics`]), and the largest change of an amplitude at the
/// frequencies `at_hz` (every lattice frequency of the first when empty), relative to the
/// largest amplitude.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceReport {
    /// The steady state on the chosen lattice.
    pub state: SteadyState,
    /// Lattice sizes: chosen, widened.
    pub lattice_sizes: (usize, usize),
    /// `max |X − X'| / max |X|` over the compared frequencies.
    pub change: f64,
}

/// Solves twice (chosen and widened lattice) and reports the change; see [`ConvergenceReport`].
pub fn convergence_report(
    model: &NumericModel,
    drive: &Excitation,
    settings: &HbSettings,
    at_hz: &[f64],
) -> Result<ConvergenceReport, SimError> {
    let state = steady_state(model, drive, settings)?;
    let mut wide = settings.clone();
    wide.lattice.order += 2;
    wide.lattice.window_rel *= 1.5;
    // The direct harmonics (3f, 2f1 + f2, …) lie far from any resonance and are left out by
    // the window, yet feed back on the lines near resonance (1.2e-6 relative on the
    // nanostring's sidebands).
    wide.lattice.harmonics = true;
    let state2 = steady_state(model, drive, &wide)?;
    let freqs: Vec<f64> = if at_hz.is_empty() {
        state.lattice_hz.clone()
    } else {
        at_hz.to_vec()
    };
    let mut big: f64 = 0.0;
    let mut diff: f64 = 0.0;
    for n in 0..state.amplitudes.len() {
        for &f in &freqs {
            let a = state.amplitude(n, f);
            big = big.max(a.norm());
            diff = diff.max((a - state2.amplitude(n, f)).norm());
        }
    }
    Ok(ConvergenceReport {
        lattice_sizes: (state.lattice_hz.len(), state2.lattice_hz.len()),
        state,
        change: diff / big.max(f64::MIN_POSITIVE),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{linear_response, Term};

    fn duffing(beta: f64) -> NumericModel {
        NumericModel::new(
            vec!["q".into()],
            vec![1000.0],
            vec![100.0],
            vec![Term {
                eq: 0,
                coef: beta,
                factors: vec![(0, 3)],
            }],
        )
        .expect("model")
    }

    #[test]
    fn status_reads_as_words() {
        let s = HbStatus::NotConverged {
            drive_fraction: 0.8996,
        };
        assert_eq!(s.to_string(), "stopped at 90.0 % of the drive");
        assert!(!s.to_string().contains('{'));
    }

    #[test]
    fn vanishing_drive_is_linear_frf() {
        let m = duffing(1e12);
        let drive = Excitation {
            tones_hz: vec![995.0, 1005.0],
            force: vec![vec![Complex64::new(1e-6, 0.0), Complex64::new(0.0, 2e-6)]],
        };
        let st = steady_state(&m, &drive, &HbSettings::default()).expect("solve");
        assert!(st.converged(), "{:?}", st.status);
        for (d, &f) in drive.tones_hz.iter().enumerate() {
            let want = linear_response(m.omega(0), m.gamma(0), f, drive.force[0][d]);
            let got = st.amplitude(0, f);
            assert!((got - want).norm() <= 1e-9 * want.norm(), "{got} vs {want}");
        }
    }

    #[test]
    fn single_tone_matches_cubic_balance() {
        // One harmonic: (ω² − Ω² + iΩγ) X + 3/4 β |X|² X = F, checked on the solution.
        let beta = 4e13;
        let m = duffing(beta);
        let drive = Excitation {
            tones_hz: vec![1003.0],
            force: vec![vec![Complex64::new(30.0, 0.0)]],
        };
        let mut s = HbSettings::default();
        s.lattice.window_rel = 0.01; // only the fundamental (3f is far)
        let st = steady_state(&m, &drive, &s).expect("solve");
        assert!(st.converged());
        assert_eq!(st.lattice_hz, vec![1003.0]);
        let x = st.amplitude(0, 1003.0);
        let o = TAU * 1003.0;
        let l = Complex64::new(m.omega(0).powi(2) - o * o, o * m.gamma(0));
        let r = l * x + x * x.norm_sqr() * 0.75 * beta - 30.0;
        assert!(r.norm() < 1e-9 * 30.0, "{r}");
        // Nonlinear: differs clearly from the linear response.
        let lin = linear_response(m.omega(0), m.gamma(0), 1003.0, Complex64::new(30.0, 0.0));
        assert!((x - lin).norm() > 0.05 * lin.norm());
    }

    /// Positive roots `a = |X|²` of the one-harmonic Duffing balance
    /// `k² a³ + 2pk a² + (p² + q²) a − |F|² = 0` (`L = p + iq`, `k = 3β/4`).
    fn duffing_roots(l: Complex64, k: f64, f: f64) -> Vec<f64> {
        let g = |a: f64| k * k * a * a * a + 2.0 * l.re * k * a * a + l.norm_sqr() * a - f * f;
        let grid: Vec<f64> = (0..4000)
            .map(|i| 1e-16 * 10f64.powf(i as f64 / 250.0))
            .collect();
        let mut out = Vec::new();
        for w in grid.windows(2) {
            let (mut lo, mut hi) = (w[0], w[1]);
            if g(lo).signum() == g(hi).signum() {
                continue;
            }
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if g(mid).signum() == g(lo).signum() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            out.push(0.5 * (lo + hi));
        }
        out
    }

    #[test]
    fn duffing_branches_stability() {
        // Hardening Duffing, f0 = 1 kHz, Q = 100, strongly driven: three branches above resonance.
        let beta = 4e13;
        let m = duffing(beta);
        let force = 300.0;
        let k = 0.75 * beta;
        let (w, g) = (m.omega(0), m.gamma(0));
        let mut found = None;
        for i in 0..400 {
            let f = 1000.0 + 0.5 * i as f64;
            let o = TAU * f;
            let l = Complex64::new(w * w - o * o, o * g);
            let roots = duffing_roots(l, k, force);
            if roots.len() == 3 {
                found = Some((f, l, roots));
                break;
            }
        }
        let (f, l, roots) = found.expect("a frequency with three branches");
        let drive = Excitation {
            tones_hz: vec![f],
            force: vec![vec![Complex64::new(force, 0.0)]],
        };
        let mut solver = HbSolver::with_lattice(&m, &drive, vec![f]).expect("solver");
        let mut verdicts = Vec::new();
        for &a in &roots {
            let x = Complex64::new(force, 0.0) / (l + k * a);
            let st = solver.solve_from(&[vec![x]], &HbSettings::default());
            assert!(st.converged());
            assert!((st.amplitudes[0][0] - x).norm() < 1e-8 * x.norm());
            let v = solver.stability(&st).expect("verdict");
            verdicts.push((v, st));
        }
        // Lower and upper branches stable, the middle one a saddle.
        assert!(verdicts[0].0.stable && verdicts[2].0.stable, "{verdicts:?}");
        assert!(!verdicts[1].0.stable, "{:?}", verdicts[1].0);
        assert!(verdicts[1].0.growth_rate > 1e-3 * verdicts[1].0.linear_decay_rate);
        // Stable branches decay no faster than the linear resonator (rate γ/2).
        for i in [0, 2] {
            let v = verdicts[i].0;
            assert!(
                v.growth_rate < 0.0 && v.growth_rate >= -1.1 * v.linear_decay_rate,
                "{v:?}"
            );
        }
        // check_stability agrees, and a linear-regime state is stable at rate ≈ γ/2.
        let v = check_stability(&m, &drive, &verdicts[1].1).expect("verdict");
        assert!(!v.stable);
        let weak = Excitation {
            tones_hz: vec![1000.0],
            force: vec![vec![Complex64::new(1e-3, 0.0)]],
        };
        let st = steady_state(&m, &weak, &HbSettings::default()).expect("solve");
        let v = check_stability(&m, &weak, &st).expect("verdict");
        assert!(v.stable);
        assert!((v.growth_rate + 0.5 * g).abs() < 1e-3 * g, "{v:?}");
    }

    /// The nanostring of the method's paper (two coupled Duffing modes).
    fn nanostring() -> NumericModel {
        let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
        NumericModel::new(
            vec!["q1".into(), "q2".into()],
            vec![207582.0, 415842.0],
            vec![116232.0, 599173.0],
            vec![
                t(0, 2.68e22, vec![(0, 3)]),
                t(0, 8.57e22, vec![(0, 1), (1, 2)]),
                t(1, 8.57e22, vec![(0, 2), (1, 1)]),
                t(1, 3.70e23, vec![(1, 3)]),
            ],
        )
        .expect("model")
    }

    /// Largest amplitude difference relative to the largest amplitude.
    fn rel_change(a: &SteadyState, b: &SteadyState) -> f64 {
        let big = a
            .amplitudes
            .iter()
            .flatten()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        let diff = a
            .amplitudes
            .iter()
            .flatten()
            .zip(b.amplitudes.iter().flatten())
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max);
        diff / big
    }

    #[test]
    fn coarse_ramp_lands_where_the_full_ramp_does() {
        let c = |x: f64| Complex64::new(x, 0.0);
        let model = nanostring();
        let three_tone = Excitation {
            tones_hz: vec![207572.5, 207592.5, 415841.5],
            force: vec![vec![c(3.5), c(3.5), c(0.0)], vec![c(0.0), c(0.0), c(1.81)]],
        };
        // Two tones above resonance, strong enough for the two-tone response to be bistable:
        // the drive-up branch is the low one, which a direct solve at full drive can miss.
        let bistable = Excitation {
            tones_hz: vec![207590.0, 207600.0],
            force: vec![vec![c(4.0), c(0.4)], vec![c(0.0), c(0.0)]],
        };
        let settings = HbSettings::default();
        for drive in [three_tone, bistable] {
            let mut solver = HbSolver::new(&model, &drive, &settings.lattice).expect("solver");
            let (coarse, lines) = solver.coarse.as_ref().expect("a coarse ramp lattice");
            assert!(lines.len() < solver.lattice.len() && coarse.lattice.len() == lines.len());
            let fast = solver.solve(&settings);
            let full = solver.solve_ramp(&settings);
            assert!(fast.converged() && full.converged(), "{fast:?} {full:?}");
            assert!(fast.residual <= settings.tol, "{}", fast.residual);
            let d = rel_change(&fast, &full);
            assert!(d < 1e-9, "coarse and full ramps differ by {d:e}");
            if drive.tones_hz[1] - drive.tones_hz[0] < 15.0 {
                // Bistable indeed: from a large guess Newton finds another steady state.
                let mut guess = fast.amplitudes.clone();
                guess[0].iter_mut().for_each(|z| *z *= 2.5);
                let other = solver.solve_from(&guess, &settings);
                assert!(other.converged() && rel_change(&fast, &other) > 0.1);
            }
        }
    }

    #[test]
    fn drive_ramp_jumps_at_a_fold_like_the_experiment() {
        // Hardening Duffing above resonance: driven up at a fixed frequency, the low branch
        // ends at a fold in the force and the state jumps to the high branch, which is the
        // only state left beyond the fold.
        let beta = 4e13;
        let m = duffing(beta);
        let k = 0.75 * beta;
        let (w, g) = (m.omega(0), m.gamma(0));
        let f = 1030.0;
        let o = TAU * f;
        let l = Complex64::new(w * w - o * o, o * g);
        // The fold: the largest force with three branches.
        let fold = (1..4000)
            .map(|i| 0.5 * i as f64)
            .filter(|&force| duffing_roots(l, k, force).len() == 3)
            .fold(0.0, f64::max);
        assert!(fold > 0.0, "no bistable range at {f} Hz");
        let force = 1.25 * fold;
        let roots = duffing_roots(l, k, force);
        assert_eq!(
            roots.len(),
            1,
            "beyond the fold only the high branch is left"
        );
        let want = Complex64::new(force, 0.0) / (l + k * roots[0]);
        let drive = Excitation {
            tones_hz: vec![f],
            force: vec![vec![Complex64::new(force, 0.0)]],
        };
        let st = steady_state(&m, &drive, &HbSettings::default()).expect("solve");
        assert!(st.converged(), "{:?}", st.status);
        let got = st.amplitude(0, f);
        assert!((got - want).norm() < 1e-8 * want.norm(), "{got} vs {want}");
        // One jump, where the low branch ends (fold / force), located to the ramp's step.
        assert_eq!(st.drive_jumps.len(), 1, "{:?}", st.drive_jumps);
        let at = st.drive_jumps[0] * force;
        assert!(
            (at - fold).abs() < 0.01 * fold,
            "jump at {at}, fold at {fold}"
        );
        assert!(check_stability(&m, &drive, &st).expect("verdict").stable);
    }

    #[test]
    fn convergence_report_sees_the_far_harmonics() {
        // single_q1 of the nanostring: the lines near resonance are converged in the order
        // (1e-9), but the third harmonics near 623 kHz, outside the window, change them by
        // 1.2e-7 of the largest amplitude, 1.2e-6 relative on the sidebands (the time domain
        // agrees with the widened lattice to 2e-8).
        let c = |x: f64| Complex64::new(x, 0.0);
        let drive = Excitation {
            tones_hz: vec![207572.5, 207592.5],
            force: vec![vec![c(3.5), c(3.5)], vec![c(0.0), c(0.0)]],
        };
        let rep =
            convergence_report(&nanostring(), &drive, &HbSettings::default(), &[]).expect("report");
        assert!(rep.state.converged());
        assert!(rep.lattice_sizes.1 > rep.lattice_sizes.0);
        assert!(rep.change > 3e-8 && rep.change < 1e-5, "{:e}", rep.change);
    }
}

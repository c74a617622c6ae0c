//! [`ReducedSolver`]: harmonic balance on the modes a drive reaches ([`ActiveModes`]), with
//! states, stability and sensitivities of the whole model.
//!
//! A measurement that drives one or two modes of a twenty-mode string with Duffing and
//! dispersive couplings only (every term of mode `j`'s equation holds `q_j`) excites those
//! modes alone; the others are exactly zero. Solving all twenty costs a dense Jacobian of
//! `(2·20·R)²` and its LU; solving the reached ones costs `(2·|A|·R)²`. The idle modes enter
//! only the stability verdict, through their own block of the Jacobian (parametric
//! instability), judged on small solvers of the active modes and one idle part each.

use super::{ActiveModes, HbSettings, HbSolver, Stability, SteadyState};
use crate::lattice::{choose_lattice, LatticeSettings};
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;

/// A harmonic-balance problem solved on the modes its drive reaches: the reduction of
/// [`HbSolver`] that callers re-solving one experiment at many values (a fit, a planner) use.
/// Every state it takes and returns has every mode of the model (idle ones zero), on the
/// lattice it was set up with. With every mode reached it is [`HbSolver`] itself.
#[derive(Debug, Clone)]
pub struct ReducedSolver {
    /// The whole model and drive of the current values.
    model: NumericModel,
    drive: Excitation,
    /// Modes counted as forced whatever their force's value (see [`ActiveModes::of`]).
    forced: Vec<usize>,
    active: ActiveModes,
    lattice: Vec<f64>,
    /// The solver of the active modes.
    pub(crate) inner: HbSolver,
    /// Per idle part ([`ActiveModes::idle_parts`]): the solver of the active modes and that
    /// part (built at the first stability check) and the part's indices in it. (One solver
    /// of every idle part, its Jacobian assembled once, measured slower on the ten-mode
    /// string: the assembly of all the idle equations cost more than the parts' apart.)
    idle: Vec<Option<(HbSolver, Vec<usize>)>>,
}

impl ReducedSolver {
    /// Sets the problem up on the lattice `settings` choose for the whole model (the lattice
    /// [`HbSolver::new`] would have), solving only the modes `drive` reaches and those of
    /// `forced` (modes whose force is a free quantity, zero or not). Errors as
    /// [`HbSolver::new`].
    pub fn new(
        model: &NumericModel,
        drive: &Excitation,
        settings: &LatticeSettings,
        forced: &[usize],
    ) -> Result<Self, SimError> {
        let lattice = choose_lattice(model, drive, settings)?;
        Self::with_lattice(model, drive, lattice, forced)
    }

    /// As [`ReducedSolver::new`] on a given lattice (as [`HbSolver::with_lattice`]).
    pub fn with_lattice(
        model: &NumericModel,
        drive: &Excitation,
        lattice: Vec<f64>,
        forced: &[usize],
    ) -> Result<Self, SimError> {
        drive.check(model.n_modes())?;
        let active = reach(model, drive, forced);
        let inner = if active.is_all() {
            HbSolver::with_lattice(model, drive, lattice.clone())?
        } else {
            let modes = active.modes();
            HbSolver::with_lattice(
                &model.restricted(modes)?,
                &drive.restricted(modes),
                lattice.clone(),
            )?
        };
        Ok(Self {
            model: model.clone(),
            drive: drive.clone(),
            forced: forced.to_vec(),
            idle: vec![None; active.idle_parts().len()],
            active,
            lattice,
            inner,
        })
    }

    /// Sets new values of the same experiment (as [`HbSolver::set_values`]: the same terms,
    /// the same tones); when the drive now reaches other modes (a force turned zero or not),
    /// the problem is set up again on the same lattice.
    pub fn set_values(&mut self, model: &NumericModel, drive: &Excitation) -> Result<(), SimError> {
        drive.check(model.n_modes())?;
        let active = reach(model, drive, &self.forced);
        if active != self.active || model.n_modes() != self.model.n_modes() {
            *self = Self::with_lattice(model, drive, self.lattice.clone(), &self.forced)?;
            return Ok(());
        }
        if active.is_all() {
            self.inner.set_values(model, drive)?;
        } else {
            let modes = active.modes();
            self.inner
                .set_values(&model.restricted(modes)?, &drive.restricted(modes))?;
        }
        for (slot, part) in self.idle.iter_mut().zip(active.idle_parts()) {
            if let Some((solver, _)) = slot.as_mut() {
                let modes = with_part(active.modes(), part);
                let sub = idle_block_model(model, active.modes(), part)?;
                solver.set_values(&sub, &drive.restricted(&modes))?;
            }
        }
        self.model = model.clone();
        self.drive = drive.clone();
        Ok(())
    }

    /// Whether [`ReducedSolver::set_values`] with `model` and `drive` gives the solver
    /// [`ReducedSolver::with_lattice`] would set up on `lattice` (no forced modes): the same
    /// lattice, tones, pump tones and number of modes (`set_values` checks the terms).
    pub(crate) fn same_set_up(
        &self,
        model: &NumericModel,
        drive: &Excitation,
        lattice: &[f64],
    ) -> bool {
        self.forced.is_empty()
            && self.lattice == lattice
            && self.model.n_modes() == model.n_modes()
            && self.drive.tones_hz == drive.tones_hz
            && self.drive.pumps.len() == drive.pumps.len()
            && self
                .drive
                .pumps
                .iter()
                .zip(&drive.pumps)
                .all(|(a, b)| a.hz == b.hz)
    }

    /// The lattice, Hz.
    pub fn lattice(&self) -> &[f64] {
        &self.lattice
    }

    /// The whole model of the current values.
    pub fn model(&self) -> &NumericModel {
        &self.model
    }

    /// The modes solved for and the idle rest.
    pub fn active(&self) -> &ActiveModes {
        &self.active
    }

    /// Number of real unknowns solved for (`2 · |A| · R`).
    pub fn unknowns(&self) -> usize {
        self.inner.unknowns()
    }

    /// [`HbSolver::solve`] (the drive ramp from rest), the idle modes zero.
    pub fn solve(&mut self, settings: &HbSettings) -> SteadyState {
        let st = self.inner.solve(settings);
        self.active.expand_state(st)
    }

    /// [`HbSolver::solve_from`] from `start[n][r]` (every mode of the model).
    pub fn solve_from(&mut self, start: &[Vec<Complex64>], settings: &HbSettings) -> SteadyState {
        let st = self
            .inner
            .solve_from(&self.active.restrict_rows(start), settings);
        self.active.expand_state(st)
    }

    /// [`HbSolver::solve_continued`] from `start[n][r]` (every mode of the model).
    pub fn solve_continued(
        &mut self,
        start: &[Vec<Complex64>],
        settings: &HbSettings,
    ) -> SteadyState {
        let st = self
            .inner
            .solve_continued(&self.active.restrict_rows(start), settings);
        self.active.expand_state(st)
    }

    /// [`HbSolver::solve_after`] from `start[n][r]` (every mode of the model).
    pub fn solve_after(&mut self, start: &[Vec<Complex64>], settings: &HbSettings) -> SteadyState {
        let st = self
            .inner
            .solve_after(&self.active.restrict_rows(start), settings);
        self.active.expand_state(st)
    }

    /// Stability of `state` (every mode of the model, idle ones zero) as
    /// [`HbSolver::stability`] judges it on the whole model: the active block's slow flow and
    /// every idle part's block (parametric instability of an idle mode), the growth rate the
    /// largest of them, the decay rate the slowest of every mode's.
    pub fn stability(&mut self, state: &SteadyState) -> Result<Stability, SimError> {
        self.judge(state, false)
    }

    /// The verdict of [`ReducedSolver::stability`] for a caller that needs no rates when the
    /// state is stable (a planner's range checks): `None` when it is stable, its
    /// [`Stability`] (exact rates) when not. Blocks that a norm bound proves decaying (most,
    /// at the weak drives a plan keeps) skip their spectra, the bulk of a check's cost; the
    /// verdict is the same (a test compares them).
    pub fn unstable(&mut self, state: &SteadyState) -> Result<Option<Stability>, SimError> {
        let quick = self.judge(state, true)?;
        if quick.stable {
            return Ok(None);
        }
        let v = self.judge(state, false)?;
        Ok((!v.stable).then_some(v))
    }

    /// [`ReducedSolver::stability`]; with `skip_proven`, without the blocks proven decaying
    /// (its growth rate then that of the others, `-∞` when every block is proven).
    fn judge(&mut self, state: &SteadyState, skip_proven: bool) -> Result<Stability, SimError> {
        if state.amplitudes.len() != self.model.n_modes() {
            return Err(SimError::OtherLattice);
        }
        // A state that moves an idle mode (not one this solver found: another branch of the
        // whole model) is judged on the whole model.
        let zero = Complex64::new(0.0, 0.0);
        let idle_moves = (0..self.model.n_modes())
            .filter(|m| !self.active.modes().contains(m))
            .any(|m| state.amplitudes[m].iter().any(|z| *z != zero));
        if idle_moves {
            let mut full = HbSolver::with_lattice(&self.model, &self.drive, self.lattice.clone())?;
            return full.stability(state);
        }
        let decay = (0..self.model.n_modes())
            .map(|n| 0.5 * self.model.gamma(n))
            .fold(f64::INFINITY, f64::min);
        let active = self.active.restrict_state(state);
        let mut growth = if skip_proven {
            self.inner.unproven_growth(&active, None)?
        } else {
            self.inner.stability(&active)?.growth_rate
        };
        // The verdict is decided once a block is unstable.
        for i in 0..self.active.idle_parts().len() {
            if skip_proven && growth >= 1e-6 * decay {
                break;
            }
            growth = growth.max(self.idle_growth(state, i, skip_proven)?);
        }
        Ok(Stability {
            stable: growth < 1e-6 * decay,
            growth_rate: growth,
            linear_decay_rate: decay,
        })
    }

    /// The largest growth rate of idle part `i`'s block at `state` (every mode of the model),
    /// its solver built at the first call; with `skip_proven`, `-∞` when a norm bound proves
    /// it decaying.
    fn idle_growth(
        &mut self,
        state: &SteadyState,
        i: usize,
        skip_proven: bool,
    ) -> Result<f64, SimError> {
        let part = &self.active.idle_parts()[i];
        let modes = with_part(self.active.modes(), part);
        let (solver, idx) = match &mut self.idle[i] {
            Some(s) => s,
            slot => {
                let solver = HbSolver::single_sharing(
                    &idle_block_model(&self.model, self.active.modes(), part)?,
                    &self.drive.restricted(&modes),
                    self.lattice.clone(),
                    Some(&self.inner),
                )?;
                let idx = part
                    .iter()
                    .filter_map(|m| modes.iter().position(|x| x == m))
                    .collect();
                slot.insert((solver, idx))
            }
        };
        let st = SteadyState {
            amplitudes: modes.iter().map(|&m| state.amplitudes[m].clone()).collect(),
            lattice_hz: state.lattice_hz.clone(),
            drive_jumps: Vec::new(),
            ..*state
        };
        solver.parts_growth(&st, std::slice::from_ref(idx), skip_proven)
    }
}

/// The modes `drive` reaches, every mode when it reaches none (a drive without force: the
/// rest state of the whole model).
fn reach(model: &NumericModel, drive: &Excitation, forced: &[usize]) -> ActiveModes {
    let a = ActiveModes::of(model, drive, forced);
    if a.modes().is_empty() {
        ActiveModes::all(model.n_modes())
    } else {
        a
    }
}

/// The model whose Jacobian's block of the idle modes `part` is the whole model's at a state
/// where every idle mode is zero: the active modes and `part`, with only the terms of
/// `part`'s equations that hold exactly one idle factor (the others' derivatives by a
/// `part` amplitude vanish there). The active modes' equations are left linear: their rows
/// are not judged, and dropping their terms leaves few products to evaluate.
fn idle_block_model(
    model: &NumericModel,
    active: &[usize],
    part: &[usize],
) -> Result<NumericModel, SimError> {
    let n = model.n_modes();
    let idle = |v: usize| v < 2 * n && !active.contains(&(v % n));
    let modes = with_part(active, part);
    model
        .restricted_where(&modes, |eq, factors| {
            let k: u32 = factors
                .iter()
                .filter(|&&(v, _)| idle(v))
                .map(|&(_, e)| e)
                .sum();
            part.contains(&eq) && k == 1
        })
        // Without its higher own powers an idle mode of negative linear stiffness is
        // refused as unbounded: then the block of every term.
        .or_else(|_| model.restricted(&modes))
}

/// `active` and `part` merged, ascending.
fn with_part(active: &[usize], part: &[usize]) -> Vec<usize> {
    let mut m: Vec<usize> = active.iter().chain(part).copied().collect();
    m.sort_unstable();
    m
}

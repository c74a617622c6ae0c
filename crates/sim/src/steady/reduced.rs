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
use std::f64::consts::TAU;

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
    /// Per idle part: its solver still has the values before the last
    /// [`ReducedSolver::set_values`] (set when first needed: a check that
    /// [`ReducedSolver::idle_bound`] settles never needs them).
    idle_stale: Vec<bool>,
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
            idle_stale: vec![false; active.idle_parts().len()],
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
        // The idle parts' solvers take the new values when a check first needs them.
        for (stale, slot) in self.idle_stale.iter_mut().zip(&self.idle) {
            *stale = slot.is_some();
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
            // Proven decaying without assembling the block: as if its solver had proven it.
            if skip_proven && self.idle_bound(state, i) < 0.0 {
                continue;
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
        if std::mem::take(&mut self.idle_stale[i]) {
            if let Some((solver, _)) = self.idle[i].as_mut() {
                let sub = idle_block_model(&self.model, self.active.modes(), part)?;
                solver.set_values(&sub, &self.drive.restricted(&modes))?;
            }
        }
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

    /// An upper bound (1/s) on the growth rates of idle part `i`'s block at `state` (every
    /// mode of the model, idle ones zero) as [`HbSolver::parts_growth`] computes them (the far
    /// lines condensed), from the active amplitudes and the terms' coefficients alone: no
    /// solver, no assembly. `+∞` when it finds none (pump or non-smooth terms, non-finite
    /// values). Most idle blocks of a plan's drives are proven decaying here, for a fraction
    /// of the cost of assembling their Jacobian.
    ///
    /// The block is `J = L + R`: `L` the linear lines `l_k = ω_n² − Ω_r² + iΩ_rγ_n`, `R` the
    /// derivatives of the part's terms with one idle factor (the others vanish at the state).
    /// Such a term `b · x_idle · P(active)` maps a perturbation `δx` to the lattice lines of
    /// `b P(t) δx(t)`; with `q = Re Σ X_r e^{iΩ_r t}`, the lines' squared sum is at most twice
    /// the mean square of the product (Bessel), `≤ 2 sup|bP|² ⟨δx²⟩ ≤ 2 sup|bP|² ‖δX‖²`
    /// (`‖δX‖²` with `Ω_max²` for a velocity), so `‖R‖₂ ≤ B = √2 Σ sup|bP| (· Ω_max)`, each
    /// `sup|q_a| ≤ Σ_r |X_{a,r}|`, `sup|q̇_a| ≤ Σ_r Ω_r |X_{a,r}|`. The flow the verdict
    /// takes the spectrum of is `−C_N (J_NN − J_NF J_FF⁻¹ J_FN)` for the near and far lines
    /// `N`, `F` of [`HbSolver::far_lines`], `= D + E` with `D = diag(−c_k l_k)` normal and
    /// `‖E‖₂ ≤ max|c_k| (B + B²/(min_F |l_k| − B))` (`J_NF = R_NF`, `‖J_FF⁻¹‖ ≤ 1/(min_F |l_k| −
    /// B)`); by Bauer–Fike `Re λ ≤ max Re(−c_k l_k) + ‖E‖₂`. Not knowing `N` and `F` without
    /// the Jacobian, it takes the maxima over every line and `min_F` over every line that
    /// can be far (not its mode's nearest, `|c_k l_k| > 30 γ_n`): an upper bound for any split.
    fn idle_bound(&self, state: &SteadyState, i: usize) -> f64 {
        let model = &self.model;
        let n = model.n_modes();
        if !model.rough_terms().is_empty() || !self.drive.pumps.is_empty() || model.has_pump_terms()
        {
            return f64::INFINITY;
        }
        let part = &self.active.idle_parts()[i];
        let active = self.active.modes();
        let omega: Vec<f64> = self.lattice.iter().map(|f| TAU * f).collect();
        let omega_max = omega.iter().copied().fold(0.0, f64::max);
        // sup |x_v(t)| of an active variable (position or velocity).
        let sup = |v: usize| -> f64 {
            let rate = |r: usize| if v < n { 1.0 } else { omega[r] };
            state.amplitudes[v % n]
                .iter()
                .enumerate()
                .map(|(r, z)| rate(r) * z.norm())
                .sum()
        };
        let mut b = 0.0;
        for t in model.terms().iter().filter(|t| part.contains(&t.eq)) {
            let idle: Vec<&(usize, u32)> = t
                .factors
                .iter()
                .filter(|&&(v, _)| !active.contains(&(v % n)))
                .collect();
            let &[&(v_idle, 1)] = idle.as_slice() else {
                continue;
            };
            let mut p = t.coef.abs();
            for &(v, e) in t.factors.iter().filter(|f| f.0 != v_idle) {
                p *= sup(v).powi(e as i32);
            }
            if v_idle >= n {
                p *= omega_max;
            }
            b += p;
        }
        b *= std::f64::consts::SQRT_2;
        let (mut re_d, mut c_max, mut l_far) = (f64::NEG_INFINITY, 0.0_f64, f64::INFINITY);
        for &m in part {
            let (w, g) = (model.omega(m), model.gamma(m));
            // The line far_lines always keeps: the first nearest to the resonance.
            let mut nearest = 0;
            for (r, f) in self.lattice.iter().enumerate() {
                if (f - w / TAU).abs() < (self.lattice[nearest] - w / TAU).abs() {
                    nearest = r;
                }
            }
            for (r, &o) in omega.iter().enumerate() {
                let l = Complex64::new(w * w - o * o, o * g);
                let c = Complex64::new(1.0, 0.0) / Complex64::new(g, 2.0 * o);
                re_d = re_d.max((-c * l).re);
                c_max = c_max.max(c.norm());
                if r != nearest && (l * c).norm() > super::CONDENSE_SEPARATION * g {
                    l_far = l_far.min(l.norm());
                }
            }
        }
        let mut bound = re_d + c_max * b;
        if l_far.is_finite() {
            // (A NaN `b` falls through to the NaN check below.)
            if l_far <= b {
                return f64::INFINITY;
            }
            bound += c_max * b * b / (l_far - b);
        }
        if bound.is_nan() {
            f64::INFINITY
        } else {
            bound
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Term;

    /// Two Duffing modes with a dispersive coupling, the second idle under a drive of the
    /// first; its frequency `f2`.
    fn pair(f2: f64) -> NumericModel {
        let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
        NumericModel::new(
            vec!["q1".into(), "q2".into()],
            vec![207582.0, f2],
            vec![116232.0, 116232.0],
            vec![
                t(0, 2.68e22, vec![(0, 3)]),
                t(0, 8.57e22, vec![(0, 1), (1, 2)]),
                t(1, 8.57e22, vec![(0, 2), (1, 1)]),
                t(1, 3.70e23, vec![(1, 3)]),
            ],
        )
        .expect("model")
    }

    /// The idle block's bound lies above its exact growth rate on every state, weak and
    /// strong, stable and parametrically unstable (the idle mode beside the driven one, the
    /// drive's square pumping it), and proves the weakly driven ones: the verdict of
    /// `unstable()` with it is the full check's.
    #[test]
    fn the_idle_bound_lies_above_the_idle_growth() {
        let c = |x: f64| Complex64::new(x, 0.0);
        let (mut proven, mut unproven, mut unstable) = (0, 0, 0);
        for f2 in [415842.0, 207582.0 * 1.000_01, 207582.0 * 0.999_99] {
            let model = pair(f2);
            for force in [0.05, 0.3, 1.0, 3.0, 8.0] {
                for tones in [vec![207580.0, 207590.0], vec![207575.0]] {
                    let drive = Excitation {
                        pumps: Vec::new(),
                        force: vec![vec![c(force); tones.len()], vec![c(0.0); tones.len()]],
                        tones_hz: tones,
                    };
                    let mut s = ReducedSolver::new(&model, &drive, &Default::default(), &[])
                        .expect("solver");
                    assert_eq!(s.active().idle_parts().len(), 1);
                    let st = s.solve(&HbSettings::default());
                    if !st.converged() {
                        continue;
                    }
                    let bound = s.idle_bound(&st, 0);
                    let growth = s.idle_growth(&st, 0, false).expect("growth");
                    assert!(bound >= growth, "f2 {f2} force {force}: {bound} < {growth}");
                    proven += usize::from(bound < 0.0);
                    unproven += usize::from(bound >= 0.0);
                    unstable += usize::from(growth > 0.0);
                    let full = s.stability(&st).expect("stability");
                    let quick = s.unstable(&st).expect("verdict");
                    assert_eq!(quick.is_none(), full.stable, "f2 {f2} force {force}");
                }
            }
        }
        assert!(
            proven > 0 && unproven > 0 && unstable > 0,
            "proven {proven}, unproven {unproven}, unstable {unstable}"
        );
    }
}

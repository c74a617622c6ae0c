//! The problem on one lattice: set-up, residual and analytic Jacobian, and the state returned.

use super::ramp::{RAMP_MAX_TONES, RAMP_MIN_SAVING, RAMP_ORDER};
use super::rough_aft::RoughAft;
use super::{HbSettings, HbStatus, ReducedSolver, SteadyState, Z};
use crate::lattice::{choose_lattice, low_order_lines, LatticeSettings, LINE_TOL_HZ};
use crate::linalg::DenseLu;
use crate::{Excitation, NumericModel, SimError};
use harmonid_spectral::{
    velocity_spectrum, velocity_to_amplitude, ProductPlan, SystemPlan, SystemScratch,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Most modes a harmonic-balance problem handles (fixed-size slice tables, no allocation).
pub const MAX_MODES: usize = 32;

/// A harmonic-balance problem on a fixed lattice, with every table and buffer allocated once;
/// [`HbSolver::solve`] can then run many times (drive levels, noise studies) without allocating.
#[derive(Debug, Clone)]
pub struct HbSolver {
    pub(super) model: NumericModel,
    pub(super) lattice: Vec<f64>,
    /// The nonlinear forces of all equations, sharing partial products.
    pub(super) system: SystemPlan,
    pub(super) scratch: SystemScratch,
    /// `lin[n*R + r] = ω_n² − Ω_r² + iΩ_r γ_n`.
    pub(super) lin: Vec<Complex64>,
    /// Full-drive forces on the lattice, `[n*R + r]`.
    pub(super) force: Vec<Complex64>,
    pub(super) force_max: f64,
    // Buffers.
    pub(super) x: Vec<Complex64>,
    pub(super) res: Vec<Complex64>,
    pub(super) out: Vec<Complex64>,
    pub(super) jre: Vec<Complex64>,
    pub(super) jim: Vec<Complex64>,
    pub(super) jac: Vec<f64>,
    pub(super) lu: DenseLu,
    /// `[e·N + v]`: the Jacobian's block of equation `e`, mode `v` is not zero (assembly).
    pub(super) coupled: Vec<bool>,
    pub(super) step: Vec<f64>,
    pub(super) x_try: Vec<Complex64>,
    /// Velocity spectra `i Ω_r X_{n,r}` of the state being evaluated, for models with
    /// velocity or pump terms (empty otherwise).
    pub(super) vel: Vec<Complex64>,
    /// The pump signal's spectrum on the lattice, for models with pump terms (empty
    /// otherwise): a known factor of the products, not an unknown.
    pub(super) pump: Vec<Complex64>,
    /// `lu` holds a factorised Jacobian (of some earlier state).
    pub(super) have_lu: bool,
    /// The factorised Jacobian is that of the current `x`.
    pub(super) fresh: bool,
    /// The same problem on the lines of intermodulation order ≤ [`RAMP_ORDER`], where the drive
    /// ramp runs, and the index of each of its lines in `lattice`.
    pub(super) coarse: Option<(Box<HbSolver>, Vec<usize>)>,
    /// The non-smooth terms by alternating frequency–time (`None` for a model without).
    pub(crate) rough: Option<RoughAft>,
}

/// What the values of a problem (coefficients, `f`, `Q`, forces) set on a planned lattice.
struct Operators {
    system: SystemPlan,
    lin: Vec<Complex64>,
    force: Vec<Complex64>,
    force_max: f64,
    pump: Vec<Complex64>,
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
            .map(|t| (t.eq, model.term_monomial(&t.factors), t.coef))
            .collect();
        let system = SystemPlan::new(plan, model.n_vars(), nm, &terms)?;
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
            pump: pump_spectrum(model, drive, lattice)?,
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
        if drive.generators_hz().len() <= RAMP_MAX_TONES {
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
                .all(|(a, b)| a.eq == b.eq && a.factors == b.factors)
            && model.rough_terms().len() == self.model.rough_terms().len()
            && model
                .rough_terms()
                .iter()
                .zip(self.model.rough_terms())
                .all(|(a, b)| a.eq == b.eq && a.factors == b.factors && a.nonsmooth == b.nonsmooth);
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
        self.pump = ops.pump;
        if let Some(r) = self.rough.as_mut() {
            r.set_terms(model);
        }
        // A factorised Jacobian stays for [`HbSolver::solve_continued`] (chord steps check
        // that it still contracts); it is no longer that of the current state.
        self.fresh = false;
        if let Some((coarse, _)) = self.coarse.as_mut() {
            coarse.set_values(model, drive)?;
        }
        Ok(())
    }

    /// The solver on exactly `lattice`, without a coarse ramp lattice.
    pub(super) fn single(
        model: &NumericModel,
        drive: &Excitation,
        lattice: Vec<f64>,
    ) -> Result<Self, SimError> {
        Self::single_sharing(model, drive, lattice, None)
    }

    /// [`HbSolver::single`], with the product plan of `other` (a solver on the same lattice)
    /// when it covers every degree of `model`'s terms: planning a large lattice's products
    /// costs more than the rest of the set-up.
    pub(super) fn single_sharing(
        model: &NumericModel,
        drive: &Excitation,
        lattice: Vec<f64>,
        other: Option<&HbSolver>,
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
        let shared = other.filter(|o| {
            o.lattice == lattice
                && degrees
                    .iter()
                    .all(|&d| o.model.terms().iter().any(|t| t.degree() as usize == d))
        });
        let plan = match shared {
            Some(o) => o.system.plan().clone(),
            None => ProductPlan::for_degrees(&lattice, &lattice, &degrees)?,
        };
        let nr = lattice.len();
        let ops = Operators::new(model, drive, &lattice, plan)?;
        let nu = 2 * nm * nr;
        let rough = RoughAft::new(model, drive, &lattice)?;
        Ok(Self {
            rough,
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
            // Set by each assembly before it is read; none yet (`jac` is zero).
            coupled: vec![false; nm * nm],
            step: vec![0.0; nu],
            x_try: vec![Z; nm * nr],
            vel: if model.n_vars() > nm {
                vec![Z; nm * nr]
            } else {
                Vec::new()
            },
            pump: ops.pump,
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

    /// Residual at `x` with drive fraction `s` into `res`; returns `max |R| / max |s F|`
    /// (without a drive force, `max |R| / max |L X|`, `L` the linear operator).
    pub(super) fn residual(&mut self, use_try: bool, s: f64) -> f64 {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let x = if use_try { &self.x_try } else { &self.x };
        // Velocity spectra (none without velocity terms: `vel` is empty).
        velocity_spectrum(&self.lattice, x, &mut self.vel);
        let refs = variable_spectra(x, &self.vel, &self.pump, nm, nr);
        let nv = self.model.n_vars();
        self.system
            .forces(&refs[..nv], &mut self.out, &mut self.scratch);
        if let Some(r) = self.rough.as_mut() {
            r.add_forces(x, &self.pump, &mut self.out);
        }
        for i in 0..nm * nr {
            self.res[i] = self.lin[i] * x[i] - self.force[i] * s + self.out[i];
        }
        // Relative to the drive; without one (a pump alone sustains the state), relative to
        // the largest linear force of the state, so that a force-free problem can converge.
        let fm = if self.force_max > 0.0 {
            self.force_max * s
        } else {
            self.lin
                .iter()
                .zip(x)
                .map(|(l, z)| (l * z).norm())
                .fold(0.0, f64::max)
        }
        .max(f64::MIN_POSITIVE);
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
    pub(super) fn jacobian(&mut self) -> bool {
        self.assemble_jacobian();
        self.lu.factor_coupled(&self.jac, &self.coupled)
    }

    /// Assembles the real Jacobian `∂(Re R, Im R)/∂(Re X, Im X)` at `self.x` into `self.jac`
    /// (row-major, unknowns interleaved re/im).
    pub(super) fn assemble_jacobian(&mut self) {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let nu = 2 * nm * nr;
        // Zero only the blocks the last assembly flagged (`coupled` still holds them; every
        // entry outside them is zero): the solver of a stability check's idle blocks
        // ([`ReducedSolver::stability`]) holds every mode but writes few blocks, and zeroing
        // its whole `nu²` cost more than assembling them.
        for (b, _) in self.coupled.iter().enumerate().filter(|(_, &c)| c) {
            let (e, m) = (b / nm, b % nm);
            for row in 2 * e * nr..2 * (e + 1) * nr {
                self.jac[row * nu + 2 * m * nr..row * nu + 2 * (m + 1) * nr].fill(0.0);
            }
        }
        for i in 0..nm * nr {
            let l = self.lin[i];
            self.jac[(2 * i) * nu + 2 * i] = l.re;
            self.jac[(2 * i) * nu + 2 * i + 1] = -l.im;
            self.jac[(2 * i + 1) * nu + 2 * i] = l.im;
            self.jac[(2 * i + 1) * nu + 2 * i + 1] = l.re;
        }
        velocity_spectrum(&self.lattice, &self.x, &mut self.vel);
        let refs = variable_spectra(&self.x, &self.vel, &self.pump, nm, nr);
        let nv = self.model.n_vars();
        let jac = &mut self.jac;
        let coupled = &mut self.coupled;
        for (i, c) in coupled.iter_mut().enumerate() {
            *c = i / nm == i % nm;
        }
        let lattice = &self.lattice;
        self.system.jacobian(
            &refs[..nv],
            &mut self.jre,
            &mut self.jim,
            &mut self.scratch,
            |eq, j, jre, jim| {
                // A zero block (a factor of the derivative vanishes in this state: an undriven
                // mode) is skipped and leaves the modes uncoupled for the factorisation.
                // The pump is given, not solved for: no column.
                if j >= 2 * nm || jre.iter().chain(jim).all(|z| *z == Z) {
                    return;
                }
                // A velocity's block carries back onto its mode's amplitudes.
                let (m, velocity) = if j < nm { (j, false) } else { (j - nm, true) };
                coupled[eq * nm + m] = true;
                for o in 0..nr {
                    let row0 = 2 * (eq * nr + o);
                    let (top, bottom) = jac[row0 * nu..(row0 + 2) * nu].split_at_mut(nu);
                    for r in 0..nr {
                        let col0 = 2 * (m * nr + r);
                        let (mut a, mut c) = (jre[o * nr + r], jim[o * nr + r]);
                        if velocity {
                            (a, c) = velocity_to_amplitude(a, c, lattice[r]);
                        }
                        top[col0] += a.re;
                        bottom[col0] += a.im;
                        top[col0 + 1] += c.re;
                        bottom[col0 + 1] += c.im;
                    }
                }
            },
        );
        if let Some(r) = self.rough.as_mut() {
            r.add_jacobian(&self.x, &self.pump, &mut self.jac, &mut self.coupled);
        }
    }

    /// Copies `state` (solved on this lattice) into the current amplitudes.
    pub(super) fn load_state(&mut self, state: &SteadyState) -> Result<(), SimError> {
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

    /// The pump signal's spectrum on the lattice (empty for a model without pump terms).
    pub(crate) fn pump_spectrum(&self) -> &[Complex64] {
        &self.pump
    }

    /// The product plan of the lattice (input = output = the lattice).
    pub(crate) fn product_plan(&self) -> &ProductPlan {
        self.system.plan()
    }

    pub(super) fn finish(
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
            pump_sustained: false,
        }
    }
}

/// Solves the steady state under `drive` with the lattice chosen by `settings.lattice`, on
/// the modes the drive reaches ([`ReducedSolver`]; the others are exactly zero).
pub fn steady_state(
    model: &NumericModel,
    drive: &Excitation,
    settings: &HbSettings,
) -> Result<SteadyState, SimError> {
    let mut solver = ReducedSolver::new(model, drive, &settings.lattice, &[])?;
    Ok(solver.solve(settings))
}

/// The steady state on `settings`' lattice continued from `start`, a steady state of the same
/// drive on another lattice (lines matched by frequency, the others from zero), by Newton at
/// full drive: the same branch on a wider lattice, as a truncation check needs, at the cost of
/// a few factorisations instead of a drive ramp. The jumps and ramp steps are `start`'s. Falls
/// back to [`steady_state`] (the ramp from rest) when Newton does not converge from there, or
/// when `start` is an oscillation a pump sustains (its lattice settles apart).
pub fn steady_state_from(
    model: &NumericModel,
    drive: &Excitation,
    settings: &HbSettings,
    start: &SteadyState,
) -> Result<SteadyState, SimError> {
    let mut solver = ReducedSolver::new(model, drive, &settings.lattice, &[])?;
    if start.converged() && !start.pump_sustained {
        let guess: Vec<Vec<Complex64>> = (0..model.n_modes())
            .map(|n| {
                solver
                    .lattice()
                    .iter()
                    .map(|&f| start.amplitude(n, f))
                    .collect()
            })
            .collect();
        let mut st = solver.solve_from(&guess, settings);
        if st.converged() {
            st.ramp_steps = start.ramp_steps;
            st.drive_jumps.clone_from(&start.drive_jumps);
            return Ok(st);
        }
    }
    Ok(solver.solve(settings))
}

/// The spectra of the model's variables: each mode's amplitudes in `x`, then each mode's
/// velocity in `vel` (when not empty), then the pump (when not empty), `R = nr` lines each.
pub(crate) fn variable_spectra<'a>(
    x: &'a [Complex64],
    vel: &'a [Complex64],
    pump: &'a [Complex64],
    nm: usize,
    nr: usize,
) -> [&'a [Complex64]; 2 * MAX_MODES + 1] {
    let mut refs: [&[Complex64]; 2 * MAX_MODES + 1] = [&[]; 2 * MAX_MODES + 1];
    for n in 0..nm {
        refs[n] = &x[n * nr..(n + 1) * nr];
        if !vel.is_empty() {
            refs[nm + n] = &vel[n * nr..(n + 1) * nr];
        }
    }
    if !pump.is_empty() {
        refs[2 * nm] = pump;
    }
    refs
}

/// The pump signal's spectrum on `lattice` (empty for a model without pump terms): each pump
/// tone's amplitude on its line. Errors: a model with pump terms and an excitation without a
/// pump, a pump tone off the lattice.
fn pump_spectrum(
    model: &NumericModel,
    drive: &Excitation,
    lattice: &[f64],
) -> Result<Vec<Complex64>, SimError> {
    if !model.has_pump_terms() {
        return Ok(Vec::new());
    }
    if drive.pumps.is_empty() {
        return Err(SimError::NoPump {
            terms: model.pump_term_names().join(", "),
        });
    }
    let mut pump = vec![Z; lattice.len()];
    for p in &drive.pumps {
        let i = lattice.partition_point(|&x| x < p.hz - LINE_TOL_HZ);
        if lattice
            .get(i)
            .is_none_or(|&x| (x - p.hz).abs() > LINE_TOL_HZ)
        {
            return Err(SimError::NotOnLattice { hz: p.hz });
        }
        pump[i] += p.amplitude;
    }
    Ok(pump)
}

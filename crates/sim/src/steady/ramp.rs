//! The drive ramp: the continuation in the drive level an experiment turning the drive up
//! follows, through folds (where the state jumps, [`HbSolver::land`]).

use super::{HbSettings, HbSolver, HbStatus, SteadyState, Step, Z};
use num_complex::Complex64;

/// Residual tolerance at the intermediate levels of the drive ramp (they only serve the
/// predictor of the next level; the full drive is solved to [`HbSettings::tol`]).
const RAMP_TOL: f64 = 1e-7;
/// Intermodulation order of the coarse lattice the drive ramp runs on (see [`HbSolver::solve`]).
pub(super) const RAMP_ORDER: usize = 5;
/// The coarse ramp is used when it leaves out at least this fraction of the lattice's lines.
pub(super) const RAMP_MIN_SAVING: f64 = 0.25;
/// Most drive tones for which the coarse ramp lattice is enumerated (the count of
/// combinations grows as `tones^RAMP_ORDER`).
pub(super) const RAMP_MAX_TONES: usize = 8;
/// A ramp step this small (fraction of the full drive) that still fails marks a fold in the
/// drive: the branch ends and the state jumps (see [`HbSolver::land`]).
const FOLD_STEP: f64 = 1e-4;
/// A converged ramp step continues the branch only if Newton moved the state at most this many
/// times as far from the tangent predictor as the predictor moved it from the last state, and
/// the tangent changed its size by at most this factor (see [`HbSolver::continues_branch`]).
const BRANCH_CORRECTION: f64 = 2.0;

impl HbSolver {
    /// Solves for the steady state under the full drive (ramped up from a small fraction when
    /// `settings.ramp`), starting from the linear response. Never returns NaN: a failure is an
    /// [`HbStatus::NotConverged`] status with the last converged state and its residual.
    ///
    /// The ramp runs on the lattice's lines of intermodulation order ≤ 5 when they are
    /// markedly fewer: they carry the branch structure (folds, jumps), while the higher orders
    /// are corrections of relative size ~`(nonlinear shift / linewidth)^3` smaller. Newton then
    /// finishes at full drive on the whole lattice from the coarse state. Should that fail, the
    /// ramp is run again on the whole lattice.
    ///
    /// With a pump above its parametric threshold the state the ramp follows is unstable, and
    /// the state returned is the oscillation the resonator settles on from it (the slow flow
    /// integrated from it plus a small seed) when a nonlinearity limits it.
    pub fn solve(&mut self, settings: &HbSettings) -> SteadyState {
        let state = self.solve_ramped(settings);
        self.settle_parametric(&state, settings).unwrap_or(state)
    }

    fn solve_ramped(&mut self, settings: &HbSettings) -> SteadyState {
        if let Some(state) = self.solve_from_linear(settings) {
            return state;
        }
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

    /// The drive ramp on this solver's own lattice (see [`HbSolver::solve`]): [`Ramp`] steps
    /// from the linear response up to the full drive; at a fold it stops
    /// ([`HbSettings::stop_at_fold`]) or the state jumps where the slow flow takes it.
    pub(super) fn solve_ramp(&mut self, settings: &HbSettings) -> SteadyState {
        let mut ramp = match Ramp::start(self, settings) {
            Ok(ramp) => ramp,
            Err(failed) => return failed,
        };
        let mut jumps = Vec::new();
        loop {
            match ramp.step(self, settings) {
                Step::Advanced => {}
                Step::Jump { at } => jumps.push(at),
                Step::Reached => break,
                Step::Fold { at } => {
                    // The caller only wanted to know.
                    jumps.push(at);
                    return self.stop_ramp(&ramp.good, ramp.s, ramp.steps, jumps);
                }
                Step::Stuck => {
                    jumps.extend(ramp.unlanded);
                    return self.stop_ramp(&ramp.good, ramp.s, ramp.steps, jumps);
                }
            }
        }
        let r = self.residual(false, 1.0);
        self.finish(
            HbStatus::Converged {
                iterations: ramp.iters,
            },
            r,
            ramp.steps,
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
    pub(super) fn tangent(&mut self, out: &mut [Complex64]) {
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
    pub(super) fn branch_sign(&mut self) -> f64 {
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
}

/// The drive ramp between two steps: the branch's last state and what predicts the next one.
///
/// A step is kept only when the state it converged to continues the branch of the last one
/// ([`HbSolver::continues_branch`]): Newton converges from a large step past a fold onto
/// another branch as readily as onto the same one, and the ramp would then miss the jump an
/// experiment driving up sees. A step that does not continue the branch is halved like one
/// that fails; one of at most [`FOLD_STEP`] that still fails or leaves the branch is a fold.
struct Ramp {
    /// Drive fraction of `good`, and of the state before it (`prev`, for the secant).
    s: f64,
    prev_s: f64,
    /// Next step of the drive fraction.
    ds: f64,
    good: Vec<Complex64>,
    prev: Vec<Complex64>,
    /// The branch's tangent dx/ds at `good` (from the factorisation at hand), and scratch for
    /// the next one.
    tangent: Vec<Complex64>,
    tangent_new: Vec<Complex64>,
    /// Sign of det J along the branch (`0.0`: unknown).
    sign: f64,
    /// Jacobian evaluations of Newton at the last level.
    iters: usize,
    /// Drive levels solved.
    steps: usize,
    /// A fold whose landing failed: named if the ramp stops there.
    unlanded: Option<f64>,
}

impl Ramp {
    /// Newton at the first drive fraction from the linear response, lowered while the state
    /// found is past a fold already; `Err`: the failed state, when Newton does not converge.
    fn start(solver: &mut HbSolver, settings: &HbSettings) -> Result<Self, SteadyState> {
        let nm = solver.model.n_modes();
        let nr = solver.lattice.len();
        let mut s0 = if settings.ramp {
            settings.ramp_start.clamp(1e-6, 1.0)
        } else {
            1.0
        };
        let mut steps = 0;
        let (iters, sign) = loop {
            for i in 0..nm * nr {
                solver.x[i] = solver.force[i] * s0 / solver.lin[i];
            }
            solver.have_lu = false;
            let (ok, iters, res) =
                solver.newton(s0, level_tol(s0, settings), settings.max_iter * 2);
            steps += 1;
            if !ok {
                return Err(solver.finish(
                    HbStatus::NotConverged {
                        drive_fraction: 0.0,
                    },
                    res,
                    steps,
                    true,
                    Vec::new(),
                ));
            }
            if s0 >= 1.0 {
                break (iters, 0.0);
            }
            // The branch of the linear response has det J > 0 (each line's 2×2 block
            // [[p, −q], [q, p]] has det p² + q²); a start on another sign is past a fold
            // already: start lower.
            let sign = solver.branch_sign();
            if sign > 0.0 || s0 <= 1e-6 {
                break (iters, sign);
            }
            s0 = (0.1 * s0).max(1e-6);
        };
        let mut tangent = solver.x.clone();
        if s0 < 1.0 {
            solver.tangent(&mut tangent);
        }
        Ok(Self {
            s: s0,
            prev_s: s0,
            ds: settings.ramp_step,
            good: solver.x.clone(),
            prev: solver.x.clone(),
            tangent_new: solver.x.clone(),
            tangent,
            sign,
            iters,
            steps,
            unlanded: None,
        })
    }

    /// One step up the drive: halves the step until Newton converges on the same branch
    /// ([`Step::Advanced`], [`Step::Reached`] at the full drive), or the smallest step fails:
    /// a fold, where the ramp stops ([`Step::Fold`], asked to by
    /// [`HbSettings::stop_at_fold`]) or the state lands where the slow flow takes it
    /// ([`Step::Jump`]). [`Step::Stuck`] when the step budget is spent.
    fn step(&mut self, solver: &mut HbSolver, settings: &HbSettings) -> Step {
        let n = self.good.len();
        loop {
            if self.s >= 1.0 {
                return Step::Reached;
            }
            if self.steps >= settings.max_ramp_steps || self.ds < 1e-7 {
                return Step::Stuck;
            }
            let (s, ds) = (self.s, self.ds);
            let s_new = (s + ds).min(1.0);
            // Secant predictor.
            let secant = s > self.prev_s;
            let slope = if secant {
                (s_new - s) / (s - self.prev_s)
            } else {
                s_new / s - 1.0
            };
            for i in 0..n {
                let base = self.good[i];
                let d = if secant { base - self.prev[i] } else { base };
                solver.x[i] = base + d * slope;
            }
            let tol = level_tol(s_new, settings);
            let (ok, it, _) = solver.newton(s_new, tol, settings.max_iter);
            self.steps += 1;
            let (ok, sign_new) = if ok {
                let tangents = (&self.tangent[..], &mut self.tangent_new[..]);
                solver.continues_branch(&self.good, tangents, s_new - s, self.sign)
            } else {
                (false, self.sign)
            };
            if ok {
                self.prev.copy_from_slice(&self.good);
                self.good.copy_from_slice(&solver.x);
                self.prev_s = s;
                self.s = s_new;
                self.iters = it;
                self.sign = sign_new;
                std::mem::swap(&mut self.tangent, &mut self.tangent_new);
                if it <= 3 {
                    self.ds = (ds * 1.6).min(settings.ramp_step_max);
                }
                return if self.s >= 1.0 {
                    Step::Reached
                } else {
                    Step::Advanced
                };
            }
            if ds > FOLD_STEP {
                self.ds *= 0.5;
                continue;
            }
            // The branch ends between s and s + ds: a fold in the drive.
            if settings.stop_at_fold {
                return Step::Fold { at: s };
            }
            // An experiment jumps there; follow the slow flow from the last state at the
            // next level.
            solver.x.copy_from_slice(&self.good);
            if solver.land_persistently(s_new, tol) {
                self.unlanded = None;
                self.good.copy_from_slice(&solver.x);
                self.prev.copy_from_slice(&solver.x);
                self.s = s_new;
                self.prev_s = s_new;
                self.ds = settings.ramp_step;
                self.sign = solver.branch_sign();
                solver.tangent(&mut self.tangent);
                return Step::Jump { at: s };
            }
            // Closer to the fold the landing may succeed; if the ramp ends here, it ends at
            // this fold.
            self.unlanded = Some(s);
            self.ds *= 0.5;
        }
    }
}

/// Newton's tolerance at drive fraction `s`: intermediate levels only feed the predictor, so
/// a loose one there; the full drive to [`HbSettings::tol`].
fn level_tol(s: f64, settings: &HbSettings) -> f64 {
    if s < 1.0 {
        settings.tol.max(RAMP_TOL)
    } else {
        settings.tol
    }
}

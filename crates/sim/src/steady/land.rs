//! Landing beyond a fold: the slow flow integrated until it settles on a steady state.

use super::HbSolver;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Most pseudo-time steps of a landing attempt.
const LAND_MAX_STEPS: usize = 400;
/// Most landing attempts in a row ([`HbSolver::land_persistently`]).
const LANDINGS: usize = 8;
/// Largest move of a landing step along the slow flow, relative to the state's largest
/// amplitude ([`HbSolver::land`]).
const LAND_FLOW_STEP: f64 = 0.25;

impl HbSolver {
    /// [`HbSolver::land`] up to [`LANDINGS`] times in a row, each from where the last ended
    /// with the pseudo-time step small again: just past a fold the flow crawls through the
    /// fold's ghost, where the residual hardly falls, and a step grown on the way there
    /// overshoots instead of following it.
    pub(super) fn land_persistently(&mut self, s: f64, tol: f64) -> bool {
        (0..LANDINGS).any(|_| self.land(s, tol))
    }

    /// Lands at drive fraction `s` from the current state (beyond a fold, off any branch) the
    /// way the resonator does: the slow flow `(2iΩ_r + γ_n) Ẋ = −R(X)` (see
    /// [`HbSolver::stability`]) integrated by linearly implicit Euler,
    /// `(C/Δt + J) ΔX = −R`, from `Δt` a tenth of the fastest decay time, growing as the
    /// residual falls (switched evolution relaxation) until it is Newton. Small steps first
    /// keep the trajectory, so the state ends in the basin the physical transient reaches.
    /// Beyond its first value `Δt` is also held to where the flow's own step `Δt |C⁻¹R|`
    /// moves the state by at most [`LAND_FLOW_STEP`] of its largest amplitude: in a fold's
    /// ghost the residual falls while the state is still far from any steady state, and a
    /// `Δt` grown there is a Newton step that leaves the trajectory (a stepped sweep of a
    /// strongly softening beam jumped from 5 nm to a spurious 300 nm orbit that way). A step
    /// that would still move the state by more than that (the linearly implicit step is not
    /// the flow's where the flow is far from linear) is not taken: `Δt` is halved and the
    /// step solved again. Without it, just past a strong Duffing fold (0.09 Hz past the
    /// saddle-node, linewidth 10 Hz) the accepted steps wandered between 1 and 10 µm without
    /// ever reaching the 63 nm low branch.
    /// Returns whether the residual met `tol` within [`LAND_MAX_STEPS`] steps (the state is
    /// where the flow got to either way: another call continues from there).
    pub(super) fn land(&mut self, s: f64, tol: f64) -> bool {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let nu = self.unknowns();
        let g_max = (0..nm).map(|n| self.model.gamma(n)).fold(0.0, f64::max);
        let dt0 = 0.1 * 2.0 / g_max;
        let mut dt = dt0;
        let mut r0 = self.residual(false, s);
        for _ in 0..LAND_MAX_STEPS {
            if r0 <= tol {
                self.have_lu = false;
                return true;
            }
            dt = dt.min(dt0.max(LAND_FLOW_STEP * self.flow_time_scale()));
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
            // Held to the flow's step bound (see above), or solved again with half the step.
            let size = self.x.iter().map(|z| z.norm()).fold(0.0, f64::max);
            let moved = (0..nu / 2)
                .map(|i| Complex64::new(self.step[2 * i], self.step[2 * i + 1]).norm())
                .fold(0.0, f64::max);
            if moved > LAND_FLOW_STEP * size && size > 0.0 {
                dt *= 0.5;
                continue;
            }
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

    /// The time (s) the slow flow takes to move the state by its own largest amplitude at
    /// the current rate: `max |X| / max |C⁻¹R|`, with `C = γ_n + 2iΩ_r` per line and `R` the
    /// residual in `self.res` (infinite at a steady state).
    fn flow_time_scale(&self) -> f64 {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        let mut rate: f64 = 0.0;
        for n in 0..nm {
            let g = self.model.gamma(n);
            for (r, &f) in self.lattice.iter().enumerate() {
                let c = Complex64::new(g, 2.0 * TAU * f).norm();
                rate = rate.max(self.res[n * nr + r].norm() / c);
            }
        }
        let size = self.x.iter().map(|z| z.norm()).fold(0.0, f64::max);
        if rate > 0.0 {
            size / rate
        } else {
            f64::INFINITY
        }
    }
}

//! The next step of a stepped-sine experiment: the state the resonator settles into when the
//! drive changes from the previous step's to this solver's, starting from where it was.

use super::{HbSettings, HbSolver, HbStatus, SteadyState, Z};
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;

/// The states a stepped-sine experiment reaches under `drives`, one per step in the order they
/// were measured: the first by the drive ramp from rest, each later one from the state before
/// it ([`HbSolver::solve_after`]), each on its own lattice (`settings.lattice`). A step that
/// does not converge is returned as such (its status says so), and the next one starts from
/// it. Errors: a lattice or solver that cannot be set up for a step.
pub fn stepped_sweep(
    model: &NumericModel,
    drives: &[Excitation],
    settings: &HbSettings,
) -> Result<Vec<SteadyState>, SimError> {
    let mut states: Vec<SteadyState> = Vec::with_capacity(drives.len());
    for drive in drives {
        let mut solver = HbSolver::new(model, drive, &settings.lattice)?;
        let state = match states.last() {
            None => solver.solve(settings),
            Some(prev) => solver.solve_after(&prev.carried_to(solver.lattice()), settings),
        };
        states.push(state);
    }
    Ok(states)
}

impl HbSolver {
    /// The steady state a stepped experiment reaches under this solver's drive from the
    /// previous step's state `start` (`start[n][r]`: amplitudes on this lattice, see
    /// [`SteadyState::carried_to`]): the slow flow integrated from there until it settles (by
    /// linearly implicit pseudo-time steps, up to 8 landings of 400 steps), as the resonator's
    /// transient does. On the branch the previous step was on while that branch exists; past
    /// its fold, on the branch the jump reaches.
    /// Never through a fold the experiment did not cross, which a ramp of the drive from rest
    /// may do (from rest, the drive ramp lands on the low branch of a hardening resonance
    /// where an up-sweep is on the high one).
    ///
    /// With a pump above its threshold an unstable landing is left the way
    /// [`HbSolver::solve`] leaves it, from a small seed.
    ///
    /// Should the flow not settle within its step budget (slow near a fold), Newton from
    /// `start` is tried, and its state kept only when it is stable (not the middle branch).
    /// Never returns NaN: a failure is [`HbStatus::NotConverged`] with the start's residual.
    pub fn solve_after(&mut self, start: &[Vec<Complex64>], settings: &HbSettings) -> SteadyState {
        let nr = self.lattice.len();
        for (n, row) in start.iter().enumerate().take(self.model.n_modes()) {
            self.x[n * nr..(n + 1) * nr].copy_from_slice(&row[..nr]);
        }
        self.have_lu = false;
        if self.land_persistently(1.0, settings.tol) {
            let r = self.residual(false, 1.0);
            let state = self.finish(
                HbStatus::Converged { iterations: 0 },
                r,
                1,
                false,
                Vec::new(),
            );
            // A pump above its threshold: the flow may sit on the unstable state it left no
            // seed to grow from.
            return self.settle_parametric(&state, settings).unwrap_or(state);
        }
        let state = self.solve_from(start, settings);
        if state.converged() && self.stability(&state).is_ok_and(|s| s.stable) {
            return state;
        }
        for (n, row) in start.iter().enumerate().take(self.model.n_modes()) {
            self.x[n * nr..(n + 1) * nr].copy_from_slice(&row[..nr]);
        }
        let r = self.residual(false, 1.0);
        self.finish(
            HbStatus::NotConverged {
                drive_fraction: 1.0,
            },
            r,
            1,
            false,
            Vec::new(),
        )
    }
}

impl SteadyState {
    /// This state's amplitudes carried onto `lattice` (Hz, sorted), the start of the next
    /// step of a stepped sweep ([`HbSolver::solve_after`]). Lattices of the same length are
    /// the same combinations of tones that moved a little, in the same order: line `r` goes to
    /// line `r`. Otherwise each line goes to the new line nearest in frequency within half
    /// the new lattice's smallest spacing, and new lines without one start at zero.
    pub fn carried_to(&self, lattice: &[f64]) -> Vec<Vec<Complex64>> {
        if lattice.len() == self.lattice_hz.len() {
            return self.amplitudes.clone();
        }
        let spacing = lattice
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let mut out = vec![vec![Z; lattice.len()]; self.amplitudes.len()];
        for (r, &f) in self.lattice_hz.iter().enumerate() {
            let i = lattice.partition_point(|&x| x < f);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter(|&j| j < lattice.len())
                .min_by(|&a, &b| (lattice[a] - f).abs().total_cmp(&(lattice[b] - f).abs()));
            if let Some(j) = nearest.filter(|&j| (lattice[j] - f).abs() < 0.5 * spacing) {
                for (row_out, row) in out.iter_mut().zip(&self.amplitudes) {
                    row_out[j] = row[r];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_models::duffing;
    use super::super::{sweep, SweepSettings};
    use super::*;
    use std::f64::consts::TAU;

    /// The single-harmonic amplitudes `a` of `q̈ + γq̇ + ω0²q + βq³ = F cos Ωt`, the real roots
    /// of `u[(ω0² − Ω² + ¾βu)² + (γΩ)²] = F²` in `u = a²`, ascending (bisection on the cubic's
    /// monotone pieces).
    fn single_harmonic(w0: f64, g: f64, beta: f64, force: f64, w: f64) -> Vec<f64> {
        let p = |u: f64| {
            u * ((w0 * w0 - w * w + 0.75 * beta * u).powi(2) + (g * w).powi(2)) - force * force
        };
        // p'(u) = 0 where (d + 3c u)(d + c u) + (gw)² = 0, c = ¾β, d = ω0² − Ω².
        let (c, d) = (0.75 * beta, w0 * w0 - w * w);
        let (qa, qb, qc) = (3.0 * c * c, 4.0 * c * d, d * d + (g * w).powi(2));
        let disc = qb * qb - 4.0 * qa * qc;
        let mut knots = vec![0.0];
        if disc > 0.0 {
            for s in [-1.0, 1.0] {
                let u = (-qb + s * disc.sqrt()) / (2.0 * qa);
                if u > 0.0 {
                    knots.push(u);
                }
            }
        }
        knots.sort_by(f64::total_cmp);
        knots.push(1.0);
        while p(*knots.last().expect("knot")) < 0.0 {
            *knots.last_mut().expect("knot") *= 2.0;
        }
        let mut roots = Vec::new();
        for w2 in knots.windows(2) {
            let (mut lo, mut hi) = (w2[0], w2[1]);
            if p(lo).signum() == p(hi).signum() {
                continue;
            }
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if p(mid).signum() == p(lo).signum() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            roots.push((0.5 * (lo + hi)).sqrt());
        }
        roots
    }

    #[test]
    fn a_stepped_sweep_stays_on_its_branch_until_the_fold_and_jumps_there() {
        let (beta, q, force) = (1e14, 200.0, 20.0);
        let m = duffing(beta, q);
        let (w0, g) = (m.omega(0), m.gamma(0));
        let arc = sweep(
            &m,
            &[Complex64::new(force, 0.0)],
            &SweepSettings {
                f_start_hz: 990.0,
                f_stop_hz: 1030.0,
                points: 2000,
                ..Default::default()
            },
        )
        .expect("sweep");
        let (up_folds, down_folds) = arc.jumps();
        let (f_up, f_down) = (up_folds[0], down_folds[0]);
        let settings = HbSettings::default();
        let steps: Vec<f64> = (0..=160).map(|k| 990.0 + 0.25 * f64::from(k)).collect();
        for upward in [true, false] {
            let order: Vec<f64> = if upward {
                steps.clone()
            } else {
                steps.iter().rev().copied().collect()
            };
            let drives: Vec<Excitation> = order
                .iter()
                .map(|&f| Excitation {
                    pumps: Vec::new(),
                    tones_hz: vec![f],
                    force: vec![vec![Complex64::new(force, 0.0)]],
                })
                .collect();
            let states = stepped_sweep(&m, &drives, &settings).expect("sweep");
            let mut bistable = 0;
            for (&f, state) in order.iter().zip(&states) {
                assert!(
                    state.converged(),
                    "{f} Hz: {} {} folds {f_down} {f_up}",
                    state.status,
                    state.residual
                );
                let a = state.amplitude(0, f).norm();
                let roots = single_harmonic(w0, g, beta, force, TAU * f);
                // In the bistable range an up-sweep is on the high branch, a down-sweep on
                // the low one; elsewhere there is one branch.
                let want = if roots.len() == 3 && upward {
                    bistable += 1;
                    roots[2]
                } else if roots.len() == 3 {
                    bistable += 1;
                    roots[0]
                } else {
                    roots[0]
                };
                assert!(
                    (a - want).abs() < 0.01 * want,
                    "{} sweep at {f} Hz: {a:e} where the branch has {want:e} (roots {roots:?}; folds {f_down}, {f_up} Hz)",
                    if upward { "up" } else { "down" }
                );
            }
            assert!(bistable >= 10, "{bistable} steps in the bistable range");
        }
    }
}

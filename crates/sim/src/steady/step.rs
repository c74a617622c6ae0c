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

    /// The saddle-nodes (Hz, ascending) of the single-harmonic response of `duffing(beta, q)`
    /// under `force` in `[lo, hi]`: where the number of real amplitudes changes, from a scan
    /// in `lo`..`hi` by a hundredth of a linewidth, bisected.
    fn saddle_nodes(m: &NumericModel, beta: f64, force: f64, lo: f64, hi: f64) -> Vec<f64> {
        let (w0, g) = (m.omega(0), m.gamma(0));
        let count = |f: f64| single_harmonic(w0, g, beta, force, TAU * f).len();
        let scan = 0.01 * g / TAU;
        let mut out = Vec::new();
        let mut a = lo;
        while a < hi {
            let mut b = a + scan;
            if count(a) != count(b) {
                let mut lo = a;
                for _ in 0..60 {
                    let mid = 0.5 * (lo + b);
                    if count(mid) == count(lo) {
                        lo = mid;
                    } else {
                        b = mid;
                    }
                }
                out.push(0.5 * (lo + b));
            }
            a += scan;
        }
        out
    }

    /// `duffing(beta, q)` under `force`, stepped up then down over `steps` (Hz, ascending):
    /// every step converges and sits within 1 % of the single-harmonic amplitude of the branch
    /// the sweep is on (in the bistable range, the high one for the sweep that entered it
    /// from the side the backbone leans to, the low one for the other), at least
    /// `min_bistable` steps are bistable, and each sweep's largest jump lies between the two
    /// steps around its saddle-node, to `tol_hz` (the harmonics' shift of the folds, which
    /// the single-harmonic cubic leaves out).
    fn stepped_sweeps_follow_the_closed_form(
        (beta, q, force): (f64, f64, f64),
        steps: &[f64],
        min_bistable: usize,
        tol_hz: f64,
    ) {
        let m = duffing(beta, q);
        let (w0, g) = (m.omega(0), m.gamma(0));
        let folds = saddle_nodes(&m, beta, force, steps[0], steps[steps.len() - 1]);
        assert_eq!(folds.len(), 2, "beta {beta:e}: saddle-nodes {folds:?}");
        for upward in [true, false] {
            let order: Vec<f64> = if upward {
                steps.to_vec()
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
            let states = stepped_sweep(&m, &drives, &HbSettings::default()).expect("sweep");
            let way = if upward { "up" } else { "down" };
            let high = upward == (beta > 0.0);
            let mut bistable = 0;
            let mut amps = Vec::with_capacity(order.len());
            for (&f, state) in order.iter().zip(&states) {
                assert!(
                    state.converged(),
                    "beta {beta:e}, {way} at {f} Hz: {} {:e} (folds {folds:?})",
                    state.status,
                    state.residual
                );
                let a = state.amplitude(0, f).norm();
                let roots = single_harmonic(w0, g, beta, force, TAU * f);
                let want = match roots.len() {
                    3 if high => roots[2],
                    3 => roots[0],
                    _ => roots[0],
                };
                bistable += usize::from(roots.len() == 3);
                assert!(
                    (a - want).abs() < 0.01 * want,
                    "beta {beta:e}, {way} at {f} Hz: {a:e} where the branch has {want:e} (roots {roots:?}, folds {folds:?})"
                );
                amps.push(a);
            }
            assert!(bistable >= min_bistable, "{bistable} bistable steps");
            let k = (0..amps.len() - 1)
                .max_by(|&i, &j| {
                    let r = |k: usize| (amps[k + 1] / amps[k]).ln().abs();
                    r(i).total_cmp(&r(j))
                })
                .expect("steps");
            let (a, b) = (order[k].min(order[k + 1]), order[k].max(order[k + 1]));
            // The bistable range ends for an up-sweep's branch at its upper saddle-node (the
            // high branch falls there if hardening, the low one jumps up if softening), for a
            // down-sweep's at its lower one.
            let fold = if upward { folds[1] } else { folds[0] };
            assert!(
                a - tol_hz <= fold && fold <= b + tol_hz,
                "beta {beta:e}: the {way} sweep jumps between {a} and {b} Hz, the fold is at {fold} Hz"
            );
        }
    }

    #[test]
    fn a_stepped_sweep_stays_on_its_branch_until_the_fold_and_jumps_there() {
        let steps: Vec<f64> = (0..=160).map(|k| 990.0 + 0.25 * f64::from(k)).collect();
        stepped_sweeps_follow_the_closed_form((1e14, 200.0, 20.0), &steps, 10, 0.25);
    }

    /// Strong folds, hardening and softening (1 kHz, Q 1000: linewidth 1 Hz): the backbone
    /// leans 8 linewidths at a linear peak of 1 µm and the jumps are 4–16 times the amplitude,
    /// stepped in a twentieth of a linewidth. Just past the hardening up-sweep's fold (0.009
    /// linewidths past it) the landing's accepted steps once wandered between 1 and 10 µm
    /// without reaching the 63 nm low branch (`HbSolver::land`).
    #[test]
    fn stepped_sweeps_jump_at_the_closed_form_folds_of_strong_duffing_resonances() {
        let (f0, q, a_peak) = (1000.0, 1000.0, 1e-6);
        let w0 = TAU * f0;
        let force = a_peak * w0 * w0 / q;
        let beta = 8.0 * (w0 / q) * 8.0 * w0 / (3.0 * a_peak * a_peak);
        for beta in [beta, -beta] {
            let lo = if beta > 0.0 { f0 - 4.0 } else { f0 - 12.0 };
            let steps: Vec<f64> = (0..=320)
                .map(|k| lo + 0.0123 + 0.05 * f64::from(k))
                .collect();
            stepped_sweeps_follow_the_closed_form((beta, q, force), &steps, 100, 0.01);
        }
    }
}

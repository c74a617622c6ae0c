//! Newton on the lattice: chord steps while a stale Jacobian contracts, full steps with
//! backtracking otherwise; and Newton from a given state (the next point of a sweep or a fit).

use super::{HbSettings, HbSolver, HbStatus, SteadyState};
use num_complex::Complex64;

/// A chord step (stale Jacobian) is kept when it shrinks the residual at least this much.
const CHORD_RATE: f64 = 0.25;

impl HbSolver {
    /// Newton at drive fraction `s` from the current `self.x`, reusing the factorised Jacobian
    /// of an earlier state while it contracts the residual by at least [`CHORD_RATE`] per step
    /// (chord/Shamanskii Newton: a refresh costs far more than a residual). `max_iter` bounds
    /// the Jacobian evaluations; `4 · max_iter` the chord steps. Returns `(converged,
    /// Jacobian evaluations, residual)`.
    pub(super) fn newton(&mut self, s: f64, tol: f64, max_iter: usize) -> (bool, usize, f64) {
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
}

//! Above a parametric threshold: the pump makes the state the drive ramp follows unstable, and
//! the resonator settles on an oscillation the pump sustains (at `f_p/2` and its mixing
//! products with the drive), which a nonlinearity limits.

use super::{HbSettings, HbSolver, HbStatus, SteadyState};
use num_complex::Complex64;

/// Size of the seed that starts the growth, relative to the largest amplitude of the state.
const SEED_REL: f64 = 1e-3;

impl HbSolver {
    /// For a model with pump terms: when `state` (converged) is unstable, the state the
    /// resonator reaches from it, integrating the slow flow from `state` plus a small seed on
    /// every line (the growing perturbation picks its own shape, as noise does in the
    /// experiment). `None` when the state is stable, the model has no pump, or the flow does
    /// not settle on a stable state (nothing in the model limits the growth).
    pub(super) fn settle_parametric(
        &mut self,
        state: &SteadyState,
        settings: &HbSettings,
    ) -> Option<SteadyState> {
        if !self.model.has_pump_terms() || !state.converged() {
            return None;
        }
        if self.stability(state).ok()?.stable {
            return None;
        }
        let nr = self.lattice.len();
        let big = state
            .amplitudes
            .iter()
            .flatten()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        let seed = SEED_REL * big.max(f64::MIN_POSITIVE);
        for (n, row) in state.amplitudes.iter().enumerate() {
            for (r, z) in row.iter().enumerate() {
                // Alternating phases, so no quadrature is left out.
                let ph = 0.7 * (1 + r + 3 * n) as f64;
                self.x[n * nr + r] = z + Complex64::from_polar(seed, ph);
            }
        }
        self.have_lu = false;
        if !self.land_persistently(1.0, settings.tol) {
            return None;
        }
        let r = self.residual(false, 1.0);
        let mut settled = self.finish(
            HbStatus::Converged { iterations: 0 },
            r,
            state.ramp_steps + 1,
            false,
            state.drive_jumps.clone(),
        );
        settled.pump_sustained = true;
        self.stability(&settled)
            .ok()
            .filter(|s| s.stable)
            .map(|_| settled)
    }
}

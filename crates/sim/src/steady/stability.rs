//! Stability of a steady state by Hill's method in slow-flow form.

use super::{HbSolver, Stability, SteadyState, MAX_MODES, Z};
use crate::linalg::coupled_parts;
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

impl HbSolver {
    /// Stability of the steady state `state` (amplitudes on this solver's lattice) by Hill's
    /// method in its slow-flow (first-order) form: with `X_{n,r}` slowly varying,
    /// `q̈` contributes `(2iΩ_r + γ_n) Ẋ_{n,r}` and the amplitudes obey
    /// `(2iΩ_r + γ_n) Ẋ = −R(X)`; the state is stable when every eigenvalue of the linearised
    /// flow `−(2iΩ + γ)⁻¹ ∂R/∂X` has a negative real part. The neglected `Ẍ` term is
    /// `O(λ/Ω)` relative, negligible for the high-Q resonators this crate is for (`Q ≫ 1`).
    /// Velocity terms also add `∂f/∂q̇ · Ẋ` to the flow's left side; like the linear damping
    /// beside `2iΩ`, that is a relative correction of the damping rate over `Ω`, neglected.
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

//! Multi-tone harmonic-balance steady states: Newton with an analytic Jacobian on a frequency
//! lattice, nonlinear terms by exact sparse products ([`harmonid_spectral::ProductPlan`]), and a
//! drive ramp that follows the branch an experiment sweeping the drive up would see.
//!
//! Unknowns: `X_{n,r}`, the complex amplitude of mode `n` at lattice frequency `f_r`. Residual
//! (DATA_FORMAT conventions, `Ω_r = 2π f_r`):
//!
//! ```text
//! R_{n,r} = (ω_n² − Ω_r² + i Ω_r ω_n/Q_n) X_{n,r} + Σ_m b_m^(n) [m(q, q̇)]_r − F_{n,r}.
//! ```
//!
//! A monomial may hold velocities (nonlinear damping): the velocity of mode `n` has the spectrum
//! `i Ω_r X_{n,r}`, which enters the products like another variable; its Jacobian block folds
//! back onto `X` (`∂/∂Re X = Ω ∂/∂Im V`, `∂/∂Im X = −Ω ∂/∂Re V`).
//!
//! Static offset: models with even-degree terms have a 0 Hz line (see
//! [`crate::choose_lattice`]) whose amplitude is the real offset `X_{n,0} = q̄_n` (the mean of
//! `q_n`); there the linear part is `ω_n² X` and `[m(q)]_0` is the mean of the product. Its
//! imaginary part has no physical meaning: the products ignore it, so its residual row is
//! `ω_n² Im X_{n,0} = 0`, a decoupled diagonal entry that keeps the Jacobian nonsingular and
//! Newton leaves it at zero (it is set exactly to zero in the returned state).
//!
//! One folder, one job per file: [`HbSolver`]'s set-up, residual and Jacobian (`solver`),
//! Newton (`newton`), the drive ramp (`ramp`), landing after a fold (`land`), stability
//! (`stability`) and lattice convergence (`convergence`), the next step of a stepped-sine
//! experiment (`step`), the undriven self-excited oscillation (`limit_cycle`), the
//! quasi-periodic branch from a Hopf point of a driven curve (`quasi_periodic`, on the
//! two-frequency balance of `torus`), the oscillation a pump sustains above its threshold
//! (`pumped`); and the
//! continuations in frequency:
//! the single-tone arclength sweep on its alternating frequency–time engine (`sweep`, `aft`),
//! backbones (`backbone`) and the two-tone sweep on [`HbSolver`] (`two_tone`). Every
//! continuation has one shape: a `step()` that returns a [`Step`].

mod active;
mod aft;
mod backbone;
mod convergence;
mod hopf;
mod land;
mod limit_cycle;
mod newton;
mod pumped;
mod quasi_periodic;
mod ramp;
mod reduced;
mod rough_aft;
mod solver;
mod stability;
mod state;
mod step;
mod sweep;
#[cfg(test)]
mod sweep_tests;
#[cfg(test)]
mod test_models;
#[cfg(test)]
mod tests;
mod torus;
mod two_tone;

pub use active::ActiveModes;
pub use backbone::backbone;
pub use convergence::{convergence_report, ConvergenceReport};
pub use hopf::Hopf;
pub use limit_cycle::{limit_cycle, LimitCycle};
pub use quasi_periodic::{
    quasi_periodic_branch, BranchEnd, QuasiPeriodicBranch, QuasiPeriodicPoint,
    QuasiPeriodicSettings,
};
pub use reduced::ReducedSolver;
pub use rough_aft::{Grid, GridSampler};
pub(crate) use solver::variable_spectra;
pub use solver::{steady_state, steady_state_from, HbSolver, MAX_MODES};
pub use stability::{check_stability, CONDENSE_SEPARATION};
pub use state::{HbSettings, HbStatus, Stability, SteadyState};
pub use step::stepped_sweep;
pub use sweep::{
    sweep, Fold, SweepPoint, SweepResult, SweepSettings, MAX_SWEEP_HARMONICS, MAX_SWEEP_HZ,
    MAX_SWEEP_POINTS,
};
pub use two_tone::{
    sweep_two_tone, ModeLine, TwoToneCurve, TwoToneJump, TwoTonePoint, TwoToneSettings,
    TwoToneStatus, TwoToneSweep,
};

use num_complex::Complex64;

const Z: Complex64 = Complex64::new(0.0, 0.0);

/// What one step of a continuation did: the shape every continuation of this family shares
/// (the drive ramp, the single-tone arclength sweep, the two-tone sweep). A continuation
/// retries smaller steps inside `step()`; it returns once the branch moved or ended.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    /// Moved along the branch.
    Advanced,
    /// The branch ends within the smallest step after the parameter value `at` (a fold), and
    /// the continuation stops there.
    Fold { at: f64 },
    /// The branch ended after `at` and the state jumped onto the branch the slow flow
    /// reaches, as the resonator does.
    Jump { at: f64 },
    /// The end of the range is reached.
    Reached,
    /// Cannot go on: the step budget is spent or the step vanished.
    Stuck,
}

//! Lattice convergence: the same steady state on a widened lattice.

use super::{steady_state, HbSettings, SteadyState};
use crate::{Excitation, NumericModel, SimError};

/// What widening the lattice changes: the steady state with the given settings, the one with
/// the order raised by 2, the window by 1.5× and the direct harmonics added wherever they fall
/// ([`crate::LatticeSettings::harmonics`]), and the largest change of an amplitude at the
/// frequencies `at_hz` (every lattice frequency of the first when empty), relative to the
/// largest amplitude.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceReport {
    /// The steady state on the chosen lattice.
    pub state: SteadyState,
    /// Lattice sizes: chosen, widened.
    pub lattice_sizes: (usize, usize),
    /// `max |X − X'| / max |X|` over the compared frequencies.
    pub change: f64,
}

/// Solves twice (chosen and widened lattice) and reports the change; see [`ConvergenceReport`].
pub fn convergence_report(
    model: &NumericModel,
    drive: &Excitation,
    settings: &HbSettings,
    at_hz: &[f64],
) -> Result<ConvergenceReport, SimError> {
    let state = steady_state(model, drive, settings)?;
    let mut wide = settings.clone();
    wide.lattice.order += 2;
    wide.lattice.window_rel *= 1.5;
    // The direct harmonics (3f, 2f1 + f2, …) lie far from any resonance and are left out by
    // the window, yet feed back on the lines near resonance (1.2e-6 relative on the
    // nanostring's sidebands).
    wide.lattice.harmonics = true;
    let state2 = steady_state(model, drive, &wide)?;
    let freqs: Vec<f64> = if at_hz.is_empty() {
        state.lattice_hz.clone()
    } else {
        at_hz.to_vec()
    };
    let mut big: f64 = 0.0;
    let mut diff: f64 = 0.0;
    for n in 0..state.amplitudes.len() {
        for &f in &freqs {
            let a = state.amplitude(n, f);
            big = big.max(a.norm());
            diff = diff.max((a - state2.amplitude(n, f)).norm());
        }
    }
    Ok(ConvergenceReport {
        lattice_sizes: (state.lattice_hz.len(), state2.lattice_hz.len()),
        state,
        change: diff / big.max(f64::MIN_POSITIVE),
    })
}

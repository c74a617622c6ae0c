//! Errors of the virtual experiment: a plan that breaks a rule (located in its file), values
//! that cannot be read, and steady states that must not be written (unstable, unconverged, or
//! truncated too coarsely).

use harmonid_files::QuotedSource;
use miette::{Diagnostic, SourceSpan};

/// A plan that breaks a rule: where (file, the key's path and, when read from text, its span)
/// and what was expected.
#[derive(Debug, thiserror::Error, Diagnostic)]
#[error("{origin}: {path}: {message}")]
#[diagnostic(code(harmonid::plan))]
pub struct PlanError {
    /// Where the plan came from (file name, or a description).
    pub origin: String,
    /// The key that breaks the rule (`measurement[2] "couple".drives_hz[1]`), or `plan`.
    pub path: String,
    /// What is wrong and what was expected.
    pub message: String,
    /// What to try.
    #[help]
    pub help: Option<String>,
    /// The plan's text, when it was read from text (a long line is quoted as a window of it).
    #[source_code]
    pub src: Option<QuotedSource>,
    /// The offending key or value in `src`.
    #[label("here")]
    pub span: Option<SourceSpan>,
}

/// What can go wrong between a plan and a dataset.
#[derive(Debug, thiserror::Error, Diagnostic)]
#[non_exhaustive]
pub enum ExperimentError {
    /// The plan breaks a rule.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Plan(#[from] PlanError),
    /// A values file or result could not be read.
    #[error("{origin}: {message}")]
    #[diagnostic(code(harmonid::values))]
    Values {
        /// The file.
        origin: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The simulation crate refused (a value, a shape, a blow-up).
    #[error("{context}: {source}")]
    #[diagnostic(code(harmonid::simulate))]
    Sim {
        /// What was being done (measurement name).
        context: String,
        /// The cause.
        #[source]
        source: harmonid_sim::SimError,
    },
    /// Newton did not reach the full drive.
    #[error("measurement {measurement}: the harmonic balance did not converge: the drive ramp stopped at {:.1} % of the full drive (force balance error {residual:.2e})", 100.0 * drive_fraction)]
    #[diagnostic(
        code(harmonid::not_converged),
        help("try a smaller drive, a higher --order, or --time-domain")
    )]
    NotConverged {
        /// Measurement name.
        measurement: String,
        /// Fraction of the full drive reached.
        drive_fraction: f64,
        /// Relative force balance error of the last state.
        residual: f64,
    },
    /// A mode's net linear damping is not positive: it oscillates on its own.
    #[error("{mode} is self-excited: its net linear damping w/Q plus its d({mode}) term is {net_damping:.3e} 1/s, not positive, so it oscillates without a drive{cycle}; driven, its motion is not periodic at the drive's frequencies (it locks to the drive or beats with it), and harmonid simulates driven steady states only")]
    #[diagnostic(
        code(harmonid::self_excited),
        help("harmonid simulates driven steady states; a mode with more linear damping than its negative velocity term (a larger w/Q, a smaller mu) has one")
    )]
    SelfExcited {
        /// The mode.
        mode: String,
        /// Net linear damping rate, 1/s.
        net_damping: f64,
        /// The undriven limit cycle in words (`: on a limit cycle of 1.22e-4 m at 1000.0 Hz
        /// (autonomous harmonic balance)`), or why it was not found.
        cycle: String,
    },
    /// The steady state is unstable (Hill).
    #[error("measurement {measurement}: the steady state is unstable: perturbations grow at {growth_rate:.3e} 1/s (the linear resonator decays at {linear_decay_rate:.3e} 1/s), so an experiment would not stay on it")]
    #[diagnostic(
        code(harmonid::unstable),
        help("try a smaller drive, the other side of the fold, or --time-domain --from-rest to see where the motion settles; --allow-unstable writes it anyway")
    )]
    Unstable {
        /// Measurement name.
        measurement: String,
        /// Largest real part of the Floquet exponents, 1/s.
        growth_rate: f64,
        /// `min ω/2Q`, 1/s.
        linear_decay_rate: f64,
    },
    /// Under a pump the steady state is unstable and no bounded state settles from it.
    #[error("measurement {measurement}: with the pump on, the steady state is unstable (perturbations grow at {growth_rate:.3e} 1/s) and the motion settles on no bounded state from it: the pump is above its parametric threshold and nothing in the model limits the oscillation it drives at f_p/2")]
    #[diagnostic(
        code(harmonid::parametric_instability),
        help("lower the pump level below the threshold (λ|P| = 2ω²/Q for a mode pumped at twice its resonance), or add the nonlinearity that limits the oscillation (a Duffing term); --allow-unstable writes the unstable state anyway")
    )]
    ParametricInstability {
        /// Measurement name.
        measurement: String,
        /// Largest real part of the Floquet exponents, 1/s.
        growth_rate: f64,
    },
    /// Widening the lattice keeps changing the measured lines.
    #[error("measurement {measurement}: the harmonic balance's spectrum is truncated too coarsely: widening it from order {order} ({lines} lines) to order {wider_order} ({wider_lines} lines) still changes the measured lines by {change:.2e} of the largest (tolerance {tol:.0e}){why}")]
    #[diagnostic(
        code(harmonid::truncation),
        help("try a smaller drive or a higher --order; --allow-truncation writes it anyway")
    )]
    Truncated {
        /// Measurement name.
        measurement: String,
        /// Last order tried.
        order: usize,
        /// Its lattice lines.
        lines: usize,
        /// The widened order compared with.
        wider_order: usize,
        /// Its lattice lines.
        wider_lines: usize,
        /// The change, relative to the largest measured amplitude.
        change: f64,
        /// The tolerance.
        tol: f64,
        /// Why the order was not raised further (empty when the order limit was reached).
        why: String,
    },
    /// A simulated amplitude is not finite.
    #[error("measurement {measurement}: a simulated amplitude is not finite; nothing written")]
    #[diagnostic(code(harmonid::non_finite))]
    NonFinite {
        /// Measurement name.
        measurement: String,
    },
    /// A setting is outside what bounded work allows.
    #[error("{what} = {value}: {why}")]
    #[diagnostic(code(harmonid::settings))]
    Setting {
        /// The setting (as the command line spells it).
        what: String,
        /// Its value.
        value: String,
        /// The rule.
        why: String,
    },
}

impl ExperimentError {
    /// Whether this is the device's own answer at a drive level (the ramp stopped at a fold
    /// with nothing to land on, or the state is unstable) rather than a broken input or a
    /// numerical limit: a drive ladder loses that level and records the others.
    pub fn is_lost_level(&self) -> bool {
        matches!(
            self,
            ExperimentError::NotConverged { .. }
                | ExperimentError::Unstable { .. }
                | ExperimentError::ParametricInstability { .. }
        )
    }
}

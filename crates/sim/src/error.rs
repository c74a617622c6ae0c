//! Errors of the simulation crate. Non-convergence of a solve is a status in its result
//! ([`crate::HbStatus`]); these are the failures that leave nothing to report.

/// What went wrong in a simulation, with the numbers and what to try.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A value the model needs was not supplied.
    #[error("no value for {what}; give it in the values file (e.g. `[parameters] {what} = ...` or `[modes.<name>] f_hz = ..., Q = ...`)")]
    MissingValue {
        /// The parameter or modal quantity.
        what: String,
    },
    /// A value is not a finite number in its allowed range.
    #[error("{what} = {} is not allowed: {why}", harmonid_files::number(*value))]
    BadValue {
        /// The quantity.
        what: String,
        /// The value given.
        value: f64,
        /// The rule it breaks.
        why: String,
    },
    /// A monomial name in a values file does not parse or names an unknown mode.
    #[error("cannot read the monomial `{name}`: {why} (expected factors like `q1^3` or `q1*q2^2` joined by `*`, with mode names {modes})")]
    BadMonomial {
        /// The name as written.
        name: String,
        /// Why it failed.
        why: String,
        /// The known mode names, for the message.
        modes: String,
    },
    /// The restoring force of a mode is unbounded: the model has no stable equilibrium to
    /// oscillate about, so every simulation would run away.
    #[error("the model is unbounded along {mode}: {why}; add a positive odd-degree term that stops it (e.g. a positive `{mode}^3` coefficient) or check the sign of the parameters")]
    Unbounded {
        /// The mode.
        mode: String,
        /// What makes it unbounded.
        why: String,
    },
    /// An input has the wrong number of entries.
    #[error("{what}: {found} given, {expected} expected ({per})")]
    Length {
        /// The input (`the sweep's forces`, `a point's mode shape`).
        what: &'static str,
        /// Entries given.
        found: usize,
        /// Entries expected.
        expected: usize,
        /// What one entry stands for (`one per mode`, `modes × tones`).
        per: String,
    },
    /// The values name a mode the model does not declare.
    #[error("the values name a mode `{name}` the model does not declare (modes: {declared})")]
    UnknownMode {
        /// The name as written.
        name: String,
        /// The model's modes, for the message.
        declared: String,
    },
    /// The values give a parameter the model does not declare.
    #[error("the values give parameter `{name}`, which the model does not declare (parameters: {declared})")]
    UnknownParameter {
        /// The name as written.
        name: String,
        /// The model's parameters, for the message.
        declared: String,
    },
    /// A computation that does not handle velocity terms (`d(q)`) yet.
    #[error("{what} does not handle velocity terms (d(q) in the model): a free oscillation with nonlinear damping decays, so it has no backbone; the steady states (`harmonid simulate`, `sweep`) do")]
    VelocityTerms {
        /// The computation.
        what: &'static str,
    },
    /// A computation that has no pump signal to give a model with pump terms.
    #[error("{what} has no pump, and the model has pump terms ({terms}): {instead}")]
    PumpTerms {
        /// The computation.
        what: &'static str,
        /// The pump terms, named.
        terms: String,
        /// What handles a pump.
        instead: &'static str,
    },
    /// A limit cycle was asked of a model no mode of which is self-excited.
    #[error("{mode} is not self-excited: its net linear damping (w/Q plus its own d({mode}) term) is {net_damping:.3e} 1/s, positive, so without a drive the motion decays to rest and there is no limit cycle to follow")]
    NotSelfExcited {
        /// The mode with the least net damping.
        mode: String,
        /// Its net linear damping rate, 1/s.
        net_damping: f64,
    },
    /// A self-excited mode whose limit cycle was not found.
    #[error("no limit cycle of the self-excited mode {mode}: {why}")]
    NoLimitCycle {
        /// The mode.
        mode: String,
        /// Why.
        why: String,
    },
    /// A term of a hand-built model refers to a mode it does not have.
    #[error("a term refers to a mode beyond the {modes} declared")]
    TermBeyondModes {
        /// How many modes the model has.
        modes: usize,
    },
    /// No drive tone at all.
    #[error("no drive tone given")]
    NoTone,
    /// A coefficient's derivative with respect to a parameter overflows its exact arithmetic.
    #[error("the derivative of the coefficient of {monomial} in the equation of {mode} overflows")]
    DerivativeOverflow {
        /// The term's monomial.
        monomial: String,
        /// The equation's mode.
        mode: String,
    },
    /// A frequency a sensitivity needs is not on the harmonic-balance lattice.
    #[error("{what} {hz} Hz is not a line of the harmonic-balance lattice (add it to the lattice's extra_hz)")]
    NotALine {
        /// `drive tone` or `observed frequency`.
        what: &'static str,
        /// The frequency, Hz.
        hz: f64,
    },
    /// A sensitivity parameter indexes beyond the model.
    #[error("sensitivity parameter {param} is out of range ({modes} modes, {tones} tones, {params} parameters in the terms)")]
    ParamOutOfRange {
        /// The parameter, as its debug form.
        param: String,
        /// Modes of the model.
        modes: usize,
        /// Drive tones.
        tones: usize,
        /// Parameters the terms depend on.
        params: usize,
    },
    /// A sensitivity to the force on a mode the reduced solver leaves idle.
    #[error("the sensitivity to a force on mode {mode} (index from 0) is asked of a solver that leaves that mode idle (the drive does not reach it): set the solver up with the mode among its forced modes")]
    IdleForce {
        /// The mode (0-based).
        mode: usize,
    },
    /// A solver, or a set-up made for one, is used with another model or lattice.
    #[error("{what}: the model's modes, terms or lattice differ from the ones it was set up for")]
    SetUpFor {
        /// Which call (`set_values`, `sensitivity`).
        what: &'static str,
    },
    /// The time integration left any reasonable amplitude (or produced a non-finite value).
    #[error("the time integration blew up at t = {t_s:.6e} s (|q| = {amplitude:.3e}, {scale:.3e} expected from the linear response): the drive is beyond what the model can hold (softening or unbounded terms) or the step is too coarse; try a smaller drive or more steps per period (--steps-per-period)")]
    BlowUp {
        /// Time of the failure, s.
        t_s: f64,
        /// Largest modal amplitude at that time.
        amplitude: f64,
        /// Amplitude scale of the linear response.
        scale: f64,
    },
    /// The demodulated amplitudes kept changing between consecutive lock-in windows.
    #[error("the response did not settle: after {t_s:.3} s the demodulated amplitudes still change by {change:.2e} (relative) from one window to the next (tolerance {tol:.1e}); the state may be quasi-periodic or chaotic, or the transient longer than expected; try a longer settling time (--settle-tau), a smaller drive, or starting from the harmonic-balance state")]
    NotSettled {
        /// Simulated time when giving up, s.
        t_s: f64,
        /// Relative change between the last two windows.
        change: f64,
        /// Tolerance asked for.
        tol: f64,
    },
    /// The lock-in window cannot hold an integer number of periods of every measured frequency
    /// within the allowed length.
    #[error("the measured frequencies have no common period up to {max_s} s (the lock-in needs a window that is an integer number of periods of every frequency): put the tones on a common grid (e.g. multiples of 0.5 Hz)")]
    NoCommonPeriod {
        /// Longest window tried, s.
        max_s: f64,
    },
    /// Terms with a non-smooth factor (`abs`, `sign`, `tanh`) where they cannot be taken:
    /// a backbone, or lattice lines that are not harmonics of one common frequency.
    #[error("{what} cannot take the model's non-smooth terms ({terms}): {why}")]
    NonSmooth {
        /// The computation refused.
        what: &'static str,
        /// The terms, as `monomial in the equation of mode`.
        terms: String,
        /// Why, and what to do instead.
        why: String,
    },
    /// The harmonic-balance problem could not be set up (a free-text reason; prefer a typed
    /// variant below in new code).
    #[error("harmonic balance: {0}")]
    Hb(String),
    /// The products of the model's terms could not be planned on the lattice.
    #[error("cannot plan the products of the model's terms: {0}")]
    Spectral(#[from] harmonid_spectral::SpectralError),
    /// A size that drives the work is above its limit.
    #[error("{what}: {count}, more than the {limit} supported; {help}")]
    TooLarge {
        /// What was counted.
        what: &'static str,
        /// How many were asked for.
        count: usize,
        /// The limit.
        limit: usize,
        /// What to do.
        help: &'static str,
    },
    /// A model with pump terms simulated without a pump.
    #[error("the model has pump terms ({terms}) and this experiment has no pump: give the pump's frequency, level and phase (a measurement's `pumps_hz`, `pump_levels`, `pump_phases_rad`), or leave the pump terms out of the model")]
    NoPump {
        /// The pump terms, named.
        terms: String,
    },
    /// A drive or pump tone is not a line of the lattice the state is solved on.
    #[error("tone {hz} Hz is not on the lattice")]
    NotOnLattice {
        /// The tone, Hz.
        hz: f64,
    },
    /// Two lines of a lattice coincide (or one reaches DC).
    #[error("at centre {centre_hz} Hz two lattice lines coincide (or one reaches DC); move the extra tones off the swept combinations or lower the order")]
    CoincidentLines {
        /// Centre frequency of the tone pair, Hz.
        centre_hz: f64,
    },
    /// Newton's method found no steady state where the computation must start.
    #[error("harmonic balance: Newton did not converge at the start frequency {f_hz} Hz; start the sweep further from resonance or lower the drive")]
    NoStart {
        /// The start frequency, Hz.
        f_hz: f64,
    },
    /// Newton found no steady state at the start of a sweep of a model with Coulomb friction
    /// (`sign`, `tanh`): where the friction is stronger than the drive the resonator sticks and
    /// has no sliding (periodic, harmonic-balance) response.
    #[error("harmonic balance: no sliding steady state at the start frequency {f_hz} Hz: {why}; raise the force above the friction's fundamental, or lower the friction coefficient")]
    NoSliding {
        /// The start frequency, Hz.
        f_hz: f64,
        /// The friction terms and, where a mode's friction is `μ sign(q̇)` alone, its
        /// threshold `4μ/π` against the force.
        why: String,
    },
    /// A steady state has non-finite amplitudes, so nothing can be said about its stability.
    #[error("the steady state has non-finite amplitudes; no stability verdict")]
    NonFiniteState,
    /// The eigenvalues of the slow flow could not be computed.
    #[error("the eigenvalues of the slow flow did not converge; no stability verdict for this steady state")]
    NoEigenvalues,
    /// The Jacobian of the harmonic-balance equations is singular at a steady state.
    #[error("the Jacobian of the harmonic-balance equations is singular at this steady state (a fold or a bifurcation): its sensitivities are unbounded")]
    SingularJacobian,
    /// A steady state was solved on another lattice than the one it is used with.
    #[error("the steady state was not solved on this lattice")]
    OtherLattice,
    /// A mode index is out of range.
    #[error("mode index {index} is out of range (the model has {n_modes} modes)")]
    ModeIndex {
        /// The index given (0-based).
        index: usize,
        /// Number of modes.
        n_modes: usize,
    },
}

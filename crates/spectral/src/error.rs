//! Errors of the spectral crate.

/// What went wrong while planning a product or expanding a mixing table.
///
/// Every variant carries the numbers needed to locate the problem; the message says what was
/// expected and what to try.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpectralError {
    /// A frequency that must be positive is zero, negative or not finite.
    #[error("{what} frequency #{index} is {hz} Hz; it must be a finite number > 0 Hz")]
    NonPositiveFrequency {
        /// Which list the frequency belongs to (`"input"`, `"tone"`, ...).
        what: &'static str,
        /// Position in that list (0-based).
        index: usize,
        /// The offending value, Hz.
        hz: f64,
    },
    /// An input frequency of a product is negative or not finite.
    #[error(
        "input frequency #{index} is {hz} Hz; it must be a finite number ≥ 0 Hz \
         (0 Hz is the static offset; list each line once at its positive frequency)"
    )]
    NegativeInputFrequency {
        /// Position in the input list (0-based).
        index: usize,
        /// The offending value, Hz.
        hz: f64,
    },
    /// An output frequency is negative or not finite.
    #[error(
        "output frequency #{index} is {hz} Hz; it must be a finite number ≥ 0 Hz \
         (the amplitude at −f is the conjugate of the one at +f)"
    )]
    NegativeOutputFrequency {
        /// Position in the output list (0-based).
        index: usize,
        /// The offending value, Hz.
        hz: f64,
    },
    /// Two frequencies that must be distinct lie within [`crate::FREQ_TOLERANCE_HZ`].
    #[error(
        "{what} frequencies #{first} and #{second} coincide ({hz} Hz, within {tol} Hz); \
         list each spectral line once",
        tol = crate::FREQ_TOLERANCE_HZ
    )]
    CoincidentFrequencies {
        /// Which list (`"input"`, `"tone"`, ...).
        what: &'static str,
        /// Position of the first one.
        first: usize,
        /// Position of the second one.
        second: usize,
        /// Their value, Hz.
        hz: f64,
    },
    /// A product or expansion would need more memory than the built-in bound.
    #[error(
        "{what} would need {needed} entries, more than the limit of {limit}; \
         use fewer frequencies, a lower degree or a lower intermodulation order"
    )]
    TooLarge {
        /// What was being built.
        what: &'static str,
        /// Entries it would need (a lower bound when it overflows).
        needed: usize,
        /// The limit.
        limit: usize,
    },
    /// Too many tones for a lattice or a mixing table.
    #[error("{count} tones given, at most {limit} are supported; drop some tones")]
    TooManyTones {
        /// Tones given.
        count: usize,
        /// Maximum supported.
        limit: usize,
    },
    /// A tone is assigned to a mode that the model does not declare.
    #[error("tone on mode `{mode}`, which is not declared (declared modes: {declared})")]
    UnknownMode {
        /// The name given.
        mode: String,
        /// The declared names, comma separated.
        declared: String,
    },
    /// Exact rational arithmetic overflowed 128 bits.
    #[error("exact arithmetic overflowed while {context}; use a lower degree or fewer tones")]
    Overflow {
        /// What was being computed.
        context: &'static str,
    },
    /// Inconsistent sizes or arguments.
    #[error("{0}")]
    Invalid(String),
}

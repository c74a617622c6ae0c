//! Errors of the identification.

use harmonid_data::DatasetError;

/// Errors of the identification (bad model/dataset combinations, detected before fitting).
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum IdentError {
    /// The dataset itself is malformed.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Dataset(#[from] DatasetError),
    /// The model has a coefficient that is not affine in the parameters.
    #[error("{0}")]
    #[diagnostic(
        code(harmonid::ident::non_affine),
        help("identification needs every coefficient linear in the parameters (e.g. `g12`, `3/4*beta1 + g12`); fix the product of parameters in the model")
    )]
    NonAffine(#[from] harmonid_model::NonAffineTerm),
    /// More measurements than an identification holds in memory.
    #[error("{file}: {found} measurements, above the {limit} one identification takes: it holds about 27 kB per one-line step (10,000 steps take 270 MB and 3 s), so this dataset would need about {gb:.1} GB", gb = *found as f64 * 27e3 / 1e9)]
    #[diagnostic(
        code(harmonid::ident::too_many_measurements),
        help("identify the sweeps of a few drive levels at a time (`--holdout` the others, or a dataset per level), or keep every n-th step of each sweep")
    )]
    TooManyMeasurements {
        /// Manifest path.
        file: String,
        /// Its measurements.
        found: usize,
        /// [`crate::MAX_MEASUREMENTS`].
        limit: usize,
    },
    /// A measurement background (`--background`) the dataset or the settings cannot fit.
    #[error("{file}: {why}")]
    #[diagnostic(
        code(harmonid::ident::background),
        help("the background terms are drive (B·V), slope (S·V·(f − f_mode)) and constant (C); see docs/identification.md, \"Measurement backgrounds\"")
    )]
    Background {
        /// Manifest path.
        file: String,
        /// What is refused and what to do.
        why: String,
    },
    /// No nominal frequency for a mode.
    #[error("mode {mode} has no nominal resonance frequency: give it in the model (`mode {mode} at ... kHz`), in the dataset's [nominal_hz], or on the command line")]
    #[diagnostic(
        code(harmonid::ident::no_nominal),
        help("e.g. `--nominal q1=207.58e3`")
    )]
    NoNominal {
        /// Mode name.
        mode: String,
    },
    /// A drive tone sits near no resonance.
    #[error("{file}: measurement \"{measurement}\": drive tone {drive_hz} Hz is near no resonance (nearest: {mode} at {nominal_hz} Hz, {rel:.3} relative away; limit {limit}); check drives_hz and the nominal frequencies")]
    #[diagnostic(
        code(harmonid::ident::tone_near_no_resonance),
        help("a wider --near-rel accepts tones further from a resonance (a stepped sweep's tone is also near within --near-rel of the sweep's own resonance: its largest response, a peak inside the sweep)")
    )]
    ToneNearNoResonance {
        /// Manifest path.
        file: String,
        /// Measurement name.
        measurement: String,
        /// Drive frequency, Hz.
        drive_hz: f64,
        /// Nearest mode.
        mode: String,
        /// Its nominal frequency, Hz.
        nominal_hz: f64,
        /// Relative distance.
        rel: f64,
        /// The limit ([`Settings::near_rel`](super::Settings::near_rel)).
        limit: f64,
    },
    /// A measurement without a pump for a model with pump terms.
    #[error(
        "{file}: measurement \"{measurement}\" has no pump, and the model has pump terms: {terms}"
    )]
    #[diagnostic(
        code(harmonid::ident::no_pump),
        help("give the measurement's pump tones with their levels and phases (`pumps_hz`, `pump_levels`, `pump_phases_rad` in dataset.toml), or identify with a model without the pump terms")
    )]
    NoPump {
        /// Manifest path.
        file: String,
        /// Measurement name.
        measurement: String,
        /// The model's pump terms.
        terms: String,
    },
    /// A measured mode has zero shape at every measured point.
    #[error("{file}: measurement \"{measurement}\": mode {mode} has zero shape at every measured point, so its amplitude cannot be measured; give a point where it moves")]
    #[diagnostic(
        code(harmonid::ident::zero_shape),
        help("check the [[point]] shapes in dataset.toml")
    )]
    ZeroShape {
        /// Manifest path.
        file: String,
        /// Measurement name.
        measurement: String,
        /// Mode.
        mode: String,
    },
    /// Fewer real equations than unknowns in a fit.
    #[error("{file}: {what} has {rows} real equations (2 per measured frequency) for {unknowns} unknowns ({names}); measure more frequencies (sidebands) or fix some parameters")]
    #[diagnostic(
        code(harmonid::ident::too_few_frequencies),
        help("with drive levels, one gain per measurement adds two unknowns to every measurement: a stepped sweep with one line per step needs --gain-per-mode (one gain for the whole dataset)")
    )]
    TooFewFrequencies {
        /// Manifest path.
        file: String,
        /// The measurement(s).
        what: String,
        /// Real equations.
        rows: usize,
        /// Unknowns.
        unknowns: usize,
        /// Names of the unknowns (the first eight, then how many more).
        names: String,
    },
    /// Unsupported model feature.
    #[error("{0}")]
    #[diagnostic(code(harmonid::ident::unsupported))]
    Unsupported(String),
    /// A held-out set that cannot be used (names no measurement, is every measurement, or
    /// leaves a quantity undetermined).
    #[error("{0}")]
    #[diagnostic(
        code(harmonid::ident::holdout),
        help("--holdout takes measurement names from the dataset's manifest, comma-separated")
    )]
    Holdout(String),
    /// Planning products failed.
    #[error("measurement \"{measurement}\": {source}")]
    #[diagnostic(code(harmonid::ident::spectral))]
    Spectral {
        /// Measurement name.
        measurement: String,
        /// The error.
        source: harmonid_spectral::SpectralError,
    },
    /// A dataset given to a fit does not have the shape of the one the problem was set up for.
    #[error("{file}: the dataset's measurements, frequencies or points differ from those the identification was set up for; set it up again for this dataset")]
    #[diagnostic(code(harmonid::ident::shape_mismatch))]
    ShapeMismatch {
        /// Manifest path.
        file: String,
    },
}

//! Settings of an identification: the estimator, the force model and the fits' options, each
//! option with one spelling ([`FromStr`](std::str::FromStr), `Display`, serde) that the command
//! line, Python and the result file share.

use crate::background_terms::Background;
use std::collections::BTreeMap;

pub use harmonid_data::result::{Estimator, UnknownEstimator};

/// Which force model to use. [`ForceModel::name`] is its one spelling (Python's
/// `force_model=`, serde), read back by [`FromStr`](std::str::FromStr); `Display` gives words
/// for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForceModel {
    /// Drive levels when every measurement gives them (one gain per mode and measurement, or
    /// per mode for the whole dataset when it holds stepped sweeps), free forces otherwise.
    #[default]
    Auto,
    /// Every tone's force a free complex unknown (the paper's model).
    Free,
    /// `F = G_n V e^{iφ}` with one complex gain per mode and measurement.
    GainPerMeasurement,
    /// `F = G_n V e^{iφ}` with one complex gain per mode for the whole dataset.
    GainPerMode,
}

impl ForceModel {
    /// Every force model, the default first.
    pub const ALL: [ForceModel; 4] = [
        ForceModel::Auto,
        ForceModel::Free,
        ForceModel::GainPerMeasurement,
        ForceModel::GainPerMode,
    ];

    /// The force model's name: `auto`, `free`, `gain_per_measurement`, `gain_per_mode`.
    pub fn name(self) -> &'static str {
        match self {
            ForceModel::Auto => "auto",
            ForceModel::Free => "free",
            ForceModel::GainPerMeasurement => "gain_per_measurement",
            ForceModel::GainPerMode => "gain_per_mode",
        }
    }

    /// What the force model is, for the summary and the result's `force_model`.
    pub fn description(self) -> &'static str {
        match self {
            ForceModel::Auto => {
                "drive levels when every measurement gives them, free forces otherwise"
            }
            ForceModel::Free => "free complex force per drive tone",
            ForceModel::GainPerMeasurement => {
                "drive levels: one complex actuator gain per mode and measurement"
            }
            ForceModel::GainPerMode => {
                "drive levels: one complex actuator gain per mode for the whole dataset"
            }
        }
    }

    /// The model in use: `Auto` becomes [`ForceModel::GainPerMeasurement`] when every
    /// measurement gives drive levels (`all_levels`), [`ForceModel::Free`] otherwise; the
    /// others stay.
    pub fn resolved(self, all_levels: bool) -> ForceModel {
        self.resolved_for(all_levels, false)
    }

    /// [`ForceModel::resolved`] for a dataset that holds stepped sweeps (`sweeps`) or not:
    /// with drive levels everywhere, `Auto` is then one gain per mode for the whole dataset
    /// (a sweep's steps share one actuator; a gain per step would leave Q undetermined).
    pub fn resolved_for(self, all_levels: bool, sweeps: bool) -> ForceModel {
        match self {
            ForceModel::Auto if all_levels && sweeps => ForceModel::GainPerMode,
            ForceModel::Auto if all_levels => ForceModel::GainPerMeasurement,
            ForceModel::Auto => ForceModel::Free,
            f => f,
        }
    }
}

/// For messages: the force model in words.
impl std::fmt::Display for ForceModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ForceModel::Auto => "auto",
            ForceModel::Free => "free forces",
            ForceModel::GainPerMeasurement => "gain per measurement",
            ForceModel::GainPerMode => "gain per mode",
        })
    }
}

impl std::str::FromStr for ForceModel {
    type Err = UnknownForceModel;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ForceModel::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| UnknownForceModel {
                found: s.to_string(),
            })
    }
}

/// A name that is no [`ForceModel`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected {}, found {found:?}", ForceModel::ALL.map(|f| format!("{:?}", f.name())).join(", "))]
pub struct UnknownForceModel {
    /// The name given.
    pub found: String,
}

/// Settings of an identification. `Default` gives the documented defaults.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Force model (default [`ForceModel::Auto`]).
    pub force_model: ForceModel,
    /// Fit every unknown in one problem instead of the sequential stages (default false).
    pub joint: bool,
    /// Nominal resonance frequencies, Hz, that override the dataset's and the model's.
    pub nominal_hz: BTreeMap<String, f64>,
    /// A drive tone is "near" a resonance when `|f − f_nominal| ≤ near_rel · f_nominal`
    /// (default 0.05), or, in a stepped sweep, when `|f − f_sweep| ≤ near_rel · f_sweep` where
    /// `f_sweep` is the sweep's own resonance (the step of largest response, inside the sweep)
    /// and that mode's is the nearest nominal one: a low-Q resonance swept wide, or one its
    /// nonlinearity shifted (the sloshing tank's peaks at 0.94 of its linear frequency).
    pub near_rel: f64,
    /// Take the noise of each measured amplitude from the scatter across shots when there are
    /// at least this many shots (default 5; 0: assume equal noise on every amplitude).
    pub min_shots_for_weights: usize,
    /// Relative singular value below which a fit's matrix is considered rank deficient (default
    /// 1e-9): the unknown dominating the weakest direction is reported as not identifiable.
    pub rank_tol: f64,
    /// Generalised least squares (default true): after an unweighted first fit, weight the
    /// equations by the covariance of their errors that noise on the measured amplitudes
    /// causes (linearised, regressor noise included), twice. With at least
    /// `min_shots_for_weights` shots the amplitudes' noise comes from the scatter across shots.
    pub gls: bool,
    /// Number of reweighted fits after the unweighted one (default 1; a second changed the
    /// estimates by far less than their scatter in tests).
    pub gls_iterations: usize,
    /// With at least 20 shots (default true): weight by the sample covariance across shots of
    /// the equation residuals at the median estimate (shrunk 20 % towards its diagonal)
    /// instead of the linearised one. On simulated nanostring data (0.1 nm, 50 shots, four
    /// seeds) it gave 10-25 % smaller per-shot scatter of Q1 and f1 than the linearised one.
    pub sample_covariance: bool,
    /// The estimator of the reported values (default [`Estimator::Ml`]).
    pub estimator: Estimator,
    /// Compute and report the Cramér–Rao bound of every quantity at the estimate (default
    /// false; the ml estimator computes it anyway for its standard errors).
    pub crlb: bool,
    /// Cross-check the standard errors by a linearised delete-one-shot jackknife (default true).
    pub jackknife: bool,
    /// Add an error floor to the shot noise (default false): every line's noise becomes
    /// `√(s² + σ₀²)`, with one `σ₀` (m per quadrature) estimated with the output-error fit
    /// as the floor at which `χ²/dof` is a correct model's expectation. For measured data
    /// whose steps carry errors the scatter of their own samples does not see (drift between
    /// steps, drive-level and frequency jitter): the shot noise alone then weighs the lines
    /// by a noise they do not have. With a floor fitted to the residuals, `χ²` no longer
    /// tests the model (no p-value); a held-out prediction (`holdout`) does.
    pub error_floor: bool,
    /// The measurement background fitted with the model (default none; `--background`):
    /// per mode, on every measured line at a drive tone, a complex feedthrough times the
    /// drive level, a slope times drive × (f − f_mode) and a drive-independent offset, as
    /// chosen ([`crate::background`]). Output-error estimator only.
    pub background: Background,
    /// Background values to hold fixed instead of fitting (per mode, in the dataset's unit,
    /// as a result reports them; default empty): a held-out prediction (`holdout`) keeps the
    /// background the fit found, as it keeps the model.
    pub background_fixed: BTreeMap<String, harmonid_data::result::BackgroundResult>,
    /// Let the output-error fit's staged start scan a group's new model parameters over a
    /// geometric grid where neither the linear estimate nor zero starts the group well
    /// (default true: on a many-mode device a coupling's linear estimate can be hundreds of
    /// times off). [`crate::discover()`] turns it off for the models it tries: most of them lack
    /// a term the device has, so their groups fit poorly from every start, and the scan, which
    /// cannot make a wrong model fit, was a third of a discovery's time. Off, the groups that
    /// share unknowns are not refitted at the combined values either (another third).
    pub staged_scan: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            force_model: ForceModel::Auto,
            joint: false,
            nominal_hz: BTreeMap::new(),
            near_rel: 0.05,
            min_shots_for_weights: 5,
            rank_tol: 1e-9,
            gls: true,
            gls_iterations: 1,
            sample_covariance: true,
            estimator: Estimator::Ml,
            crlb: false,
            jackknife: true,
            error_floor: false,
            background: Background::default(),
            background_fixed: BTreeMap::new(),
            staged_scan: true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimator_names_read_back_in_every_spelling() {
        for e in Estimator::ALL {
            assert_eq!(e.name().parse::<Estimator>(), Ok(e));
            assert_eq!(e.to_string(), e.name());
            let json = serde_json::to_string(&e).expect("json");
            assert_eq!(json, format!("\"{}\"", e.name()));
            assert_eq!(serde_json::from_str::<Estimator>(&json).expect("back"), e);
        }
        assert_eq!(Estimator::default(), Estimator::ALL[0]);
        let err = "mle".parse::<Estimator>().expect_err("unknown");
        assert_eq!(err.found, "mle");
        assert!(err.to_string().starts_with("expected \"ml\" ("), "{err}");
    }

    #[test]
    fn force_model_names_read_back_and_auto_resolves() {
        for f in ForceModel::ALL {
            assert_eq!(f.name().parse::<ForceModel>(), Ok(f));
            let json = serde_json::to_string(&f).expect("json");
            assert_eq!(json, format!("\"{}\"", f.name()));
            assert_eq!(serde_json::from_str::<ForceModel>(&json).expect("back"), f);
        }
        assert_eq!(ForceModel::default(), ForceModel::ALL[0]);
        assert_eq!(
            ForceModel::Auto.resolved(true),
            ForceModel::GainPerMeasurement
        );
        assert_eq!(ForceModel::Auto.resolved(false), ForceModel::Free);
        assert_eq!(
            ForceModel::GainPerMode.resolved(false),
            ForceModel::GainPerMode
        );
        let err = "gains".parse::<ForceModel>().expect_err("unknown");
        assert_eq!(
            err.to_string(),
            "expected \"auto\", \"free\", \"gain_per_measurement\", \"gain_per_mode\", found \"gains\""
        );
    }
}

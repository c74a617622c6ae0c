//! Settings of an identification and the force model.

use super::IdentError;
use crate::dataset::Dataset;
use std::collections::BTreeMap;

/// Which estimate to report as `value`. [`Estimator::name`] is its one spelling: the command
/// line's `--estimator`, Python's `estimator=` and the result file's `estimator` (serde), read
/// back by [`FromStr`](std::str::FromStr).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Output-error maximum likelihood by harmonic balance, started from the pooled
    /// equation-error fit (default; falls back to `Linear` with a warning when the model
    /// cannot be simulated at the start).
    #[default]
    Ml,
    /// The equation-error fit of the pooled shots.
    Linear,
}

impl Estimator {
    /// Every estimator, the default first.
    pub const ALL: [Estimator; 2] = [Estimator::Ml, Estimator::Linear];

    /// The estimator's name: `ml`, `linear`.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Ml => "ml",
            Estimator::Linear => "linear",
        }
    }

    /// What the estimator is, for the summary and the command line's help.
    pub fn description(self) -> &'static str {
        match self {
            Estimator::Ml => {
                "output-error maximum likelihood (harmonic balance) on the pooled shots"
            }
            Estimator::Linear => "equation-error fit of the pooled shots",
        }
    }
}

impl std::fmt::Display for Estimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Estimator {
    type Err = UnknownEstimator;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Estimator::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| UnknownEstimator {
                found: s.to_string(),
            })
    }
}

/// A name that is no [`Estimator`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected {}, found {found:?}", Estimator::ALL.map(|e| format!("{:?} ({})", e.name(), e.description())).join(" or "))]
pub struct UnknownEstimator {
    /// The name given.
    pub found: String,
}

/// Which force model to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ForceModel {
    /// Drive levels when every measurement gives them, free forces otherwise.
    #[default]
    Auto,
    /// Every tone's force a free complex unknown (the paper's model).
    Free,
    /// `F = G_n V e^{iφ}` with one complex gain per mode and measurement.
    GainPerMeasurement,
    /// `F = G_n V e^{iφ}` with one complex gain per mode for the whole dataset.
    GainPerMode,
}

/// For messages: the command-line name of the force model.
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
    /// (default 0.05).
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
        }
    }
}

/// The force model in use: `Auto` resolves to drive levels when every measurement gives them;
/// a gain model without drive levels is an error naming the measurement.
pub(super) fn resolve_force_model(
    requested: ForceModel,
    ds: &Dataset,
    manifest_path: &str,
) -> Result<ForceModel, IdentError> {
    let all_levels = ds
        .measurements
        .iter()
        .all(|m| m.spec.drive_levels_and_phases().is_some());
    Ok(match requested {
        ForceModel::Auto if all_levels => ForceModel::GainPerMeasurement,
        ForceModel::Auto => ForceModel::Free,
        f @ (ForceModel::GainPerMeasurement | ForceModel::GainPerMode) if !all_levels => {
            let missing = ds
                .measurements
                .iter()
                .find(|m| m.spec.drive_levels_and_phases().is_none())
                .map(|m| m.spec.name.clone())
                .unwrap_or_default();
            return Err(IdentError::Unsupported(format!(
                "{manifest_path}: the force model \"{f}\" needs drive_levels_v and drive_phases_rad in every measurement; \"{missing}\" has none (use the free-force model)"
            )));
        }
        f => f,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_model_messages_use_words_not_debug_names() {
        // Issue 11: Rust debug names (`GainPerMode`, `NotConverged { .. }`) reached users.
        let manifest = "format = \"harmonid-dataset/1\"\n[[measurement]]\nname = \"m1\"\ndrives_hz = [1000.0]\n";
        let csv = "shot,freq_hz,re,im\n0,1000,1,2\n";
        let ds = Dataset::from_readers(std::path::Path::new("d"), manifest, None, |_| {
            Ok(csv.as_bytes())
        })
        .expect("a dataset without drive levels");
        let e = resolve_force_model(ForceModel::GainPerMode, &ds, "d/dataset.toml")
            .expect_err("gains need drive levels")
            .to_string();
        assert!(
            e.contains("the force model \"gain per mode\" needs") && !e.contains("GainPerMode"),
            "{e}"
        );
        assert_eq!(ForceModel::Free.to_string(), "free forces");
    }

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
}

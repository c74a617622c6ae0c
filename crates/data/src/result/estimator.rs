//! The estimator a result reports (`estimator` in the result file): one spelling shared by the
//! command line, Python and the file.

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

    /// Whether the estimate is an output-error (maximum-likelihood) fit through the forward
    /// model: its values, bounds and goodness of fit come from that fit, not the linear one.
    pub fn is_output_error(self) -> bool {
        match self {
            Estimator::Ml => true,
            Estimator::Linear => false,
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

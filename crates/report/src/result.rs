//! The identification result as the report reads it: every field optional, unknown fields kept,
//! so a result written by a newer `identify` (extra estimator fields) still reads.

use serde::Deserialize;
use std::collections::BTreeMap;

/// One estimate (`DATA_FORMAT.md`, result schema).
#[derive(Debug, Clone, Deserialize)]
pub struct EstimateView {
    /// Reported value.
    #[serde(default = "nan")]
    pub value: f64,
    /// Spread of one shot.
    #[serde(default = "nan")]
    pub std: f64,
    /// Standard error of the value.
    #[serde(default = "nan")]
    pub stderr: f64,
    /// Whether the data determine it (absent: yes).
    #[serde(default = "yes")]
    pub identifiable: bool,
    /// Why not.
    #[serde(default)]
    pub reason: Option<String>,
    /// Outlier shots.
    #[serde(default)]
    pub outlier_shots: Vec<usize>,
    /// Per-shot estimates, when the result holds them.
    #[serde(default)]
    pub per_shot: Vec<f64>,
    /// Any other numeric field (e.g. a Fisher standard error or a Cramér–Rao bound).
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

impl Default for EstimateView {
    fn default() -> Self {
        Self {
            value: f64::NAN,
            std: f64::NAN,
            stderr: f64::NAN,
            identifiable: true,
            reason: None,
            outlier_shots: Vec::new(),
            per_shot: Vec::new(),
            extra: BTreeMap::new(),
        }
    }
}

fn nan() -> f64 {
    f64::NAN
}

fn yes() -> bool {
    true
}

/// Linear parameters of a mode.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct ModeView {
    /// Resonance frequency, Hz.
    #[serde(default)]
    pub f_hz: EstimateView,
    /// Quality factor.
    #[serde(default, rename = "Q")]
    pub q: EstimateView,
}

/// A tone's force on a mode.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct ForceView {
    /// Tone, Hz.
    pub f_hz: f64,
    /// |F|, N/kg.
    pub amplitude: f64,
    /// arg F, rad.
    #[serde(default)]
    pub phase_rad: f64,
}

/// One fit's diagnostics.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct FitView {
    /// Stage.
    #[serde(default)]
    pub stage: usize,
    /// Measurements.
    #[serde(default)]
    pub measurements: Vec<String>,
    /// Unknowns.
    #[serde(default)]
    pub unknowns: Vec<String>,
    /// Condition number.
    #[serde(default = "nan")]
    pub condition_number: f64,
    /// Relative residual.
    #[serde(default = "nan")]
    pub relative_residual: f64,
}

/// The result.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct ResultView {
    /// `harmonid-result/1`.
    #[serde(default)]
    pub format: String,
    /// Model path.
    #[serde(default)]
    pub model: String,
    /// Dataset path.
    #[serde(default)]
    pub dataset: String,
    /// Force model.
    #[serde(default)]
    pub force_model: String,
    /// Shots.
    #[serde(default)]
    pub shots: usize,
    /// Modes.
    #[serde(default)]
    pub modes: BTreeMap<String, ModeView>,
    /// Parameters.
    #[serde(default)]
    pub parameters: BTreeMap<String, EstimateView>,
    /// Monomial coefficients per equation.
    #[serde(default)]
    pub eom: BTreeMap<String, BTreeMap<String, Option<f64>>>,
    /// Forces per measurement and mode.
    #[serde(default)]
    pub forces: BTreeMap<String, BTreeMap<String, Vec<ForceView>>>,
    /// Fits.
    #[serde(default)]
    pub fits: Vec<FitView>,
    /// Warnings.
    #[serde(default)]
    pub warnings: Vec<String>,
}

impl ResultView {
    /// Reads a result JSON.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }

    /// From a fresh identification: its JSON plus the per-shot estimates the JSON leaves out.
    pub fn from_report(r: &harmonid_ident::Report) -> Result<Self, serde_json::Error> {
        let mut v = Self::from_json(&r.to_json())?;
        for (name, e) in &r.parameters {
            if let Some(p) = v.parameters.get_mut(name) {
                p.per_shot.clone_from(&e.per_shot);
            }
        }
        for (name, m) in &r.modes {
            if let Some(p) = v.modes.get_mut(name) {
                p.f_hz.per_shot.clone_from(&m.f_hz.per_shot);
                p.q.per_shot.clone_from(&m.q.per_shot);
            }
        }
        Ok(v)
    }

    /// The numbers a simulation needs: `[modes]` and `[eom]` (terms reported as null dropped).
    pub fn model_values(&self) -> harmonid_sim::ModelValues {
        let mut v = harmonid_sim::ModelValues::default();
        for (n, m) in &self.modes {
            v.modes.insert(
                n.clone(),
                harmonid_sim::ModeValues {
                    f_hz: Some(m.f_hz.value),
                    q: Some(m.q.value),
                },
            );
        }
        for (n, terms) in &self.eom {
            v.eom.insert(
                n.clone(),
                terms
                    .iter()
                    .filter_map(|(k, c)| c.filter(|c| c.is_finite()).map(|c| (k.clone(), c)))
                    .collect(),
            );
        }
        v
    }
}

impl ResultView {
    /// The truth of parameter `p`: the truth coefficient of a monomial whose identified
    /// coefficient equals the parameter's value (a monomial it alone sets).
    pub fn truth_of_param(&self, p: &str, truth: &harmonid_ident::Truth) -> Option<f64> {
        let e = self.parameters.get(p)?;
        self.eom.iter().find_map(|(mode, row)| {
            row.iter().find_map(|(mono, v)| {
                let v = (*v)?;
                ((v - e.value).abs() <= 1e-12 * e.value.abs())
                    .then(|| truth.eom.get(mode).and_then(|r| r.get(mono)).copied())
                    .flatten()
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_unknown_and_missing_fields() {
        let r = ResultView::from_json(
            r#"{"modes": {"q1": {"f_hz": {"value": 1.0, "crlb": 0.1}}},
                "parameters": {"b": {"value": 2.0, "fisher_stderr": 0.3}},
                "future": [1, 2]}"#,
        )
        .expect("reads");
        assert_eq!(r.modes["q1"].f_hz.value, 1.0);
        assert!(r.modes["q1"].q.value.is_nan());
        assert_eq!(r.parameters["b"].extra["fisher_stderr"], 0.3);
        assert!(r.parameters["b"].identifiable);
    }
}

//! The groups of unknowns an identification could not fit (`unfit[]` of the result file,
//! `docs/data-format.md`): which, why, and what measurement would help. Absent when every
//! unknown was fitted and determined.

use serde::{Deserialize, Serialize};

/// Why a group of unknowns was not fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnfitWhy {
    /// The output-error fit could not be made at all: the pooled linear estimate is
    /// reported instead (`estimator` `"linear"`).
    NoOutputError,
    /// The output-error fit stopped before converging: its values are where it stopped.
    NotConverged,
    /// The output-error fit of this group's own measurements, the others held (its staged
    /// start), missed them by far more than a correct model would.
    GroupNotFitted,
    /// The data do not determine these unknowns (relative standard error above 0.3, or no
    /// measurement shapes them independently).
    NotDetermined,
    /// The estimate sits at a bound of the parameter: the data favour a value beyond it.
    AtBound,
    /// A reason written by a later version of harmonid (read back only).
    #[serde(other)]
    Other,
}

impl UnfitWhy {
    /// The reason in words, as the summary and the report print it.
    pub fn text(self) -> &'static str {
        match self {
            UnfitWhy::NoOutputError => "no output-error fit",
            UnfitWhy::NotConverged => "not converged",
            UnfitWhy::GroupNotFitted => "group not fitted",
            UnfitWhy::NotDetermined => "not determined",
            UnfitWhy::AtBound => "at its bound",
            UnfitWhy::Other => "not fitted",
        }
    }
}

/// One group of unknowns the identification could not fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnfitGroup {
    /// Why.
    pub why: UnfitWhy,
    /// The reported quantities of the group by their result keys (`f_hz:<mode>`, `Q:<mode>`,
    /// parameter names; forces and gains are not listed).
    pub unknowns: Vec<String>,
    /// The measurements whose fit failed (a group not fitted), by name; absent otherwise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub measurements: Vec<String>,
    /// That fit's `χ²` per degree of freedom (infinite, written `null`, when no start reached
    /// a fit); absent when not a group's fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chi2_per_dof: Option<f64>,
    /// What the identification found, in words (the fit's error, the quantities' reasons).
    pub detail: String,
    /// The measurement (or change) that would help.
    pub advice: String,
}

impl UnfitGroup {
    /// One line for the summary: reason, unknowns, measurements, detail and advice.
    pub fn line(&self) -> String {
        let unknowns = crate::text::first_and_more(self.unknowns.clone(), 6).join(", ");
        let meas = if self.measurements.is_empty() {
            String::new()
        } else {
            let names = self
                .measurements
                .iter()
                .map(|m| format!("\"{m}\""))
                .collect();
            format!(" in {}", crate::text::first_and_more(names, 3).join(", "))
        };
        let chi2 = match self.chi2_per_dof {
            Some(c) if c.is_finite() => format!(" (χ²/dof {c:.3e})"),
            Some(_) => " (no fit reached)".to_string(),
            None => String::new(),
        };
        format!(
            "{} ({unknowns}){meas}{chi2}: {}. Would help: {}",
            self.why.text(),
            self.detail,
            self.advice
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_group_reads_back_and_prints_one_line() {
        let g = UnfitGroup {
            why: UnfitWhy::GroupNotFitted,
            unknowns: vec!["f_hz:q6".into(), "g67".into()],
            measurements: vec!["couple_q6_q7".into()],
            chi2_per_dof: Some(f64::INFINITY),
            detail: "its own fit".into(),
            advice: "a measurement driving q6+q7 alone".into(),
        };
        let text = serde_json::to_string(&g).expect("json");
        assert!(text.contains("\"why\":\"group_not_fitted\""), "{text}");
        // Infinity is written as null and read back as absent.
        assert!(text.contains("\"chi2_per_dof\":null"), "{text}");
        let back: UnfitGroup = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back.unknowns, g.unknowns);
        assert_eq!(back.chi2_per_dof, None);
        assert_eq!(
            g.line(),
            "group not fitted (f_hz:q6, g67) in \"couple_q6_q7\" (no fit reached): its own fit. Would help: a measurement driving q6+q7 alone"
        );
        let later: UnfitWhy = serde_json::from_str("\"beyond_us\"").expect("other");
        assert_eq!(later, UnfitWhy::Other);
    }
}

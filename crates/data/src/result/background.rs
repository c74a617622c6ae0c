//! A measurement background fitted with the resonator (`identify --background`), as the
//! result file reports it (`docs/data-format.md`, "background").
//!
//! On every measured line at a drive tone's frequency `f` attributed to mode `n` (the mode
//! whose nominal resonance `f_ref` is nearest), the measured complex amplitude is the
//! resonator's response plus
//!
//! ```text
//! B_n·D + S_n·D·(f − f_ref) + C_n
//! ```
//!
//! with `D = V e^{iφ}` the tone's drive level and phase as the dataset records them. `B`
//! (`drive`, feedthrough) is in the data's unit per drive-level unit, `S` (`slope`) in the
//! data's unit per drive-level unit per Hz, `C` (`constant`) in the data's unit
//! (`displacement_unit`: m, or V for an uncalibrated lock-in). Each is one complex unknown
//! per mode, shared by every measurement of the dataset.

use super::Estimate;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// One complex background coefficient: its real and imaginary parts, each with its standard
/// error (Fisher at the output-error estimate; `std`, the per-shot spread, is `null`: the
/// per-shot equation-error fits have no background).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ComplexEstimate {
    /// Real part.
    pub re: Estimate,
    /// Imaginary part.
    pub im: Estimate,
}

impl ComplexEstimate {
    /// The complex value `re + i·im`.
    pub fn value(&self) -> Complex64 {
        Complex64::new(self.re.value, self.im.value)
    }
}

/// The background fitted on one mode's measured lines (see the module documentation).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BackgroundResult {
    /// The dataset's unit of amplitude (`displacement_unit`), in which the background is.
    pub unit: String,
    /// The frequency the slope is counted from: the mode's nominal resonance, Hz.
    pub f_ref_hz: f64,
    /// `B`: feedthrough, unit per drive-level unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<ComplexEstimate>,
    /// `S`: slope, unit per drive-level unit per Hz of `f − f_ref_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slope: Option<ComplexEstimate>,
    /// `C`: drive-independent offset, unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constant: Option<ComplexEstimate>,
}

impl BackgroundResult {
    /// The background at a line of frequency `f_hz` (Hz) driven at the complex level
    /// `drive = V e^{iφ}` (drive-level units), in [`BackgroundResult::unit`]: what the model
    /// adds to the resonator's response there. Terms not fitted count as zero.
    pub fn at(&self, f_hz: f64, drive: Complex64) -> Complex64 {
        let v = |c: &Option<ComplexEstimate>| {
            c.as_ref().map_or(Complex64::new(0.0, 0.0), |c| c.value())
        };
        v(&self.drive) * drive + v(&self.slope) * drive * (f_hz - self.f_ref_hz) + v(&self.constant)
    }

    /// Each fitted term with its name (`drive`, `slope`, `constant`) and unit.
    pub fn terms(&self) -> Vec<(&'static str, String, &ComplexEstimate)> {
        let u = &self.unit;
        [
            ("drive", format!("{u} per drive unit"), &self.drive),
            ("slope", format!("{u} per drive unit per Hz"), &self.slope),
            ("constant", u.clone(), &self.constant),
        ]
        .into_iter()
        .filter_map(|(n, unit, c)| c.as_ref().map(|c| (n, unit, c)))
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(value: f64) -> Estimate {
        Estimate {
            value,
            std: f64::NAN,
            stderr: 0.1,
            crlb: Some(0.1),
            jackknife: None,
            at_bound: false,
            identifiable: true,
            reason: None,
            outlier_shots: Vec::new(),
            single_shot_std: f64::NAN,
            per_shot: Vec::new(),
        }
    }

    #[test]
    fn the_background_adds_its_terms_at_a_line() {
        let c = |re, im| {
            Some(ComplexEstimate {
                re: est(re),
                im: est(im),
            })
        };
        let b = BackgroundResult {
            unit: "V".into(),
            f_ref_hz: 100.0,
            drive: c(2.0, 1.0),
            slope: c(0.5, 0.0),
            constant: c(0.0, -3.0),
        };
        let d = Complex64::new(0.0, 2.0);
        // (2 + i)·2i + 0.5·2i·(-4) + (-3i) = -2 + 4i - 4i - 3i.
        let x = b.at(96.0, d);
        assert!((x - Complex64::new(-2.0, -3.0)).norm() < 1e-12, "{x}");
        let names: Vec<&str> = b.terms().iter().map(|t| t.0).collect();
        assert_eq!(names, ["drive", "slope", "constant"]);
        let json = serde_json::to_string(&b).expect("json");
        let back: BackgroundResult = serde_json::from_str(&json).expect("back");
        assert_eq!(back.at(96.0, d), x);
        let only_c = BackgroundResult {
            drive: None,
            slope: None,
            ..b
        };
        assert!(!serde_json::to_string(&only_c)
            .expect("json")
            .contains("drive"));
    }
}

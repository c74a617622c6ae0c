//! The result file of an identification (`docs/data-format.md`, "Result of an
//! identification"): its types, read and written here so that every crate reads results
//! through the data layer; `harmonid_ident` computes them.

mod background;
mod estimator;
mod goodness;
mod summary;
mod unfit;

pub use background::{BackgroundResult, ComplexEstimate};
pub use estimator::{Estimator, UnknownEstimator};
pub use goodness::{
    p_text, sig3, GoodnessOfFit, LineResidual, MeasurementFit, SweepFit, P_DOES_NOT_FIT,
};
pub use unfit::{UnfitGroup, UnfitWhy};

use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;

/// The result format written by [`Report`].
pub const RESULT_FORMAT: &str = "harmonid-result/1";

/// One reported quantity.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Estimate {
    /// The estimate: output-error maximum likelihood on the pooled shots (`estimator` "ml"),
    /// or the equation-error fit of the pooled shots ("linear"); see `docs/identification.md`.
    #[serde(deserialize_with = "nan_if_null")]
    pub value: f64,
    /// One-sigma spread of the per-shot (equation-error) estimates after outlier rejection,
    /// the width of the paper's histograms; with one shot, the fit's standard error from its
    /// residuals. A diagnostic: it is not the uncertainty of `value`.
    #[serde(deserialize_with = "nan_if_null")]
    pub std: f64,
    /// Standard error of `value`: ml, `√diag((JᵀWJ)⁻¹)` at the estimate with the noise of
    /// every line from the shot scatter (nuisances profiled), times `√(χ²/dof)` when the fit
    /// is worse than the noise; linear, the per-shot spread over `√n`.
    #[serde(deserialize_with = "nan_if_null")]
    pub stderr: f64,
    /// Cramér–Rao bound at the estimate (same noise, `√diag(I⁻¹)`), when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crlb: Option<f64>,
    /// Linearised delete-one-shot jackknife standard error of `value`, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jackknife: Option<f64>,
    /// The estimate sits at a bound of the parameter (the data favour a value beyond it).
    #[serde(default, skip_serializing_if = "is_false")]
    pub at_bound: bool,
    /// False when the data do not determine it (relative stderr above 0.3, or not
    /// identifiable).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub identifiable: bool,
    /// Why it is not identifiable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Shots flagged as outliers for this quantity.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outlier_shots: Vec<usize>,
    /// The fit's own standard error of shot 0 (from the least-squares residuals).
    #[serde(default = "nan", deserialize_with = "nan_if_null")]
    pub single_shot_std: f64,
    /// Per-shot estimates.
    #[serde(skip)]
    pub per_shot: Vec<f64>,
}

fn is_true(b: &bool) -> bool {
    *b
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn yes() -> bool {
    true
}

fn nan() -> f64 {
    f64::NAN
}

/// Reads a number written by [`Report::to_json`], where NaN became `null`, back as NaN.
fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Linear parameters of one mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModeResult {
    /// Linear resonance frequency, Hz.
    pub f_hz: Estimate,
    /// Quality factor.
    #[serde(rename = "Q")]
    pub q: Estimate,
}

/// A drive tone's identified force on a mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ForceResult {
    /// Tone frequency, Hz.
    #[serde(deserialize_with = "nan_if_null")]
    pub f_hz: f64,
    /// Peak force amplitude, N/kg (median over shots of the complex force).
    #[serde(deserialize_with = "nan_if_null")]
    pub amplitude: f64,
    /// Phase, rad.
    #[serde(deserialize_with = "nan_if_null")]
    pub phase_rad: f64,
}

/// One complex actuator gain.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GainResult {
    /// |G|, N/kg per drive-level unit.
    #[serde(deserialize_with = "nan_if_null")]
    pub amplitude: f64,
    /// arg G, rad.
    #[serde(deserialize_with = "nan_if_null")]
    pub phase_rad: f64,
    /// Real part (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub re: f64,
    /// Imaginary part (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub im: f64,
}

/// Diagnostics of one fit, as reported.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitReport {
    /// Stage (1 = single-mode measurements, 2 = two-mode, ...; 0 = joint fit).
    pub stage: usize,
    /// Measurement names.
    pub measurements: Vec<String>,
    /// Fitted unknowns.
    pub unknowns: Vec<String>,
    /// Condition number of the column-equilibrated matrix (median over shots).
    #[serde(deserialize_with = "nan_if_null")]
    pub condition_number: f64,
    /// Relative residual `sqrt(Σ RSS / Σ ‖b‖²)`.
    #[serde(deserialize_with = "nan_if_null")]
    pub relative_residual: f64,
    /// Real equations.
    pub rows: usize,
    /// Whether the equations were weighted by the covariance of their errors (generalised
    /// least squares).
    pub weighted: bool,
    /// Whether the measured amplitudes' noise came from the scatter across shots.
    pub noise_from_shots: bool,
    /// Shots in which a bound was active.
    pub shots_with_active_bounds: usize,
}

/// The result of an identification (`DATA_FORMAT.md` schema, plus diagnostics).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// [`RESULT_FORMAT`].
    pub format: String,
    /// Model path.
    pub model: String,
    /// Dataset path.
    pub dataset: String,
    /// Force model used.
    #[serde(default)]
    pub force_model: String,
    /// The estimator of `value`: `"ml"` (output-error maximum likelihood by harmonic balance)
    /// or `"linear"` (equation-error fit of the pooled shots).
    #[serde(default)]
    pub estimator: String,
    /// Per measurement, the shots left out of the pooled mean as disturbed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub rejected_shots: BTreeMap<String, Vec<usize>>,
    /// Notes on how the estimate was made (noise source, fall-backs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Whether the model fits the data: the output-error fit's `χ²` against a correct
    /// model's, per measurement and per line (`None` for the linear estimator and for a
    /// noise study's per-shot report).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goodness_of_fit: Option<GoodnessOfFit>,
    /// Levels of drive ladders left out of the fit because they do not fit the branch the
    /// ladder's other levels define (a level the response jumped or drifted at); absent when
    /// none was.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excluded_levels: Vec<ExcludedLevel>,
    /// How well the estimate predicts the measurements held out of the fit (`identify
    /// --holdout`), in the order given; absent without a holdout.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub holdout: Vec<HeldOut>,
    /// The groups of unknowns the identification could not fit: why (no output-error fit,
    /// not converged, a group's own fit failed, not determined, at a bound) and what
    /// measurement would help ([`UnfitGroup`]); absent when every unknown was fitted and
    /// determined.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unfit: Vec<UnfitGroup>,
    /// Number of shots.
    #[serde(default)]
    pub shots: usize,
    /// Shots fitted one by one for the per-shot spread (`std`, outlier shots), when fewer than
    /// `shots`: a long record is represented by `MAX_SHOT_FITS` (`harmonid_ident`) shots spread evenly
    /// over it (the pooled mean and the output-error fit use every shot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shots_fitted: Option<usize>,
    /// The shot of every per-shot estimate (`per_shot[k]` is shot `shot_index[k]`); empty: shot
    /// `k`.
    #[serde(skip)]
    pub shot_index: Vec<usize>,
    /// Linear parameters per mode.
    pub modes: BTreeMap<String, ModeResult>,
    /// Parameters by their model names.
    pub parameters: BTreeMap<String, Estimate>,
    /// Every monomial coefficient of every equation (median over shots).
    #[serde(default)]
    pub eom: BTreeMap<String, BTreeMap<String, Option<f64>>>,
    /// Forces per measurement and mode, one entry per drive tone acting on that mode.
    #[serde(default)]
    pub forces: BTreeMap<String, BTreeMap<String, Vec<ForceResult>>>,
    /// Actuator gains per measurement (or "all") and mode, for the drive-level force model.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub gains: BTreeMap<String, BTreeMap<String, GainResult>>,
    /// The measurement background per mode (`identify --background`; [`BackgroundResult`]):
    /// absent when none was fitted.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub background: BTreeMap<String, BackgroundResult>,
    /// The fits, in order.
    #[serde(default)]
    pub fits: Vec<FitReport>,
    /// Shots flagged as outliers by any quantity.
    #[serde(default)]
    pub outlier_shots: Vec<usize>,
    /// Warnings (conditioning, unidentifiable quantities, ...).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Every comparison of a frequency, Q or actuator gain between two measurements
    /// ([`Comparison`]); those beyond the threshold are also in `warnings`. Not
    /// written to the result file.
    #[serde(skip)]
    pub consistency: Vec<Comparison>,
}

impl Report {
    /// The result as pretty JSON (NaN written as `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// Reads a result written by [`Report::to_json`] (`null` numbers come back as NaN; keys
    /// added after `harmonid-result/1`'s first version default when missing). Refuses another
    /// `format`.
    pub fn from_json(text: &str) -> Result<Report, serde_json::Error> {
        use serde::de::Error as _;
        let r: Report = serde_json::from_str(text)?;
        if r.format != RESULT_FORMAT {
            return Err(serde_json::Error::custom(format!(
                "format `{}`, expected `{RESULT_FORMAT}`",
                r.format
            )));
        }
        Ok(r)
    }
}

/// A level of a drive ladder the identification left out: its fit with the others.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcludedLevel {
    /// The level's measurement (`couple_q1_q2[2]`).
    pub measurement: String,
    /// Its ladder (the `direction = "level"` sweep).
    pub ladder: String,
    /// Its `χ²` per degree of freedom in the fit with every level.
    pub chi2_per_dof: f64,
    /// What a correct model gives.
    pub expected_chi2_per_dof: f64,
    /// The probability of a `χ²` at least this large for a correct model.
    pub p_value: f64,
}

/// How well the fit predicts one held-out measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// The measurement's name.
    pub measurement: String,
    /// Its measured lines (frequencies × points).
    pub lines: usize,
    /// Root mean square of the prediction's standardized residual per quadrature, in noise
    /// sigmas (about 1 for a model that predicts to the noise; absent without shot noise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_sigma: Option<f64>,
    /// With an error floor fitted (`identify --error-floor`): the same RMS with the floor
    /// added in quadrature to every line's shot noise, as the fit weighed its own lines
    /// (about 1 for a model that predicts as well as it fits).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_sigma_floor: Option<f64>,
    /// `√(Σ|X̄ − X|² / Σ|X̄|²)` over its lines.
    pub relative_rms: f64,
    /// For a step of a held-out sweep: the sweep's name (the summary prints the sweep's
    /// entry, not each step's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<String>,
    /// For a held-out sweep's entry (`measurement` is the sweep's name): its number of steps;
    /// the entry sums them (`lines`, both RMS over every line of every step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<usize>,
}

/// Which quantity a comparison is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compared {
    /// Linear resonance frequency of a mode, Hz.
    Frequency,
    /// Quality factor of a mode.
    Q,
    /// Magnitude of a mode's actuator gain, N/kg per drive-level unit.
    Gain,
}

impl Compared {
    /// The quantity in words, for messages: `f`, `Q`, `actuator gain |G|`.
    pub fn label(self) -> &'static str {
        match self {
            Compared::Frequency => "f",
            Compared::Q => "Q",
            Compared::Gain => "actuator gain |G|",
        }
    }
}

/// One quantity of one mode as two measurements see it.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// What is compared.
    pub quantity: Compared,
    /// Mode name.
    pub mode: String,
    /// The two measurements' names.
    pub measurements: [String; 2],
    /// Each measurement's estimate (Hz for frequencies).
    pub values: [f64; 2],
    /// Each estimate's standard error.
    pub stderrs: [f64; 2],
    /// The difference over its standard error (correlations included); see the module
    /// documentation.
    pub z: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(value: f64, std: f64) -> Estimate {
        let identifiable = std <= value.abs();
        Estimate {
            value,
            std,
            stderr: std / 3.0,
            crlb: Some(std / 3.1),
            jackknife: None,
            at_bound: false,
            identifiable,
            reason: (!identifiable).then(|| "the data do not determine it".to_string()),
            outlier_shots: vec![2],
            single_shot_std: std,
            per_shot: Vec::new(),
        }
    }

    fn sample_report() -> Report {
        let mode = ModeResult {
            f_hz: est(207582.0, 0.8),
            q: est(116232.0, 1.3e4),
        };
        Report {
            format: RESULT_FORMAT.into(),
            model: "model.hb".into(),
            dataset: "ds".into(),
            force_model: "free complex force per drive tone".into(),
            estimator: "ml".into(),
            rejected_shots: [("m".to_string(), vec![1])].into(),
            notes: vec!["a note".into()],
            goodness_of_fit: None,
            excluded_levels: Vec::new(),
            holdout: Vec::new(),
            unfit: Vec::new(),
            shots: 3,
            shots_fitted: None,
            shot_index: Vec::new(),
            modes: [("q1".to_string(), mode)].into(),
            parameters: [
                ("beta1".to_string(), est(2.68e22, 1.1e21)),
                ("g12".to_string(), est(f64::NAN, 5.0)),
            ]
            .into(),
            eom: [(
                "q1".to_string(),
                [
                    ("q1^3".to_string(), Some(2.68e22)),
                    ("q1*q2^2".to_string(), None),
                ]
                .into(),
            )]
            .into(),
            forces: [(
                "single_q1".to_string(),
                [(
                    "q1".to_string(),
                    vec![ForceResult {
                        f_hz: 207572.5,
                        amplitude: 3.5,
                        phase_rad: -0.25,
                    }],
                )]
                .into(),
            )]
            .into(),
            gains: [(
                "all".to_string(),
                [(
                    "q1".to_string(),
                    GainResult {
                        amplitude: 2.0,
                        phase_rad: 0.5,
                        re: 2.0 * 0.5f64.cos(),
                        im: 2.0 * 0.5f64.sin(),
                    },
                )]
                .into(),
            )]
            .into(),
            background: BTreeMap::new(),
            fits: vec![FitReport {
                stage: 1,
                measurements: vec!["single_q1".into()],
                unknowns: vec!["f(q1)".into()],
                condition_number: f64::NAN,
                relative_residual: 1e-7,
                rows: 20,
                weighted: true,
                noise_from_shots: false,
                shots_with_active_bounds: 0,
            }],
            outlier_shots: vec![2],
            warnings: vec!["parameter g12 is not determined".into()],
            consistency: Vec::new(),
        }
    }

    #[test]
    fn result_file_reads_back_equal() {
        let r = sample_report();
        let text = r.to_json();
        let back = Report::from_json(&text).expect("reads back");
        // Written again, the same bytes: every field survived (NaN as null, both ways).
        assert_eq!(back.to_json(), text);
        assert_eq!(back.modes["q1"].f_hz.value, 207582.0);
        assert_eq!(back.modes["q1"].q.std, 1.3e4);
        assert!(back.modes["q1"].q.identifiable);
        let g12 = &back.parameters["g12"];
        assert!(g12.value.is_nan() && !g12.identifiable);
        assert_eq!(g12.reason.as_deref(), Some("the data do not determine it"));
        assert_eq!(back.eom["q1"]["q1*q2^2"], None);
        assert_eq!(back.gains["all"]["q1"].im, 2.0 * 0.5f64.sin());
        assert!(back.fits[0].condition_number.is_nan());
        assert_eq!(back.fits[0].rows, 20);
    }

    #[test]
    fn result_file_of_the_data_format_reads_with_defaults() {
        // The minimal example of DATA_FORMAT.md: no diagnostics, no single-shot std.
        let text = r#"{
          "format": "harmonid-result/1",
          "model": "examples/nanostring_2mode/model.hb",
          "dataset": "path/of/the/dataset",
          "modes": {"q1": {"f_hz": {"value": 207582.01, "std": 0.8, "stderr": 0.11},
                           "Q": {"value": 116240.0, "std": 13000.0, "stderr": 1400.0}}},
          "parameters": {"beta1": {"value": 2.68e22, "std": 1.1e22, "stderr": 1.5e21}},
          "eom": {"q1": {"q1^3": 2.68e22}},
          "forces": {"single_q1": {"q1": [{"f_hz": 207572.0, "amplitude": 10.06, "phase_rad": 0.01}]}}
        }"#;
        let r = Report::from_json(text).expect("reads");
        assert_eq!(r.parameters["beta1"].value, 2.68e22);
        assert!(r.parameters["beta1"].identifiable);
        assert!(r.parameters["beta1"].single_shot_std.is_nan());
        assert!(r.warnings.is_empty() && r.fits.is_empty() && r.gains.is_empty());
        let other = text.replace("harmonid-result/1", "harmonid-result/9");
        let e = Report::from_json(&other).expect_err("another format");
        assert!(e.to_string().contains("harmonid-result/9"), "{e}");
    }
}

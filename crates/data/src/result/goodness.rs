//! The goodness-of-fit verdict of a result (`docs/data-format.md`, `goodness_of_fit`) and its
//! words. Computed by `harmonid_ident`; here the schema and how it is told.

use serde::{Deserialize, Serialize};

/// Below this p-value the model is said not to fit the data.
pub const P_DOES_NOT_FIT: f64 = 1e-3;

/// The verdict on a fit: its `χ²` against a correct model's, per measurement and per line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GoodnessOfFit {
    /// `Σ |X̄ − X|²/s²` over every measured line (`s`: the mean's noise per quadrature).
    pub chi2: f64,
    /// Real residuals minus fitted unknowns.
    pub dof: usize,
    /// `chi2 / dof`.
    pub chi2_per_dof: f64,
    /// Its expectation for a correct model with the noise model used (above 1 when the noise
    /// is estimated from few shots; 1 when it came from the residual).
    pub expected_chi2_per_dof: f64,
    /// Its standard deviation for a correct model.
    pub spread_chi2_per_dof: f64,
    /// Probability that a correct model gives a `χ²` at least this large; `None` when the
    /// noise came from the fit's residual (nothing to judge against; absent from the file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p_value: Option<f64>,
    /// `p_value ≥` [`P_DOES_NOT_FIT`] (`None` with `p_value`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fits: Option<bool>,
    /// Root mean square of the standardized residual per quadrature, in noise sigmas (about 1
    /// for a correct model).
    pub rms_residual_sigma: f64,
    /// `√(Σ|X̄ − X|² / Σ|X̄|²)` over every line: the misfit relative to the measured
    /// amplitudes.
    pub relative_rms: f64,
    /// Whether the output-error fit converged. When it did not, the values are where it
    /// stopped, not estimates: every quantity is reported not determined, and the headline
    /// says so first.
    #[serde(default = "yes")]
    pub converged: bool,
    /// The factor the output-error standard errors were multiplied by,
    /// `√max(1, (chi2_per_dof − spread_chi2_per_dof) / expected_chi2_per_dof)` (a correct
    /// model's χ² within its spread widens nothing): above 1 they are model-limited (the
    /// misfit, not the noise, sets them).
    pub stderr_inflation: f64,
    /// Per measurement, in the dataset's order.
    pub measurements: Vec<MeasurementFit>,
    /// Every measured line's standardized residual, in the dataset's order.
    pub lines: Vec<LineResidual>,
    /// The error floor fitted with the model (m per quadrature, added in quadrature to every
    /// line's shot noise; `identify --error-floor`); `None`/absent: the shot noise alone.
    /// With a floor, `p_value` and `fits` are absent: the floor was chosen to make `χ²/dof`
    /// its expectation, so `χ²` no longer tests the model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_floor: Option<f64>,
    /// Per stepped sweep (`[[sweep]]`), its steps' misfit summed, in the order of their first
    /// step; absent for a dataset without sweeps.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sweeps: Vec<SweepFit>,
}

/// A stepped sweep's share of the misfit: its steps' [`MeasurementFit`]s summed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepFit {
    /// The sweep's name.
    pub name: String,
    /// Its steps.
    pub steps: usize,
    /// Its measured lines, every step's.
    pub lines: usize,
    /// Its part of `χ²`.
    pub chi2: f64,
    /// `√(Σ|X̄ − X|² / Σ|X̄|²)` over every line of every step: the misfit in the measured
    /// amplitudes' units, what a lab reads as "the fit is off by 6 %".
    pub relative_rms: f64,
    /// Root mean square of the standardized residuals per quadrature, in noise sigmas (the
    /// floor's included when one was fitted).
    pub rms_residual_sigma: f64,
}

impl SweepFit {
    /// The sum of `steps` (the measurements of sweep `name`).
    pub fn of_steps(name: &str, steps: &[&MeasurementFit]) -> Self {
        let lines: usize = steps.iter().map(|m| m.lines).sum();
        let meas2: f64 = steps
            .iter()
            .map(|m| m.amplitude_rms.powi(2) * m.lines as f64)
            .sum();
        let miss2: f64 = steps
            .iter()
            .map(|m| (m.relative_rms * m.amplitude_rms).powi(2) * m.lines as f64)
            .sum();
        let chi2: f64 = steps.iter().map(|m| m.chi2).sum();
        Self {
            name: name.to_string(),
            steps: steps.len(),
            lines,
            chi2,
            relative_rms: (miss2 / meas2).sqrt(),
            rms_residual_sigma: (chi2 / (2 * lines).max(1) as f64).sqrt(),
        }
    }
}

/// One measurement's share of the misfit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasurementFit {
    /// The measurement's name.
    pub name: String,
    /// Its measured lines (frequencies × points).
    pub lines: usize,
    /// Its part of `χ²`.
    pub chi2: f64,
    /// `√(Σ|X̄ − X|² / Σ|X̄|²)` over its lines.
    pub relative_rms: f64,
    /// `√(Σ|X̄|² / lines)`: the size of its measured amplitudes (m), which with
    /// `relative_rms` sums the misfit of several measurements (a sweep's steps).
    #[serde(default)]
    pub amplitude_rms: f64,
    /// Root mean square of its standardized residuals per quadrature, in noise sigmas.
    pub rms_residual_sigma: f64,
    /// `chi2` over its share of the degrees of freedom (`2·lines·dof/N`, `N` real residuals
    /// in all).
    pub chi2_per_dof: f64,
    /// The expectation of `chi2_per_dof` for a correct model (its shots' `ν/(ν − 2)`).
    pub expected_chi2_per_dof: f64,
    /// Probability that a correct model gives this measurement a `chi2` at least this large
    /// (as the whole fit's `p_value`, on its share of the degrees of freedom); `None`/absent
    /// without shot noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p_value: Option<f64>,
}

/// One measured line's residual in noise units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LineResidual {
    /// The measurement's name.
    pub measurement: String,
    /// The line's frequency, Hz.
    pub freq_hz: f64,
    /// The point's name (`None` for modal data).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// `Re(X̄ − X)/s`: measured minus model, in-phase, in noise sigmas.
    pub re: f64,
    /// `Im(X̄ − X)/s`, quadrature.
    pub im: f64,
    /// `|X̄ − X|/s` (about √2 for a correct model).
    pub sigma: f64,
}

impl GoodnessOfFit {
    /// The misfit in percent of the measured amplitudes, overall and per sweep, as the
    /// summary prints it (the number a lab reads beside `χ²`).
    pub fn misfit_line(&self) -> String {
        let mut s = format!(
            "misfit {} % RMS of the measured amplitudes",
            sig3(100.0 * self.relative_rms)
        );
        if !self.sweeps.is_empty() {
            let per: Vec<String> = self
                .sweeps
                .iter()
                .map(|w| format!("{} {} %", w.name, sig3(100.0 * w.relative_rms)))
                .collect();
            s.push_str(&format!("; per sweep: {}", per.join(", ")));
        }
        s
    }

    /// The verdict in one line, for the summary's head.
    pub fn one_line(&self) -> String {
        let head = format!(
            "χ²/dof = {} (a correct model: {:.3} ± {:.2})",
            sig3(self.chi2_per_dof),
            self.expected_chi2_per_dof,
            self.spread_chi2_per_dof
        );
        if !self.converged {
            return format!(
                "{head}: THE OUTPUT-ERROR FIT DID NOT CONVERGE (values are where it stopped)"
            );
        }
        match (self.p_value, self.fits) {
            (Some(p), Some(true)) => {
                format!(
                    "{head}, p {}: the model fits the data to their noise",
                    p_text(p)
                )
            }
            (Some(p), _) => format!(
                "{head}, p {}: THE MODEL DOES NOT FIT; standard errors model-limited (×{})",
                p_text(p),
                sig3(self.stderr_inflation)
            ),
            _ => match self.error_floor {
                Some(f) => format!(
                    "{head}: not judged (an error floor of {} per quadrature was fitted with the model; judge by --holdout)",
                    sig3(f)
                ),
                None => format!("{head}: not judged (no noise estimate from the shot scatter)"),
            },
        }
    }

    /// What a reader must know before the values, in plain words (`None` when the fit
    /// converged and the model fits): a fit that stopped before converging, or a model that
    /// does not fit the data by how many noise sigmas, where, and what that means for the
    /// error bars.
    pub fn headline(&self) -> Option<String> {
        if !self.converged {
            return Some(format!(
                "THE OUTPUT-ERROR FIT DID NOT CONVERGE: it stopped at χ²/dof = {} (a correct model gives {:.3} ± {:.2}). The values are where it stopped, not estimates, and every quantity is reported NOT DETERMINED; a plan that determines them (harmonid plan), more shots, or the linear estimate (--estimator linear) may help.",
                sig3(self.chi2_per_dof),
                self.expected_chi2_per_dof,
                self.spread_chi2_per_dof,
            ));
        }
        if self.fits != Some(false) {
            return None;
        }
        let mut worst: Vec<&MeasurementFit> = self.measurements.iter().collect();
        worst.sort_by(|a, b| b.chi2_per_dof.total_cmp(&a.chi2_per_dof));
        let named: Vec<String> = worst
            .iter()
            .take(3)
            .map(|m| format!("\"{}\" (χ²/dof {})", m.name, sig3(m.chi2_per_dof)))
            .collect();
        let line = self
            .lines
            .iter()
            .max_by(|a, b| a.sigma.total_cmp(&b.sigma))
            .map(|l| {
                format!(
                    "; worst line {:.3} Hz in \"{}\"{}, {} sigmas off",
                    l.freq_hz,
                    l.measurement,
                    l.point
                        .as_ref()
                        .map_or(String::new(), |p| format!(" at point {p}")),
                    sig3(l.sigma)
                )
            })
            .unwrap_or_default();
        Some(format!(
            "THE MODEL DOES NOT FIT THE DATA: χ²/dof = {} where a correct model gives {:.3} ± {:.2} (p {}); it misses the measured lines by {} noise sigmas RMS. Worst: {}{line}. The standard errors assume the model is right: they are model-limited (inflated by √((χ²/dof − spread) / expected) = {}), and the values are the best this model can do, not the device's.",
            sig3(self.chi2_per_dof),
            self.expected_chi2_per_dof,
            self.spread_chi2_per_dof,
            p_text(self.p_value.unwrap_or(f64::NAN)),
            sig3(self.rms_residual_sigma),
            named.join(", "),
            sig3(self.stderr_inflation),
        ))
    }
}

fn yes() -> bool {
    true
}

/// A p-value as text: below the smallest double it is "< 1e-300", not 0.
pub fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "< 1e-300".into()
    } else if p < 0.01 {
        format!("= {p:.1e}")
    } else {
        format!("= {p:.2}")
    }
}

/// Three significant digits, plainly between 0.01 and 10⁵, in exponent form outside.
pub fn sig3(x: f64) -> String {
    let a = x.abs();
    if !x.is_finite() || a == 0.0 {
        format!("{x}")
    } else if (0.01..1e5).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_significant_digits() {
        assert_eq!(sig3(3.0), "3.00");
        assert_eq!(sig3(123.456), "123");
        assert_eq!(sig3(0.012345), "0.0123");
        assert_eq!(sig3(1.7e8), "1.70e8");
    }
}

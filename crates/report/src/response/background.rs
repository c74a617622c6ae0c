//! The fitted measurement background (`identify --background`, `Report::background`) added to
//! the model's response, so that the model drawn is the one the identification fitted: on a
//! step's drive line `B·D + S·D·(f − f_ref) + C` of the mode whose `f_ref` is nearest (`D`
//! the step's drive level and phase), with the step's phase reference; on the model's curve
//! the same at the family's median referenced drive.

use super::{MeasuredSweep, ModelCurve};
use harmonid_data::result::{BackgroundResult, Report};
use harmonid_data::Dataset;
use num_complex::Complex64;

/// The background of the mode whose reference frequency is nearest `f_hz`.
fn nearest(result: &Report, f_hz: f64) -> Option<&BackgroundResult> {
    result.background.values().min_by(|a, b| {
        (a.f_ref_hz - f_hz)
            .abs()
            .total_cmp(&(b.f_ref_hz - f_hz).abs())
    })
}

/// The drive level and phase `V e^{iφ}` of step `name`'s tone at `f_hz` (0 without levels).
fn drive_of(ds: &Dataset, name: &str, f_hz: f64) -> Complex64 {
    ds.measurement(name)
        .and_then(|m| {
            let (levels, phases) = m.spec.drive_levels_and_phases()?;
            let t = m
                .spec
                .drives_hz
                .iter()
                .position(|&d| (d - f_hz).abs() <= 1e-9 * d.abs().max(f_hz.abs()))?;
            Some(Complex64::from_polar(levels[t], phases[t]))
        })
        .unwrap_or_default()
}

/// The complex median of `z` (real and imaginary parts apart).
fn median(z: impl Iterator<Item = Complex64>) -> Complex64 {
    super::measured::complex_median(z)
}

/// Adds the result's background to the model at every step of `sweeps` and to `curve`;
/// returns the caption's note saying so (`None` without a background).
pub(super) fn add(
    result: &Report,
    ds: &Dataset,
    sweeps: &mut [MeasuredSweep],
    curve: Option<&mut ModelCurve>,
) -> Option<String> {
    if result.background.is_empty() {
        return None;
    }
    // Per step: the drive and the unit phasor, both against the step's reference.
    let mut referenced: Vec<(Complex64, Complex64)> = Vec::new();
    for sw in sweeps.iter_mut() {
        for k in 0..sw.steps.len() {
            let f = sw.f_hz[k];
            let turn = Complex64::from_polar(1.0, -sw.reference_rad[k]);
            let d = drive_of(ds, &sw.steps[k], f);
            referenced.push((d * turn, turn));
            let (Some(model), Some(bg)) = (sw.model.as_mut(), nearest(result, f)) else {
                continue;
            };
            model[k] += bg.at(f, d) * turn;
        }
    }
    if let Some(c) = curve {
        let d = median(referenced.iter().map(|r| r.0));
        let turn = median(referenced.iter().map(|r| r.1));
        for (x, &f) in c.x.iter_mut().zip(&c.f_hz) {
            if let Some(bg) = nearest(result, f) {
                let constant = bg
                    .constant
                    .as_ref()
                    .map_or(Complex64::default(), |c| c.value());
                *x += bg.at(f, d) + constant * (turn - 1.0);
            }
        }
    }
    let modes: Vec<&str> = result.background.keys().map(String::as_str).collect();
    Some(format!(
        "the model (curve and steps) includes the measurement background fitted with it (--background; B·D + S·D·(f − f_ref) + C on {}'s drive line, D the drive level and phase): the resonator alone is the model minus it",
        modes.join(", ")
    ))
}

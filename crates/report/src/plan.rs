//! The figure of a drive-tone plan (`harmonid plan --plot`): each mode's linear response, the
//! planned tones and the lines the plan's noise-free simulation predicts, named and classed as
//! the report's spectra are ([`crate::spectra::classify`]).

use harmonid_data::Dataset;
use harmonid_plot::{ModeResponse, PlanFigure, PlannedMeasurement, SpectrumLine};
use harmonid_sim::{Excitation, NumericModel};

/// The plan figure of `ds`, the noise-free simulation of a plan whose measurements drive
/// `excitations` (same order). Each mode's response curve is drawn for the plan's largest
/// single-tone force on it; the predicted |X| of a line is that at the measurement's first
/// point (m). `noise_m`: the per-quadrature σ of one shot, m, drawn as a floor.
pub fn plan_figure(
    model: &NumericModel,
    excitations: &[Excitation],
    ds: &Dataset,
    noise_m: Option<f64>,
    title: &str,
) -> PlanFigure {
    let modes = model
        .mode_names
        .iter()
        .enumerate()
        .map(|(n, name)| ModeResponse {
            mode: name.clone(),
            f_hz: model.f_hz[n],
            q: model.q_factor[n],
            force: excitations
                .iter()
                .flat_map(|e| e.force.get(n).into_iter().flatten())
                .map(|z| z.norm())
                .fold(0.0, f64::max),
        })
        .collect();
    let measurements = ds
        .measurements
        .iter()
        .map(|m| {
            let kinds = crate::spectra::classify(&m.freqs_hz, &m.spec.drives_hz, &model.f_hz);
            let lines = m
                .freqs_hz
                .iter()
                .zip(kinds)
                .enumerate()
                .filter_map(|(fi, (&f, kind))| {
                    let (kind, label) = kind?;
                    Some(SpectrumLine {
                        f_hz: f,
                        measured: m.amplitude(0, fi, 0).norm(),
                        reconstructed: None,
                        residual: None,
                        kind,
                        label,
                    })
                })
                .collect();
            PlannedMeasurement {
                name: m.spec.name.clone(),
                tones_hz: m.spec.drives_hz.clone(),
                lines,
            }
        })
        .collect();
    PlanFigure {
        title: title.to_string(),
        unit: "m".into(),
        modes,
        measurements,
        noise: noise_m,
    }
}

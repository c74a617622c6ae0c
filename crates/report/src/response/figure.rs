//! A family's response as a [`harmonid_plot::FrequencyResponse`] figure, and the overview of
//! every family in one.

use super::FamilyResponse;
use harmonid_data::Direction;
use harmonid_plot::{FrequencyResponse, ModelBranch, ResponseFamily, SweepMark};
use num_complex::Complex64;

fn pairs(x: &[Complex64]) -> Vec<(f64, f64)> {
    x.iter().map(|z| (z.re, z.im)).collect()
}

/// ` at p0`, or nothing for modal coordinates.
fn at(point: &str) -> String {
    if point == super::MODAL {
        String::new()
    } else {
        format!(" at {point}")
    }
}

/// The plot's family of `r`.
fn plot_family(r: &FamilyResponse) -> ResponseFamily {
    ResponseFamily {
        label: r.family.label.clone(),
        sweeps: r
            .sweeps
            .iter()
            .map(|s| harmonid_plot::MeasuredSweep {
                name: s.name.clone(),
                mark: match s.direction {
                    Direction::Up => SweepMark::Up,
                    Direction::Down => SweepMark::Down,
                    _ => SweepMark::Unordered,
                },
                f_hz: s.f_hz.clone(),
                x: pairs(&s.x),
            })
            .collect(),
        model: r.model.as_ref().map(|m| ModelBranch {
            f_hz: m.f_hz.clone(),
            x: pairs(&m.x),
            stable: m.stable.clone(),
        }),
    }
}

/// The figure of one family: its sweeps and the model's curve.
pub fn figure(r: &FamilyResponse) -> FrequencyResponse {
    let steps: usize = r.sweeps.iter().map(|s| s.steps.len()).sum();
    FrequencyResponse {
        title: format!(
            "{}: {} ({} steps) at {}",
            r.family.label,
            r.sweeps
                .iter()
                .map(|s| s.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            steps,
            r.point
        ),
        unit: r.unit.clone(),
        families: vec![plot_family(r)],
    }
}

/// Every family in one figure, one colour per family (drive level).
pub fn overview(rs: &[FamilyResponse]) -> FrequencyResponse {
    let steps: usize = rs
        .iter()
        .flat_map(|r| &r.sweeps)
        .map(|s| s.steps.len())
        .sum();
    FrequencyResponse {
        title: format!(
            "every drive level: {} families, {steps} steps{}",
            rs.len(),
            rs.first().map_or(String::new(), |r| at(&r.point))
        ),
        unit: rs.first().map_or_else(String::new, |r| r.unit.clone()),
        families: rs.iter().map(plot_family).collect(),
    }
}

//! A measurement plan over the resonances: the linear response of each mode, the planned tones
//! and the lines the plan predicts, each named by its combination (`harmonid plan --plot`).

use crate::spectrum::{clusters, LineKind, SpectrumLine};
use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// A mode's linear response `|F| / |ω² − Ω² + iΩω/Q|` (m) against frequency, Hz.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeResponse {
    /// Mode name.
    pub mode: String,
    /// Linear resonance frequency, Hz.
    pub f_hz: f64,
    /// Quality factor.
    pub q: f64,
    /// The force the curve is drawn for, N/kg (peak): the plan's largest single-tone force on
    /// this mode.
    pub force: f64,
}

impl ModeResponse {
    /// |X| at `f` Hz, m.
    pub fn at(&self, f: f64) -> f64 {
        let w = std::f64::consts::TAU * self.f_hz;
        let o = std::f64::consts::TAU * f;
        self.force / ((w * w - o * o).powi(2) + (o * w / self.q).powi(2)).sqrt()
    }
}

/// One planned measurement: its tones and its predicted lines.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedMeasurement {
    /// Name.
    pub name: String,
    /// Drive tones, Hz.
    pub tones_hz: Vec<f64>,
    /// The predicted lines (`measured` holds the predicted |X|; reconstruction and residual
    /// unused), each with its kind and combination label.
    pub lines: Vec<SpectrumLine>,
}

/// A plan: one row per measurement, one panel per group of nearby lines (one per resonance).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanFigure {
    /// Title.
    pub title: String,
    /// Unit of |X|, e.g. `m`.
    pub unit: String,
    /// Every mode's linear response.
    pub modes: Vec<ModeResponse>,
    /// The measurements.
    pub measurements: Vec<PlannedMeasurement>,
    /// The per-quadrature noise of one shot (same unit), drawn dashed, when known.
    pub noise: Option<f64>,
}

/// Height of one measurement's row, px.
const ROW: u32 = 300;

impl Figure for PlanFigure {
    fn size(&self) -> (u32, u32) {
        (1000, 70 + ROW * self.measurements.len().max(1) as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let usable = |m: &PlannedMeasurement| {
            m.lines
                .iter()
                .any(|l| l.f_hz.is_finite() && l.measured.is_finite() && l.measured > 0.0)
        };
        if self.measurements.is_empty() || !self.measurements.iter().any(usable) {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        }
        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(28);
        let mut entries = vec![
            (LegendMark::Line, style::BLACK, "linear response".into()),
            (LegendMark::Dashed, style::BLUE, "drive tone".into()),
            (LegendMark::Dot, style::BLUE, "line at a tone".into()),
            (LegendMark::Dot, style::ORANGE, "sideband".into()),
        ];
        if self
            .measurements
            .iter()
            .flat_map(|m| &m.lines)
            .any(|l| l.kind == LineKind::Mixing)
        {
            entries.push((LegendMark::Dot, style::GREEN, "mixing product".into()));
        }
        if self.noise.is_some() {
            entries.push((
                LegendMark::Dashed,
                style::GREY,
                "noise σ of one shot".into(),
            ));
        }
        style::legend(&legend_area, &entries)?;
        let rows = body.split_evenly((self.measurements.len(), 1));
        for (m, row) in self.measurements.iter().zip(rows.iter()) {
            self.draw_row(m, row)?;
        }
        Ok(())
    }
}

impl PlanFigure {
    fn draw_row<DB: DrawingBackend>(
        &self,
        m: &PlannedMeasurement,
        row: &DrawingArea<DB, Shift>,
    ) -> Result<(), PlotError> {
        let mut lines: Vec<&SpectrumLine> = m
            .lines
            .iter()
            .filter(|l| l.f_hz.is_finite() && l.measured.is_finite() && l.measured > 0.0)
            .collect();
        if lines.is_empty() {
            return Ok(());
        }
        lines.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
        let groups = clusters(&lines);
        let row = row.titled(&m.name, style::text(style::LABEL)).drawn()?;
        let panels = row.split_evenly((1, groups.len()));
        for (g, &(a, b)) in groups.iter().enumerate() {
            let grp = &lines[a..b];
            let (lo, hi) = (grp[0].f_hz, grp[grp.len() - 1].f_hz);
            // The panel spans its lines and the resonances among them, with room on each side.
            let near: Vec<&ModeResponse> = self
                .modes
                .iter()
                .filter(|r| (r.f_hz - 0.5 * (lo + hi)).abs() < 0.01 * r.f_hz)
                .collect();
            let (f_lo, f_hi) = near
                .iter()
                .fold((lo, hi), |(a, b), r| (a.min(r.f_hz), b.max(r.f_hz)));
            let pad = (0.15 * (f_hi - f_lo)).max(5.0);
            let (f_lo, f_hi) = (f_lo - pad, f_hi + pad);
            let centre = (0.5 * (lo + hi) * 2.0).round() / 2.0;
            let curves: Vec<(String, Vec<(f64, f64)>)> = near
                .iter()
                .filter(|r| r.force > 0.0 && r.q > 0.0)
                .map(|r| {
                    let pts = (0..=400)
                        .map(|i| {
                            let f = f_lo + (f_hi - f_lo) * i as f64 / 400.0;
                            (f - centre, r.at(f))
                        })
                        .collect();
                    (r.mode.clone(), pts)
                })
                .collect();
            let (y_lo, y_hi) = style::log_range(
                grp.iter()
                    .map(|l| l.measured)
                    .chain(curves.iter().flat_map(|(_, c)| c.iter().map(|p| p.1)))
                    .chain(self.noise),
            )
            .unwrap_or((1e-12, 1e-9));
            let y_hi = y_hi * 100.0; // room for the rotated labels
            let mut chart = ChartBuilder::on(&panels[g])
                .margin(8)
                .margin_right(16)
                .x_label_area_size(40)
                .y_label_area_size(if g == 0 { 70 } else { 50 })
                .build_cartesian_2d((f_lo - centre)..(f_hi - centre), (y_lo..y_hi).log_scale())
                .drawn()?;
            chart
                .configure_mesh()
                .x_desc(format!("f − {} Hz (Hz)", style::hz(centre)))
                .y_desc(if g == 0 {
                    format!("|X| ({})", self.unit)
                } else {
                    String::new()
                })
                .axis_desc_style(style::text(style::LABEL - 2.0))
                .label_style(style::text(style::TICK))
                .light_line_style(WHITE)
                .bold_line_style(style::GREY.mix(0.25))
                .y_label_formatter(&|v| style::tick(*v))
                .x_label_formatter(&|v| style::tick(*v))
                .draw()
                .drawn()?;
            for (name, pts) in curves {
                let (x_peak, y_peak) = pts
                    .iter()
                    .copied()
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .unwrap_or((0.0, y_lo));
                chart
                    .draw_series(LineSeries::new(pts, style::BLACK.stroke_width(1)))
                    .drawn()?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        name,
                        (x_peak, y_peak * 1.5),
                        style::text(style::NOTE),
                    )))
                    .drawn()?;
            }
            if let Some(s) = self.noise.filter(|s| *s > 0.0) {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(f_lo - centre, s), (f_hi - centre, s)],
                        6,
                        4,
                        style::GREY.stroke_width(2),
                    ))
                    .drawn()?;
            }
            for &t in m.tones_hz.iter().filter(|t| (f_lo..=f_hi).contains(*t)) {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(t - centre, y_lo), (t - centre, y_hi)],
                        5,
                        4,
                        style::BLUE.mix(0.6).stroke_width(1),
                    ))
                    .drawn()?;
            }
            for l in grp {
                let x = l.f_hz - centre;
                chart
                    .draw_series(std::iter::once(Circle::new(
                        (x, l.measured.max(y_lo)),
                        4,
                        l.kind.color().filled(),
                    )))
                    .drawn()?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        l.label.clone(),
                        (x, l.measured.max(y_lo) * 3.0),
                        style::text_in(style::NOTE, &style::BLACK)
                            .transform(FontTransform::Rotate270),
                    )))
                    .drawn()?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_response_closed_form() {
        // At resonance |X| = F Q / ω²; far below, F / ω².
        let r = ModeResponse {
            mode: "q1".into(),
            f_hz: 1000.0,
            q: 500.0,
            force: 2.0,
        };
        let w2 = (std::f64::consts::TAU * 1000.0).powi(2);
        assert!((r.at(1000.0) - 2.0 * 500.0 / w2).abs() < 1e-12 * r.at(1000.0));
        assert!((r.at(1e-3) - 2.0 / w2).abs() < 1e-9 * r.at(1e-3));
    }
}

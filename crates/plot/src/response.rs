//! A frequency-response curve through folds (Fig. 3g style).

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One branch (a continuation curve, in arclength order).
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    /// Legend text, e.g. `q1 at f`.
    pub label: String,
    /// Drive frequency of each point, Hz.
    pub f_hz: Vec<f64>,
    /// Amplitude of each point (the figure's unit).
    pub amp: Vec<f64>,
    /// Stability of each point.
    pub stable: Vec<bool>,
}

/// A jump of a sweep at a fold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jump {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// Amplitude before the jump.
    pub from: f64,
    /// Amplitude after the jump.
    pub to: f64,
    /// `true` for a jump of the up-sweep (increasing frequency).
    pub up: bool,
}

/// A response curve: stable parts solid, unstable parts dashed, jumps as arrows, the backbone
/// and optional measured points.
#[derive(Debug, Clone, PartialEq)]
pub struct ResponseCurve {
    /// Title.
    pub title: String,
    /// Y-axis label with its unit, e.g. `|q1| at f (m)`.
    pub y_label: String,
    /// The branches.
    pub branches: Vec<Branch>,
    /// Jumps.
    pub jumps: Vec<Jump>,
    /// The backbone `(f_hz, amplitude)`, if computed.
    pub backbone: Vec<(f64, f64)>,
    /// Measured points `(f_hz, amplitude)`, if any.
    pub measured: Vec<(f64, f64)>,
}

impl ResponseCurve {
    /// The legend: the stability line styles (in the branch's colour, or black with one entry
    /// per branch colour), jumps, backbone and measured points when drawn.
    fn legend_entries(&self) -> Vec<(LegendMark, RGBColor, String)> {
        // One branch: its colour in the stable/unstable entries; several: black entries for the
        // line styles and one entry per branch colour.
        let ink = if self.branches.len() > 1 {
            style::BLACK
        } else {
            style::BLUE
        };
        let mut entries = vec![
            (LegendMark::Line, ink, "stable".to_string()),
            (LegendMark::Dashed, ink, "unstable".to_string()),
        ];
        if self.branches.len() > 1 {
            for (k, b) in self.branches.iter().enumerate() {
                entries.push((
                    LegendMark::Line,
                    style::PALETTE[k % style::PALETTE.len()],
                    b.label.clone(),
                ));
            }
        }
        if !self.jumps.is_empty() {
            entries.push((
                LegendMark::Triangle,
                style::VERMILLION,
                "jump up-sweep".into(),
            ));
            entries.push((LegendMark::Triangle, style::GREEN, "jump down-sweep".into()));
        }
        if !self.backbone.is_empty() {
            entries.push((LegendMark::Dashed, style::BLACK, "backbone".into()));
        }
        if !self.measured.is_empty() {
            entries.push((LegendMark::Dot, style::BLACK, "measured".into()));
        }
        entries
    }
}

impl Figure for ResponseCurve {
    fn size(&self) -> (u32, u32) {
        (900, 540)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let fs = self
            .branches
            .iter()
            .flat_map(|b| b.f_hz.iter().copied())
            .chain(self.measured.iter().map(|p| p.0));
        let Some((f_lo, f_hi)) = style::range(fs) else {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        };
        let off = style::axis_offset(f_lo, f_hi);
        let a_hi = self
            .branches
            .iter()
            .flat_map(|b| b.amp.iter().copied())
            .chain(self.measured.iter().map(|p| p.1))
            .filter(|a| a.is_finite())
            .fold(0.0f64, f64::max)
            * 1.1;
        let a_hi = if a_hi > 0.0 { a_hi } else { 1.0 };
        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(26);
        let entries = self.legend_entries();
        style::legend(&legend_area, &entries)?;
        let mut chart = ChartBuilder::on(&body)
            .margin(10)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d((f_lo - off)..(f_hi - off), 0.0..a_hi)
            .drawn()?;
        chart
            .configure_mesh()
            .x_desc(if off == 0.0 {
                "f (Hz)".to_string()
            } else {
                format!("f − {} Hz (Hz)", style::hz(off))
            })
            .y_desc(self.y_label.clone())
            .axis_desc_style(style::text(style::LABEL))
            .label_style(style::text(style::TICK))
            .light_line_style(WHITE)
            .bold_line_style(style::GREY.mix(0.25))
            .x_label_formatter(&|v| style::tick(*v))
            .y_label_formatter(&|v| style::tick(*v))
            .draw()
            .drawn()?;
        for (k, b) in self.branches.iter().enumerate() {
            let color = style::PALETTE[k % style::PALETTE.len()];
            let n = b.f_hz.len().min(b.amp.len()).min(b.stable.len());
            // Runs of equal stability; each run shares its end point with the next.
            let mut i = 0;
            while i + 1 < n {
                let s = b.stable[i + 1];
                let mut j = i + 1;
                while j + 1 < n && b.stable[j + 1] == s {
                    j += 1;
                }
                let pts: Vec<(f64, f64)> = (i..=j).map(|t| (b.f_hz[t] - off, b.amp[t])).collect();
                if s {
                    chart
                        .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                        .drawn()?;
                } else {
                    chart
                        .draw_series(DashedLineSeries::new(pts, 6, 5, color.stroke_width(2)))
                        .drawn()?;
                }
                i = j;
            }
        }
        // The backbone runs between the stable and the unstable branch, a pixel or two from
        // each at large amplitude: drawn over them, thin, or it seems to stop halfway.
        if !self.backbone.is_empty() {
            let pts: Vec<(f64, f64)> = self
                .backbone
                .iter()
                .filter(|(f, a)| {
                    f.is_finite() && a.is_finite() && *f >= f_lo && *f <= f_hi && *a <= a_hi
                })
                .map(|&(f, a)| (f - off, a))
                .collect();
            chart
                .draw_series(DashedLineSeries::new(
                    pts,
                    5,
                    4,
                    style::BLACK.stroke_width(2),
                ))
                .drawn()?;
        }
        for j in &self.jumps {
            let c = if j.up {
                style::VERMILLION
            } else {
                style::GREEN
            };
            let x = j.f_hz - off;
            chart
                .draw_series(DashedLineSeries::new(
                    [(x, j.from), (x, j.to)],
                    3,
                    3,
                    c.stroke_width(2),
                ))
                .drawn()?;
            // The arrow head points the way the amplitude jumps (pixel offsets, y down).
            let dy = if j.to < j.from { -10 } else { 10 };
            let head = EmptyElement::at((x, j.to))
                + Polygon::new(vec![(-6, dy), (6, dy), (0, 0)], c.filled());
            chart.draw_series(std::iter::once(head)).drawn()?;
        }
        if !self.measured.is_empty() {
            chart
                .draw_series(
                    self.measured
                        .iter()
                        .map(|&(f, a)| Circle::new((f - off, a), 3, style::BLACK.filled())),
                )
                .drawn()?;
        }
        Ok(())
    }
}

//! Estimates against the noise level, mean ± 3σ (Fig. S3 style).

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One parameter of a noise study.
#[derive(Debug, Clone, PartialEq)]
pub struct NoisePanel {
    /// The parameter's name.
    pub name: String,
    /// Its unit (empty if none).
    pub unit: String,
    /// The true value, when known.
    pub truth: Option<f64>,
    /// The noise levels (the x axis, log scale), ascending.
    pub levels: Vec<f64>,
    /// `estimates[i]`: the estimates (one per repetition) at `levels[i]`.
    pub estimates: Vec<Vec<f64>>,
}

/// A grid of panels, one per parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseStudy {
    /// Title.
    pub title: String,
    /// X-axis label with its unit, e.g. `noise σ per quadrature (m)`.
    pub level_label: String,
    /// One panel per parameter.
    pub panels: Vec<NoisePanel>,
}

fn mean_std(v: &[f64]) -> Option<(f64, f64)> {
    let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if f.is_empty() {
        return None;
    }
    let n = f.len() as f64;
    let m = f.iter().sum::<f64>() / n;
    let s = if f.len() > 1 {
        (f.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    Some((m, s))
}

impl NoiseStudy {
    fn grid(&self) -> (usize, usize) {
        let n = self.panels.len().max(1);
        let cols = n.min(3);
        (n.div_ceil(cols), cols)
    }
}

impl Figure for NoiseStudy {
    fn size(&self) -> (u32, u32) {
        let (rows, cols) = self.grid();
        (420 * cols as u32, 60 + 320 * rows as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        if self.panels.is_empty() {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        }
        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(26);
        style::legend(
            &legend_area,
            &[
                (LegendMark::Dot, style::GREY, "estimates".to_string()),
                (LegendMark::Line, style::BLUE, "mean".to_string()),
                (LegendMark::Band, style::BLUE, "mean ± 3σ".to_string()),
                (LegendMark::Dashed, style::VERMILLION, "truth".to_string()),
            ],
        )?;
        let (rows, cols) = self.grid();
        let areas = body.split_evenly((rows, cols));
        for (p, area) in self.panels.iter().zip(areas.iter()) {
            let stats: Vec<Option<(f64, f64)>> = p.estimates.iter().map(|e| mean_std(e)).collect();
            // Half a decade beyond the outer levels, so that their points sit inside the frame.
            let Some((x_lo, x_hi)) = style::log_range(p.levels.iter().copied()) else {
                continue;
            };
            let (x_lo, x_hi) = {
                let pos = || p.levels.iter().copied().filter(|l| *l > 0.0);
                let lo = pos().fold(f64::INFINITY, f64::min);
                let hi = pos().fold(0.0, f64::max);
                (
                    (lo / 10f64.sqrt()).max(x_lo / 10.0),
                    (hi * 10f64.sqrt()).min(x_hi * 10.0),
                )
            };
            // The y axis holds the truth and the mean ± 3σ of every level, but no more than
            // ±20 × the spread at the lowest noise around the truth: at high noise the estimates
            // run away and would flatten the rest; they are clipped at the frame.
            let mut ys: Vec<f64> = stats
                .iter()
                .flatten()
                .flat_map(|(m, s)| [m - 3.0 * s, m + 3.0 * s])
                .collect();
            ys.extend(p.truth);
            let (mut y_lo, mut y_hi) = style::range(ys).unwrap_or((-1.0, 1.0));
            if let Some(t) = p.truth {
                let scale = 10.0 * t.abs().max(1e-300);
                y_lo = y_lo.max(t - scale);
                y_hi = y_hi.min(t + scale);
            }
            let off = style::axis_offset(y_lo, y_hi);
            let unit = if p.unit.is_empty() {
                String::new()
            } else {
                format!(" ({})", p.unit)
            };
            let y_label = if off != 0.0 {
                format!(
                    "{} − {}{unit}",
                    p.name,
                    if off.abs() < 1e7 {
                        style::hz(off)
                    } else {
                        style::tick(off)
                    }
                )
            } else {
                format!("{}{unit}", p.name)
            };
            // A tick within rounding of zero reads 0 (not 3.4e7 on an axis spanning ±2e23).
            let y_span = (y_hi - y_lo).abs();
            let y_tick = move |v: &f64| style::tick(if v.abs() < 1e-9 * y_span { 0.0 } else { *v });
            let mut chart = ChartBuilder::on(area)
                .margin(10)
                .margin_right(24)
                .x_label_area_size(44)
                .y_label_area_size(72)
                .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo - off)..(y_hi - off))
                .drawn()?;
            chart
                .configure_mesh()
                .x_desc(self.level_label.clone())
                .y_desc(y_label)
                .axis_desc_style(style::text(style::LABEL - 2.0))
                .label_style(style::text(style::TICK))
                .light_line_style(WHITE)
                .bold_line_style(style::GREY.mix(0.25))
                .x_label_formatter(&|v| style::tick(*v))
                .y_label_formatter(&y_tick)
                .y_labels(6)
                .draw()
                .drawn()?;
            let clip = |y: f64| (y - off).clamp(y_lo - off, y_hi - off);
            let band: Vec<(f64, f64, f64)> = p
                .levels
                .iter()
                .zip(&stats)
                .filter_map(|(&l, s)| s.map(|(m, s)| (l, m, s)))
                .collect();
            if band.len() >= 2 {
                let mut poly: Vec<(f64, f64)> = band
                    .iter()
                    .map(|&(l, m, s)| (l, clip(m + 3.0 * s)))
                    .collect();
                poly.extend(band.iter().rev().map(|&(l, m, s)| (l, clip(m - 3.0 * s))));
                chart
                    .draw_series(std::iter::once(Polygon::new(
                        poly,
                        style::BLUE.mix(0.2).filled(),
                    )))
                    .drawn()?;
            }
            chart
                .draw_series(p.levels.iter().zip(&p.estimates).flat_map(|(&l, es)| {
                    es.iter()
                        .filter(|e| e.is_finite() && **e >= y_lo && **e <= y_hi)
                        .map(move |&e| Circle::new((l, e - off), 2, style::GREY.filled()))
                }))
                .drawn()?;
            chart
                .draw_series(LineSeries::new(
                    band.iter().map(|&(l, m, _)| (l, clip(m))),
                    style::BLUE.stroke_width(2),
                ))
                .drawn()?;
            if let Some(t) = p.truth {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(x_lo, t - off), (x_hi, t - off)],
                        8,
                        5,
                        style::VERMILLION.stroke_width(2),
                    ))
                    .drawn()?;
            }
        }
        Ok(())
    }
}

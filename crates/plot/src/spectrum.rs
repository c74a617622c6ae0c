//! A measured multi-tone spectrum with its reconstruction and residuals (Fig. 1b–c style).

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// What a spectral line is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    /// A drive tone.
    Drive,
    /// A sideband: a combination of the tones near the same resonance.
    Sideband,
    /// A mixing product: a combination involving tones near another resonance.
    Mixing,
}

impl LineKind {
    pub(crate) fn color(self) -> RGBColor {
        match self {
            LineKind::Drive => style::BLUE,
            LineKind::Sideband => style::ORANGE,
            LineKind::Mixing => style::GREEN,
        }
    }

    /// A short name for legends and tables.
    pub fn name(self) -> &'static str {
        match self {
            LineKind::Drive => "drive tone",
            LineKind::Sideband => "sideband",
            LineKind::Mixing => "mixing product",
        }
    }
}

/// One measured line.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumLine {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// Measured |X| (peak, in the spectrum's unit).
    pub measured: f64,
    /// |X| reconstructed from the identified model, when available.
    pub reconstructed: Option<f64>,
    /// |X_measured − X_reconstructed| (complex difference), when available.
    pub residual: Option<f64>,
    /// Drive tone, sideband or mixing product.
    pub kind: LineKind,
    /// The combination, e.g. `2f1−f2`.
    pub label: String,
}

/// A spectrum: the lines are grouped into panels of nearby frequencies (one per resonance), each
/// with its frequency axis relative to the panel's centre; the residuals are drawn below.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    /// Title (e.g. the measurement's name and point).
    pub title: String,
    /// Unit of |X|, e.g. `m`.
    pub unit: String,
    /// The lines, any order.
    pub lines: Vec<SpectrumLine>,
    /// The noise level of the plotted amplitudes (same unit), drawn as a dashed line in both
    /// panels, when known.
    pub noise_floor: Option<f64>,
    /// The residuals are standardized, `|X − X_rec|/σ` of each line in its own noise (a fit's
    /// verdict), instead of in the amplitudes' unit: the residual panel's axis is in noise
    /// sigmas and its dashed line at `√2`, a correct model's typical value.
    pub residual_in_sigmas: bool,
}

/// The typical standardized residual `|X − X_rec|/σ` of a correct model (a complex residual
/// with noise `σ` per quadrature: `E|r|² = 2σ²`).
pub const TYPICAL_SIGMAS: f64 = std::f64::consts::SQRT_2;

/// Groups sorted frequencies into clusters separated by more than 1 % of the frequency.
pub(crate) fn clusters(lines: &[&SpectrumLine]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=lines.len() {
        if i == lines.len() || lines[i].f_hz - lines[i - 1].f_hz > 0.01 * lines[i].f_hz {
            out.push((start, i));
            start = i;
        }
    }
    out
}

impl Spectrum {
    /// The legend: drive tones and sidebands always, mixing products, the reconstruction and
    /// the noise floor when drawn.
    fn legend_entries(&self, lines: &[&SpectrumLine]) -> Vec<(LegendMark, RGBColor, String)> {
        let mut entries = vec![
            (LegendMark::Dot, style::BLUE, "drive tone".to_string()),
            (LegendMark::Dot, style::ORANGE, "sideband".to_string()),
        ];
        if lines.iter().any(|l| l.kind == LineKind::Mixing) {
            entries.push((LegendMark::Dot, style::GREEN, "mixing product".into()));
        }
        if lines.iter().any(|l| l.reconstructed.is_some()) {
            entries.push((
                LegendMark::Open,
                style::BLACK,
                "harmonic balance, identified model".into(),
            ));
        }
        if self.noise_floor.is_some() {
            entries.push((LegendMark::Dashed, style::GREY, "noise floor".into()));
        }
        entries
    }

    /// The residual panel under one cluster of lines `grp` (around `centre`, Hz): each line's
    /// |residual| as a cross, and the noise floor; `first`: the leftmost panel, which carries
    /// the axis title.
    fn draw_residuals<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        grp: &[&SpectrumLine],
        centre: f64,
        (x_lo, x_hi): (f64, f64),
        (r_lo, r_hi): (f64, f64),
        first: bool,
    ) -> Result<(), PlotError> {
        let mut rc = ChartBuilder::on(area)
            .margin(8)
            .margin_top(4)
            .x_label_area_size(44)
            .y_label_area_size(if first { 70 } else { 50 })
            .build_cartesian_2d(x_lo..x_hi, (r_lo..r_hi).log_scale())
            .drawn()?;
        rc.configure_mesh()
            .x_desc(format!("f − {} Hz (Hz)", style::hz(centre)))
            .y_desc(match (first, self.residual_in_sigmas) {
                (false, _) => "",
                (true, false) => "|residual|",
                (true, true) => "|residual| / noise σ",
            })
            .axis_desc_style(style::text(style::LABEL))
            .label_style(style::text(style::TICK))
            .light_line_style(WHITE)
            .bold_line_style(style::GREY.mix(0.25))
            .y_labels(4)
            .y_label_formatter(&|v| style::tick(*v))
            .x_label_formatter(&|v| style::tick(*v))
            .draw()
            .drawn()?;
        let reference = if self.residual_in_sigmas {
            Some(TYPICAL_SIGMAS)
        } else {
            self.noise_floor
        };
        if let Some(nf) = reference.filter(|f| *f > 0.0) {
            rc.draw_series(DashedLineSeries::new(
                [(x_lo, nf), (x_hi, nf)],
                6,
                4,
                style::GREY.stroke_width(2),
            ))
            .drawn()?;
        }
        rc.draw_series(grp.iter().filter_map(|l| {
            l.residual
                .filter(|r| *r > 0.0)
                .map(|r| Cross::new((l.f_hz - centre, r), 5, l.kind.color().stroke_width(2)))
        }))
        .drawn()?;
        Ok(())
    }
}

impl Figure for Spectrum {
    fn size(&self) -> (u32, u32) {
        (960, 620)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let mut lines: Vec<&SpectrumLine> = self
            .lines
            .iter()
            .filter(|l| l.f_hz.is_finite() && l.measured.is_finite())
            .collect();
        if lines.is_empty() {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        }
        lines.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
        let groups = clusters(&lines);
        let (y_lo, y_hi) = style::log_range(
            lines
                .iter()
                .flat_map(|l| [Some(l.measured), l.reconstructed])
                .flatten(),
        )
        .unwrap_or((1e-12, 1e-9));
        let y_lo = self
            .noise_floor
            .filter(|f| *f > 0.0)
            .map_or(y_lo, |f| y_lo.min(10f64.powf((f / 3.0).log10().floor())));
        // Room above the highest line for the rotated combination labels.
        let y_hi = y_hi * 100.0;
        let reference = if self.residual_in_sigmas {
            Some(TYPICAL_SIGMAS)
        } else {
            self.noise_floor
        };
        let residual_range = style::log_range(
            lines
                .iter()
                .filter_map(|l| l.residual)
                .chain(reference.filter(|_| lines.iter().any(|l| l.residual.is_some()))),
        );

        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(28);
        let entries = self.legend_entries(&lines);
        style::legend(&legend_area, &entries)?;
        let (top, bottom) = match residual_range {
            Some(_) => {
                let h = body.dim_in_pixel().1;
                body.split_vertically((h as f64 * 0.68) as u32)
            }
            None => (body.clone(), body.clone()),
        };
        let tops = top.split_evenly((1, groups.len()));
        let bottoms = bottom.split_evenly((1, groups.len()));
        for (g, &(a, b)) in groups.iter().enumerate() {
            let grp = &lines[a..b];
            let drives: Vec<f64> = grp
                .iter()
                .filter(|l| l.kind == LineKind::Drive)
                .map(|l| l.f_hz)
                .collect();
            let centre_raw = if drives.is_empty() {
                0.5 * (grp[0].f_hz + grp[grp.len() - 1].f_hz)
            } else {
                drives.iter().sum::<f64>() / drives.len() as f64
            };
            // Drive tones sit on a fine grid (e.g. x.5 Hz): keep the centre on it.
            let centre = (centre_raw * 1000.0).round() / 1000.0;
            let (x_lo, x_hi) = style::range(grp.iter().map(|l| l.f_hz - centre))
                .map(|(lo, hi)| (lo.min(-1.0) - 5.0, hi.max(1.0) + 5.0))
                .unwrap_or((-10.0, 10.0));
            let x_label = format!("f − {} Hz (Hz)", style::hz(centre));
            let y_label = if g == 0 {
                format!("|X| ({})", self.unit)
            } else {
                String::new()
            };
            let mut chart = ChartBuilder::on(&tops[g])
                .margin(8)
                .margin_top(40)
                .x_label_area_size(if residual_range.is_some() { 8 } else { 44 })
                .y_label_area_size(if g == 0 { 70 } else { 50 })
                .build_cartesian_2d(x_lo..x_hi, (y_lo..y_hi).log_scale())
                .drawn()?;
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(y_label)
                .axis_desc_style(style::text(style::LABEL))
                .label_style(style::text(style::TICK))
                .light_line_style(WHITE)
                .bold_line_style(style::GREY.mix(0.25))
                .y_label_formatter(&|v| style::tick(*v))
                .x_label_formatter(&|v| style::tick(*v));
            if residual_range.is_some() {
                mesh.x_labels(0);
            } else {
                mesh.x_desc(x_label.clone());
            }
            mesh.draw().drawn()?;
            if let Some(nf) = self.noise_floor.filter(|f| *f > 0.0) {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(x_lo, nf), (x_hi, nf)],
                        6,
                        4,
                        style::GREY.stroke_width(2),
                    ))
                    .drawn()?;
            }
            for l in grp {
                let x = l.f_hz - centre;
                let c = l.kind.color();
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x, y_lo), (x, l.measured.max(y_lo))],
                        c.stroke_width(2),
                    )))
                    .drawn()?;
                chart
                    .draw_series(std::iter::once(Circle::new(
                        (x, l.measured.max(y_lo)),
                        4,
                        c.filled(),
                    )))
                    .drawn()?;
                if let Some(r) = l.reconstructed.filter(|r| *r > 0.0) {
                    chart
                        .draw_series(std::iter::once(Circle::new(
                            (x, r.max(y_lo)),
                            7,
                            style::BLACK.stroke_width(1),
                        )))
                        .drawn()?;
                }
                let top = l.measured.max(l.reconstructed.unwrap_or(0.0)).max(y_lo);
                chart
                    .draw_series(std::iter::once(Text::new(
                        l.label.clone(),
                        (x, top * 3.0),
                        style::text_in(style::NOTE, &style::BLACK)
                            .transform(FontTransform::Rotate270),
                    )))
                    .drawn()?;
            }
            if let Some(r_range) = residual_range {
                self.draw_residuals(&bottoms[g], grp, centre, (x_lo, x_hi), r_range, g == 0)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_cluster_by_resonance() {
        let mk = |f| SpectrumLine {
            f_hz: f,
            measured: 1.0,
            reconstructed: None,
            residual: None,
            kind: LineKind::Drive,
            label: String::new(),
        };
        let ls = [mk(207_560.0), mk(207_580.0), mk(415_840.0), mk(415_860.0)];
        let refs: Vec<&SpectrumLine> = ls.iter().collect();
        assert_eq!(clusters(&refs), vec![(0, 2), (2, 4)]);
    }
}

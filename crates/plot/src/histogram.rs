//! A histogram of per-shot estimates with the normal fit (Fig. 3c–f style).

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Per-shot estimates of one quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    /// The quantity's name, e.g. `gamma12` or `f_hz(q1)`.
    pub name: String,
    /// Its unit (empty for a dimensionless one).
    pub unit: String,
    /// One estimate per shot (non-finite ones are counted as outliers).
    pub values: Vec<f64>,
    /// Indices into `values` rejected as outliers.
    pub outliers: Vec<usize>,
    /// The reported value (median).
    pub value: f64,
    /// Its standard error.
    pub stderr: f64,
    /// The spread of one shot (std after outlier rejection).
    pub std: f64,
    /// The true value, when known.
    pub truth: Option<f64>,
}

/// Mean and sample standard deviation.
fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    (m, s)
}

/// The histogram's bins over the inliers (`√n` of them, 5 to 30, offset by `off`), and the
/// height of the normal fit's peak (`sd`: the inliers' spread) and of the axis.
struct Bins {
    blo: f64,
    bw: f64,
    counts: Vec<u32>,
    pdf_peak: f64,
    y_hi: f64,
}

impl Bins {
    fn of(inl: &[f64], off: f64, (lo, hi): (f64, f64), sd: f64) -> Bins {
        let n = inl.len();
        let bins = ((n as f64).sqrt().ceil() as usize).clamp(5, 30);
        let blo = inl.iter().copied().fold(f64::INFINITY, f64::min) - off;
        let bhi = inl.iter().copied().fold(f64::NEG_INFINITY, f64::max) - off;
        let (blo, bhi) = if bhi > blo {
            (blo, bhi)
        } else {
            (blo - 0.01 * (hi - lo), blo + 0.01 * (hi - lo))
        };
        let bw = (bhi - blo) / bins as f64;
        let mut counts = vec![0u32; bins];
        for v in inl {
            let k = (((v - off - blo) / bw).floor() as usize).min(bins - 1);
            counts[k] += 1;
        }
        let pdf_peak = if sd > 0.0 {
            n as f64 * bw / (sd * (2.0 * std::f64::consts::PI).sqrt())
        } else {
            0.0
        };
        let y_hi = (*counts.iter().max().unwrap_or(&1) as f64).max(pdf_peak) * 1.25;
        Bins {
            blo,
            bw,
            counts,
            pdf_peak,
            y_hi,
        }
    }
}

impl Histogram {
    /// The unit as the title writes it (` (Hz)`, or nothing) and the x axis label (with the
    /// offset `off` subtracted from the values, when there is one).
    fn axis_text(&self, off: f64) -> (String, String) {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.unit)
        };
        let x_label = if off != 0.0 {
            format!("{} − {}{unit}", self.name, style::hz(off))
        } else {
            format!("{}{unit}", self.name)
        };
        (unit, x_label)
    }

    /// The legend: shots, the normal fit and value ± stderr always; truth and outliers when
    /// drawn.
    fn legend_entries(&self) -> Vec<(LegendMark, RGBColor, String)> {
        let mut entries = vec![
            (LegendMark::Band, style::SKY, "shots".to_string()),
            (LegendMark::Line, style::BLACK, "normal fit".to_string()),
            (LegendMark::Line, style::BLUE, "value ± stderr".to_string()),
        ];
        if self.truth.is_some() {
            entries.push((LegendMark::Dashed, style::VERMILLION, "truth".into()));
        }
        if !self.outliers.is_empty() {
            entries.push((LegendMark::Triangle, style::PURPLE, "outliers".into()));
        }
        entries
    }

    /// The title: the value ± stderr, the per-shot spread and how many shots were outliers
    /// (`n` inliers).
    fn title(&self, unit: &str, n: usize) -> String {
        format!(
            "{} = {}{}   (std {} · {} shots, {} outliers)",
            self.name,
            style::pm(self.value, self.stderr),
            unit,
            style::num(self.std, 2),
            self.values.len(),
            self.values.len() - n
        )
    }
}

impl Figure for Histogram {
    fn size(&self) -> (u32, u32) {
        (720, 480)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let inl: Vec<f64> = self
            .values
            .iter()
            .enumerate()
            .filter(|(i, v)| v.is_finite() && !self.outliers.contains(i))
            .map(|(_, v)| *v)
            .collect();
        let outl: Vec<f64> = self
            .outliers
            .iter()
            .filter_map(|&i| self.values.get(i).copied())
            .filter(|v| v.is_finite())
            .collect();
        if inl.is_empty() {
            return Err(PlotError::Empty {
                what: self.name.clone(),
            });
        }
        let (mean, sd) = mean_std(&inl);
        // The axis holds the inliers, the value ± stderr and the truth; outliers beyond it are
        // drawn at the edge with their count.
        let mut pts = inl.clone();
        pts.extend([self.value - self.stderr, self.value + self.stderr]);
        pts.extend(self.truth);
        let (lo0, hi0) = style::range(pts).unwrap_or((mean - 1.0, mean + 1.0));
        let off = style::axis_offset(lo0, hi0);
        let (unit, x_label) = self.axis_text(off);
        let (lo, hi) = (lo0 - off, hi0 - off);
        let Bins {
            blo,
            bw,
            counts,
            pdf_peak,
            y_hi,
        } = Bins::of(&inl, off, (lo, hi), sd);

        let title = self.title(&unit, inl.len());
        let root = root
            .titled(&title, style::text(style::TITLE - 3.0))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(26);
        let entries = self.legend_entries();
        style::legend(&legend_area, &entries)?;
        let mut chart = ChartBuilder::on(&body)
            .margin(10)
            .x_label_area_size(48)
            .y_label_area_size(56)
            .build_cartesian_2d(lo..hi, 0.0..y_hi)
            .drawn()?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc("shots per bin")
            .axis_desc_style(style::text(style::LABEL))
            .label_style(style::text(style::TICK))
            .light_line_style(WHITE)
            .bold_line_style(style::GREY.mix(0.25))
            .x_labels(6)
            .x_label_formatter(&|v| style::tick(*v))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .drawn()?;
        // ±stderr band and the value.
        let (v, e) = (self.value - off, self.stderr);
        if e.is_finite() && e > 0.0 {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(v - e, 0.0), (v + e, y_hi)],
                    style::BLUE.mix(0.15).filled(),
                )))
                .drawn()?;
        }
        chart
            .draw_series(counts.iter().enumerate().map(|(k, &c)| {
                let x0 = blo + k as f64 * bw;
                Rectangle::new([(x0, 0.0), (x0 + bw, c as f64)], style::SKY.filled())
            }))
            .drawn()?;
        chart
            .draw_series(counts.iter().enumerate().map(|(k, &c)| {
                let x0 = blo + k as f64 * bw;
                Rectangle::new(
                    [(x0, 0.0), (x0 + bw, c as f64)],
                    style::BLUE.stroke_width(1),
                )
            }))
            .drawn()?;
        if sd > 0.0 {
            let m = mean - off;
            let pts = (0..=200).map(|i| {
                let x = lo + (hi - lo) * i as f64 / 200.0;
                let z = (x - m) / sd;
                (x, pdf_peak * (-0.5 * z * z).exp())
            });
            chart
                .draw_series(LineSeries::new(pts, style::BLACK.stroke_width(2)))
                .drawn()?;
        }
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(v, 0.0), (v, y_hi)],
                style::BLUE.stroke_width(2),
            )))
            .drawn()?;
        if let Some(t) = self.truth {
            chart
                .draw_series(DashedLineSeries::new(
                    [(t - off, 0.0), (t - off, y_hi)],
                    8,
                    5,
                    style::VERMILLION.stroke_width(2),
                ))
                .drawn()?;
        }
        // Outliers: triangles on the axis, clamped to its edges with a count.
        let (mut left, mut right) = (0, 0);
        for o in &outl {
            let x = o - off;
            if x < lo {
                left += 1;
            } else if x > hi {
                right += 1;
            } else {
                chart
                    .draw_series(std::iter::once(TriangleMarker::new(
                        (x, y_hi * 0.03),
                        7,
                        style::PURPLE.filled(),
                    )))
                    .drawn()?;
            }
        }
        let w = hi - lo;
        for (count, x, txt) in [
            (left, lo + 0.02 * w, format!("← {left}")),
            (right, hi - 0.3 * w, format!("{right} →")),
        ] {
            if count > 0 {
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!("{txt} outlier(s)"),
                        (x, y_hi * 0.93),
                        style::text_in(style::NOTE + 1.0, &style::BLACK),
                    )))
                    .drawn()?;
            }
        }
        Ok(())
    }
}

//! A measured stepped-sine frequency response with the model's curve through its folds: the
//! amplitude and the phase against the drive frequency, and the Nyquist view (Re X against
//! Im X), one figure per sweep family or one for every family.

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// The order a sweep's steps were measured in: the marker of its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepMark {
    /// Rising frequency: a filled triangle pointing up.
    Up,
    /// Falling frequency: an open triangle pointing down.
    Down,
    /// Any other order: a filled circle.
    Unordered,
}

/// The measured points of one sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredSweep {
    /// The sweep's name.
    pub name: String,
    /// Its marker.
    pub mark: SweepMark,
    /// Drive frequency of each step, Hz.
    pub f_hz: Vec<f64>,
    /// The response at the drive frequency of each step, `(Re X, Im X)` in the figure's unit,
    /// phase against the drive's force.
    pub x: Vec<(f64, f64)>,
}

/// The model's response curve of one family, in arclength order.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelBranch {
    /// Drive frequency of each point, Hz.
    pub f_hz: Vec<f64>,
    /// `(Re X, Im X)` of each point, in the figure's unit.
    pub x: Vec<(f64, f64)>,
    /// Stability of each point (unstable parts are drawn dashed).
    pub stable: Vec<bool>,
}

/// The sweeps at one drive level and the model's curve at that level.
#[derive(Debug, Clone, PartialEq)]
pub struct ResponseFamily {
    /// Legend text, e.g. `0.1 V`.
    pub label: String,
    /// Its sweeps.
    pub sweeps: Vec<MeasuredSweep>,
    /// The model's curve, when there is one.
    pub model: Option<ModelBranch>,
}

/// A frequency-response figure: amplitude (top left) and phase (bottom left) against the
/// drive frequency, the Nyquist view (right). With one family the points are coloured by
/// direction and the model is black; with several, each family has its own colour (dark to
/// light with the order given, normally rising drive level).
#[derive(Debug, Clone, PartialEq)]
pub struct FrequencyResponse {
    /// Title.
    pub title: String,
    /// The unit of X (`m`, `nm`, `V`): every axis label says it.
    pub unit: String,
    /// The families.
    pub families: Vec<ResponseFamily>,
}

/// The colour of family `k` of `n`: a viridis shade (dark blue to green; the pale yellow end
/// is left out, too light on white).
fn family_color(k: usize, n: usize) -> RGBColor {
    use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
    let t = if n > 1 {
        0.85 * k as f64 / (n - 1) as f64
    } else {
        0.0
    };
    ViridisRGB.get_color(t)
}

/// The colour of a sweep's points with `mark` in family `k` of `n`.
fn point_color(mark: SweepMark, k: usize, n: usize) -> RGBColor {
    if n > 1 {
        return family_color(k, n);
    }
    match mark {
        SweepMark::Up => style::VERMILLION,
        SweepMark::Down => style::BLUE,
        SweepMark::Unordered => style::GREEN,
    }
}

/// Phase in degrees, `(-180, 180]`.
fn deg(x: (f64, f64)) -> f64 {
    x.1.atan2(x.0).to_degrees()
}

/// The phase of a model curve, unwrapped along the curve.
fn unwrapped(x: &[(f64, f64)]) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(x.len());
    for &z in x {
        let mut p = deg(z);
        if let Some(&last) = out.last() {
            p += 360.0 * ((last - p) / 360.0).round();
        }
        out.push(p);
    }
    out
}

/// `p` moved by whole turns to lie nearest `centre`.
fn near(p: f64, centre: f64) -> f64 {
    p + 360.0 * ((centre - p) / 360.0).round()
}

/// The phase axis' centre: the median of the models' unwrapped phases, or of the measured
/// ones, or −90° (a mode at resonance lags its force by a quarter period).
fn phase_centre(fams: &[ResponseFamily]) -> f64 {
    let mut v: Vec<f64> = fams
        .iter()
        .filter_map(|f| f.model.as_ref())
        .flat_map(|m| unwrapped(&m.x))
        .collect();
    if v.is_empty() {
        v = fams
            .iter()
            .flat_map(|f| &f.sweeps)
            .flat_map(|s| s.x.iter().map(|&z| near(deg(z), -90.0)))
            .collect();
    }
    v.retain(|p| p.is_finite());
    if v.is_empty() {
        return -90.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// `v` as 0 when it is rounding noise on an axis `span` wide (a tick at `-2.2e-16`).
fn snap(v: f64, span: f64) -> f64 {
    if v.abs() < 1e-9 * span.abs() {
        0.0
    } else {
        v
    }
}

/// One panel's data: x and y of every point of every family, measured and model.
struct Panel<'a> {
    x_of: &'a dyn Fn(f64, (f64, f64)) -> f64,
    y_of: &'a dyn Fn(f64, (f64, f64)) -> f64,
}

impl FrequencyResponse {
    /// The legend: the direction markers, the model's line styles and, with several families,
    /// one colour per family.
    fn legend_entries(&self) -> Vec<(LegendMark, RGBColor, String)> {
        let n = self.families.len();
        let mut marks: Vec<SweepMark> = self
            .families
            .iter()
            .flat_map(|f| f.sweeps.iter().map(|s| s.mark))
            .collect();
        marks.sort_by_key(|m| *m as u8);
        marks.dedup();
        let mut out = Vec::new();
        let ink = |m| {
            if n > 1 {
                style::BLACK
            } else {
                point_color(m, 0, 1)
            }
        };
        for m in marks {
            out.push(match m {
                SweepMark::Up => (LegendMark::Triangle, ink(m), "up-sweep".to_string()),
                SweepMark::Down => (LegendMark::OpenDown, ink(m), "down-sweep".to_string()),
                SweepMark::Unordered => (LegendMark::Dot, ink(m), "measured".to_string()),
            });
        }
        if self.families.iter().any(|f| f.model.is_some()) {
            out.push((LegendMark::Line, style::BLACK, "model, stable".into()));
            out.push((LegendMark::Dashed, style::BLACK, "model, unstable".into()));
        }
        if n > 1 {
            for (k, f) in self.families.iter().enumerate() {
                out.push((LegendMark::Line, family_color(k, n), f.label.clone()));
            }
        }
        out
    }

    /// Draws one panel: every family's model curve (solid where stable, dashed where not) and
    /// measured points, mapped by `p` (which also sees the drive frequency).
    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        p: &Panel<'_>,
        labels: (&str, &str),
        x_off: f64,
        equal: bool,
    ) -> Result<(), PlotError> {
        let n = self.families.len();
        let pts = self.families.iter().flat_map(|f| {
            let m = f.model.iter().flat_map(|m| m.f_hz.iter().zip(&m.x));
            let s = f.sweeps.iter().flat_map(|s| s.f_hz.iter().zip(&s.x));
            m.chain(s)
        });
        let xy: Vec<(f64, f64)> = pts
            .map(|(&f, &z)| ((p.x_of)(f, z), (p.y_of)(f, z)))
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        let (Some((mut x0, mut x1)), Some((mut y0, mut y1))) = (
            style::range(xy.iter().map(|q| q.0)),
            style::range(xy.iter().map(|q| q.1)),
        ) else {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        };
        if equal {
            // The same scale on both axes of a square panel: a circle stays a circle.
            let h = 0.5 * (x1 - x0).max(y1 - y0);
            let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            (x0, x1, y0, y1) = (cx - h, cx + h, cy - h, cy + h);
        }
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d((x0 - x_off)..(x1 - x_off), y0..y1)
            .drawn()?;
        chart
            .configure_mesh()
            .x_desc(labels.0)
            .y_desc(labels.1)
            .axis_desc_style(style::text(style::LABEL))
            .label_style(style::text(style::TICK))
            .light_line_style(WHITE)
            .bold_line_style(style::GREY.mix(0.25))
            .x_labels(6)
            .x_label_formatter(&|v| style::tick(snap(*v, x1 - x0)))
            .y_label_formatter(&|v| style::tick(snap(*v, y1 - y0)))
            .draw()
            .drawn()?;
        let at = |f: f64, z: (f64, f64)| ((p.x_of)(f, z) - x_off, (p.y_of)(f, z));
        for (k, fam) in self.families.iter().enumerate() {
            let color = if n > 1 {
                family_color(k, n)
            } else {
                style::BLACK
            };
            if let Some(m) = &fam.model {
                let len = m.f_hz.len().min(m.x.len()).min(m.stable.len());
                let mut i = 0;
                while i + 1 < len {
                    let s = m.stable[i + 1];
                    let mut j = i + 1;
                    while j + 1 < len && m.stable[j + 1] == s {
                        j += 1;
                    }
                    let line: Vec<(f64, f64)> = (i..=j).map(|t| at(m.f_hz[t], m.x[t])).collect();
                    let stroke = color.stroke_width(2);
                    if s {
                        chart.draw_series(LineSeries::new(line, stroke)).drawn()?;
                    } else {
                        chart
                            .draw_series(DashedLineSeries::new(line, 6, 5, stroke))
                            .drawn()?;
                    }
                    i = j;
                }
            }
            // Down-sweeps (open) first, up-sweeps (filled) over them: where the two agree both
            // stay visible.
            let mut order: Vec<&MeasuredSweep> = fam.sweeps.iter().collect();
            order.sort_by_key(|s| s.mark == SweepMark::Up);
            for s in order {
                let c = point_color(s.mark, k, n);
                let pts = s.f_hz.iter().zip(&s.x).map(|(&f, &z)| at(f, z));
                match s.mark {
                    SweepMark::Up => chart
                        .draw_series(pts.map(|q| TriangleMarker::new(q, 4, c.filled())))
                        .map(|_| ()),
                    SweepMark::Down => chart
                        .draw_series(pts.map(|q| {
                            EmptyElement::at(q)
                                + PathElement::new(
                                    vec![(-5, -4), (5, -4), (0, 5), (-5, -4)],
                                    c.stroke_width(1),
                                )
                        }))
                        .map(|_| ()),
                    SweepMark::Unordered => chart
                        .draw_series(pts.map(|q| Circle::new(q, 3, c.filled())))
                        .map(|_| ()),
                }
                .drawn()?;
            }
        }
        Ok(())
    }
}

impl Figure for FrequencyResponse {
    fn size(&self) -> (u32, u32) {
        (1060, 640)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let fs = self.families.iter().flat_map(|f| {
            f.sweeps
                .iter()
                .flat_map(|s| s.f_hz.iter().copied())
                .chain(f.model.iter().flat_map(|m| m.f_hz.iter().copied()))
        });
        let Some((f_lo, f_hi)) = style::range(fs) else {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        };
        let off = style::axis_offset(f_lo, f_hi);
        let f_label = if off == 0.0 {
            "drive frequency f (Hz)".to_string()
        } else {
            format!("f − {} Hz (Hz)", style::hz(off))
        };
        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (legend_area, body) = root.split_vertically(26);
        style::legend(&legend_area, &self.legend_entries())?;
        let (left, right) = body.split_horizontally(640);
        let (amp, phase) = left.split_vertically(350);
        let u = &self.unit;
        let centre = phase_centre(&self.families);
        let amp_of = |_f: f64, z: (f64, f64)| z.0.hypot(z.1);
        let freq = |f: f64, _z: (f64, f64)| f;
        let phase_of = |_f: f64, z: (f64, f64)| near(deg(z), centre);
        self.draw_panel(
            &amp,
            &Panel {
                x_of: &freq,
                y_of: &amp_of,
            },
            (&f_label, &format!("|X| ({u})")),
            off,
            false,
        )?;
        self.draw_panel(
            &phase,
            &Panel {
                x_of: &freq,
                y_of: &phase_of,
            },
            (&f_label, "arg X − arg F (°)"),
            off,
            false,
        )?;
        let (nyq, _) = right.split_vertically(392);
        let re = |_f: f64, z: (f64, f64)| z.0;
        let im = |_f: f64, z: (f64, f64)| z.1;
        self.draw_panel(
            &nyq,
            &Panel {
                x_of: &re,
                y_of: &im,
            },
            (&format!("Re X ({u})"), &format!("Im X ({u})")),
            0.0,
            true,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phases_unwrap_along_the_curve_and_points_join_them() {
        let x = [(-1.0, 0.1), (-1.0, -0.1)];
        let p = unwrapped(&x);
        assert!((p[0] - 174.29).abs() < 0.01 && (p[1] - 185.71).abs() < 0.01);
        assert!((near(170.0, -90.0) + 190.0).abs() < 1e-12);
        assert!((near(-10.0, -90.0) + 10.0).abs() < 1e-12);
    }
}

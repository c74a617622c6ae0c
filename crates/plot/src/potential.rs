//! A matrix of 2-D maps of a potential over pairs of modal coordinates (Fig. 5c style).

use crate::style;
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};

/// One cell of the matrix.
#[derive(Debug, Clone, PartialEq)]
pub enum PotentialCell {
    /// Nothing drawn.
    Empty,
    /// `U(q_col, q_row)` on an `n × n` grid: `values[r * n + c]` at `q_col = x[c]`,
    /// `q_row = y[r]`.
    Map {
        /// Grid size.
        n: usize,
        /// The column coordinate's range (`x[0]`, `x[n−1]`).
        x: (f64, f64),
        /// The row coordinate's range.
        y: (f64, f64),
        /// Row-major values.
        values: Vec<f64>,
    },
    /// `U(q)` along one coordinate (the diagonal).
    Curve {
        /// Coordinates.
        q: Vec<f64>,
        /// Values.
        u: Vec<f64>,
    },
}

/// The matrix: `cells[i][j]` is drawn in row `i`, column `j`. The maps of `(i, j)` and
/// `(j, i)` share one colour scale, so a lower triangle (identified) and an upper one (truth)
/// compare by colour.
#[derive(Debug, Clone, PartialEq)]
pub struct PotentialMatrix {
    /// Title.
    pub title: String,
    /// Mode names, in row/column order.
    pub modes: Vec<String>,
    /// The cells.
    pub cells: Vec<Vec<PotentialCell>>,
    /// A note under the title, e.g. `lower: identified · upper: truth · colour: U_nl per pair`.
    pub note: String,
}

fn span(c: &PotentialCell) -> (f64, f64) {
    match c {
        PotentialCell::Map { values, .. } => values
            .iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            }),
        _ => (f64::INFINITY, f64::NEG_INFINITY),
    }
}

/// A cell's chart: a frame without ticks, the mode names on the outer edges (`frame`: bottom
/// row, left column, x label, y label).
fn cell_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    frame: (bool, bool, String, String),
    x: (f64, f64),
    y: (f64, f64),
) -> Result<
    ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    PlotError,
> {
    let (bottom, left, x_desc, y_desc) = frame;
    let mut chart = ChartBuilder::on(area)
        .margin(4)
        .x_label_area_size(if bottom { 22 } else { 4 })
        .y_label_area_size(if left { 22 } else { 4 })
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .drawn()?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(0)
        .y_labels(0)
        .x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style(style::text(style::LABEL - 2.0))
        .draw()
        .drawn()?;
    Ok(chart)
}

impl Figure for PotentialMatrix {
    fn size(&self) -> (u32, u32) {
        let n = self.modes.len().max(1) as u32;
        let cell = if n <= 2 { 260 } else { 180 };
        (40 + cell * n, 90 + cell * n)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let n = self.modes.len();
        if n == 0 || self.cells.len() != n {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        }
        let root = root
            .titled(&self.title, style::text(style::TITLE))
            .drawn()?;
        let (note, body) = root.split_vertically(24);
        note.draw(&Text::new(
            self.note.clone(),
            (12, 4),
            style::text(style::NOTE),
        ))
        .drawn()?;
        let (_, body) = body.split_horizontally(30);
        let areas = body.split_evenly((n, n));
        for i in 0..n {
            for j in 0..n {
                let area = &areas[i * n + j];
                let Some(cell) = self.cells[i].get(j) else {
                    continue;
                };
                let mirror = self.cells.get(j).and_then(|r| r.get(i));
                let (a, b) = span(cell);
                let (c, d) = mirror
                    .map(span)
                    .unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
                let (lo, hi) = (a.min(c), b.max(d));
                let x_desc = if i + 1 == n {
                    self.modes[j].clone()
                } else {
                    String::new()
                };
                let y_desc = if j == 0 {
                    self.modes[i].clone()
                } else {
                    String::new()
                };
                match cell {
                    PotentialCell::Empty => {}
                    PotentialCell::Map { n: g, x, y, values } => {
                        let g = *g;
                        if g < 2 || values.len() != g * g {
                            continue;
                        }
                        let frame = (i + 1 == n, j == 0, x_desc, y_desc);
                        let mut chart = cell_chart(area, frame, (x.0, x.1), (y.0, y.1))?;
                        let (dx, dy) = ((x.1 - x.0) / (g - 1) as f64, (y.1 - y.0) / (g - 1) as f64);
                        let w = if hi > lo { hi - lo } else { 1.0 };
                        chart
                            .draw_series((0..g * g).filter_map(|k| {
                                let (r, c) = (k / g, k % g);
                                let v = values[k];
                                v.is_finite().then(|| {
                                    let (cx, cy) = (x.0 + c as f64 * dx, y.0 + r as f64 * dy);
                                    let h = ((v - lo) / w).clamp(0.0, 1.0) as f32;
                                    Rectangle::new(
                                        [
                                            (cx - 0.5 * dx, cy - 0.5 * dy),
                                            (cx + 0.5 * dx, cy + 0.5 * dy),
                                        ],
                                        ViridisRGB.get_color(h).filled(),
                                    )
                                })
                            }))
                            .drawn()?;
                    }
                    PotentialCell::Curve { q, u } => {
                        let (Some((q0, q1)), Some((u0, u1))) = (
                            style::range(q.iter().copied()),
                            style::range(u.iter().copied()),
                        ) else {
                            continue;
                        };
                        let frame = (i + 1 == n, j == 0, x_desc, y_desc);
                        let mut chart = cell_chart(area, frame, (q0, q1), (u0, u1))?;
                        chart
                            .draw_series(LineSeries::new(
                                q.iter().copied().zip(u.iter().copied()),
                                style::BLUE.stroke_width(2),
                            ))
                            .drawn()?;
                    }
                }
            }
        }
        Ok(())
    }
}

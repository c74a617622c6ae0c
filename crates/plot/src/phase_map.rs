//! A phase diagram: over two parameters, the number of stable and unstable steady states,
//! one colour per combination (`harmonid phase-diagram --plot`).

use crate::style::{self, LegendMark};
use crate::{Drawn, Figure, PlotError};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Counts of states over a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseMap {
    /// Title.
    pub title: String,
    /// x axis label (with its unit).
    pub x_label: String,
    /// y axis label (with its unit).
    pub y_label: String,
    /// The x values (evenly spaced, ascending or descending).
    pub x: Vec<f64>,
    /// The y values.
    pub y: Vec<f64>,
    /// `counts[iy · nx + ix]`: `(stable, unstable)`, `None` where nothing was computed.
    pub counts: Vec<Option<(u32, u32)>>,
}

impl PhaseMap {
    /// The combinations present, in order of (stable, unstable).
    fn kinds(&self) -> Vec<(u32, u32)> {
        let mut k: Vec<(u32, u32)> = self.counts.iter().flatten().copied().collect();
        k.sort_unstable();
        k.dedup();
        k
    }

    /// Half a cell on each side of the grid's values.
    fn edges(v: &[f64]) -> Vec<f64> {
        let n = v.len();
        let h = if n > 1 { 0.5 * (v[1] - v[0]) } else { 0.5 };
        let mut e: Vec<f64> = v.iter().map(|x| x - h).collect();
        e.push(v[n - 1] + h);
        e
    }
}

impl Figure for PhaseMap {
    fn size(&self) -> (u32, u32) {
        (640, 520)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let kinds = self.kinds();
        let (nx, ny) = (self.x.len(), self.y.len());
        if kinds.is_empty() || nx * ny != self.counts.len() {
            return Err(PlotError::Empty {
                what: self.title.clone(),
            });
        }
        let (ex, ey) = (Self::edges(&self.x), Self::edges(&self.y));
        let xr = style::range(ex.iter().copied()).unwrap_or((0.0, 1.0));
        let yr = style::range(ey.iter().copied()).unwrap_or((0.0, 1.0));
        let root = root
            .titled(&self.title, style::text(style::TITLE - 3.0))
            .drawn()?;
        // The legend, four entries a row.
        let rows = kinds.len().div_ceil(4) as u32;
        let (legend_area, body) = root.split_vertically(24 * rows + 2);
        let colour = |k: (u32, u32)| {
            let i = kinds.iter().position(|&c| c == k).unwrap_or(0);
            // The palette, then its colours lightened halfway to white.
            let RGBColor(r, g, b) = style::PALETTE[i % style::PALETTE.len()];
            let l = |c: u8| {
                if i < style::PALETTE.len() {
                    c
                } else {
                    c / 2 + 128
                }
            };
            RGBColor(l(r), l(g), l(b))
        };
        let entries: Vec<(LegendMark, RGBColor, String)> = kinds
            .iter()
            .map(|&(s, u)| {
                (
                    LegendMark::Dot,
                    colour((s, u)),
                    format!("{s} stable, {u} unstable"),
                )
            })
            .collect();
        for (k, area) in legend_area
            .split_evenly((rows as usize, 1))
            .iter()
            .enumerate()
        {
            style::legend(area, &entries[4 * k..(4 * k + 4).min(entries.len())])?;
        }
        let mut chart = ChartBuilder::on(&body)
            .margin(10)
            .x_label_area_size(48)
            .y_label_area_size(64)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .drawn()?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .axis_desc_style(style::text(style::LABEL))
            .label_style(style::text(style::TICK))
            .x_labels(6)
            .x_label_formatter(&|v| style::tick(*v))
            .y_label_formatter(&|v| style::tick(*v))
            .draw()
            .drawn()?;
        // One rectangle per run of equal cells along x: a small file.
        let mut rects = Vec::new();
        for iy in 0..ny {
            let mut ix = 0;
            while ix < nx {
                let c = self.counts[iy * nx + ix];
                let mut end = ix + 1;
                while end < nx && self.counts[iy * nx + end] == c {
                    end += 1;
                }
                if let Some(k) = c {
                    rects.push(Rectangle::new(
                        [(ex[ix], ey[iy]), (ex[end], ey[iy + 1])],
                        colour(k).filled(),
                    ));
                }
                ix = end;
            }
        }
        chart.draw_series(rects).drawn()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_one_rectangle_per_run() {
        let map = PhaseMap {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            x: vec![0.0, 1.0, 2.0],
            y: vec![0.0, 1.0],
            counts: vec![
                Some((1, 0)),
                Some((1, 0)),
                Some((2, 1)),
                None,
                Some((1, 0)),
                Some((1, 0)),
            ],
        };
        let svg = crate::to_svg(&map).expect("draws");
        assert!(svg.contains("2 stable, 1 unstable") && svg.contains("1 stable, 0 unstable"));
    }
}

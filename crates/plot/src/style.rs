//! The one shared style of every figure: fonts, sizes, the Okabe–Ito palette (safe for the
//! common colour-vision deficiencies), number formatting and axis ranges.

use plotters::prelude::*;
use plotters::style::{FontStyle, TextStyle};
use std::sync::Once;

/// DejaVu Sans (Bitstream Vera licence, `fonts/DejaVu-LICENSE`), used for bitmap output.
static DEJAVU_SANS: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Font family of every text.
pub const FONT: &str = "sans-serif";
/// Title size, px.
pub const TITLE: f64 = 20.0;
/// Axis label size, px.
pub const LABEL: f64 = 16.0;
/// Tick label size, px.
pub const TICK: f64 = 13.0;
/// Annotation size (line labels, legends), px.
pub const NOTE: f64 = 12.0;

/// Okabe–Ito black.
pub const BLACK: RGBColor = RGBColor(0, 0, 0);
/// Okabe–Ito orange.
pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
/// Okabe–Ito sky blue.
pub const SKY: RGBColor = RGBColor(86, 180, 233);
/// Okabe–Ito bluish green.
pub const GREEN: RGBColor = RGBColor(0, 158, 115);
/// Okabe–Ito yellow.
pub const YELLOW: RGBColor = RGBColor(240, 228, 66);
/// Okabe–Ito blue.
pub const BLUE: RGBColor = RGBColor(0, 114, 178);
/// Okabe–Ito vermillion.
pub const VERMILLION: RGBColor = RGBColor(213, 94, 0);
/// Okabe–Ito reddish purple.
pub const PURPLE: RGBColor = RGBColor(204, 121, 167);
/// Grid and secondary lines.
pub const GREY: RGBColor = RGBColor(150, 150, 150);
/// The palette in the order series take it.
pub const PALETTE: [RGBColor; 7] = [BLUE, VERMILLION, GREEN, ORANGE, PURPLE, SKY, BLACK];

/// Registers the embedded font once (needed by the bitmap backend's text layout).
pub fn init() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for st in [FontStyle::Normal, FontStyle::Bold, FontStyle::Italic] {
            // The font is compiled in and known to parse (tested below).
            let _ = plotters::style::register_font(FONT, st, DEJAVU_SANS);
        }
    });
}

/// Text of `size` px in the house font.
pub fn text(size: f64) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// Text of `size` px in `color`.
pub fn text_in(size: f64, color: &RGBColor) -> TextStyle<'static> {
    (FONT, size).into_font().color(color)
}

/// A readable number with `sig` significant digits: plain notation from 1e-3 to 1e5,
/// scientific (`1.23e-9`) outside; `0` as `0`.
pub fn num(v: f64, sig: usize) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let mag = a.log10().floor() as i32;
        let dec = (sig as i32 - 1 - mag).max(0) as usize;
        format!("{v:.dec$}")
    } else {
        let s = format!("{:.*e}", sig.saturating_sub(1), v);
        // 1.50e-9 keeps its digits; only the exponent's form is tidied.
        s.replace("e-0", "e-")
    }
}

/// A frequency offset in plain digits (`207582`, `0.25`), never in scientific notation.
pub fn hz(v: f64) -> String {
    if v == v.round() && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// A tick label: the shortest of `num(v, 1..=4)` that is exact to 1e-9 relative, so ticks read
/// `0.5`, `1e-10`, `2.5e5`.
pub fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return num(v, 1);
    }
    for sig in 1..=5 {
        let s = num(v, sig);
        if let Ok(back) = s.parse::<f64>() {
            if (back - v).abs() <= 1e-9 * v.abs() {
                return s;
            }
        }
    }
    num(v, 6)
}

/// `value ± err` with the error to 2 significant digits and the value to the same decimal.
pub fn pm(value: f64, err: f64) -> String {
    if !(err.is_finite() && err > 0.0 && value.is_finite()) {
        return num(value, 6);
    }
    // Plain digits while they stay short (207581.98 ± 0.14), scientific otherwise.
    let a = value.abs().max(err);
    if (1e-3..1e7).contains(&a) && err >= 1e-4 {
        let dec = (1 - err.log10().floor() as i32).max(0) as usize;
        format!("{value:.dec$} ± {err:.dec$}")
    } else {
        let e = a.log10().floor() as i32;
        let scale = 10f64.powi(e);
        let (v, s) = (value / scale, err / scale);
        let dec = (1 - s.log10().floor() as i32).max(0) as usize;
        format!("({v:.dec$} ± {s:.dec$})e{e}")
    }
}

/// A padded axis range containing every finite value of `values` (10 % padding, at least a
/// small width around a single value).
pub fn range(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.into_iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return None;
    }
    let w = hi - lo;
    let pad = if w > 0.0 {
        0.08 * w
    } else {
        0.05 * lo.abs().max(1e-300)
    };
    Some((lo - pad, hi + pad))
}

/// A log-axis range (decades, rounded outwards) containing every positive finite value.
pub fn log_range(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.into_iter().filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return None;
    }
    let (a, b) = (lo.log10().floor(), hi.log10().ceil());
    let b = if b <= a { a + 1.0 } else { b };
    Some((10f64.powf(a), 10f64.powf(b)))
}

/// The offset subtracted from an axis whose values vary in their last digits (e.g. 207 582.31 Hz
/// ± 0.05): a round number near the values, or 0 when the spread is large enough to read.
pub fn axis_offset(lo: f64, hi: f64) -> f64 {
    let mid = 0.5 * (lo + hi);
    let w = hi - lo;
    if !(w > 0.0 && mid.is_finite()) || w >= 1e-2 * mid.abs() {
        return 0.0;
    }
    let step = 10f64.powf(w.log10().ceil());
    (mid / step).round() * step
}

/// Draws a row of legend entries (a marker or line in a colour, then its text) on `area`.
pub fn legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[(LegendMark, RGBColor, String)],
) -> Result<(), crate::PlotError> {
    use crate::Drawn;
    let (w, h) = area.dim_in_pixel();
    let y = h as i32 / 2;
    let mut x = 12i32;
    let font = text(NOTE);
    for (mark, color, label) in entries {
        match mark {
            LegendMark::Dot => area
                .draw(&Circle::new((x + 6, y), 4, color.filled()))
                .drawn()?,
            LegendMark::Open => area
                .draw(&Circle::new((x + 6, y), 5, color.stroke_width(2)))
                .drawn()?,
            LegendMark::Line => area
                .draw(&PathElement::new(
                    vec![(x, y), (x + 14, y)],
                    color.stroke_width(2),
                ))
                .drawn()?,
            LegendMark::Dashed => {
                for k in 0..3 {
                    area.draw(&PathElement::new(
                        vec![(x + 5 * k, y), (x + 5 * k + 3, y)],
                        color.stroke_width(2),
                    ))
                    .drawn()?;
                }
            }
            LegendMark::Band => area
                .draw(&Rectangle::new(
                    [(x, y - 5), (x + 14, y + 5)],
                    color.mix(0.25).filled(),
                ))
                .drawn()?,
            LegendMark::Triangle => area
                .draw(&TriangleMarker::new((x + 6, y), 6, color.filled()))
                .drawn()?,
            LegendMark::OpenDown => area
                .draw(&PathElement::new(
                    vec![
                        (x + 1, y - 4),
                        (x + 11, y - 4),
                        (x + 6, y + 5),
                        (x + 1, y - 4),
                    ],
                    color.stroke_width(2),
                ))
                .drawn()?,
        }
        x += 20;
        area.draw(&Text::new(
            label.clone(),
            (x, y - (NOTE as i32) / 2),
            font.clone(),
        ))
        .drawn()?;
        let (tw, _) = area.estimate_text_size(label, &font).drawn()?;
        x += tw as i32 + 18;
        if x > w as i32 {
            break;
        }
    }
    Ok(())
}

/// The mark of a legend entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LegendMark {
    /// A filled dot.
    Dot,
    /// An open circle.
    Open,
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// A shaded band.
    Band,
    /// A triangle.
    Triangle,
    /// An open triangle pointing down (a down-sweep's points).
    OpenDown,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_font_parses() {
        assert!(plotters::style::register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok());
    }

    #[test]
    fn numbers_read_well() {
        assert_eq!(num(207582.31, 4), "2.076e5");
        assert_eq!(num(0.5, 2), "0.50");
        assert_eq!(num(1.5e-9, 2), "1.5e-9");
        assert_eq!(tick(0.5), "0.5");
        assert_eq!(hz(207582.0), "207582");
        assert_eq!(hz(207582.5), "207582.5");
        assert_eq!(tick(1e-10), "1e-10");
        assert_eq!(tick(250000.0), "2.5e5");
        assert_eq!(pm(1.2345, 0.012), "1.234 ± 0.012");
        assert_eq!(pm(3.1e10, 2.0e8), "(3.100 ± 0.020)e10");
        assert_eq!(pm(207581.98, 0.14), "207581.98 ± 0.14");
    }

    #[test]
    fn axis_offset_only_for_narrow_spreads() {
        assert_eq!(axis_offset(207582.2, 207582.4), 207582.0);
        assert_eq!(axis_offset(0.9, 1.1), 0.0);
    }

    #[test]
    fn ranges() {
        assert_eq!(log_range([2e-10, 3e-8]), Some((1e-10, 1e-7)));
        let (lo, hi) = range([1.0, 2.0]).expect("a range");
        assert!(lo < 1.0 && hi > 2.0);
        assert_eq!(range([f64::NAN]), None);
    }
}

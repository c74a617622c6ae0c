//! Figures of harmonid as SVG and PNG, in one shared style.
//!
//! Every figure is a plain data struct that implements [`Figure`]; [`to_svg`] renders it to an
//! SVG string and [`save`] writes it as `.svg` or `.png` (chosen by the extension). The style
//! (fonts, palette, axes) lives in [`style`], so a new figure is a short `draw` function:
//!
//! - [`Spectrum`]: a measured multi-tone spectrum, log |X| against frequency, each line marked as
//!   drive tone, sideband or mixing product with its combination, the harmonic-balance
//!   reconstruction overlaid and the residuals below (the method's Fig. 1b–c);
//! - [`Histogram`]: per-shot estimates with the normal fit, outliers, value ± stderr and the
//!   truth (Fig. 3c–f);
//! - [`ResponseCurve`]: a frequency-response curve, stable solid, unstable dashed, jumps and
//!   backbone (Fig. 3g);
//! - [`FrequencyResponse`]: a measured stepped-sine response (amplitude and phase against the
//!   drive frequency, up- and down-sweeps marked apart, and the Nyquist view) with the model's
//!   curve through its folds, one colour per drive level;
//! - [`NoiseStudy`]: estimates ± 3σ against the noise level (Fig. S3);
//! - [`PotentialMatrix`]: pairwise 2-D maps of a potential (Fig. 5c);
//! - [`PlanFigure`]: a measurement plan over the resonances (each mode's linear response, the
//!   planned tones, the predicted lines with their combinations).
//!
//! The bitmap backend draws text with DejaVu Sans compiled into the crate (no system fonts
//! needed); SVG text names the `sans-serif` family and is drawn by the viewer.
//!
//! ```
//! use harmonid_plot::{to_svg, Histogram};
//! let h = Histogram {
//!     name: "beta1".into(),
//!     unit: "1/(m² s²)".into(),
//!     values: vec![1.0, 1.1, 0.9, 1.05, 0.95, 3.0],
//!     outliers: vec![5],
//!     value: 1.0,
//!     stderr: 0.03,
//!     std: 0.07,
//!     truth: Some(1.02),
//! };
//! let svg = to_svg(&h).expect("renders");
//! assert!(svg.starts_with("<svg") && svg.contains("beta1"));
//! ```

#![warn(missing_docs)]

mod frequency_response;
mod histogram;
mod noise;
mod phase_map;
mod plan;
mod potential;
mod response;
mod spectrum;
pub mod style;

/// The plotting library the figures are drawn with (for [`Figure`] implementations elsewhere).
pub use plotters;

pub use frequency_response::{
    FrequencyResponse, MeasuredSweep, ModelBranch, ResponseFamily, SweepMark,
};
pub use histogram::Histogram;
pub use noise::{NoisePanel, NoiseStudy};
pub use phase_map::PhaseMap;
pub use plan::{ModeResponse, PlanFigure, PlannedMeasurement};
pub use potential::{PotentialCell, PotentialMatrix};
pub use response::{Branch, Jump, ResponseCurve};
pub use spectrum::{LineKind, Spectrum, SpectrumLine, TYPICAL_SIGMAS};

use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Errors of rendering a figure, each a diagnostic with a stable code.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum PlotError {
    /// The drawing backend failed.
    #[error("cannot draw the figure: {reason}")]
    #[diagnostic(code(harmonid::plot::draw))]
    Draw {
        /// What the backend said.
        reason: String,
    },
    /// The file extension is neither `.svg` nor `.png`.
    #[error("{}: unknown figure format (use a .svg or .png file name)", path.display())]
    #[diagnostic(
        code(harmonid::plot::format),
        help("name the figure file with .svg (vector) or .png (bitmap)")
    )]
    Format {
        /// The path given.
        path: PathBuf,
    },
    /// The figure has nothing to draw.
    #[error("the figure \"{what}\" has no data to draw")]
    #[diagnostic(code(harmonid::plot::empty))]
    Empty {
        /// Which figure.
        what: String,
    },
    /// Writing the file failed (or it may not be written there).
    #[error(transparent)]
    #[diagnostic(transparent)]
    File(#[from] harmonid_files::FileError),
}

/// Turns a plotters error into a [`PlotError`].
pub(crate) trait Drawn<T> {
    fn drawn(self) -> Result<T, PlotError>;
}

impl<T, E: std::fmt::Display> Drawn<T> for Result<T, E> {
    fn drawn(self) -> Result<T, PlotError> {
        self.map_err(|e| PlotError::Draw {
            reason: e.to_string(),
        })
    }
}

/// A figure: a size in pixels and a function that draws it on any plotters backend.
pub trait Figure {
    /// Width and height, px.
    fn size(&self) -> (u32, u32);
    /// Draws the figure on `root` (already filled white).
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError>;
}

/// Renders `fig` as an SVG document.
pub fn to_svg(fig: &impl Figure) -> Result<String, PlotError> {
    style::init();
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, fig.size()).into_drawing_area();
        root.fill(&WHITE).drawn()?;
        fig.draw(&root)?;
        root.present().drawn()?;
    }
    Ok(s)
}

/// The structure of an SVG: the count of each kind of element and every distinct text, one per
/// line. Golden tests compare this (it changes when a figure's content does, not with
/// anti-aliasing or float formatting).
pub fn svg_structure(svg: &str) -> String {
    let mut out = String::new();
    for tag in [
        "<rect",
        "<circle",
        "<polyline",
        "<polygon",
        "<line",
        "<path",
        "<text",
    ] {
        out += &format!("{tag}: {}\n", svg.matches(tag).count());
    }
    let mut texts: Vec<&str> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| {
            t.split_once('>')
                .and_then(|(_, r)| r.split_once("</text>"))
                .map(|(t, _)| t)
        })
        .collect();
    texts.dedup();
    out += &texts.join("\n");
    out
}

/// [`svg_structure`] without the tick labels (texts that are numbers) and blank texts: for
/// golden tests of figures drawn from computed data, whose ticks move with the last digits of
/// the results while what is drawn and every name and label stay.
pub fn svg_structure_without_ticks(svg: &str) -> String {
    svg_structure(svg)
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && (l.contains(": ") || l.replace('−', "-").parse::<f64>().is_err())
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// A figure file's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Scalable vector graphics (text drawn by the viewer).
    Svg,
    /// A bitmap (text drawn with the embedded DejaVu Sans).
    Png,
}

impl Format {
    /// The format named by `path`'s extension (`.svg`, `.png`, any case).
    pub fn of_path(path: &Path) -> Result<Format, PlotError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("svg") => Ok(Format::Svg),
            Some("png") => Ok(Format::Png),
            _ => Err(PlotError::Format {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// Renders `fig` as a PNG image (the encoded file's bytes).
pub fn to_png(fig: &impl Figure) -> Result<Vec<u8>, PlotError> {
    use image::ImageEncoder;
    style::init();
    let (w, h) = fig.size();
    let mut rgb = vec![0u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).drawn()?;
        fig.draw(&root)?;
        root.present().drawn()?;
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgb, w, h, image::ColorType::Rgb8)
        .drawn()?;
    Ok(png)
}

/// Renders `fig` in `format` (the file's bytes).
pub fn render(fig: &impl Figure, format: Format) -> Result<Vec<u8>, PlotError> {
    match format {
        Format::Svg => to_svg(fig).map(String::into_bytes),
        Format::Png => to_png(fig),
    }
}

/// Writes `fig` to `path` as SVG or PNG, by the extension (`.svg`, `.png`), through
/// [`harmonid_files::write_file`]: atomically, only over a regular file, never over one of
/// `inputs`. The format is checked before anything is drawn.
pub fn save(fig: &impl Figure, path: &Path, inputs: &[&Path]) -> Result<(), PlotError> {
    let bytes = render(fig, Format::of_path(path)?)?;
    harmonid_files::write_file(path, &bytes, inputs)?;
    Ok(())
}

#[cfg(test)]
mod error_tests {
    use super::*;
    use miette::Diagnostic;

    #[test]
    fn errors_are_coded_diagnostics() {
        let e = PlotError::Format {
            path: "fig.jpg".into(),
        };
        assert_eq!(
            e.code().map(|c| c.to_string()).as_deref(),
            Some("harmonid::plot::format")
        );
        assert!(e.help().is_some());
        let e: Result<(), &str> = Err("backend broke");
        let e = e.drawn().expect_err("draw");
        assert_eq!(e.to_string(), "cannot draw the figure: backend broke");
        assert_eq!(
            e.code().map(|c| c.to_string()).as_deref(),
            Some("harmonid::plot::draw")
        );
    }
}

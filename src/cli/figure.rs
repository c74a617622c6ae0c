//! Writing a command's `--plot` figure: drawn by `harmonid_plot`, written like every other output
//! (atomically, only over a regular file, never over an input; `harmonid_files`).

use harmonid_plot::{Figure, Format, PlotError};
use std::path::Path;

/// Checks before any work that `path` names a figure format (`.svg`, `.png`) and can be written.
pub fn check(path: &Path, inputs: &[&Path]) -> miette::Result<()> {
    Format::of_path(path)?;
    super::common::check_outputs(&[path], inputs)
}

/// Draws `fig` to `path` (`.svg` or `.png`, by the extension).
pub fn save(fig: &impl Figure, path: &Path, inputs: &[&Path]) -> miette::Result<()> {
    harmonid_plot::save(fig, path, inputs).map_err(|e| match e {
        PlotError::File(_) => miette::Report::new(e),
        other => miette::Report::new(other).wrap_err(format!("--plot {}", path.display())),
    })
}

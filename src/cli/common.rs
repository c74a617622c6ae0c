//! Helpers shared by the subcommands: atomic output files.

use miette::{miette, IntoDiagnostic, WrapErr};
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, renamed over the
/// target only once fully written, so an interrupted run never leaves a partial file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> miette::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::NamedTempFile::new_in(dir)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot create a temporary file in {}", dir.display()))?;
    tmp.write_all(bytes)
        .and_then(|()| tmp.flush())
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot write {}", path.display()))?;
    tmp.persist(path)
        .map_err(|e| miette!("cannot write {}: {}", path.display(), e.error))?;
    Ok(())
}

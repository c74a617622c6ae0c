//! Writing the report folder safely: everything goes to a staging folder beside the target,
//! which is renamed into place only when complete; an existing target is replaced only when it
//! is a harmonid report (it holds [`MARKER`]).

use crate::ReportError;
use std::path::Path;

/// The file that marks a folder as a harmonid report.
pub const MARKER: &str = ".harmonid-report";

/// Fills a fresh staging folder with `fill`, then puts it at `out`.
pub fn write_folder(
    out: &Path,
    fill: impl FnOnce(&Path) -> Result<(), ReportError>,
) -> Result<(), ReportError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Io { path, source }
    };
    if out.exists() && !out.join(MARKER).is_file() {
        return Err(ReportError::Clobber {
            path: out.to_path_buf(),
        });
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(parent).map_err(io(parent))?;
    let staging = tempfile::Builder::new()
        .prefix(".harmonid-report-staging-")
        .tempdir_in(parent)
        .map_err(io(parent))?;
    fill(staging.path())?;
    let marker = staging.path().join(MARKER);
    std::fs::write(&marker, "written by harmonid report\n").map_err(io(&marker))?;
    if out.exists() {
        // Move the old report aside first, so `out` is never half old, half new.
        let old = tempfile::Builder::new()
            .prefix(".harmonid-report-old-")
            .tempdir_in(parent)
            .map_err(io(parent))?;
        let aside = old.path().join("report");
        std::fs::rename(out, &aside).map_err(io(out))?;
        std::fs::rename(staging.keep(), out).map_err(io(out))?;
        drop(old);
    } else {
        std::fs::rename(staging.keep(), out).map_err(io(out))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_a_foreign_folder_and_replaces_a_report() {
        let tmp = tempfile::tempdir().expect("tmp");
        let foreign = tmp.path().join("mine");
        std::fs::create_dir(&foreign).expect("dir");
        std::fs::write(foreign.join("thesis.tex"), "x").expect("file");
        let r = write_folder(&foreign, |_| Ok(()));
        assert!(matches!(r, Err(ReportError::Clobber { .. })));
        assert!(foreign.join("thesis.tex").is_file());

        let out = tmp.path().join("rep");
        write_folder(&out, |d| {
            std::fs::write(d.join("a"), "1").map_err(|source| ReportError::Io {
                path: d.into(),
                source,
            })
        })
        .expect("first");
        write_folder(&out, |d| {
            std::fs::write(d.join("b"), "2").map_err(|source| ReportError::Io {
                path: d.into(),
                source,
            })
        })
        .expect("second");
        assert!(out.join("b").is_file() && !out.join("a").exists());
        // A failing fill leaves the old report and no staging folder.
        let r = write_folder(&out, |_| Err(ReportError::Clobber { path: "x".into() }));
        assert!(r.is_err() && out.join("b").is_file());
        let left: Vec<_> = std::fs::read_dir(tmp.path())
            .expect("ls")
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with(".harmonid"))
            .collect();
        assert!(left.is_empty(), "staging left behind");
    }
}

//! Staging names, and the removal of staging left behind by killed runs.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime};

/// Every staging file or folder harmonid creates is named `<STAGING_PREFIX><pid>-<unique>` in the
/// folder of its target, so that a later run can tell whether its writer is still alive.
pub const STAGING_PREFIX: &str = ".harmonid-staging-";

/// Names used by earlier versions (`.harmonid-dataset-XXXXXX` staging folders, and
/// `.harmonid-old-<pid>-<name>` folders moved aside): removed once older than [`LEGACY_AGE`].
const LEGACY_PREFIXES: [&str; 2] = [".harmonid-dataset-", ".harmonid-old-"];
const LEGACY_AGE: Duration = Duration::from_secs(3600);
/// Where the process table cannot be read, staging of this age counts as abandoned.
const UNKNOWN_PID_AGE: Duration = Duration::from_secs(24 * 3600);

/// A fresh staging name for a target in `dir` (not created).
pub(crate) fn staging_path(dir: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let nanos = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    dir.join(format!(
        "{STAGING_PREFIX}{}-{nanos:x}{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Removes, from folder `dir`, the staging files and folders of harmonid's own naming whose
/// process has ended (on Linux, checked in `/proc`; elsewhere, after a day), and those of older
/// versions' naming after an hour. Returns what it removed. Errors are ignored: cleaning is a
/// courtesy, never a reason to fail a run. Entries of any other name are never touched.
pub fn clean_stale(dir: &Path) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return removed;
    };
    let proc_ok = Path::new("/proc/self").exists();
    for entry in entries.flatten().take(100_000) {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let age = entry
            .metadata()
            .ok()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.elapsed().ok())
            .unwrap_or(Duration::ZERO);
        let stale = if let Some(rest) = name.strip_prefix(STAGING_PREFIX) {
            let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
            match pid {
                Some(pid) if pid == std::process::id() => false,
                Some(pid) if proc_ok => !Path::new("/proc").join(pid.to_string()).exists(),
                _ => age > UNKNOWN_PID_AGE,
            }
        } else {
            LEGACY_PREFIXES.iter().any(|p| name.starts_with(p)) && age > LEGACY_AGE
        };
        if !stale {
            continue;
        }
        let path = entry.path();
        let is_dir = entry.file_type().map(|t| t.is_dir()).unwrap_or(false);
        let ok = if is_dir {
            std::fs::remove_dir_all(&path).is_ok()
        } else {
            std::fs::remove_file(&path).is_ok()
        };
        if ok {
            removed.push(path);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removes_only_dead_staging_of_our_naming() {
        let root = tempfile::tempdir().expect("tempdir");
        let d = root.path();
        // A process id that cannot be alive (above Linux's pid_max of 2^22).
        let dead = d.join(format!("{STAGING_PREFIX}4294967-abc"));
        std::fs::create_dir(&dead).expect("mkdir");
        std::fs::write(dead.join("m1.csv"), "x").expect("write");
        let dead_file = d.join(format!("{STAGING_PREFIX}4294968-0"));
        std::fs::write(&dead_file, "x").expect("write");
        let mine = staging_path(d);
        std::fs::create_dir(&mine).expect("mkdir");
        let users = d.join(".harmonid-notes");
        std::fs::write(&users, "x").expect("write");
        let legacy_fresh = d.join(".harmonid-dataset-XYZ");
        std::fs::create_dir(&legacy_fresh).expect("mkdir");
        let removed = clean_stale(d);
        if Path::new("/proc/self").exists() {
            assert_eq!(removed.len(), 2, "{removed:?}");
            assert!(!dead.exists() && !dead_file.exists());
        }
        assert!(mine.exists(), "this process's staging is kept");
        assert!(users.exists(), "other names are never touched");
        assert!(
            legacy_fresh.exists(),
            "recent legacy staging may belong to a running old binary"
        );
    }
}

//! Input paths: confinement to a folder, and file identity.

use crate::error::{io_err, FileError};
use std::path::{Path, PathBuf};

/// Resolves `rel` (a path relative to folder `dir`) to its real path, following symbolic links,
/// and refuses it when the real path is not inside `dir`'s real path. The file must exist.
///
/// `..` components and links that leave the folder are both refused with
/// [`FileError::Outside`], which names the path as written, never the target or its content.
pub fn resolve_inside(dir: &Path, rel: &Path) -> Result<PathBuf, FileError> {
    let joined = dir.join(rel);
    let outside = || FileError::Outside {
        path: joined.clone(),
        dir: dir.to_path_buf(),
    };
    if rel.is_absolute() {
        return Err(outside());
    }
    let real_dir = dir.canonicalize().map_err(io_err(dir))?;
    let real = joined.canonicalize().map_err(io_err(&joined))?;
    if real.starts_with(&real_dir) && real != real_dir {
        Ok(real)
    } else {
        Err(outside())
    }
}

/// True when `a` and `b` name the same existing file or folder (same device and inode on Unix,
/// the same real path elsewhere). False when either does not exist.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (a.canonicalize(), b.canonicalize()) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_out_of_the_folder_are_refused() {
        let root = tempfile::tempdir().expect("tempdir");
        let ds = root.path().join("ds");
        std::fs::create_dir(&ds).expect("mkdir");
        std::fs::write(ds.join("m1.csv"), "x").expect("write");
        std::fs::write(root.path().join("secret"), "root:x:0:0").expect("write");
        assert!(resolve_inside(&ds, Path::new("m1.csv")).is_ok());
        let e = resolve_inside(&ds, Path::new("../secret")).expect_err("dotdot");
        assert!(matches!(e, FileError::Outside { .. }));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(root.path().join("secret"), ds.join("link.csv"))
                .expect("symlink");
            let e = resolve_inside(&ds, Path::new("link.csv")).expect_err("link");
            let s = e.to_string();
            assert!(s.contains("link.csv") && s.contains("outside"), "{s}");
            assert!(!s.contains("root:x"), "{s}");
            // A link that stays inside is fine.
            std::os::unix::fs::symlink(ds.join("m1.csv"), ds.join("alias.csv")).expect("symlink");
            assert!(resolve_inside(&ds, Path::new("alias.csv")).is_ok());
        }
        // The folder itself is not a file inside it.
        assert!(resolve_inside(&ds, Path::new(".")).is_err());
    }

    #[test]
    fn same_file_sees_through_names() {
        let root = tempfile::tempdir().expect("tempdir");
        let a = root.path().join("a");
        std::fs::write(&a, "x").expect("write");
        assert!(same_file(&a, &root.path().join(".").join("a")));
        assert!(!same_file(&a, &root.path().join("b")));
    }
}

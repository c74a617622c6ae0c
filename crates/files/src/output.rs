//! Output files and dataset folders.

use crate::error::{io_err, FileError};
use crate::inputs::same_file;
use crate::stale::{clean_stale, staging_path};
use std::io::Write;
use std::path::{Path, PathBuf};

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// What is at `path` when it is not a regular file (`None` when it is one or does not exist).
fn non_regular_kind(path: &Path) -> Result<Option<&'static str>, FileError> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(FileError::Io {
            path: path.to_path_buf(),
            source: e,
        }),
        Ok(m) => {
            let t = m.file_type();
            Ok(if t.is_symlink() {
                Some("a symbolic link")
            } else if t.is_dir() {
                Some("a folder")
            } else if !t.is_file() {
                Some("a device node, pipe or socket")
            } else {
                None
            })
        }
    }
}

/// Checks that `path` can receive an output file: its folder exists, nothing but a regular file
/// is there, and it is none of `inputs` (compared as files, so another name of an input is caught).
/// Call it before computing, so that a run fails before it writes anything.
pub fn check_output_file(path: &Path, inputs: &[&Path]) -> Result<(), FileError> {
    let parent = parent_of(path);
    if !parent.is_dir() {
        return Err(FileError::NoFolder {
            path: path.to_path_buf(),
            parent,
        });
    }
    if let Some(kind) = non_regular_kind(path)? {
        return Err(FileError::NotRegular {
            path: path.to_path_buf(),
            kind,
        });
    }
    if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
        return Err(FileError::IsInput {
            path: path.to_path_buf(),
            input: input.to_path_buf(),
        });
    }
    Ok(())
}

/// Writes `bytes` to the regular file `path`, atomically: a staging file in the same folder,
/// renamed over the target once fully written, so an interrupted run never leaves a partial
/// file. Refuses what [`check_output_file`] refuses. A new file gets `0o666` less the umask; a
/// replaced file keeps its mode. Stale staging of killed runs in that folder is removed first.
pub fn write_file(path: &Path, bytes: &[u8], inputs: &[&Path]) -> Result<(), FileError> {
    check_output_file(path, inputs)?;
    let dir = parent_of(path);
    clean_stale(&dir);
    let staging = staging_path(&dir);
    let result = (|| {
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&staging)
            .map_err(io_err(&staging))?;
        f.write_all(bytes)
            .and_then(|()| f.flush())
            .map_err(io_err(path))?;
        if let Ok(m) = std::fs::metadata(path) {
            std::fs::set_permissions(&staging, m.permissions()).map_err(io_err(path))?;
        }
        drop(f);
        std::fs::rename(&staging, path).map_err(io_err(path))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&staging);
    }
    result
}

/// How [`replace_dir`] may treat an existing folder.
#[derive(Debug, Clone, Copy, Default)]
pub struct DirWrite<'a> {
    /// Replace a non-empty folder even when it is not a harmonid dataset (`--force`).
    pub force: bool,
    /// The run's inputs: a folder holding one of them is never replaced, even with `force`.
    pub inputs: &'a [&'a Path],
}

/// True when folder `dir` holds a harmonid dataset and nothing else: a `dataset.toml` whose
/// `format` is `harmonid-dataset/…`, plus only `truth.toml` and `*.csv` files (in subfolders
/// too). `Err` carries why not, e.g. "it holds thesis.tex" (for messages).
pub fn is_dataset_dir(dir: &Path) -> Result<(), String> {
    let Ok(manifest) = std::fs::read_to_string(dir.join("dataset.toml")) else {
        let names: Vec<String> = std::fs::read_dir(dir)
            .map(|rd| {
                rd.flatten()
                    .take(3)
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        return Err(format!(
            "it has no dataset.toml; it holds {}{}",
            names.join(", "),
            if names.len() == 3 { ", ..." } else { "" }
        ));
    };
    let declared = manifest.lines().any(|l| {
        let l = l.trim();
        l.starts_with("format") && l.contains("\"harmonid-dataset/")
    });
    if !declared {
        return Err("its dataset.toml does not declare format = \"harmonid-dataset/1\"".into());
    }
    fn scan(dir: &Path, top: bool, budget: &mut usize) -> Result<(), String> {
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries {
            let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
            *budget = budget.saturating_sub(1);
            if *budget == 0 {
                return Err("it holds too many files".into());
            }
            let name = entry.file_name();
            let name_s = name.to_string_lossy();
            let t = entry
                .file_type()
                .map_err(|e| format!("{}: {e}", entry.path().display()))?;
            let ok = if t.is_dir() {
                scan(&entry.path(), false, budget).is_ok()
            } else {
                t.is_file()
                    && (name_s.ends_with(".csv")
                        || (top && (name_s == "dataset.toml" || name_s == "truth.toml")))
            };
            if !ok {
                return Err(format!("it holds {name_s}, which is not part of a dataset"));
            }
        }
        Ok(())
    }
    scan(dir, true, &mut 100_000)
}

/// Checks that `dir` can be replaced by a dataset folder: nothing but a folder is there, it is
/// empty or a harmonid dataset (or `opts.force`), and it holds none of `opts.inputs`.
/// Call it before computing, so that a run fails before it writes anything.
pub fn check_output_dir(dir: &Path, opts: DirWrite<'_>) -> Result<(), FileError> {
    match non_regular_kind(dir)? {
        None if dir.exists() => {
            return Err(FileError::NotAFolder {
                path: dir.to_path_buf(),
                kind: "a file, not a folder",
            })
        }
        Some(kind) if kind != "a folder" => {
            return Err(FileError::NotAFolder {
                path: dir.to_path_buf(),
                kind,
            })
        }
        _ => {}
    }
    if !dir.exists() {
        return Ok(());
    }
    let real = dir.canonicalize().map_err(io_err(dir))?;
    for input in opts.inputs {
        if let Ok(ri) = input.canonicalize() {
            if ri.starts_with(&real) {
                return Err(FileError::IsInput {
                    path: dir.to_path_buf(),
                    input: input.to_path_buf(),
                });
            }
        }
    }
    let empty = std::fs::read_dir(dir)
        .map_err(io_err(dir))?
        .next()
        .is_none();
    if !empty {
        if let Err(reason) = is_dataset_dir(dir) {
            if !opts.force {
                return Err(FileError::NotADataset {
                    path: dir.to_path_buf(),
                    reason,
                });
            }
            if let Some(file) = work_file(dir) {
                return Err(FileError::HoldsWork {
                    path: dir.to_path_buf(),
                    file,
                });
            }
        }
    }
    Ok(())
}

/// The first file under `dir` (symbolic links not followed; at most 100,000 entries looked
/// at, and a folder too large to look through counts as holding work) that harmonid reads as
/// someone's work: a model (`.hb`), values, plan or mapping (`.toml`, other than a dataset's
/// own `dataset.toml` and `truth.toml` at the top beside a `dataset.toml`) or a result
/// (`.json`).
fn work_file(dir: &Path) -> Option<PathBuf> {
    fn scan(dir: &Path, top: bool, budget: &mut usize) -> Option<PathBuf> {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Some(dir.to_path_buf());
        };
        for entry in entries.flatten() {
            *budget = budget.saturating_sub(1);
            let path = entry.path();
            if *budget == 0 {
                return Some(path);
            }
            let Ok(t) = entry.file_type() else {
                return Some(path);
            };
            let name = entry.file_name().to_string_lossy().to_lowercase();
            if t.is_dir() {
                if let Some(found) = scan(&path, false, budget) {
                    return Some(found);
                }
                continue;
            }
            // A dataset's own manifest and truth (with its manifest beside them).
            let own = top
                && (name == "dataset.toml" || name == "truth.toml")
                && dir.join("dataset.toml").is_file();
            let work = [".hb", ".toml", ".json"].iter().any(|e| name.ends_with(e));
            if work && !own {
                return Some(path);
            }
        }
        None
    }
    scan(dir, true, &mut 100_000)
}

/// Writes folder `dir` atomically: checks it with [`check_output_dir`], creates a staging
/// folder beside it (mode `0o777` less the umask; its parents are created), lets `fill` write
/// the content into it, then swaps it in place of the old folder, which is deleted. On any
/// error the old folder is left as it was and the staging folder is removed.
pub fn replace_dir<E: From<FileError>>(
    dir: &Path,
    opts: DirWrite<'_>,
    fill: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    check_output_dir(dir, opts)?;
    let parent = parent_of(dir);
    std::fs::create_dir_all(&parent).map_err(io_err(&parent))?;
    clean_stale(&parent);
    let staging = staging_path(&parent);
    std::fs::create_dir(&staging).map_err(io_err(&staging))?;
    if let Err(e) = fill(&staging) {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    let old = if dir.exists() {
        let old = staging_path(&parent);
        if let Err(e) = std::fs::rename(dir, &old) {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(FileError::Io {
                path: dir.to_path_buf(),
                source: e,
            }
            .into());
        }
        Some(old)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&staging, dir) {
        if let Some(old) = &old {
            let _ = std::fs::rename(old, dir);
        }
        let _ = std::fs::remove_dir_all(&staging);
        return Err(FileError::Io {
            path: dir.to_path_buf(),
            source: e,
        }
        .into());
    }
    if let Some(old) = old {
        let _ = std::fs::remove_dir_all(old);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(p: &Path) -> u32 {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::metadata(p).expect("metadata").permissions().mode() & 0o777
        }
        #[cfg(not(unix))]
        {
            let _ = p;
            0o644
        }
    }

    #[test]
    fn writes_regular_files_with_the_umask_mode() {
        let root = tempfile::tempdir().expect("tempdir");
        let out = root.path().join("r.json");
        write_file(&out, b"1", &[]).expect("write");
        // Whatever the umask, a plain file created by the process has the same mode.
        let probe = root.path().join("probe");
        std::fs::write(&probe, "x").expect("probe");
        assert_eq!(mode(&out), mode(&probe));
        assert_ne!(mode(&out), 0o600, "not the temporary file's private mode");
        write_file(&out, b"22", &[]).expect("rewrite");
        assert_eq!(std::fs::read(&out).expect("read"), b"22");
        let names: Vec<_> = std::fs::read_dir(root.path())
            .expect("read_dir")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names.len(), 2, "no staging left: {names:?}");
    }

    #[test]
    fn refuses_what_is_not_a_regular_file() {
        let root = tempfile::tempdir().expect("tempdir");
        let d = root.path();
        let e = write_file(d, b"x", &[]).expect_err("folder");
        assert!(e.to_string().contains("is a folder"), "{e}");
        let e = write_file(&d.join("missing/r.json"), b"x", &[]).expect_err("no folder");
        assert!(e.to_string().contains("does not exist"), "{e}");
        #[cfg(unix)]
        {
            let target = d.join("target.txt");
            std::fs::write(&target, "keep").expect("write");
            std::os::unix::fs::symlink(&target, d.join("link.json")).expect("symlink");
            let e = write_file(&d.join("link.json"), b"x", &[]).expect_err("link");
            assert!(e.to_string().contains("symbolic link"), "{e}");
            assert_eq!(std::fs::read(&target).expect("read"), b"keep");
            if Path::new("/dev/null").exists() {
                let e = check_output_file(Path::new("/dev/null"), &[]).expect_err("device");
                assert!(e.to_string().contains("device node"), "{e}");
            }
        }
    }

    #[test]
    fn never_overwrites_an_input() {
        let root = tempfile::tempdir().expect("tempdir");
        let model = root.path().join("model.hb");
        std::fs::write(&model, "mode q1").expect("write");
        let other_name = root.path().join(".").join("model.hb");
        let e = write_file(&other_name, b"{}", &[&model]).expect_err("input");
        assert!(matches!(e, FileError::IsInput { .. }), "{e}");
        assert_eq!(std::fs::read(&model).expect("read"), b"mode q1");
    }

    #[test]
    fn replaces_datasets_but_not_other_folders() {
        let root = tempfile::tempdir().expect("tempdir");
        let fill = |d: &Path| -> Result<(), FileError> {
            std::fs::write(d.join("dataset.toml"), "format = \"harmonid-dataset/1\"\n")
                .map_err(io_err(d))
        };
        let ds = root.path().join("ds");
        replace_dir(&ds, DirWrite::default(), fill).expect("new");
        replace_dir(&ds, DirWrite::default(), fill).expect("replace a dataset");
        let probe = root.path().join("probe");
        std::fs::create_dir(&probe).expect("probe");
        assert_eq!(
            mode(&ds),
            mode(&probe),
            "the umask's mode, not a staging folder's 0700"
        );
        std::fs::remove_dir(&probe).expect("rm probe");

        let thesis = root.path().join("thesis");
        std::fs::create_dir(&thesis).expect("mkdir");
        std::fs::write(thesis.join("thesis.tex"), "years of work").expect("write");
        let e = replace_dir(&thesis, DirWrite::default(), fill).expect_err("not a dataset");
        let s = e.to_string();
        assert!(
            s.contains("not a harmonid dataset") && s.contains("thesis.tex"),
            "{s}"
        );
        assert!(thesis.join("thesis.tex").exists());

        // A dataset with a foreign file is not replaced either.
        std::fs::write(ds.join("notes.txt"), "mine").expect("write");
        assert!(replace_dir(&ds, DirWrite::default(), fill).is_err());

        // The folder holding the run's inputs is never replaced, even with force.
        let model = thesis.join("thesis.tex");
        let inputs = [model.as_path()];
        let opts = DirWrite {
            force: true,
            inputs: &inputs,
        };
        let e = replace_dir(&thesis, opts, fill).expect_err("input inside");
        assert!(matches!(e, FileError::IsInput { .. }), "{e}");
        let opts = DirWrite {
            force: true,
            inputs: &[],
        };
        replace_dir(&thesis, opts, fill).expect("forced");
        assert!(!thesis.join("thesis.tex").exists());

        // Even forced, a folder holding a model, values, plan or result is never replaced.
        for work in [
            "model.hb",
            "values.toml",
            "sub/plan.TOML",
            "r.json",
            "truth.toml",
        ] {
            let folder = root.path().join("work");
            let file = folder.join(work);
            std::fs::create_dir_all(file.parent().expect("parent")).expect("mkdir");
            std::fs::write(folder.join("notes.txt"), "mine").expect("write");
            std::fs::write(&file, "mine").expect("write");
            let e = replace_dir(&folder, opts, fill).expect_err(work);
            assert!(
                matches!(&e, FileError::HoldsWork { file: f, .. } if f == &file),
                "{work}: {e}"
            );
            assert!(e.to_string().contains("even with --force"), "{e}");
            assert!(file.exists(), "{work}");
            std::fs::remove_dir_all(&folder).expect("clean");
        }

        // A failing fill leaves the old folder and no staging behind.
        let before: Vec<_> = std::fs::read_dir(root.path()).expect("ls").collect();
        let r = replace_dir(
            &ds,
            DirWrite {
                force: true,
                inputs: &[],
            },
            |_| {
                Err(FileError::NotADataset {
                    path: PathBuf::new(),
                    reason: "test".into(),
                })
            },
        );
        assert!(r.is_err());
        let after: Vec<_> = std::fs::read_dir(root.path()).expect("ls").collect();
        assert_eq!(before.len(), after.len());
    }
}

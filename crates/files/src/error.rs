//! The errors of this crate: each names the path and says what to do.

use std::path::PathBuf;

/// Why an output could not be written or an input path was refused.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum FileError {
    /// An operating-system error on `path`.
    #[error("{path}: {source}", path = path.display())]
    #[diagnostic(code(harmonid::files::io))]
    Io {
        /// File or folder concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The output path exists and is not a regular file (a link, a folder, a device node, ...).
    #[error("{path} is {kind}; harmonid writes only regular files and does not replace or follow it", path = path.display())]
    #[diagnostic(
        code(harmonid::files::not_regular),
        help("give the path of a new or existing regular file")
    )]
    NotRegular {
        /// The output path.
        path: PathBuf,
        /// What it is ("a symbolic link", "a folder", "a device node, pipe or socket").
        kind: &'static str,
    },
    /// An output folder's path exists and is not a plain folder (a file, a link, ...).
    #[error("{path} is {kind}; an output folder must be a new folder or an existing plain folder", path = path.display())]
    #[diagnostic(
        code(harmonid::files::not_a_folder),
        help("give the path of a new folder (it is created), or of a folder the command wrote before")
    )]
    NotAFolder {
        /// The output folder's path.
        path: PathBuf,
        /// What it is ("a file, not a folder", "a symbolic link", ...).
        kind: &'static str,
    },
    /// The output folder of a file does not exist.
    #[error("cannot write {path}: the folder {parent} does not exist", path = path.display(), parent = parent.display())]
    #[diagnostic(
        code(harmonid::files::no_folder),
        help("create the folder first (mkdir -p), or write somewhere else")
    )]
    NoFolder {
        /// The output path.
        path: PathBuf,
        /// Its missing folder.
        parent: PathBuf,
    },
    /// The output would overwrite (or a replaced folder holds) an input of the same run.
    #[error("will not write {path}: {input} is an input of this run", path = path.display(), input = input.display())]
    #[diagnostic(
        code(harmonid::files::is_input),
        help("write the output somewhere else; the inputs are never overwritten")
    )]
    IsInput {
        /// The output path.
        path: PathBuf,
        /// The input it would destroy.
        input: PathBuf,
    },
    /// The output folder exists, is not empty and is not a harmonid dataset.
    #[error("will not replace {path}: it is not empty and not a harmonid dataset ({reason})", path = path.display())]
    #[diagnostic(
        code(harmonid::files::not_a_dataset),
        help("choose a new or empty folder, or pass --force to replace the folder and everything in it")
    )]
    NotADataset {
        /// The output folder.
        path: PathBuf,
        /// What made it not a dataset (e.g. "it holds thesis.tex").
        reason: String,
    },
    /// The output folder holds a model, values, plan or result file: never replaced, even
    /// with `--force` (that is someone's work, not a dataset harmonid wrote).
    #[error("will not replace {path}, even with --force: it holds {file}, a harmonid model, values, plan or result file, not part of a dataset", path = path.display(), file = file.display())]
    #[diagnostic(
        code(harmonid::files::holds_work),
        help(
            "write the dataset to a new or empty folder, or move that file out of the folder first"
        )
    )]
    HoldsWork {
        /// The output folder.
        path: PathBuf,
        /// The file found in it.
        file: PathBuf,
    },
    /// A path of an input leads outside the folder it must stay in.
    #[error("{path} leads outside {dir} (through `..` or a symbolic link); it is not read", path = path.display(), dir = dir.display())]
    #[diagnostic(
        code(harmonid::files::outside),
        help(
            "keep the dataset's files inside its folder; copy the file in instead of linking to it"
        )
    )]
    Outside {
        /// The path as given (folder joined with the relative path).
        path: PathBuf,
        /// The folder it must stay in.
        dir: PathBuf,
    },
}

pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> FileError + '_ {
    move |source| FileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

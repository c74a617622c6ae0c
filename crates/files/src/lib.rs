//! Safe output files and folders for harmonid's commands, and input paths confined to a folder.
//!
//! Every command that writes goes through this crate, so that no run loses a user's file:
//!
//! - [`write_file`] writes a file atomically (a temporary sibling renamed into place), only over a
//!   regular file (a symbolic link, a folder or a device node at the path is refused, not
//!   replaced), never over an input of the same run, with the permissions the umask gives
//!   (`0o666 & !umask`, or the mode of the file it replaces).
//! - [`check_output_file`] and [`check_output_dir`] make the same checks up front, so a command
//!   can refuse before it computes anything (e.g. `--per-shot` into a missing folder).
//! - [`replace_dir`] fills a staging folder and swaps it in for a dataset folder; it refuses a
//!   non-empty folder that is not a harmonid dataset unless forced, and a folder holding an input.
//! - [`clean_stale`] removes staging files and folders of harmonid's own naming left by killed runs
//!   (their process is gone); the writers call it on the folder they write in.
//! - [`QuotedSource`] and [`quote_line`] quote an input file in a message: the lines around the
//!   point, but of a long line (a plan's 2,000 tones) only a window around it; [`number`] quotes
//!   a number (`1e300`, not 301 digits).
//! - [`resolve_inside`] resolves a path given relative to a folder (symbolic links included) and
//!   refuses anything that lands outside it.
//!
//! ```
//! let dir = tempfile::tempdir()?;
//! let out = dir.path().join("result.json");
//! let input = dir.path().join("model.hb");
//! std::fs::write(&input, "mode q1 at 1 kHz\n")?;
//! harmonid_files::write_file(&out, b"{}", &[input.as_path()])?;
//! assert_eq!(std::fs::read(&out)?, b"{}");
//! // The run's own input is never overwritten.
//! let err = harmonid_files::write_file(&input, b"{}", &[input.as_path()]).unwrap_err();
//! assert!(err.to_string().contains("is an input of this run"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod error;
mod excerpt;
mod inputs;
mod number;
mod output;
mod stale;

pub use error::FileError;
pub use excerpt::{quote_line, QuotedSource, QUOTE_CONTEXT, QUOTE_LINE, QUOTE_SPAN};
pub use inputs::{resolve_inside, same_file};
pub use number::number;
pub use output::{
    check_output_dir, check_output_file, is_dataset_dir, replace_dir, write_file, DirWrite,
};
pub use stale::{clean_stale, STAGING_PREFIX};

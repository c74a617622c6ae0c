//! Progress on stderr for the commands that can take over a second (sweeps, noise studies,
//! time-domain simulation, planning, identification of many shots). indicatif lives in the
//! binary only: the library crates report progress, where they do, through a plain callback
//! (e.g. `harmonid_plan::design_with_progress`). Every bar draws nothing when stderr is not a
//! terminal (pipes, files, CI logs), so the output of tests and scripts is unchanged.

use indicatif::{ProgressBar, ProgressStyle};
use std::time::Duration;

/// A spinner with `what` and the elapsed time, ticking on its own while a computation without
/// steps of its own runs. Call `finish_and_clear` when done.
pub fn spinner(what: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// A bar of `len` steps named `what` (hidden when `quiet`), with the elapsed time and an
/// estimate of the time left.
pub fn bar(len: u64, what: &str, quiet: bool) -> ProgressBar {
    let pb = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    pb.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {what} {{pos}}/{{len}} {{wide_bar}} {{elapsed}} (eta {{eta}}) {{msg}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

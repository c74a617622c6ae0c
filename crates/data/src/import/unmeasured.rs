//! Rows where nothing was measured: every measured value NaN ([`Record::unmeasured`]). A LabOne
//! sweeper stopped before its end writes its whole grid, the points it never reached as NaN;
//! refusing the file would refuse every point it did measure.
//!
//! Such rows at the end of a sweep (after its last measured row; a sweep with none is never
//! measured) are dropped, one warning line per run naming the file, the sweep and the rows. A
//! run inside a sweep (measured rows before and after it in the same sweep, or before its first
//! measured row) is a gap in the data: refused with its row, unless
//! [`Grouping::drop_nan_rows`] asks to drop those too (again with a warning). Nothing NaN
//! reaches a dataset: a row with only some values NaN is refused by `check_record`.

use super::{base_name, input_path, Grouping, ImportError, Record};
use std::path::PathBuf;

/// The unmeasured records held until the next measured one says where they sit, and the
/// warnings on those dropped.
#[derive(Default)]
pub(super) struct Gaps {
    held: Vec<Record>,
    /// One line per run of rows dropped (file, sweep, rows).
    pub warnings: Vec<String>,
    /// Rows dropped, counted in each run's first file.
    pub dropped: usize,
}

/// Where a run of unmeasured rows sits in its sweep.
#[derive(Clone, Copy, PartialEq)]
enum Place {
    /// After the sweep's last measured row: not measured yet.
    End,
    /// In a sweep with no measured row at all.
    Never,
    /// Between measured rows of the sweep.
    Inside,
    /// Before the sweep's first measured row.
    Before,
}

/// Whether `a` and `b` belong to one sweep: one group (any, when the groups are passes of
/// [`Grouping::one_sweep`]), and one drive level when `grouping` cuts by level (a NaN level, as
/// an unmeasured row may have, matches any).
fn same_sweep(a: &Record, b: &Record, grouping: &Grouping) -> bool {
    if grouping.one_sweep {
        return true;
    }
    let level = match (a.level, b.level) {
        (Some(x), Some(y)) => x.to_bits() == y.to_bits() || x.is_nan() || y.is_nan(),
        _ => true,
    };
    a.group == b.group && (!grouping.split_on_level || level)
}

impl Gaps {
    /// Holds the unmeasured record `r` until [`Gaps::settle`] knows where it sits.
    pub fn hold(&mut self, r: Record) {
        self.held.push(r);
    }

    /// Drops (with a warning) or refuses the held records, which sit between the measured
    /// records `prev` and `next` (`None`: the input's start or end).
    pub fn settle(
        &mut self,
        prev: Option<&Record>,
        next: Option<&Record>,
        grouping: &Grouping,
        inputs: &[PathBuf],
    ) -> Result<(), ImportError> {
        let held = std::mem::take(&mut self.held);
        let mut from = 0;
        while from < held.len() {
            let first = &held[from];
            let n = held[from..]
                .iter()
                .take_while(|r| same_sweep(r, first, grouping))
                .count();
            let chunk = &held[from..from + n];
            from += n;
            let in_prev = prev.filter(|q| same_sweep(first, q, grouping));
            let in_next = next.filter(|q| same_sweep(first, q, grouping));
            let (place, named) = match (in_prev, in_next) {
                (Some(q), None) => (Place::End, q),
                (None, None) => (Place::Never, first),
                (Some(q), Some(_)) => (Place::Inside, q),
                (None, Some(q)) => (Place::Before, q),
            };
            let name = base_name(named.group, named.level, grouping);
            self.run(chunk, place, &name, grouping, inputs)?;
        }
        Ok(())
    }

    /// The warning on the run `chunk` of sweep `name` at `place`, or its refusal.
    fn run(
        &mut self,
        chunk: &[Record],
        place: Place,
        name: &str,
        grouping: &Grouping,
        inputs: &[PathBuf],
    ) -> Result<(), ImportError> {
        let file = chunk[0].origin.0;
        let mut rows: Vec<usize> = chunk
            .iter()
            .filter(|r| r.origin.0 == file)
            .map(|r| r.origin.1)
            .collect();
        rows.dedup();
        let n = rows.len();
        let (a, b) = (rows[0], rows[n - 1]);
        let span = if n == 1 {
            format!("1 row (row {a})")
        } else {
            format!("{n} rows (rows {a} to {b})")
        };
        let mut others: Vec<usize> = chunk
            .iter()
            .map(|r| r.origin.0)
            .filter(|&f| f != file)
            .collect();
        others.sort_unstable();
        others.dedup();
        let also = match others.len() {
            0 => String::new(),
            k => format!(
                " (and the same points of {k} other input{})",
                if k == 1 { "" } else { "s" }
            ),
        };
        let path = input_path(inputs, chunk[0].origin).display().to_string();
        let where_ = match place {
            Place::End if grouping.one_sweep => {
                format!("at the end of the sweep (it stopped in \"{name}\")")
            }
            Place::End => format!("at the end of sweep \"{name}\""),
            Place::Never => format!("in sweep \"{name}\", which has no measured row"),
            Place::Inside => format!("inside sweep \"{name}\" (measured rows before and after)"),
            Place::Before => format!("before the first measured row of sweep \"{name}\""),
        };
        let inner = matches!(place, Place::Inside | Place::Before);
        if inner && !grouping.drop_nan_rows {
            return Err(ImportError::Input {
                path: input_path(inputs, chunk[0].origin),
                row: Some(a),
                message: format!(
                    "{span}{also} {where_} measured nothing (every value NaN): a gap in the data is refused. Remove the rows, or drop every row with every value NaN with --drop-nan-rows (mapping: drop_nan_rows = true; Python: drop_nan_rows=True)"
                ),
            });
        }
        let what = match place {
            Place::End => "not measured (every value NaN: a sweep stopped early): dropped",
            Place::Never => "not measured (every value NaN): dropped, the sweep left out",
            _ => "not measured (every value NaN): dropped, as --drop-nan-rows asks",
        };
        self.warnings
            .push(format!("{path}: {span}{also} {where_} {what}"));
        self.dropped += n;
        Ok(())
    }
}

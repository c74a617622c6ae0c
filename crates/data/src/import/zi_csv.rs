//! `harmonid import zi-csv`: Zurich Instruments LabOne demodulator CSV exports
//! (`dev…_demods_N_sample_00000.csv`, `;`-separated, header
//! `chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1`), one file per demodulator.
//!
//! The first file's demodulator is the drive (its `freq` is the step's drive tone); every
//! file is one measured line. Rows of the files are samples taken together: the same
//! timestamps, row by row. Timestamps are device ticks: `--clockbase-hz` (60 MHz on the MFLI,
//! 1.8 GHz on the UHFLI) turns them into seconds; a timestamp that goes backwards is sample
//! loss or a mixed file, and refused.

use super::{
    build, check_clockbase, for_each_line, record_instrument, Conventions, Grouping, ImportError,
    Record, Settle,
};
use crate::dataset::Dataset;
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// What the demodulator files do not say.
#[derive(Debug, Clone)]
pub struct Options {
    /// Device ticks per second (the node `/devN/system/properties/timebase` inverted).
    pub clockbase_hz: f64,
    /// The drive level of every sample, if known (V or the instrument's unit).
    pub drive_level: Option<f64>,
    /// The drive phase, rad, if known.
    pub drive_phase_rad: Option<f64>,
}

/// One demodulator file's columns.
struct Demod {
    timestamp: Vec<u64>,
    z: Vec<Complex64>,
    freq: Vec<f64>,
}

fn read_demod(path: &Path) -> Result<Demod, ImportError> {
    let bad = |row: Option<usize>, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row,
        message,
    };
    let mut d = Demod {
        timestamp: Vec::new(),
        z: Vec::new(),
        freq: Vec::new(),
    };
    // Column indices of timestamp, x, y, freq, once the header is read.
    let mut cols: Option<[usize; 4]> = None;
    const NAMES: [&str; 4] = ["timestamp", "x", "y", "freq"];
    for_each_line(path, |row, line| {
        let Some(cols) = cols else {
            let header: Vec<&str> = line.split(';').map(str::trim).collect();
            let mut found = [0; 4];
            for (c, name) in found.iter_mut().zip(NAMES) {
                *c = header.iter().position(|h| *h == name).ok_or_else(|| {
                    bad(
                        Some(1),
                        format!(
                            "no column \"{name}\" (found: {}); a LabOne demodulator CSV has chunk;timestamp;x;y;freq;...",
                            crate::text::header_names(header.iter().copied())
                        ),
                    )
                })?;
            }
            cols = Some(found);
            return Ok(());
        };
        if line.trim().is_empty() {
            return Ok(());
        }
        let mut fields: [Option<&str>; 4] = [None; 4];
        for (i, field) in line.split(';').enumerate() {
            for (k, &c) in cols.iter().enumerate() {
                if c == i {
                    fields[k] = Some(field.trim());
                }
            }
        }
        let field = |k: usize| {
            fields[k].ok_or_else(|| {
                bad(
                    Some(row),
                    format!("no value in column \"{}\" (a truncated row?)", NAMES[k]),
                )
            })
        };
        let num = |k: usize| -> Result<f64, ImportError> {
            let t = field(k)?;
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        Some(row),
                        format!("column \"{}\": \"{t}\" is not a finite number", NAMES[k]),
                    )
                })
        };
        let t = field(0)?;
        let ts: u64 = t.parse().map_err(|_| {
            bad(
                Some(row),
                format!("column \"timestamp\": \"{t}\" is not a tick count"),
            )
        })?;
        if let Some(&prev) = d.timestamp.last() {
            if ts <= prev {
                return Err(bad(
                    Some(row),
                    format!("timestamp {ts} does not follow {prev}: samples lost or files mixed; export one continuous record per file"),
                ));
            }
        }
        d.timestamp.push(ts);
        d.z.push(Complex64::new(num(1)?, num(2)?));
        d.freq.push(num(3)?);
        Ok(())
    })?;
    if cols.is_none() {
        return Err(bad(None, "the file is empty".into()));
    }
    Ok(d)
}

/// Imports the demodulator files `inputs` (the drive's first) into a dataset named `out`.
pub fn import(
    inputs: &[PathBuf],
    conv: &Conventions,
    settle: Settle,
    opts: &Options,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    check_clockbase(opts.clockbase_hz)?;
    let demods: Vec<Demod> = inputs
        .iter()
        .map(|p| read_demod(p))
        .collect::<Result<_, _>>()?;
    let drive = &demods[0];
    for (k, d) in demods.iter().enumerate().skip(1) {
        if d.timestamp != drive.timestamp {
            let row = d
                .timestamp
                .iter()
                .zip(&drive.timestamp)
                .position(|(a, b)| a != b)
                .unwrap_or(d.timestamp.len().min(drive.timestamp.len()));
            return Err(ImportError::Input {
                path: inputs[k].clone(),
                row: Some(row + 2),
                message: format!(
                    "its samples are not those of {} (timestamps differ from row {}, or the files have {} and {} rows); export the demodulators together",
                    inputs[0].display(),
                    row + 2,
                    d.timestamp.len(),
                    drive.timestamp.len()
                ),
            });
        }
    }
    let records = (0..drive.timestamp.len()).flat_map(|i| {
        demods.iter().enumerate().map(move |(k, d)| Record {
            drive: drive.freq[i],
            line: d.freq[i],
            z: d.z[i],
            level: opts.drive_level,
            drive_phase_rad: opts
                .drive_level
                .map(|_| opts.drive_phase_rad.unwrap_or(0.0)),
            group: 0,
            step: None,
            time_s: Some(d.timestamp[i] as f64 / opts.clockbase_hz),
            origin: (k, i + 2),
            noise: None,
            unmeasured: false,
        })
    });
    let grouping = Grouping {
        group_names: vec!["sweep".into()],
        split_on_level: false,
        sources: Vec::new(),
        drop_nan_rows: false,
        passes_need_level: false,
        one_sweep: false,
    };
    let (mut ds, note) = build("zi-csv", inputs, records, conv, settle, &grouping, out)?;
    record_instrument(
        &mut ds,
        &[("clockbase_hz", format!("{}", opts.clockbase_hz))],
    );
    Ok((ds, note))
}

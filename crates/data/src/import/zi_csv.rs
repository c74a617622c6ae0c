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
    build, read_input, record_instrument, Conventions, Grouping, ImportError, Record, Settle,
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
    let text = read_input(path)?;
    let bad = |row: Option<usize>, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row,
        message,
    };
    let mut lines = text.lines().enumerate();
    let (_, header) = lines
        .next()
        .ok_or_else(|| bad(None, "the file is empty".into()))?;
    let header: Vec<&str> = header.split(';').map(str::trim).collect();
    let col = |name: &str| {
        header.iter().position(|h| *h == name).ok_or_else(|| {
            bad(
                Some(1),
                format!(
                    "no column \"{name}\" (found: {}); a LabOne demodulator CSV has chunk;timestamp;x;y;freq;...",
                    header.join(";")
                ),
            )
        })
    };
    let (ct, cx, cy, cf) = (col("timestamp")?, col("x")?, col("y")?, col("freq")?);
    let mut d = Demod {
        timestamp: Vec::new(),
        z: Vec::new(),
        freq: Vec::new(),
    };
    for (n, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let row = n + 1;
        let fields: Vec<&str> = line.split(';').map(str::trim).collect();
        let field = |c: usize, name: &str| {
            fields.get(c).copied().ok_or_else(|| {
                bad(
                    Some(row),
                    format!("no value in column \"{name}\" (a truncated row?)"),
                )
            })
        };
        let num = |c: usize, name: &str| -> Result<f64, ImportError> {
            let t = field(c, name)?;
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        Some(row),
                        format!("column \"{name}\": \"{t}\" is not a finite number"),
                    )
                })
        };
        let t = field(ct, "timestamp")?;
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
        d.z.push(Complex64::new(num(cx, "x")?, num(cy, "y")?));
        d.freq.push(num(cf, "freq")?);
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
    if !(opts.clockbase_hz.is_finite() && opts.clockbase_hz > 0.0) {
        return Err(ImportError::Convention {
            origin: "--clockbase-hz".into(),
            message: "the device's clock base is needed to turn ticks into seconds (60e6 on the MFLI, 1.8e9 on the UHFLI)".into(),
        });
    }
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
    let mut records = Vec::with_capacity(demods.len() * drive.timestamp.len());
    for i in 0..drive.timestamp.len() {
        for (k, d) in demods.iter().enumerate() {
            records.push(Record {
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
            });
        }
    }
    let grouping = Grouping {
        group_names: vec!["sweep".into()],
        split_on_level: false,
    };
    let (mut ds, note) = build("zi-csv", inputs, &records, conv, settle, &grouping, out)?;
    record_instrument(
        &mut ds,
        &[("clockbase_hz", format!("{}", opts.clockbase_hz))],
    );
    Ok((ds, note))
}

//! `harmonid import zi-hdf5`: Zurich Instruments LabOne HDF5 records (the UI's record or
//! stream save, `.h5`), read by the pure-Rust `hdf5-pure` (no C library to install).
//!
//! Layout (seen in user code; no vendor page describes it): one group per saved record at the
//! root (`000`, `001`, …), then the node path, `000/dev4434/demods/0/sample/{x, y, frequency,
//! timestamp}`. Each record is one sweep; each demodulator one measured line, the first listed
//! (`--demods`, default every one in the record, in number order) the drive. Timestamps are
//! device ticks: `--clockbase-hz` turns them into seconds; a timestamp that goes backwards is
//! sample loss and refused.

use super::{
    build, check_clockbase, record_instrument, Conventions, Grouping, ImportError, Record, Settle,
};
use crate::dataset::Dataset;
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// What the file does not say.
#[derive(Debug, Clone)]
pub struct Options {
    /// Device ticks per second (60e6 on the MFLI, 1.8e9 on the UHFLI).
    pub clockbase_hz: f64,
    /// The demodulators to read, the drive's first; empty: every one in each record, in
    /// number order.
    pub demods: Vec<usize>,
    /// The drive level of every sample, if known.
    pub drive_level: Option<f64>,
}

/// One demodulator's samples.
struct Demod {
    timestamp: Vec<u64>,
    x: Vec<f64>,
    y: Vec<f64>,
    frequency: Vec<f64>,
}

/// Imports the records of the LabOne HDF5 file(s) `inputs` into a dataset named `out`.
pub fn import(
    inputs: &[PathBuf],
    conv: &Conventions,
    settle: Settle,
    opts: &Options,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    check_clockbase(opts.clockbase_hz)?;
    // Per record: its input file and demodulators (the drive's first).
    let mut parts: Vec<(usize, Vec<Demod>)> = Vec::new();
    let mut names = Vec::new();
    for (fi, path) in inputs.iter().enumerate() {
        let bad = |message: String| ImportError::Input {
            path: path.clone(),
            row: None,
            message,
        };
        let h5 = |what: &str, e: hdf5_pure::Error| bad(format!("{what}: {e}"));
        let file = hdf5_pure::File::open(path).map_err(|e| h5("not a readable HDF5 file", e))?;
        let mut recs = file
            .root()
            .groups()
            .map_err(|e| h5("cannot list the records", e))?;
        recs.sort();
        if recs.is_empty() {
            return Err(bad(
                "no record groups (000, 001, …) at the root: is this a LabOne HDF5 save?".into(),
            ));
        }
        for rec in recs {
            let rg = file
                .group(&rec)
                .map_err(|e| h5(&format!("record \"{rec}\""), e))?;
            let devices: Vec<String> = rg
                .groups()
                .map_err(|e| h5(&format!("record \"{rec}\""), e))?
                .into_iter()
                .filter(|g| g.starts_with("dev"))
                .collect();
            let [dev] = devices.as_slice() else {
                return Err(bad(format!(
                    "record \"{rec}\" holds {} device groups ({}); export one device per file",
                    devices.len(),
                    devices.join(", ")
                )));
            };
            let base = format!("{rec}/{dev}/demods");
            let demods: Vec<usize> = if opts.demods.is_empty() {
                let mut d: Vec<usize> = file
                    .group(&base)
                    .and_then(|g| g.groups())
                    .map_err(|e| h5(&format!("\"{base}\""), e))?
                    .iter()
                    .filter_map(|n| n.parse().ok())
                    .collect();
                d.sort_unstable();
                d
            } else {
                opts.demods.clone()
            };
            if demods.is_empty() {
                return Err(bad(format!("\"{base}\" holds no demodulator")));
            }
            let read: Vec<Demod> = demods
                .iter()
                .map(|k| read_demod(&file, &format!("{base}/{k}/sample"), path))
                .collect::<Result<_, _>>()?;
            let drive = &read[0];
            for (k, d) in read.iter().enumerate().skip(1) {
                if d.timestamp != drive.timestamp {
                    return Err(bad(format!(
                        "record \"{rec}\": demodulator {} has other sample times than demodulator {} ({} and {} samples); save the demodulators together",
                        demods[k],
                        demods[0],
                        d.timestamp.len(),
                        drive.timestamp.len()
                    )));
                }
            }
            names.push(format!("{rec}_{dev}"));
            parts.push((fi, read));
        }
    }
    // Every record's samples, one record per line, as `build` consumes them.
    let level = opts.drive_level;
    let clock = opts.clockbase_hz;
    let records = parts.iter().enumerate().flat_map(|(group, (fi, read))| {
        let drive = &read[0];
        (0..drive.timestamp.len()).flat_map(move |i| {
            read.iter().map(move |d| Record {
                drive: drive.frequency[i],
                line: d.frequency[i],
                z: Complex64::new(d.x[i], d.y[i]),
                level,
                drive_phase_rad: level.map(|_| 0.0),
                group,
                step: None,
                time_s: Some(d.timestamp[i] as f64 / clock),
                // No rows in HDF5: the sample index, 1-based.
                origin: (*fi, i + 1),
                noise: None,
                unmeasured: false,
            })
        })
    });
    let grouping = Grouping {
        group_names: names,
        split_on_level: false,
        sources: Vec::new(),
        drop_nan_rows: false,
        passes_need_level: false,
        one_sweep: false,
    };
    let (mut ds, note) = build("zi-hdf5", inputs, records, conv, settle, &grouping, out)?;
    record_instrument(
        &mut ds,
        &[
            ("clockbase_hz", format!("{}", opts.clockbase_hz)),
            (
                "demods",
                if opts.demods.is_empty() {
                    "every one, in number order".into()
                } else {
                    opts.demods
                        .iter()
                        .map(usize::to_string)
                        .collect::<Vec<_>>()
                        .join(",")
                },
            ),
        ],
    );
    Ok((ds, note))
}

/// The samples of the demodulator group `at` (`…/demods/N/sample`), checked: the four
/// datasets as long as each other, finite, timestamps increasing.
fn read_demod(file: &hdf5_pure::File, at: &str, path: &Path) -> Result<Demod, ImportError> {
    let bad = |message: String| ImportError::Input {
        path: path.to_path_buf(),
        row: None,
        message,
    };
    let f64s = |name: &str| -> Result<Vec<f64>, ImportError> {
        let v = file
            .dataset(&format!("{at}/{name}"))
            .and_then(|d| d.read_f64())
            .map_err(|e| {
                bad(format!(
                    "\"{at}/{name}\": {e} (a demodulator's samples need x, y, frequency and timestamp)"
                ))
            })?;
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(bad(format!(
                "\"{at}/{name}\" sample {i} is {}: remove non-finite samples before importing",
                v[i]
            )));
        }
        Ok(v)
    };
    let timestamp = file
        .dataset(&format!("{at}/timestamp"))
        .and_then(|d| d.read_u64())
        .map_err(|e| {
            bad(format!(
                "\"{at}/timestamp\": {e} (a demodulator's samples need x, y, frequency and timestamp)"
            ))
        })?;
    let d = Demod {
        x: f64s("x")?,
        y: f64s("y")?,
        frequency: f64s("frequency")?,
        timestamp,
    };
    let n = d.timestamp.len();
    if d.x.len() != n || d.y.len() != n || d.frequency.len() != n {
        return Err(bad(format!(
            "\"{at}\": timestamp, x, y and frequency hold {n}, {}, {} and {} samples; a truncated save?",
            d.x.len(),
            d.y.len(),
            d.frequency.len()
        )));
    }
    if let Some(i) = d.timestamp.windows(2).position(|w| w[1] <= w[0]) {
        return Err(bad(format!(
            "\"{at}/timestamp\": sample {} ({}) does not follow {}: samples lost or records joined",
            i + 1,
            d.timestamp[i + 1],
            d.timestamp[i]
        )));
    }
    Ok(d)
}

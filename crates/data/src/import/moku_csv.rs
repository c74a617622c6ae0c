//! `harmonid import moku-csv`: Liquid Instruments Moku lock-in records converted to CSV
//! (`mokucli convert --format csv`): header lines start with `%` (instrument, settings,
//! `% Acquisition rate: … Hz`), then rows of `time (s), channel 1, channel 2` (comma-separated).
//!
//! The file does not say which lock-in output each channel carries (Main ∈ X, R; Aux ∈ Y,
//! Theta), nor always the demodulation frequency: both are options, never guessed. The
//! channels are volts after the output gain and offset, which are undone here. Theta is
//! "1 V per cycle" on the Moku: `phase_unit = cycles`. Each file is one step (one drive
//! frequency); several files make one stepped sweep, in the order given.

use super::{
    build, read_input, record_instrument, Conventions, Grouping, ImportError, PhaseUnit, Record,
    Settle,
};
use crate::dataset::Dataset;
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// Which lock-in outputs the two channels carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channels {
    /// Channel 1 = X, channel 2 = Y.
    XY,
    /// Channel 1 = R, channel 2 = Theta (in [`Options::phase_unit`]).
    RTheta,
}

/// What the files do not say.
#[derive(Debug, Clone)]
pub struct Options {
    /// What channels 1 and 2 are.
    pub channels: Channels,
    /// The output gain (V out per V of the lock-in output): divided out.
    pub output_gain: f64,
    /// The output offset, V: subtracted from both channels before the gain is divided out.
    pub output_offset_v: f64,
    /// Unit of the Theta channel (cycles on the Moku: 1 V per cycle).
    pub phase_unit: Option<PhaseUnit>,
    /// The demodulation (drive) frequency of each file, Hz; empty: read from each file's
    /// `% … demodulation … <number> <unit>` header line.
    pub demod_hz: Vec<f64>,
    /// The drive level of every step, if known.
    pub drive_level: Option<f64>,
}

/// One file: its header's demodulation frequency (if any) and its rows.
struct MokuFile {
    /// The header's demodulation frequency, Hz, and its row.
    demod_hz: Option<(usize, f64)>,
    rows: Vec<(usize, f64, f64, f64)>,
}

/// A frequency with its unit in `text` after the word "demodulation" (`1.000 000 MHz`,
/// `2.5e5 Hz`, `250 kHz`), in Hz, with its sign (`-1000 Hz` is -1000: refused by the caller,
/// never read as +1000).
fn header_frequency(text: &str) -> Option<f64> {
    let lower = text.to_ascii_lowercase();
    let at = lower.find("demodulation")?;
    let rest = &lower[at..];
    let units = [("ghz", 1e9), ("mhz", 1e6), ("khz", 1e3), ("hz", 1.0)];
    // The first number followed (after spaces) by a frequency unit.
    let bytes: Vec<char> = rest.chars().collect();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && "+-".contains(bytes[i - 1]) {
                i - 1
            } else {
                i
            };
            while i < bytes.len()
                && (bytes[i].is_ascii_digit() || ".eE+- ".contains(bytes[i]))
                && !(bytes[i] == ' ' && i + 1 < bytes.len() && bytes[i + 1].is_alphabetic())
            {
                i += 1;
            }
            let number: String = bytes[start..i].iter().filter(|c| **c != ' ').collect();
            let tail: String = bytes[i..].iter().collect::<String>();
            let tail = tail.trim_start();
            for (u, scale) in units {
                if tail.starts_with(u) {
                    if let Ok(v) = number.parse::<f64>() {
                        return Some(v * scale);
                    }
                }
            }
        }
        i += 1;
    }
    None
}

fn read_moku(path: &Path) -> Result<MokuFile, ImportError> {
    let text = read_input(path)?;
    let bad = |row: usize, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row: Some(row),
        message,
    };
    let mut file = MokuFile {
        demod_hz: None,
        rows: Vec::new(),
    };
    for (n, line) in text.lines().enumerate() {
        let row = n + 1;
        let t = line.trim();
        if t.is_empty() {
            continue;
        }
        if let Some(h) = t.strip_prefix('%') {
            if file.demod_hz.is_none() {
                file.demod_hz = header_frequency(h).map(|f| (row, f));
            }
            continue;
        }
        let fields: Vec<&str> = t.split(',').map(str::trim).collect();
        if fields.len() < 3 {
            return Err(bad(
                row,
                format!(
                    "{} fields; a Moku lock-in CSV row is time, channel 1, channel 2 (a truncated row?)",
                    fields.len()
                ),
            ));
        }
        let num = |k: usize, what: &str| -> Result<f64, ImportError> {
            fields[k]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        row,
                        format!("{what}: \"{}\" is not a finite number", fields[k]),
                    )
                })
        };
        let time = num(0, "time")?;
        if let Some(&(_, prev, _, _)) = file.rows.last() {
            if time <= prev {
                return Err(bad(
                    row,
                    format!("time {time} s does not follow {prev} s: samples lost or records joined; convert one continuous record per file"),
                ));
            }
        }
        file.rows
            .push((row, time, num(1, "channel 1")?, num(2, "channel 2")?));
    }
    Ok(file)
}

/// Imports the Moku records `inputs` (one step each, in sweep order) into a dataset named
/// `out`.
pub fn import(
    inputs: &[PathBuf],
    conv: &Conventions,
    settle: Settle,
    opts: &Options,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    if !(opts.output_gain.is_finite() && opts.output_gain != 0.0) {
        return Err(ImportError::Convention {
            origin: "--output-gain".into(),
            message: format!(
                "{}: the lock-in's output gain (V per V, 1 for 0 dB) must be a finite nonzero number",
                opts.output_gain
            ),
        });
    }
    if !opts.output_offset_v.is_finite() {
        return Err(ImportError::Convention {
            origin: "--output-offset".into(),
            message: "the output offset must be a finite number of volts".into(),
        });
    }
    if opts.channels == Channels::RTheta && opts.phase_unit.is_none() {
        return Err(ImportError::Convention {
            origin: "--phase-unit".into(),
            message:
                "a Theta channel needs its unit: cycles (the Moku's 1 V per cycle), deg or rad"
                    .into(),
        });
    }
    if let Some(f) = opts.demod_hz.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        return Err(ImportError::Convention {
            origin: "--demod-hz".into(),
            message: format!(
                "{}: a demodulation frequency is a positive number of Hz",
                harmonid_files::number(*f)
            ),
        });
    }
    if !opts.demod_hz.is_empty() && opts.demod_hz.len() != inputs.len() {
        return Err(ImportError::Convention {
            origin: "--demod-hz".into(),
            message: format!(
                "{} frequencies for {} files: give one per file, in the same order",
                opts.demod_hz.len(),
                inputs.len()
            ),
        });
    }
    let mut records = Vec::new();
    for (fi, path) in inputs.iter().enumerate() {
        let file = read_moku(path)?;
        let f = match (opts.demod_hz.get(fi), file.demod_hz) {
            (Some(&f), _) => f,
            (None, Some((row, f))) if !(f.is_finite() && f > 0.0) => {
                return Err(ImportError::Input {
                    path: path.clone(),
                    row: Some(row),
                    message: format!(
                        "the header's demodulation frequency is {} Hz, not a positive frequency: the sign is never dropped silently (demodulating at -f conjugates x + iy); check the instrument's settings, then give the drive frequency with --demod-hz and the matching --quadrature",
                        harmonid_files::number(f)
                    ),
                })
            }
            (None, Some((_, f))) => f,
            (None, None) => {
                return Err(ImportError::Input {
                    path: path.clone(),
                    row: None,
                    message: "no `% … demodulation … Hz` header line gives the demodulation frequency: give --demod-hz".into(),
                })
            }
        };
        let undo = |v: f64| (v - opts.output_offset_v) / opts.output_gain;
        for &(row, time, c1, c2) in &file.rows {
            let z = match opts.channels {
                Channels::XY => Complex64::new(undo(c1), undo(c2)),
                Channels::RTheta => {
                    let unit = opts.phase_unit.unwrap_or(PhaseUnit::Rad);
                    Complex64::from_polar(undo(c1), unit.to_rad(undo(c2)))
                }
            };
            records.push(Record {
                drive: f,
                line: f,
                z,
                level: opts.drive_level,
                drive_phase_rad: opts.drive_level.map(|_| 0.0),
                group: 0,
                step: Some(fi as u64),
                time_s: Some(time),
                origin: (fi, row),
                noise: None,
                unmeasured: false,
            });
        }
    }
    let grouping = Grouping {
        group_names: vec!["sweep".into()],
        split_on_level: false,
        sources: Vec::new(),
        drop_nan_rows: false,
        passes_need_level: false,
        one_sweep: false,
    };
    let (mut ds, note) = build("moku-csv", inputs, records, conv, settle, &grouping, out)?;
    record_instrument(
        &mut ds,
        &[
            (
                "channels",
                match opts.channels {
                    Channels::XY => "x,y",
                    Channels::RTheta => "r,theta",
                }
                .to_string(),
            ),
            ("output_gain", format!("{}", opts.output_gain)),
            ("output_offset_v", format!("{}", opts.output_offset_v)),
            (
                "demod_hz_from",
                if opts.demod_hz.is_empty() {
                    "each file's header"
                } else {
                    "--demod-hz"
                }
                .to_string(),
            ),
        ],
    );
    Ok((ds, note))
}

#[cfg(test)]
mod tests {
    use super::header_frequency;

    #[test]
    fn the_demodulation_frequency_is_read_with_its_unit() {
        assert_eq!(
            header_frequency(" Demodulation frequency 1.25 MHz, phase 0 deg"),
            Some(1.25e6)
        );
        assert_eq!(header_frequency(" demodulation: 2.5e5 Hz"), Some(2.5e5));
        assert_eq!(header_frequency(" Demodulation at 250 kHz"), Some(250e3));
        assert_eq!(header_frequency(" Acquisition rate: 1000 Hz"), None);
        assert_eq!(header_frequency(" Demodulation: external"), None);
        // hostile 10: the sign is kept (it was read as +1000 Hz).
        assert_eq!(
            header_frequency(" Demodulation frequency -1000 Hz"),
            Some(-1000.0)
        );
    }
}

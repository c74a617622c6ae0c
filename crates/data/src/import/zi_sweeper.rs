//! `harmonid import zi-sweeper`: Zurich Instruments LabOne sweeper results saved as CSV, one
//! file per demodulator (the drive's first), one row per sweep point with the sweeper's
//! fields (`ZISweeperDemodWave`): `grid` (the swept frequency), the means `x`, `y`, their
//! standard deviations `xstddev`, `ystddev`, and `count` (samples averaged); optional
//! `frequency` (the demodulator's own frequency, which is the line when present: a harmonic
//! demodulator sits at n × grid). Separated by `;` (or `,`, as the header is).
//!
//! Each point becomes one step of one sample with its noise given (the dataset's `std` and
//! `samples`): `√((σx² + σy²)/2)` per quadrature, from `count` samples. A sweep that turns
//! back (the sweeper's bidirectional mode) becomes two sweeps, up and down; with several
//! loops, one per pass (`sweep_up`, `sweep_down`, `sweep_up_2`, …), counted in the note.
//!
//! A sweep stopped early still writes its whole grid, the points not reached with `x` and `y`
//! NaN (their other fields NaN or 0 too): those rows are not measured, dropped at the sweep's
//! end with a warning (refused inside it unless [`Options::drop_nan_rows`]).

use super::{build, for_each_line, Conventions, Grouping, ImportError, Record};
use crate::dataset::Dataset;
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// What the files do not say.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// The drive level of every point, if known.
    pub drive_level: Option<f64>,
    /// Drop the points not measured (`x` and `y` NaN) inside the sweep too, not only at its
    /// end (`--drop-nan-rows`); each run is counted in a warning.
    pub drop_nan_rows: bool,
}

/// One point of one demodulator.
#[derive(Clone, Copy)]
struct Point {
    grid: f64,
    line: f64,
    z: Complex64,
    std: f64,
    count: u32,
    row: usize,
    /// `x` and `y` are NaN: the sweeper never reached this point.
    unmeasured: bool,
}

const REQUIRED: [&str; 6] = ["grid", "x", "y", "xstddev", "ystddev", "count"];

fn read_points(path: &Path) -> Result<Vec<Point>, ImportError> {
    let bad = |row: usize, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row: Some(row),
        message,
    };
    let mut cols: Option<([usize; 6], Option<usize>, char)> = None;
    let mut points = Vec::new();
    for_each_line(path, |row, line| {
        let Some((c, c_freq, sep)) = cols else {
            let sep = if line.contains(';') { ';' } else { ',' };
            let header: Vec<&str> = line.split(sep).map(str::trim).collect();
            let mut found = [0; 6];
            for (f, name) in found.iter_mut().zip(REQUIRED) {
                *f = header.iter().position(|h| *h == name).ok_or_else(|| {
                    bad(
                        1,
                        format!(
                            "no column \"{name}\" (found: {}); a LabOne sweeper CSV has grid, x, y, xstddev, ystddev, count, ...",
                            crate::text::header_names(header.iter().copied())
                        ),
                    )
                })?;
            }
            cols = Some((found, header.iter().position(|h| *h == "frequency"), sep));
            return Ok(());
        };
        if line.trim().is_empty() {
            return Ok(());
        }
        let fields: Vec<&str> = line.split(sep).map(str::trim).collect();
        let field = |i: usize, name: &str| {
            fields.get(i).copied().ok_or_else(|| {
                bad(
                    row,
                    format!("no value in column \"{name}\" (a truncated row?)"),
                )
            })
        };
        let num = |i: usize, name: &str| -> Result<f64, ImportError> {
            let t = field(i, name)?;
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        row,
                        format!("column \"{name}\": \"{t}\" is not a finite number"),
                    )
                })
        };
        let grid = num(c[0], "grid")?;
        let nan = |i: usize| {
            fields
                .get(i)
                .is_some_and(|t| t.parse::<f64>().is_ok_and(f64::is_nan))
        };
        if nan(c[1]) && nan(c[2]) {
            points.push(Point {
                grid,
                line: grid,
                z: Complex64::new(f64::NAN, f64::NAN),
                std: f64::NAN,
                count: 0,
                row,
                unmeasured: true,
            });
            return Ok(());
        }
        let (sx, sy) = (num(c[3], "xstddev")?, num(c[4], "ystddev")?);
        for (name, sd) in [("xstddev", sx), ("ystddev", sy)] {
            if sd < 0.0 {
                return Err(bad(
                    row,
                    format!("column \"{name}\": {} is negative; a standard deviation is 0 or more (is this column the deviation, or another quantity?)", harmonid_files::number(sd)),
                ));
            }
        }
        let t = field(c[5], "count")?;
        let count: u32 = t
            .parse::<f64>()
            .ok()
            .filter(|n| n.fract() == 0.0 && *n >= 2.0 && *n <= f64::from(u32::MAX))
            .map(|n| n as u32)
            .ok_or_else(|| {
                bad(
                    row,
                    format!("column \"count\": \"{t}\" is not a count of at least 2 samples (a point needs two for its standard deviation)"),
                )
            })?;
        let std = ((sx * sx + sy * sy) / 2.0).sqrt();
        if std <= 0.0 {
            return Err(bad(
                row,
                "xstddev and ystddev are 0: a point's noise must be positive".into(),
            ));
        }
        points.push(Point {
            grid,
            line: match c_freq {
                Some(i) => num(i, "frequency")?,
                None => grid,
            },
            z: Complex64::new(num(c[1], "x")?, num(c[2], "y")?),
            std,
            count,
            row,
            unmeasured: false,
        });
        Ok(())
    })?;
    if cols.is_none() {
        return Err(ImportError::Input {
            path: path.to_path_buf(),
            row: None,
            message: "the file is empty".into(),
        });
    }
    Ok(points)
}

/// Imports the sweeper files `inputs` (one per demodulator, the drive's first) into a dataset
/// named `out`.
pub fn import(
    inputs: &[PathBuf],
    conv: &Conventions,
    opts: &Options,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    let demods: Vec<Vec<Point>> = inputs
        .iter()
        .map(|p| read_points(p))
        .collect::<Result<_, _>>()?;
    let drive = &demods[0];
    for (k, d) in demods.iter().enumerate().skip(1) {
        let differs = d.len() != drive.len()
            || d.iter().zip(drive).any(|(a, b)| {
                (a.grid - b.grid).abs() > crate::dataset::FREQ_REL_TOL * a.grid.abs()
            });
        if differs {
            return Err(ImportError::Input {
                path: inputs[k].clone(),
                row: None,
                message: format!(
                    "its grid is not that of {} ({} and {} points): save the demodulators of one sweep together",
                    inputs[0].display(),
                    d.len(),
                    drive.len()
                ),
            });
        }
        // Two demodulators on one line are not two lines: most likely the files of two sweeps
        // or drive levels given together (each file then looks like a demodulator).
        let same_line = d
            .iter()
            .zip(drive)
            .all(|(a, b)| (a.line - b.line).abs() <= crate::dataset::FREQ_REL_TOL * b.line.abs());
        if same_line {
            return Err(ImportError::Input {
                path: inputs[k].clone(),
                row: None,
                message: format!(
                    "it measured the same frequencies as {} ({} Hz at the first point), so it is not another demodulator of that sweep: zi-sweeper reads the demodulators of one sweep (the drive's first, each other on its own line, a harmonic or another tone); import the files of several sweeps or drive levels one at a time (each with its --drive-level) and join them with `harmonid merge`",
                    inputs[0].display(),
                    harmonid_files::number(drive[0].line)
                ),
            });
        }
    }
    // Legs: a new sweep where the grid turns back (at the repeated end point, when there is
    // one).
    let mut leg = vec![0usize; drive.len()];
    let mut dir = 0.0_f64;
    for i in 1..drive.len() {
        let step = drive[i].grid - drive[i - 1].grid;
        leg[i] = leg[i - 1];
        if dir != 0.0 && (step == 0.0 || step.signum() != dir) {
            leg[i] += 1;
            dir = if step == 0.0 { 0.0 } else { step.signum() };
        } else if step != 0.0 {
            dir = step.signum();
        }
    }
    let legs = leg.last().map_or(1, |l| l + 1);
    let records = (0..drive.len()).flat_map(|i| {
        let leg = leg[i];
        demods.iter().enumerate().map(move |(k, d)| {
            let p = d[i];
            Record {
                drive: drive[i].grid,
                line: p.line,
                z: p.z,
                level: opts.drive_level,
                drive_phase_rad: opts.drive_level.map(|_| 0.0),
                group: leg,
                step: Some(i as u64),
                time_s: None,
                origin: (k, p.row),
                noise: Some((p.std, p.count)),
                unmeasured: p.unmeasured,
            }
        })
    });
    // A bidirectional sweep's legs are named by their direction (`sweep_up`, `sweep_down`,
    // then `sweep_up_2`, ... when it repeats); a sweep one way is `sweep`.
    let leg_dir = |l: usize| {
        let mut g = (0..drive.len())
            .filter(|&i| leg[i] == l)
            .map(|i| drive[i].grid);
        let (a, b) = (g.next(), g.next());
        match (a, b) {
            (Some(a), Some(b)) if b < a => "sweep_down",
            _ => "sweep_up",
        }
    };
    let grouping = Grouping {
        // Each leg its final name (the n-th leg each way `_2`, ...), so a warning names it as
        // the dataset does.
        group_names: (0..legs)
            .map(|l| {
                let dir = leg_dir(l);
                let n = (0..=l).filter(|&m| leg_dir(m) == dir).count();
                match (legs, n) {
                    (1, _) => "sweep".into(),
                    (_, 1) => dir.to_string(),
                    _ => format!("{dir}_{n}"),
                }
            })
            .collect(),
        split_on_level: false,
        sources: Vec::new(),
        drop_nan_rows: opts.drop_nan_rows,
        passes_need_level: false,
        // A point never reached ends the whole sweep, not one of its passes.
        one_sweep: true,
    };
    let (ds, mut note) = build(
        "zi-sweeper",
        inputs,
        records,
        conv,
        super::Settle::default(),
        &grouping,
        out,
    )?;
    if ds.manifest.sweeps.len() > 1 {
        let names: Vec<&str> = ds.manifest.sweeps.iter().map(|s| s.name.as_str()).collect();
        note += &format!(
            "; the grid turned back: {} passes ({})",
            names.len(),
            names.join(", ")
        );
    }
    Ok((ds, note))
}

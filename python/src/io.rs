//! `harmonid.io`: instrument files into a `Dataset`, the importers of `harmonid import` (the
//! same code): a mapping-file table, LabOne demodulator CSV and HDF5 records, Moku lock-in CSV.
//! Every convention is a keyword without a default (`amplitude`, `quadrature`,
//! `metres_per_unit`, where `None` keeps volts), so nothing is guessed. The returned dataset's
//! `notes` carry the import's line on settling.

use crate::dataset::Dataset;
use crate::errors::DatasetError;
use harmonid_data::import::{
    moku_csv, table, zi_csv, zi_hdf5, zi_sweeper, Conventions, ImportError, PhaseUnit, Settle,
};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

fn import_error(e: &ImportError) -> PyErr {
    DatasetError::new_err(e.to_string())
}

/// The dataset an import made, with its note, as a Python `Dataset`: each warning of the
/// import (rows where nothing was measured, dropped) raised as a Python `UserWarning` too.
fn done(
    py: Python<'_>,
    r: Result<(harmonid_data::Dataset, String), ImportError>,
) -> PyResult<Dataset> {
    let (mut ds, note) = r.map_err(|e| import_error(&e))?;
    for w in &ds.notes {
        let msg = std::ffi::CString::new(w.replace('\0', " ")).unwrap_or_default();
        PyErr::warn(
            py,
            py.get_type::<pyo3::exceptions::PyUserWarning>().as_any(),
            &msg,
            1,
        )?;
    }
    ds.notes.push(note);
    Ok(Dataset::wrap(ds))
}

/// Conventions from the keywords; an unknown spelling is an error naming the keyword.
fn conventions(
    amplitude: &str,
    quadrature: &str,
    response: &str,
    metres_per_unit: Option<f64>,
    phase_unit: Option<PhaseUnit>,
) -> PyResult<Conventions> {
    let bad = |key: &str, why: String| DatasetError::new_err(format!("{key}={why}"));
    let conv = Conventions {
        amplitude: amplitude.parse().map_err(|e| bad("amplitude", e))?,
        quadrature: quadrature.parse().map_err(|e| bad("quadrature", e))?,
        response: response.parse().map_err(|e| bad("response", e))?,
        metres_per_unit,
        displacement_unit: if metres_per_unit.is_some() { "m" } else { "V" }.into(),
        phase_unit: phase_unit.or(Some(PhaseUnit::Rad)),
        frequency_scale: None,
    };
    conv.check("the keywords").map_err(|e| import_error(&e))?;
    Ok(conv)
}

fn phase_unit(unit: Option<&str>) -> PyResult<Option<PhaseUnit>> {
    unit.map(|u| {
        u.parse()
            .map_err(|e| DatasetError::new_err(format!("phase_unit={e}")))
    })
    .transpose()
}

/// Reads `files` (CSV/TSV/whitespace text or MATLAB v5/v7) with the mapping file `mapping`
/// (columns, conventions, settling: docs/data-format.md, "From your instrument to a dataset").
/// Rows where nothing was measured (every value NaN) are dropped at a sweep's end with a
/// warning; `drop_nan_rows=True` (or the mapping's `drop_nan_rows = true`) drops those inside a
/// sweep too, which are refused otherwise.
#[pyfunction]
#[pyo3(signature = (files, mapping, *, drop_nan_rows = false))]
pub fn read_table(
    py: Python<'_>,
    files: Vec<PathBuf>,
    mapping: PathBuf,
    drop_nan_rows: bool,
) -> PyResult<Dataset> {
    let mut m = table::Mapping::load(&mapping).map_err(|e| import_error(&e))?;
    m.drop_nan_rows |= drop_nan_rows;
    let r = py.detach(|| table::import(&files, &m, Path::new("<imported>")));
    done(py, r)
}

/// Reads LabOne demodulator CSV exports, one file per demodulator (the drive's first).
/// `clockbase_hz`: device ticks per second (60e6 MFLI, 1.8e9 UHFLI). `metres_per_unit=None`
/// keeps volts.
#[pyfunction]
#[pyo3(signature = (files, *, amplitude, quadrature, metres_per_unit, clockbase_hz, response = "displacement", drive_level = None, settle_s = None, settle_samples = None))]
#[allow(clippy::too_many_arguments)] // one keyword per convention, as the CLI's flags
pub fn read_zi_csv(
    py: Python<'_>,
    files: Vec<PathBuf>,
    amplitude: &str,
    quadrature: &str,
    metres_per_unit: Option<f64>,
    clockbase_hz: f64,
    response: &str,
    drive_level: Option<f64>,
    settle_s: Option<f64>,
    settle_samples: Option<usize>,
) -> PyResult<Dataset> {
    let conv = conventions(amplitude, quadrature, response, metres_per_unit, None)?;
    let settle = Settle {
        settle_s,
        settle_samples,
    };
    let opts = zi_csv::Options {
        clockbase_hz,
        drive_level,
        drive_phase_rad: None,
    };
    let r = py.detach(|| zi_csv::import(&files, &conv, settle, &opts, Path::new("<imported>")));
    done(py, r)
}

/// Reads LabOne HDF5 saves (record groups `000`, `001`, … each one sweep); `demods` lists the
/// demodulators to read, the drive's first (default: every one, in number order).
#[pyfunction]
#[pyo3(signature = (files, *, amplitude, quadrature, metres_per_unit, clockbase_hz, demods = None, response = "displacement", drive_level = None, settle_s = None, settle_samples = None))]
#[allow(clippy::too_many_arguments)] // one keyword per convention, as the CLI's flags
pub fn read_zi_hdf5(
    py: Python<'_>,
    files: Vec<PathBuf>,
    amplitude: &str,
    quadrature: &str,
    metres_per_unit: Option<f64>,
    clockbase_hz: f64,
    demods: Option<Vec<usize>>,
    response: &str,
    drive_level: Option<f64>,
    settle_s: Option<f64>,
    settle_samples: Option<usize>,
) -> PyResult<Dataset> {
    let conv = conventions(amplitude, quadrature, response, metres_per_unit, None)?;
    let settle = Settle {
        settle_s,
        settle_samples,
    };
    let opts = zi_hdf5::Options {
        clockbase_hz,
        demods: demods.unwrap_or_default(),
        drive_level,
    };
    let r = py.detach(|| zi_hdf5::import(&files, &conv, settle, &opts, Path::new("<imported>")));
    done(py, r)
}

/// Reads Moku lock-in records converted to CSV, one file per frequency step. `channels` is
/// `"x,y"` or `"r,theta"`; `output_gain` (V/V) and `output_offset` (V) are undone; Theta needs
/// `phase_unit` ("cycles" on the Moku); `demod_hz` gives each file's frequency when its header
/// does not.
#[pyfunction]
#[pyo3(signature = (files, *, channels, output_gain, amplitude, quadrature, metres_per_unit, output_offset = 0.0, phase_unit = None, demod_hz = None, response = "displacement", drive_level = None, settle_s = None, settle_samples = None))]
#[allow(clippy::too_many_arguments)] // one keyword per convention, as the CLI's flags
pub fn read_moku_csv(
    py: Python<'_>,
    files: Vec<PathBuf>,
    channels: &str,
    output_gain: f64,
    amplitude: &str,
    quadrature: &str,
    metres_per_unit: Option<f64>,
    output_offset: f64,
    phase_unit: Option<&str>,
    demod_hz: Option<Vec<f64>>,
    response: &str,
    drive_level: Option<f64>,
    settle_s: Option<f64>,
    settle_samples: Option<usize>,
) -> PyResult<Dataset> {
    let unit = self::phase_unit(phase_unit)?;
    let mut conv = conventions(amplitude, quadrature, response, metres_per_unit, unit)?;
    conv.phase_unit = unit;
    let settle = Settle {
        settle_s,
        settle_samples,
    };
    let opts = moku_csv::Options {
        channels: match channels {
            "x,y" => moku_csv::Channels::XY,
            "r,theta" => moku_csv::Channels::RTheta,
            c => {
                return Err(DatasetError::new_err(format!(
                    "channels=\"{c}\": expected \"x,y\" or \"r,theta\""
                )))
            }
        },
        output_gain,
        output_offset_v: output_offset,
        phase_unit: unit,
        demod_hz: demod_hz.unwrap_or_default(),
        drive_level,
    };
    let r = py.detach(|| moku_csv::import(&files, &conv, settle, &opts, Path::new("<imported>")));
    done(py, r)
}

/// Reads LabOne sweeper CSVs (one per demodulator, the drive's first): each point a step whose
/// noise is the sweeper's standard deviation over `count` samples. Points never reached (`x`
/// and `y` NaN: a sweep stopped early) are dropped at the sweep's end with a warning;
/// `drop_nan_rows=True` drops those inside the sweep too, which are refused otherwise.
#[pyfunction]
#[pyo3(signature = (files, *, amplitude, quadrature, metres_per_unit, response = "displacement", drive_level = None, drop_nan_rows = false))]
#[allow(clippy::too_many_arguments)] // one keyword per convention, as the CLI's flags
pub fn read_zi_sweeper(
    py: Python<'_>,
    files: Vec<PathBuf>,
    amplitude: &str,
    quadrature: &str,
    metres_per_unit: Option<f64>,
    response: &str,
    drive_level: Option<f64>,
    drop_nan_rows: bool,
) -> PyResult<Dataset> {
    let conv = conventions(amplitude, quadrature, response, metres_per_unit, None)?;
    let opts = zi_sweeper::Options {
        drive_level,
        drop_nan_rows,
    };
    let r = py.detach(|| zi_sweeper::import(&files, &conv, &opts, Path::new("<imported>")));
    done(py, r)
}

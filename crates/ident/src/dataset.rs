//! Measurement datasets: the folder layout of `DATA_FORMAT.md` (`dataset.toml`, one CSV per
//! measurement, optional `truth.toml`), read into memory and written back atomically.
//!
//! Complex amplitudes follow the `DATA_FORMAT.md` convention: `X` at frequency `f` means the
//! real signal `Re[X · e^{i 2π f t}]` (peak amplitude). In memory every amplitude is in SI
//! metres, whatever `displacement_unit` the manifest declares; [`Dataset::write`] writes metres
//! back (`displacement_unit = "m"`) unless the manifest says otherwise, in which case it converts.

use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

/// The only manifest format this reader understands.
pub const DATASET_FORMAT: &str = "harmonid-dataset/1";

/// Relative tolerance used to match a drive frequency to a measured frequency, and to compare
/// frequency sets between shots and points.
pub const FREQ_REL_TOL: f64 = 1e-9;

/// Everything that can be wrong with a dataset. Every variant names the file, and the row
/// (1-based, counting the header as row 1, as a spreadsheet shows it) where it applies.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File or folder concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// `dataset.toml` or `truth.toml` is not valid TOML or lacks a required key.
    #[error("{path}: {message}")]
    Toml {
        /// File concerned.
        path: PathBuf,
        /// Parser message (with line and column).
        message: String,
    },
    /// The manifest's `format` is not [`DATASET_FORMAT`].
    #[error("{path}: format is \"{found}\", expected \"{DATASET_FORMAT}\"")]
    Format {
        /// Manifest path.
        path: PathBuf,
        /// What the file says.
        found: String,
    },
    /// A problem in the manifest that is not a TOML syntax error.
    #[error("{path}: {message}")]
    Manifest {
        /// Manifest path.
        path: PathBuf,
        /// What is wrong and what to do about it.
        message: String,
    },
    /// A CSV file lacks a required column.
    #[error("{path}: missing column \"{column}\" in the header (found: {found}); required: shot, freq_hz, re, im")]
    MissingColumn {
        /// CSV path.
        path: PathBuf,
        /// The missing column.
        column: String,
        /// The header as read.
        found: String,
    },
    /// A CSV row is malformed (wrong number of fields, unparsable or non-finite number, ...).
    #[error("{path}, row {row}: {message}")]
    Row {
        /// CSV path.
        path: PathBuf,
        /// 1-based row number (the header is row 1).
        row: usize,
        /// What is wrong.
        message: String,
    },
    /// Shots or points of one measurement list different frequencies.
    #[error("{path}: {message}")]
    Inconsistent {
        /// CSV path.
        path: PathBuf,
        /// Which shot/point differs from which, and how.
        message: String,
    },
    /// A drive frequency of the manifest is not among the measured frequencies.
    #[error("{path}: drive frequency {drive_hz} Hz of measurement \"{measurement}\" is not among its measured frequencies (nearest measured: {nearest_hz} Hz); every drive tone must be measured")]
    DriveNotMeasured {
        /// CSV path.
        path: PathBuf,
        /// Measurement name.
        measurement: String,
        /// The drive frequency, Hz.
        drive_hz: f64,
        /// Closest measured frequency, Hz.
        nearest_hz: f64,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A measurement point: where displacement was measured, and how much of each mode shows there
/// (`x_p = Σ_n shape[n] q_n`; modes not listed have shape 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Point {
    /// Point name, referenced by the CSV column `point`.
    pub name: String,
    /// Mode-shape value of each mode at this point (dimensionless; modes not listed: 1.0).
    #[serde(default)]
    pub shape: BTreeMap<String, f64>,
}

impl Point {
    /// Shape value of mode `mode` at this point (1.0 when not listed).
    pub fn shape_of(&self, mode: &str) -> f64 {
        self.shape.get(mode).copied().unwrap_or(1.0)
    }
}

/// One `[[measurement]]` of the manifest: one drive configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSpec {
    /// Unique name; also the CSV's stem unless `file` is given.
    pub name: String,
    /// CSV file, relative to the dataset folder and inside it (default `<name>.csv`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Every drive tone of this measurement, Hz.
    pub drives_hz: Vec<f64>,
    /// Drive voltage of each tone, in `drives_hz` order (V, or any consistent unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_levels_v: Option<Vec<f64>>,
    /// Drive phase of each tone, radians, same time origin as the measured amplitudes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_phases_rad: Option<Vec<f64>>,
    /// Measurement bandwidth, Hz (metadata, carried to reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_hz: Option<f64>,
}

impl MeasurementSpec {
    /// The CSV file name relative to the dataset folder.
    pub fn file_name(&self) -> String {
        self.file
            .clone()
            .unwrap_or_else(|| format!("{}.csv", self.name))
    }

    /// `Some((levels, phases))` when the manifest gives both drive levels and phases.
    pub fn drive_levels_and_phases(&self) -> Option<(&[f64], &[f64])> {
        match (&self.drive_levels_v, &self.drive_phases_rad) {
            (Some(l), Some(p)) => Some((l, p)),
            _ => None,
        }
    }
}

fn default_unit() -> String {
    "m".to_string()
}

/// `dataset.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Must be [`DATASET_FORMAT`].
    pub format: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Unit of `re`/`im` in the CSV files: "m", "um", "nm" or "pm".
    #[serde(default = "default_unit")]
    pub displacement_unit: String,
    /// Measurement points (may be empty: then the data are modal amplitudes directly).
    #[serde(default, rename = "point", skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<Point>,
    /// Approximate resonance frequency of each mode, Hz.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub nominal_hz: BTreeMap<String, f64>,
    /// The measurements.
    #[serde(default, rename = "measurement")]
    pub measurements: Vec<MeasurementSpec>,
}

impl Manifest {
    /// A manifest with the current format, unit "m" and nothing else.
    pub fn new(description: impl Into<String>) -> Self {
        Manifest {
            format: DATASET_FORMAT.to_string(),
            description: description.into(),
            displacement_unit: "m".to_string(),
            points: Vec::new(),
            nominal_hz: BTreeMap::new(),
            measurements: Vec::new(),
        }
    }

    /// Metres per `displacement_unit`, or `None` for an unknown unit.
    pub fn unit_scale(&self) -> Option<f64> {
        unit_scale(&self.displacement_unit)
    }

    /// Every mode name the manifest mentions (points' shapes and `nominal_hz`), sorted.
    pub fn mode_names(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .nominal_hz
            .keys()
            .cloned()
            .chain(self.points.iter().flat_map(|p| p.shape.keys().cloned()))
            .collect();
        v.sort();
        v.dedup();
        v
    }
}

/// Metres per unit for the units `DATA_FORMAT.md` allows.
pub fn unit_scale(unit: &str) -> Option<f64> {
    match unit {
        "m" => Some(1.0),
        "um" | "µm" => Some(1e-6),
        "nm" => Some(1e-9),
        "pm" => Some(1e-12),
        _ => None,
    }
}

/// `[modes.<name>]` of `truth.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthMode {
    /// Linear resonance frequency, Hz.
    pub f_hz: f64,
    /// Quality factor.
    #[serde(rename = "Q")]
    pub q: f64,
}

/// `[forces.<measurement>.<mode>]` of `truth.toml`: one entry per drive tone, `drives_hz` order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthForce {
    /// Force amplitude per tone, N/kg (peak).
    pub amplitude: Vec<f64>,
    /// Force phase per tone, rad.
    pub phase_rad: Vec<f64>,
}

/// `[noise]` of `truth.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TruthNoise {
    /// Std of the Gaussian noise added to re and to im, in `displacement_unit`.
    #[serde(default)]
    pub sigma_per_quadrature: f64,
    /// Number of shots, if given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shots: Option<usize>,
}

/// `truth.toml`: the true values of a synthetic dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Truth {
    /// Linear parameters per mode.
    #[serde(default)]
    pub modes: BTreeMap<String, TruthMode>,
    /// Coefficient of each monomial (by its `DATA_FORMAT.md` name) in each mode's equation.
    #[serde(default)]
    pub eom: BTreeMap<String, BTreeMap<String, f64>>,
    /// Forces per measurement and mode.
    #[serde(default)]
    pub forces: BTreeMap<String, BTreeMap<String, TruthForce>>,
    /// Noise added.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<TruthNoise>,
}

/// One measurement in memory: `shots × frequencies × points` complex amplitudes in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The manifest entry.
    pub spec: MeasurementSpec,
    /// Measured frequencies, Hz, ascending (the same for every shot and point).
    pub freqs_hz: Vec<f64>,
    /// Indices into [`Manifest::points`] of the points present in this measurement, ascending.
    /// Empty manifest points: a single implicit point `0` (modal data).
    pub points: Vec<usize>,
    /// Number of shots.
    pub n_shots: usize,
    /// Amplitudes, metres, index `(shot * freqs_hz.len() + f) * points.len() + p`.
    pub data: Vec<Complex64>,
}

impl Measurement {
    /// Amplitude (metres) of shot `s`, frequency index `f`, local point index `p`.
    pub fn amplitude(&self, s: usize, f: usize, p: usize) -> Complex64 {
        self.data[(s * self.freqs_hz.len() + f) * self.points.len() + p]
    }

    /// Mutable amplitude (metres) of shot `s`, frequency index `f`, local point index `p`.
    pub fn amplitude_mut(&mut self, s: usize, f: usize, p: usize) -> &mut Complex64 {
        let nf = self.freqs_hz.len();
        let np = self.points.len();
        &mut self.data[(s * nf + f) * np + p]
    }

    /// Builds a measurement from its spec, frequency list, point indices and shot count, with
    /// all amplitudes zero (for generators; fill with [`Measurement::amplitude_mut`]).
    pub fn zeros(
        spec: MeasurementSpec,
        freqs_hz: Vec<f64>,
        points: Vec<usize>,
        n_shots: usize,
    ) -> Self {
        let n = n_shots * freqs_hz.len() * points.len().max(1);
        let points = if points.is_empty() { vec![0] } else { points };
        Measurement {
            spec,
            freqs_hz,
            points,
            n_shots,
            data: vec![Complex64::new(0.0, 0.0); n],
        }
    }

    /// Index of the measured frequency matching `hz` (relative tolerance [`FREQ_REL_TOL`]).
    pub fn freq_index(&self, hz: f64) -> Option<usize> {
        self.freqs_hz
            .iter()
            .position(|&f| (f - hz).abs() <= FREQ_REL_TOL * hz.abs().max(1.0))
    }
}

/// A dataset in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Folder it was read from (empty for a dataset built in memory).
    pub dir: PathBuf,
    /// The manifest as read.
    pub manifest: Manifest,
    /// The measurements, in manifest order.
    pub measurements: Vec<Measurement>,
    /// `truth.toml`, if present.
    pub truth: Option<Truth>,
}

impl Dataset {
    /// Reads the dataset folder `dir`: `dir/dataset.toml`, every measurement's CSV, and
    /// `dir/truth.toml` if it exists. Amplitudes are converted to metres.
    ///
    /// Every violation of `DATA_FORMAT.md` is an error naming the file and, for CSV content, the
    /// row: missing columns, rows with extra or missing fields, NaN/inf, non-positive or
    /// duplicate frequencies, a shot or point with a different frequency set, an unknown point,
    /// a drive frequency not among the measured ones.
    pub fn load(dir: impl AsRef<Path>) -> Result<Dataset, DatasetError> {
        let dir = dir.as_ref();
        let mpath = dir.join("dataset.toml");
        let text = std::fs::read_to_string(&mpath).map_err(io_err(&mpath))?;
        let manifest: Manifest = toml::from_str(&text).map_err(|e| DatasetError::Toml {
            path: mpath.clone(),
            message: e.to_string(),
        })?;
        validate_manifest(&manifest, &mpath)?;
        let scale = manifest.unit_scale().unwrap_or(1.0);
        let mut measurements = Vec::with_capacity(manifest.measurements.len());
        for spec in &manifest.measurements {
            let path = dir.join(spec.file_name());
            measurements.push(read_csv(&path, spec, &manifest, scale)?);
        }
        let tpath = dir.join("truth.toml");
        let truth = if tpath.exists() {
            let text = std::fs::read_to_string(&tpath).map_err(io_err(&tpath))?;
            Some(
                toml::from_str::<Truth>(&text).map_err(|e| DatasetError::Toml {
                    path: tpath.clone(),
                    message: e.to_string(),
                })?,
            )
        } else {
            None
        };
        Ok(Dataset {
            dir: dir.to_path_buf(),
            manifest,
            measurements,
            truth,
        })
    }

    /// Builds a dataset from measurements made in memory (from arrays, or by a simulation),
    /// checked as [`Dataset::load`] checks files: the manifest's rules, shapes, positive and
    /// distinct frequencies, finite amplitudes (metres), every drive tone measured. The
    /// manifest's measurement list is replaced by the measurements' specs, and frequencies are
    /// sorted in increasing order as a file read gives them. `dir` names the data in errors
    /// (and in results, as the dataset's path).
    pub fn from_parts(
        dir: impl Into<PathBuf>,
        mut manifest: Manifest,
        mut measurements: Vec<Measurement>,
        truth: Option<Truth>,
    ) -> Result<Dataset, DatasetError> {
        let dir = dir.into();
        manifest.measurements = measurements.iter().map(|m| m.spec.clone()).collect();
        validate_manifest(&manifest, &dir)?;
        for m in &mut measurements {
            check_measurement(m, manifest.points.len(), &dir)?;
        }
        Ok(Dataset {
            dir,
            manifest,
            measurements,
            truth,
        })
    }

    /// The measurement called `name`.
    pub fn measurement(&self, name: &str) -> Option<&Measurement> {
        self.measurements.iter().find(|m| m.spec.name == name)
    }

    /// Checks the dataset against the model's mode names: every mode named in the manifest
    /// (points' shapes, `nominal_hz`) must be declared by the model. Returns a message naming
    /// the manifest and the unknown mode.
    pub fn check_modes(&self, model_modes: &[&str]) -> Result<(), DatasetError> {
        for name in self.manifest.mode_names() {
            if !model_modes.contains(&name.as_str()) {
                return Err(DatasetError::Manifest {
                    path: self.dir.join("dataset.toml"),
                    message: format!(
                        "mode \"{name}\" is not declared by the model (model modes: {}); fix the name in [nominal_hz] or the point shapes",
                        model_modes.join(", ")
                    ),
                });
            }
        }
        Ok(())
    }

    /// Writes the dataset into folder `dir` (created; replaced if it exists) atomically: all
    /// files are written into a temporary sibling folder which is then renamed into place, so a
    /// reader never sees a partial dataset. The manifest written is `self.manifest` (its
    /// `measurements` are taken from `self.measurements[..].spec`), amplitudes are converted
    /// from metres to its `displacement_unit`. Writes `truth.toml` when `self.truth` is set.
    pub fn write(&self, dir: impl AsRef<Path>) -> Result<(), DatasetError> {
        let dir = dir.as_ref();
        let mut manifest = self.manifest.clone();
        manifest.measurements = self.measurements.iter().map(|m| m.spec.clone()).collect();
        let mpath = dir.join("dataset.toml");
        validate_manifest(&manifest, &mpath)?;
        let scale = manifest.unit_scale().unwrap_or(1.0);
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(io_err(&parent))?;
        let tmp = tempfile::Builder::new()
            .prefix(".harmonid-dataset-")
            .tempdir_in(&parent)
            .map_err(io_err(&parent))?;
        let manifest_text = toml::to_string(&manifest).map_err(|e| DatasetError::Toml {
            path: mpath.clone(),
            message: e.to_string(),
        })?;
        let p = tmp.path().join("dataset.toml");
        std::fs::write(&p, manifest_text).map_err(io_err(&p))?;
        for m in &self.measurements {
            let p = tmp.path().join(m.spec.file_name());
            if let Some(d) = p.parent() {
                std::fs::create_dir_all(d).map_err(io_err(d))?;
            }
            std::fs::write(&p, csv_text(m, &manifest, scale)).map_err(io_err(&p))?;
        }
        if let Some(t) = &self.truth {
            let tp = dir.join("truth.toml");
            let text = toml::to_string(t).map_err(|e| DatasetError::Toml {
                path: tp,
                message: e.to_string(),
            })?;
            let p = tmp.path().join("truth.toml");
            std::fs::write(&p, text).map_err(io_err(&p))?;
        }
        let staged = tmp.keep();
        // Replace an existing folder: move it aside, move the new one in, delete the old one.
        let old = if dir.exists() {
            let old = parent.join(format!(
                ".harmonid-old-{}-{}",
                std::process::id(),
                dir.file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default()
            ));
            std::fs::rename(dir, &old).map_err(io_err(dir))?;
            Some(old)
        } else {
            None
        };
        if let Err(e) = std::fs::rename(&staged, dir) {
            if let Some(old) = &old {
                let _ = std::fs::rename(old, dir);
            }
            let _ = std::fs::remove_dir_all(&staged);
            return Err(DatasetError::Io {
                path: dir.to_path_buf(),
                source: e,
            });
        }
        if let Some(old) = old {
            let _ = std::fs::remove_dir_all(old);
        }
        Ok(())
    }
}

fn csv_text(m: &Measurement, manifest: &Manifest, scale: f64) -> String {
    let with_point = !manifest.points.is_empty();
    let mut s = String::new();
    s.push_str(if with_point {
        "shot,freq_hz,point,re,im\n"
    } else {
        "shot,freq_hz,re,im\n"
    });
    for shot in 0..m.n_shots {
        for (f, hz) in m.freqs_hz.iter().enumerate() {
            for (p, &pi) in m.points.iter().enumerate() {
                let x = m.amplitude(shot, f, p) / scale;
                if with_point {
                    let _ = writeln!(
                        s,
                        "{shot},{hz:?},{},{:e},{:e}",
                        manifest.points[pi].name, x.re, x.im
                    );
                } else {
                    let _ = writeln!(s, "{shot},{hz:?},{:e},{:e}", x.re, x.im);
                }
            }
        }
    }
    s
}

fn validate_manifest(m: &Manifest, path: &Path) -> Result<(), DatasetError> {
    let err = |message: String| DatasetError::Manifest {
        path: path.to_path_buf(),
        message,
    };
    if m.format != DATASET_FORMAT {
        return Err(DatasetError::Format {
            path: path.to_path_buf(),
            found: m.format.clone(),
        });
    }
    if m.unit_scale().is_none() {
        return Err(err(format!(
            "displacement_unit = \"{}\" is not one of \"m\", \"um\", \"nm\", \"pm\"",
            m.displacement_unit
        )));
    }
    let mut seen = std::collections::HashSet::new();
    for p in &m.points {
        if !seen.insert(p.name.as_str()) {
            return Err(err(format!("point \"{}\" is declared twice", p.name)));
        }
        for (mode, v) in &p.shape {
            if !v.is_finite() {
                return Err(err(format!(
                    "point \"{}\": shape of {mode} is {v}, expected a finite number",
                    p.name
                )));
            }
        }
    }
    for (mode, f) in &m.nominal_hz {
        if !(f.is_finite() && *f > 0.0) {
            return Err(err(format!(
                "nominal_hz.{mode} = {f}, expected a positive frequency in Hz"
            )));
        }
    }
    let mut names = std::collections::HashSet::new();
    for ms in &m.measurements {
        if !names.insert(ms.name.as_str()) {
            return Err(err(format!(
                "measurement \"{}\" is declared twice; names must be unique",
                ms.name
            )));
        }
        let file = ms.file_name();
        let fp = Path::new(&file);
        if fp.is_absolute()
            || fp
                .components()
                .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
        {
            return Err(err(format!(
                "measurement \"{}\": file \"{file}\" must be a relative path inside the dataset folder",
                ms.name
            )));
        }
        if ms.drives_hz.is_empty() {
            return Err(err(format!(
                "measurement \"{}\": drives_hz is empty; list every drive tone in Hz",
                ms.name
            )));
        }
        for d in &ms.drives_hz {
            if !(d.is_finite() && *d > 0.0) {
                return Err(err(format!(
                    "measurement \"{}\": drive frequency {d} is not a positive number of Hz",
                    ms.name
                )));
            }
        }
        for (key, v) in [
            ("drive_levels_v", &ms.drive_levels_v),
            ("drive_phases_rad", &ms.drive_phases_rad),
        ] {
            if let Some(v) = v {
                if v.len() != ms.drives_hz.len() {
                    return Err(err(format!(
                        "measurement \"{}\": {key} has {} entries but drives_hz has {}; give one per drive tone, in drives_hz order",
                        ms.name,
                        v.len(),
                        ms.drives_hz.len()
                    )));
                }
                if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                    return Err(err(format!(
                        "measurement \"{}\": {key} contains {x}, expected finite numbers",
                        ms.name
                    )));
                }
            }
        }
        if ms.drive_levels_v.is_some() != ms.drive_phases_rad.is_some() {
            return Err(err(format!(
                "measurement \"{}\": give both drive_levels_v and drive_phases_rad, or neither",
                ms.name
            )));
        }
    }
    Ok(())
}

/// Every drive tone of `spec` must be among the measured frequencies `freqs`.
fn check_drives_measured(
    spec: &MeasurementSpec,
    freqs: &[f64],
    path: &Path,
) -> Result<(), DatasetError> {
    for &d in &spec.drives_hz {
        if !freqs.iter().any(|f| (f - d).abs() <= FREQ_REL_TOL * d) {
            let nearest = freqs
                .iter()
                .copied()
                .min_by(|a, b| (a - d).abs().total_cmp(&(b - d).abs()))
                .unwrap_or(f64::NAN);
            return Err(DatasetError::DriveNotMeasured {
                path: path.to_path_buf(),
                measurement: spec.name.clone(),
                drive_hz: d,
                nearest_hz: nearest,
            });
        }
    }
    Ok(())
}

/// Checks one measurement built in memory (by [`Dataset::from_parts`]) as [`read_csv`] checks a
/// file, and sorts its frequencies (with their data) in increasing order as a file read gives
/// them.
fn check_measurement(
    m: &mut Measurement,
    n_points: usize,
    path: &Path,
) -> Result<(), DatasetError> {
    let name = m.spec.name.clone();
    let bad = |message: String| DatasetError::Inconsistent {
        path: path.to_path_buf(),
        message: format!("measurement \"{name}\": {message}"),
    };
    let (nf, np) = (m.freqs_hz.len(), m.points.len());
    if m.n_shots == 0 || nf == 0 {
        return Err(bad(format!(
            "{} shots of {nf} frequencies: give at least one shot and one frequency",
            m.n_shots
        )));
    }
    if np == 0 || m.points.iter().any(|&p| p >= n_points.max(1)) {
        return Err(bad(format!(
            "point indices {:?} do not fit the {n_points} declared points",
            m.points
        )));
    }
    if m.data.len() != m.n_shots * nf * np {
        return Err(bad(format!(
            "{} amplitudes for {} shots × {nf} frequencies × {np} points = {}",
            m.data.len(),
            m.n_shots,
            m.n_shots * nf * np
        )));
    }
    if let Some(f) = m.freqs_hz.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        return Err(bad(format!(
            "frequency {f} Hz: frequencies must be positive and finite"
        )));
    }
    if let Some(i) = m
        .data
        .iter()
        .position(|x| !(x.re.is_finite() && x.im.is_finite()))
    {
        let (s, f, p) = (i / (nf * np), (i / np) % nf, i % np);
        return Err(bad(format!(
            "the amplitude of shot {s} at {} Hz (point #{p}) is {}, expected a finite number",
            m.freqs_hz[f], m.data[i]
        )));
    }
    let mut order: Vec<usize> = (0..nf).collect();
    order.sort_by(|&a, &b| m.freqs_hz[a].total_cmp(&m.freqs_hz[b]));
    let freqs: Vec<f64> = order.iter().map(|&i| m.freqs_hz[i]).collect();
    if let Some(w) = freqs
        .windows(2)
        .find(|w| (w[1] - w[0]).abs() <= FREQ_REL_TOL * w[1])
    {
        return Err(bad(format!("frequency {} Hz appears twice", w[1])));
    }
    check_drives_measured(&m.spec, &freqs, path)?;
    if order.iter().enumerate().any(|(k, &i)| k != i) {
        let mut data = Vec::with_capacity(m.data.len());
        for s in 0..m.n_shots {
            for &f in &order {
                let at = (s * nf + f) * np;
                data.extend_from_slice(&m.data[at..at + np]);
            }
        }
        m.data = data;
        m.freqs_hz = freqs;
    }
    Ok(())
}

/// One CSV value: frequency (Hz), amplitude (m), 1-based row.
type Cell = (f64, Complex64, usize);

fn read_csv(
    path: &Path,
    spec: &MeasurementSpec,
    manifest: &Manifest,
    scale: f64,
) -> Result<Measurement, DatasetError> {
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(file);
    let headers = rdr
        .headers()
        .map_err(|e| DatasetError::Row {
            path: path.to_path_buf(),
            row: 1,
            message: format!("cannot read the header: {e}"),
        })?
        .clone();
    let found = headers.iter().collect::<Vec<_>>().join(",");
    let col = |name: &str| -> Result<Option<usize>, DatasetError> {
        let idx: Vec<usize> = headers
            .iter()
            .enumerate()
            .filter(|(_, h)| *h == name)
            .map(|(i, _)| i)
            .collect();
        if idx.len() > 1 {
            return Err(DatasetError::Row {
                path: path.to_path_buf(),
                row: 1,
                message: format!(
                    "column \"{name}\" appears {} times in the header",
                    idx.len()
                ),
            });
        }
        Ok(idx.first().copied())
    };
    let req = |name: &str| -> Result<usize, DatasetError> {
        col(name)?.ok_or_else(|| DatasetError::MissingColumn {
            path: path.to_path_buf(),
            column: name.to_string(),
            found: found.clone(),
        })
    };
    let (c_shot, c_freq, c_re, c_im) = (req("shot")?, req("freq_hz")?, req("re")?, req("im")?);
    let c_point = col("point")?;
    let point_index: HashMap<&str, usize> = manifest
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.name.as_str(), i))
        .collect();

    // (shot, point) -> list of (freq, value, row)
    let mut cells: BTreeMap<(usize, usize), Vec<Cell>> = BTreeMap::new();
    for (i, rec) in rdr.records().enumerate() {
        let row = i + 2;
        let rec = rec.map_err(|e| DatasetError::Row {
            path: path.to_path_buf(),
            row,
            message: match e.kind() {
                csv::ErrorKind::UnequalLengths {
                    expected_len, len, ..
                } => format!(
                    "{len} fields, but the header has {expected_len} columns (a missing or extra column)"
                ),
                _ => e.to_string(),
            },
        })?;
        let field = |c: usize, name: &str| -> Result<&str, DatasetError> {
            rec.get(c).ok_or_else(|| DatasetError::Row {
                path: path.to_path_buf(),
                row,
                message: format!("no value in column \"{name}\""),
            })
        };
        let num = |c: usize, name: &str| -> Result<f64, DatasetError> {
            let t = field(c, name)?;
            let v: f64 = t.parse().map_err(|_| DatasetError::Row {
                path: path.to_path_buf(),
                row,
                message: format!("column \"{name}\": \"{t}\" is not a number"),
            })?;
            if !v.is_finite() {
                return Err(DatasetError::Row {
                    path: path.to_path_buf(),
                    row,
                    message: format!("column \"{name}\": {t} is not finite"),
                });
            }
            Ok(v)
        };
        let st = field(c_shot, "shot")?;
        let shot: usize = st.parse().map_err(|_| DatasetError::Row {
            path: path.to_path_buf(),
            row,
            message: format!("column \"shot\": \"{st}\" is not a non-negative integer"),
        })?;
        let f = num(c_freq, "freq_hz")?;
        if f <= 0.0 {
            return Err(DatasetError::Row {
                path: path.to_path_buf(),
                row,
                message: format!("freq_hz = {f}: frequencies must be positive"),
            });
        }
        let x = Complex64::new(num(c_re, "re")?, num(c_im, "im")?) * scale;
        let p = match c_point {
            Some(c) if !field(c, "point")?.is_empty() => {
                let name = field(c, "point")?;
                *point_index.get(name).ok_or_else(|| DatasetError::Row {
                    path: path.to_path_buf(),
                    row,
                    message: format!(
                        "point \"{name}\" is not declared in dataset.toml (declared: {})",
                        manifest
                            .points
                            .iter()
                            .map(|p| p.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                })?
            }
            _ => 0,
        };
        cells.entry((shot, p)).or_default().push((f, x, row));
    }
    if cells.is_empty() {
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!("measurement \"{}\" has no data rows", spec.name),
        });
    }
    let shots: Vec<usize> = {
        let mut s: Vec<usize> = cells.keys().map(|k| k.0).collect();
        s.dedup();
        s
    };
    let n_shots = shots.len();
    if shots.iter().enumerate().any(|(i, &s)| i != s) {
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!(
                "shots must be numbered 0..S-1 without gaps; found {:?}",
                shots
            ),
        });
    }
    let mut points: Vec<usize> = cells.keys().map(|k| k.1).collect();
    points.sort_unstable();
    points.dedup();
    for v in cells.values_mut() {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        for w in v.windows(2) {
            if (w[1].0 - w[0].0).abs() <= FREQ_REL_TOL * w[1].0 {
                return Err(DatasetError::Row {
                    path: path.to_path_buf(),
                    row: w[1].2,
                    message: format!(
                        "frequency {} Hz appears twice in the same shot and point (also row {})",
                        w[1].0, w[0].2
                    ),
                });
            }
        }
    }
    let Some((&(s0, p0), ref_cells)) = cells.iter().next() else {
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!("measurement \"{}\" has no data rows", spec.name),
        });
    };
    let freqs: Vec<f64> = ref_cells.iter().map(|c| c.0).collect();
    let pname = |p: usize| {
        manifest
            .points
            .get(p)
            .map(|q| q.name.clone())
            .unwrap_or_else(|| "(modal)".into())
    };
    for &s in &shots {
        for &p in &points {
            let Some(v) = cells.get(&(s, p)) else {
                return Err(DatasetError::Inconsistent {
                    path: path.to_path_buf(),
                    message: format!("shot {s} has no rows for point \"{}\"", pname(p)),
                });
            };
            let same = v.len() == freqs.len()
                && v.iter()
                    .zip(&freqs)
                    .all(|(c, f)| (c.0 - f).abs() <= FREQ_REL_TOL * f);
            if !same {
                let extra = v
                    .iter()
                    .find(|c| !freqs.iter().any(|f| (c.0 - f).abs() <= FREQ_REL_TOL * f));
                let detail = match extra {
                    Some(c) => format!("{} Hz (row {}) is not measured in shot {s0}", c.0, c.2),
                    None => format!(
                        "it lists {} frequencies, shot {s0} lists {}",
                        v.len(),
                        freqs.len()
                    ),
                };
                return Err(DatasetError::Inconsistent {
                    path: path.to_path_buf(),
                    message: format!(
                        "shot {s}, point \"{}\" has a different frequency set from shot {s0}, point \"{}\": {detail}; every shot must list the same frequencies",
                        pname(p),
                        pname(p0)
                    ),
                });
            }
        }
    }
    check_drives_measured(spec, &freqs, path)?;
    let nf = freqs.len();
    let np = points.len();
    let mut data = vec![Complex64::new(0.0, 0.0); n_shots * nf * np];
    for ((s, p), v) in &cells {
        let pl = points.iter().position(|q| q == p).unwrap_or(0);
        for (f, c) in v.iter().enumerate() {
            data[(s * nf + f) * np + pl] = c.1;
        }
    }
    Ok(Measurement {
        spec: spec.clone(),
        freqs_hz: freqs,
        points,
        n_shots,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).expect("write test file");
    }

    const MANIFEST: &str = r#"
format = "harmonid-dataset/1"
description = "test"
displacement_unit = "nm"
[[point]]
name = "p0"
shape = { q1 = 0.5 }
[nominal_hz]
q1 = 1000.0
[[measurement]]
name = "m1"
drives_hz = [990.0, 1010.0]
drive_levels_v = [1.0, 1.0]
drive_phases_rad = [0.0, 0.5]
"#;

    fn good_dir() -> tempfile::TempDir {
        let d = tempfile::tempdir().expect("tempdir");
        write(d.path(), "dataset.toml", MANIFEST);
        write(
            d.path(),
            "m1.csv",
            "shot,freq_hz,re,im,extra\n0,970,1,2,x\n0,990,3,4,x\n0,1010,5,6,x\n1,1010,7,8,x\n1,990,9,10,x\n1,970,11,12,x\n",
        );
        d
    }

    #[test]
    fn reads_and_converts_units() {
        let d = good_dir();
        let ds = Dataset::load(d.path()).expect("load");
        let m = &ds.measurements[0];
        assert_eq!(m.freqs_hz, vec![970.0, 990.0, 1010.0]);
        assert_eq!(m.n_shots, 2);
        assert_eq!(m.points, vec![0]);
        assert!((m.amplitude(0, 1, 0) - Complex64::new(3e-9, 4e-9)).norm() < 1e-22);
        assert!((m.amplitude(1, 0, 0) - Complex64::new(11e-9, 12e-9)).norm() < 1e-22);
        assert_eq!(m.freq_index(1010.0), Some(2));
        assert!(ds.truth.is_none());
        assert!(ds.check_modes(&["q1", "q2"]).is_ok());
        let e = ds.check_modes(&["x1"]).expect_err("unknown mode");
        assert!(e.to_string().contains("\"q1\" is not declared"), "{e}");
    }

    #[test]
    fn write_then_read_round_trips() {
        let d = good_dir();
        let mut ds = Dataset::load(d.path()).expect("load");
        ds.truth = Some(Truth {
            noise: Some(TruthNoise {
                sigma_per_quadrature: 0.1,
                shots: Some(2),
            }),
            ..Truth::default()
        });
        let out = tempfile::tempdir().expect("tempdir");
        let target = out.path().join("copy");
        ds.write(&target).expect("write");
        // Overwrite works too.
        ds.write(&target).expect("rewrite");
        let back = Dataset::load(&target).expect("load back");
        assert_eq!(back.manifest, ds.manifest);
        assert_eq!(back.truth, ds.truth);
        let (a, b) = (&back.measurements[0], &ds.measurements[0]);
        assert_eq!(a.freqs_hz, b.freqs_hz);
        for (x, y) in a.data.iter().zip(&b.data) {
            assert!((x - y).norm() <= 1e-15 * y.norm(), "{x} vs {y}");
        }
        // No temporary folders are left behind.
        let n = std::fs::read_dir(out.path()).expect("read_dir").count();
        assert_eq!(n, 1);
    }

    fn expect_err(csv: &str, needle: &str) {
        let d = tempfile::tempdir().expect("tempdir");
        write(d.path(), "dataset.toml", MANIFEST);
        write(d.path(), "m1.csv", csv);
        let e = Dataset::load(d.path()).expect_err("should fail");
        let s = e.to_string();
        assert!(s.contains("m1.csv"), "no file name in: {s}");
        assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
    }

    #[test]
    fn bad_csv_inputs_are_located() {
        expect_err("shot,freq_hz,re\n0,990,1\n", "missing column \"im\"");
        expect_err("shot,freq_hz,re,im\n0,990,1,2\n0,1010,1\n", "row 3");
        expect_err("shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2,3\n", "row 3");
        expect_err("shot,freq_hz,re,im\n0,990,NaN,2\n0,1010,1,2\n", "row 2");
        expect_err(
            "shot,freq_hz,re,im\n0,990,1,inf\n0,1010,1,2\n",
            "not finite",
        );
        expect_err("shot,freq_hz,re,im\n0,990,1,x\n", "not a number");
        expect_err(
            "shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2\n1,990,1,2\n1,1011,1,2\n",
            "different frequency set",
        );
        expect_err(
            "shot,freq_hz,re,im\n0,990,1,2\n0,1011,1,2\n",
            "drive frequency 1010",
        );
        expect_err(
            "shot,freq_hz,re,im\n0,990,1,2\n0,990,1,2\n0,1010,1,2\n",
            "appears twice",
        );
        expect_err(
            "shot,freq_hz,re,im,point\n0,990,1,2,p9\n0,1010,1,2,p0\n",
            "point \"p9\" is not declared",
        );
        expect_err("shot,freq_hz,re,im\n0,-990,1,2\n", "positive");
        expect_err("shot,freq_hz,re,im\n", "no data rows");
    }

    #[test]
    fn from_parts_checks_and_sorts_like_a_file() {
        let d = good_dir();
        let ds = Dataset::load(d.path()).expect("load");
        let m = &ds.measurements[0];
        // The same measurement with its frequencies reversed comes back sorted.
        let mut rev = m.clone();
        rev.freqs_hz.reverse();
        rev.data = (0..m.n_shots)
            .flat_map(|s| (0..3).rev().map(move |f| (s, f)))
            .map(|(s, f)| m.amplitude(s, f, 0))
            .collect();
        let built = Dataset::from_parts("arrays", ds.manifest.clone(), vec![rev], None)
            .expect("from_parts");
        assert_eq!(built.measurements[0], *m);
        assert_eq!(built.manifest, ds.manifest);
        let fail = |edit: &dyn Fn(&mut Measurement), needle: &str| {
            let mut x = m.clone();
            edit(&mut x);
            let e = Dataset::from_parts("arrays", ds.manifest.clone(), vec![x], None)
                .expect_err("should fail");
            let s = e.to_string();
            assert!(s.starts_with("arrays"), "no origin in: {s}");
            assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
        };
        fail(&|x| x.data.truncate(5), "= 6");
        fail(&|x| x.data[4].im = f64::NAN, "shot 1 at 990 Hz");
        fail(&|x| x.freqs_hz[0] = 990.0, "appears twice");
        fail(&|x| x.freqs_hz[2] = 1011.0, "drive frequency 1010");
        fail(&|x| x.freqs_hz[0] = -1.0, "positive");
        fail(&|x| x.points = vec![3], "declared points");
        fail(&|x| x.spec.drive_levels_v = None, "give both");
    }

    #[test]
    fn bad_manifests_are_reported() {
        let d = tempfile::tempdir().expect("tempdir");
        write(
            d.path(),
            "m1.csv",
            "shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2\n",
        );
        for (text, needle) in [
            (
                MANIFEST.replace("harmonid-dataset/1", "v0"),
                "format is \"v0\"",
            ),
            (MANIFEST.replace("\"nm\"", "\"mm\""), "displacement_unit"),
            (
                MANIFEST.replace("drive_levels_v = [1.0, 1.0]", "drive_levels_v = [1.0]"),
                "1 entries",
            ),
            (MANIFEST.replace("drives_hz", "drives"), "dataset.toml"),
            (
                MANIFEST.replace("name = \"m1\"", "name = \"m1\"\nfile = \"../x.csv\""),
                "inside the dataset folder",
            ),
        ] {
            write(d.path(), "dataset.toml", &text);
            let e = Dataset::load(d.path()).expect_err("should fail");
            let s = e.to_string();
            assert!(s.contains("dataset.toml"), "{s}");
            assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
        }
    }

    #[test]
    fn missing_file_names_the_path() {
        let d = tempfile::tempdir().expect("tempdir");
        write(d.path(), "dataset.toml", MANIFEST);
        let e = Dataset::load(d.path()).expect_err("should fail");
        assert!(e.to_string().contains("m1.csv"));
    }
}

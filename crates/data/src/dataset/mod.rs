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
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum DatasetError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    #[diagnostic(
        code(harmonid::dataset::io),
        help("check that the dataset folder exists and holds dataset.toml and every measurement's CSV")
    )]
    Io {
        /// File or folder concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// `dataset.toml` or `truth.toml` is not valid TOML or lacks a required key.
    #[error("{path}: {message}")]
    #[diagnostic(
        code(harmonid::dataset::toml),
        help("the manifest's keys are described in docs/data-format.md (format, displacement_unit, [[point]], [nominal_hz], [[measurement]])")
    )]
    Toml {
        /// File concerned.
        path: PathBuf,
        /// Parser message (with line and column).
        message: String,
    },
    /// The manifest's `format` is not [`DATASET_FORMAT`].
    #[error("{path}: format is \"{found}\", expected \"{DATASET_FORMAT}\"")]
    #[diagnostic(
        code(harmonid::dataset::format),
        help("write format = \"harmonid-dataset/1\" on the manifest's first line")
    )]
    Format {
        /// Manifest path.
        path: PathBuf,
        /// What the file says.
        found: String,
    },
    /// A problem in the manifest that is not a TOML syntax error.
    #[error("{path}: {message}")]
    #[diagnostic(code(harmonid::dataset::manifest))]
    Manifest {
        /// Manifest path.
        path: PathBuf,
        /// What is wrong and what to do about it.
        message: String,
    },
    /// A CSV file lacks a required column.
    #[error("{path}: missing column \"{column}\" in the header (found: {found}); required: shot, freq_hz, re, im")]
    #[diagnostic(
        code(harmonid::dataset::missing_column),
        help("the first row names the columns, e.g. shot,freq_hz,re,im")
    )]
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
    #[diagnostic(code(harmonid::dataset::row))]
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
    #[diagnostic(
        code(harmonid::dataset::inconsistent),
        help("every shot and point of a measurement lists the same frequencies (docs/data-format.md)")
    )]
    Inconsistent {
        /// CSV path.
        path: PathBuf,
        /// Which shot/point differs from which, and how.
        message: String,
    },
    /// A drive frequency of the manifest is not among the measured frequencies.
    #[error("{path}: drive frequency {drive_hz} Hz of measurement \"{measurement}\" is not among its measured frequencies (nearest measured: {nearest_hz} Hz); every drive tone must be measured")]
    #[diagnostic(
        code(harmonid::dataset::drive_not_measured),
        help("correct drives_hz in dataset.toml, or add the drive tone's row to every shot")
    )]
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
    /// Datasets to merge disagree on a key that says what their numbers mean.
    #[error(
        "{path}: {key} is {found}, but {first} has {expected}; datasets merged must agree on it"
    )]
    #[diagnostic(
        code(harmonid::dataset::merge_mismatch),
        help("merge pools datasets of one device taken with the same conventions, unit, points and nominal frequencies (docs/data-format.md, \"Merging datasets\"); convert or re-import the odd one")
    )]
    MergeMismatch {
        /// Manifest of the input that differs.
        path: PathBuf,
        /// The key (`displacement_unit`, `point "p0" shape.q1`, `nominal_hz.q2`, ...).
        key: String,
        /// Its value there.
        found: String,
        /// Manifest of the first input.
        first: PathBuf,
        /// Its value in the first input.
        expected: String,
    },
    /// Under the merged dataset's nominal frequencies (the last input's) a line of an input
    /// would belong to another mode than under the input's own.
    #[error("{path}: line {hz} Hz of \"{measurement}\" belongs to mode {own} under its own nominal_hz but to {merged} under the last input's, which the merged dataset keeps")]
    #[diagnostic(
        code(harmonid::dataset::merge_attribution),
        help("nominal frequencies decide which mode a line belongs to; give the inputs nominal_hz values that attribute every line alike (edit [nominal_hz] in one dataset.toml), or identify them apart")
    )]
    MergeAttribution {
        /// Manifest of the input holding the line.
        path: PathBuf,
        /// Its measurement.
        measurement: String,
        /// The line (a measured frequency or a drive tone), Hz.
        hz: f64,
        /// Its mode under the input's nominal frequencies.
        own: String,
        /// Its mode under the merged ones.
        merged: String,
    },
    /// One dataset folder given twice: its measurements would count twice.
    #[error(
        "{path} is given twice; merging a dataset with itself would count every measurement twice"
    )]
    #[diagnostic(
        code(harmonid::dataset::merge_twice),
        help("give each dataset folder once")
    )]
    MergeTwice {
        /// The folder given twice.
        path: PathBuf,
    },
    /// A name in two inputs whose folders have the same name too: renaming cannot part them.
    #[error("measurement or sweep \"{name}\" is in {first} and in {second}, and both would be renamed \"{renamed}\"")]
    #[diagnostic(
        code(harmonid::dataset::merge_name_clash),
        help("a name in several inputs is prefixed by its folder's name; give the input folders different names (e.g. round1, round2)")
    )]
    MergeNameClash {
        /// The name found in both.
        name: String,
        /// The prefixed name both would get.
        renamed: String,
        /// Manifest of one input.
        first: PathBuf,
        /// Manifest of the other.
        second: PathBuf,
    },
    /// An output folder that may not be replaced, or an input path outside the dataset folder.
    #[error(transparent)]
    #[diagnostic(transparent)]
    File(#[from] harmonid_files::FileError),
}

/// Largest `dataset.toml` or `truth.toml` read, in bytes (a manifest is a short text file).
pub const MAX_MANIFEST_BYTES: u64 = 16 * 1024 * 1024;

/// Reads the small text file `name` of folder `dir`, refusing a path that leads outside it and
/// a file larger than [`MAX_MANIFEST_BYTES`].
fn read_inside(dir: &Path, name: &str) -> Result<String, DatasetError> {
    let shown = dir.join(name);
    let real = match harmonid_files::resolve_inside(dir, Path::new(name)) {
        Err(harmonid_files::FileError::Io { source, .. }) => {
            return Err(DatasetError::Io {
                path: shown,
                source,
            })
        }
        r => r?,
    };
    let len = std::fs::metadata(&real).map_err(io_err(&shown))?.len();
    if len > MAX_MANIFEST_BYTES {
        return Err(DatasetError::Manifest {
            path: shown,
            message: format!(
                "the file is {len} bytes, more than the {MAX_MANIFEST_BYTES} a manifest may have"
            ),
        });
    }
    std::fs::read_to_string(&real).map_err(io_err(&shown))
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
    /// The pump tones of a parametrically pumped measurement, Hz: the model's `pump` signal
    /// is `Σ_k pump_levels[k] · cos(2π pumps_hz[k] t + pump_phases_rad[k])` (empty: no pump).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pumps_hz: Vec<f64>,
    /// Level of each pump tone, in the unit the model's pump coefficients are per (V, or the
    /// relative stiffness modulation, ...); required with `pumps_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_levels: Option<Vec<f64>>,
    /// Phase of each pump tone, rad, on the time base of the drive and the measured amplitudes;
    /// required with `pumps_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_phases_rad: Option<Vec<f64>>,
    /// Measurement bandwidth, Hz (metadata, carried to reports).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_hz: Option<f64>,
    /// The sweep and step this measurement is, when it was read from a `[[sweep]]` (never
    /// written as a key: the sweep is).
    #[serde(skip)]
    pub sweep: Option<SweepStep>,
}

impl MeasurementSpec {
    /// A measurement called `name` driven at `drives_hz` (Hz), without drive levels, phases,
    /// file name or bandwidth (for generators and tests).
    pub fn new(name: impl Into<String>, drives_hz: Vec<f64>) -> Self {
        MeasurementSpec {
            name: name.into(),
            file: None,
            drives_hz,
            drive_levels_v: None,
            drive_phases_rad: None,
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            bandwidth_hz: None,
            sweep: None,
        }
    }

    /// The CSV file name relative to the dataset folder.
    pub fn file_name(&self) -> String {
        self.file
            .clone()
            .unwrap_or_else(|| format!("{}.csv", self.name))
    }

    /// The pump tones `(Hz, complex amplitude level · e^{i phase})` (empty without a pump;
    /// validation makes levels and phases present with the tones).
    pub fn pump_tones(&self) -> Vec<(f64, num_complex::Complex64)> {
        let (Some(l), Some(p)) = (&self.pump_levels, &self.pump_phases_rad) else {
            return Vec::new();
        };
        self.pumps_hz
            .iter()
            .zip(l)
            .zip(p)
            .map(|((&f, &l), &p)| (f, num_complex::Complex64::from_polar(l, p)))
            .collect()
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
    /// Unit of `re`/`im` in the CSV files: a length unit of [`crate::units::LENGTH_UNITS`]
    /// ("m", "um", "nm", "pm", ...), or "V" for data kept in the instrument's volts.
    #[serde(default = "default_unit")]
    pub displacement_unit: String,
    /// Measurement points (may be empty: then the data are modal amplitudes directly).
    #[serde(default, rename = "point", skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<Point>,
    /// Approximate resonance frequency of each mode, Hz.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub nominal_hz: BTreeMap<String, f64>,
    /// The measurements.
    #[serde(default, rename = "measurement", skip_serializing_if = "Vec::is_empty")]
    pub measurements: Vec<MeasurementSpec>,
    /// The stepped sweeps (each step read as one measurement).
    #[serde(default, rename = "sweep", skip_serializing_if = "Vec::is_empty")]
    pub sweeps: Vec<SweepSpec>,
    /// How `harmonid import` made this dataset: format, inputs, every convention applied.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub import: Option<crate::conventions::ImportRecord>,
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
            sweeps: Vec::new(),
            import: None,
        }
    }

    /// Metres per `displacement_unit` (1 for volts), or `None` for an unknown unit.
    pub fn unit_scale(&self) -> Option<f64> {
        crate::units::metres_per(&self.displacement_unit)
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
    /// The noise the instrument measured with the data, when each row is already an average
    /// (the CSV's `std` and `samples` columns; one shot); `None`: the noise comes from the
    /// scatter of the shots.
    pub noise: Option<GivenNoise>,
}

/// The noise of a measurement whose rows are averages an instrument made (a sweeper's mean
/// and standard deviation per point), per (frequency, point) in a shot's data order.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenNoise {
    /// Standard deviation per quadrature of one averaged sample, metres (`√((σx² + σy²)/2)`
    /// of the instrument's `xstddev`, `ystddev`).
    pub std: Vec<f64>,
    /// How many samples each row averages.
    pub samples: Vec<u32>,
}

impl GivenNoise {
    /// The noise per quadrature of each row's mean, metres: `std/√samples`.
    pub fn of_mean(&self) -> impl Iterator<Item = f64> + '_ {
        self.std
            .iter()
            .zip(&self.samples)
            .map(|(s, &n)| s / f64::from(n).sqrt())
    }
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
            noise: None,
        }
    }

    /// The measurement with only the measured frequencies `freq_idx` (indices into
    /// `freqs_hz`, in the order given), every shot and point, under `spec`.
    pub fn select_lines(&self, spec: MeasurementSpec, freq_idx: &[usize]) -> Measurement {
        let mut out = Measurement::zeros(
            spec,
            freq_idx.iter().map(|&f| self.freqs_hz[f]).collect(),
            self.points.clone(),
            self.n_shots,
        );
        for s in 0..self.n_shots {
            for (k, &f) in freq_idx.iter().enumerate() {
                for p in 0..self.points.len() {
                    *out.amplitude_mut(s, k, p) = self.amplitude(s, f, p);
                }
            }
        }
        let np = self.points.len();
        out.noise = self.noise.as_ref().map(|g| {
            let pick = || {
                freq_idx
                    .iter()
                    .flat_map(move |&f| (0..np).map(move |p| f * np + p))
            };
            GivenNoise {
                std: pick().map(|i| g.std[i]).collect(),
                samples: pick().map(|i| g.samples[i]).collect(),
            }
        });
        out
    }

    /// The measurement with only the shots `shots` (indices, in the order given; each below
    /// `n_shots`).
    pub fn select_shots(&self, shots: &[usize]) -> Measurement {
        let per = self.freqs_hz.len() * self.points.len();
        let mut data = Vec::with_capacity(shots.len() * per);
        for &s in shots {
            data.extend_from_slice(&self.data[s * per..(s + 1) * per]);
        }
        Measurement {
            spec: self.spec.clone(),
            freqs_hz: self.freqs_hz.clone(),
            points: self.points.clone(),
            n_shots: shots.len(),
            data,
            noise: self.noise.clone(),
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
    /// What reading did that a user should know of, one line each (settling samples dropped
    /// per sweep).
    pub notes: Vec<String>,
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
        let text = read_inside(dir, "dataset.toml")?;
        let truth = if dir.join("truth.toml").exists() {
            Some(read_inside(dir, "truth.toml")?)
        } else {
            None
        };
        Dataset::from_readers(dir, &text, truth.as_deref(), |file| {
            let real = harmonid_files::resolve_inside(dir, Path::new(file))?;
            let f = std::fs::File::open(&real).map_err(io_err(&dir.join(file)))?;
            Ok(std::io::BufReader::new(f))
        })
    }

    /// Builds a dataset from its manifest text, optional truth text, and a function that opens
    /// each measurement's CSV by its file name (as written in the manifest). `dir` names the
    /// files in messages. [`Dataset::load`] is this with files of a folder; tests and the fuzzer
    /// call it with text in memory. The CSVs are streamed: memory grows with the rows kept
    /// (32 bytes each), not with the file's size.
    pub fn from_readers<R: std::io::Read>(
        dir: &Path,
        manifest_text: &str,
        truth_text: Option<&str>,
        mut open_csv: impl FnMut(&str) -> Result<R, DatasetError>,
    ) -> Result<Dataset, DatasetError> {
        let mpath = dir.join("dataset.toml");
        let manifest: Manifest = toml::from_str(manifest_text).map_err(|e| DatasetError::Toml {
            path: mpath.clone(),
            message: e.to_string(),
        })?;
        validate_manifest(&manifest, &mpath)?;
        let scale = manifest.unit_scale().unwrap_or(1.0);
        let mut measurements = Vec::with_capacity(manifest.measurements.len());
        for spec in &manifest.measurements {
            let file = spec.file_name();
            let path = dir.join(&file);
            let reader = open_csv(&file)?;
            measurements.push(read_csv(reader, &path, spec, &manifest, scale)?);
        }
        let mut notes = Vec::new();
        for sw in &manifest.sweeps {
            let file = sw.file_name();
            let path = dir.join(&file);
            let reader = open_csv(&file)?;
            let (steps, note) = read_sweep_csv(reader, &path, sw, &manifest, scale)?;
            measurements.extend(steps);
            notes.extend(note);
        }
        let truth = match truth_text {
            Some(text) => {
                let tpath = dir.join("truth.toml");
                Some(
                    toml::from_str::<Truth>(text).map_err(|e| DatasetError::Toml {
                        path: tpath,
                        message: e.to_string(),
                    })?,
                )
            }
            None => None,
        };
        Ok(Dataset {
            dir: dir.to_path_buf(),
            manifest,
            measurements,
            truth,
            notes,
        })
    }

    /// Every file this dataset was read from (manifest, CSVs, `truth.toml` if any), as paths
    /// under [`Dataset::dir`]: the inputs a command must never overwrite.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut v = vec![self.dir.join("dataset.toml")];
        for m in &self.measurements {
            let p = self.dir.join(m.spec.file_name());
            if !v.contains(&p) {
                v.push(p);
            }
        }
        if self.truth.is_some() {
            v.push(self.dir.join("truth.toml"));
        }
        v
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
        entries_from(&mut manifest, &measurements, &dir)?;
        validate_manifest(&manifest, &dir)?;
        for m in &mut measurements {
            check_measurement(m, manifest.points.len(), &dir)?;
        }
        Ok(Dataset {
            dir,
            manifest,
            measurements,
            truth,
            notes: Vec::new(),
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

    /// Writes the dataset into folder `dir` atomically (see [`Dataset::write_with`]), replacing
    /// an existing folder only when it is empty or a harmonid dataset.
    pub fn write(&self, dir: impl AsRef<Path>) -> Result<(), DatasetError> {
        self.write_with(dir, harmonid_files::DirWrite::default())
    }

    /// Writes the dataset into folder `dir` (created with its parents, or replaced) atomically:
    /// all files are written into a staging folder beside it which is then renamed into place,
    /// so a reader never sees a partial dataset. An existing `dir` is replaced only when it is
    /// empty or a harmonid dataset, or with `opts.force`; never when it holds one of
    /// `opts.inputs` (see [`harmonid_files::replace_dir`]). The manifest written is
    /// `self.manifest` (its `measurements` are taken from `self.measurements[..].spec`),
    /// amplitudes are converted from metres to its `displacement_unit`. Writes `truth.toml`
    /// when `self.truth` is set. Files get the umask's permissions.
    pub fn write_with(
        &self,
        dir: impl AsRef<Path>,
        opts: harmonid_files::DirWrite<'_>,
    ) -> Result<(), DatasetError> {
        let dir = dir.as_ref();
        let mut manifest = self.manifest.clone();
        let mpath = dir.join("dataset.toml");
        entries_from(&mut manifest, &self.measurements, &mpath)?;
        for sw in &mut manifest.sweeps {
            // The settling samples were dropped when read: what is written is settled.
            sw.settle_s = None;
            sw.settle_samples = None;
        }
        validate_manifest(&manifest, &mpath)?;
        let scale = manifest.unit_scale().unwrap_or(1.0);
        let manifest_text = toml::to_string(&manifest).map_err(|e| DatasetError::Toml {
            path: mpath.clone(),
            message: e.to_string(),
        })?;
        let truth_text = match &self.truth {
            Some(t) => Some(toml::to_string(t).map_err(|e| DatasetError::Toml {
                path: dir.join("truth.toml"),
                message: e.to_string(),
            })?),
            None => None,
        };
        harmonid_files::replace_dir(dir, opts, |tmp| -> Result<(), DatasetError> {
            let p = tmp.join("dataset.toml");
            std::fs::write(&p, &manifest_text).map_err(io_err(&p))?;
            for m in self.measurements.iter().filter(|m| m.spec.sweep.is_none()) {
                let p = tmp.join(m.spec.file_name());
                if let Some(d) = p.parent() {
                    std::fs::create_dir_all(d).map_err(io_err(d))?;
                }
                std::fs::write(&p, csv_text(m, &manifest, scale)).map_err(io_err(&p))?;
            }
            for sw in &manifest.sweeps {
                let p = tmp.join(sw.file_name());
                if let Some(d) = p.parent() {
                    std::fs::create_dir_all(d).map_err(io_err(d))?;
                }
                let steps: Vec<&Measurement> = self
                    .measurements
                    .iter()
                    .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| s.sweep == sw.name))
                    .collect();
                std::fs::write(&p, sweep_csv_text(&steps, &manifest, scale)).map_err(io_err(&p))?;
            }
            if let Some(text) = &truth_text {
                let p = tmp.join("truth.toml");
                std::fs::write(&p, text).map_err(io_err(&p))?;
            }
            Ok(())
        })
    }
}

/// The manifest's entries from the measurements in memory: `[[measurement]]` from those read
/// from no sweep, and each `[[sweep]]`'s steps (tones, levels, phases) from its step
/// measurements, which must be steps of a sweep the manifest declares, in measurement order
/// (a subset of them is fine: steps left out are left out of the sweep).
fn entries_from(
    manifest: &mut Manifest,
    measurements: &[Measurement],
    path: &Path,
) -> Result<(), DatasetError> {
    let bad = |message: String| DatasetError::Manifest {
        path: path.to_path_buf(),
        message,
    };
    manifest.measurements = measurements
        .iter()
        .filter(|m| m.spec.sweep.is_none())
        .map(|m| m.spec.clone())
        .collect();
    let mut steps: Vec<Vec<&MeasurementSpec>> = vec![Vec::new(); manifest.sweeps.len()];
    for m in measurements {
        let Some(st) = &m.spec.sweep else { continue };
        let i = manifest
            .sweeps
            .iter()
            .position(|s| s.name == st.sweep)
            .ok_or_else(|| {
                bad(format!(
                    "measurement \"{}\" is a step of sweep \"{}\", which the manifest does not declare; add its [[sweep]]",
                    m.spec.name, st.sweep
                ))
            })?;
        if let Some(prev) = steps[i].last().and_then(|s| s.sweep.as_ref()) {
            if st.step <= prev.step {
                return Err(bad(format!(
                    "sweep \"{}\": step {} comes after step {}; give the steps in measurement order",
                    st.sweep, st.step, prev.step
                )));
            }
        }
        steps[i].push(&m.spec);
    }
    // A sweep none of whose steps is among the measurements (a subset, a holdout) is dropped.
    let mut kept = steps.iter().map(|s| !s.is_empty());
    manifest.sweeps.retain(|_| kept.next().unwrap_or(false));
    steps.retain(|s| !s.is_empty());
    for (sw, specs) in manifest.sweeps.iter_mut().zip(&steps) {
        sw.drives_hz = specs.iter().map(|s| s.drives_hz.clone()).collect();
        let per_step = |f: &dyn Fn(&MeasurementSpec) -> Option<Vec<f64>>| -> Option<PerStep> {
            let v: Option<Vec<Vec<f64>>> = specs.iter().map(|s| f(s)).collect();
            v.map(|v| {
                if v.windows(2).all(|w| w[0] == w[1]) {
                    PerStep::Same(v[0].clone())
                } else {
                    PerStep::Each(v)
                }
            })
        };
        sw.drive_levels_v = per_step(&|s| s.drive_levels_v.clone());
        sw.drive_phases_rad = per_step(&|s| s.drive_phases_rad.clone());
    }
    Ok(())
}

mod csv_read;
mod merge;
#[cfg(test)]
mod merge_tests;
mod parts;
mod sweep;
#[cfg(test)]
mod sweep_tests;
#[cfg(test)]
mod tests;
mod validate;
mod write;

use sweep::read_sweep_csv;
pub use sweep::{Direction, PerStep, SweepSpec, SweepStep};

use csv_read::read_csv;
pub use csv_read::{MAX_AMPLITUDE_M, MAX_FREQ_HZ};
use parts::{check_drives_measured, check_measurement};
use validate::validate_manifest;
use write::{csv_text, sweep_csv_text};

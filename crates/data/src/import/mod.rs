//! Instrument files into datasets (`harmonid import FORMAT INPUT… --out DIR`).
//!
//! Each format is one file of this folder that turns its input into [`Record`]s: one sampled
//! complex amplitude at one measured line, in the file's own units and quadrature convention,
//! with what the file knows of the drive. [`build`] then applies the [`Conventions`] (every one
//! explicit: peak or RMS, quadrature sign, what was sensed, the scale to metres or volts),
//! groups the records into sweep steps and sweeps, drops the settling samples, and ends in
//! [`Dataset::from_parts`], so an imported dataset obeys every rule a dataset file does. What
//! was assumed is written into the manifest's `[import]` table.

pub mod mat;
pub mod moku_csv;
pub mod table;
pub mod zi_csv;
pub mod zi_hdf5;
pub mod zi_sweeper;

use crate::dataset::{
    Dataset, DatasetError, Direction, Manifest, Measurement, SweepSpec, FREQ_REL_TOL,
};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// What can be wrong with an import: every variant names the file (and row or field).
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum ImportError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    #[diagnostic(code(harmonid::import::io))]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The input's content breaks what its format promises.
    #[error("{path}{}: {message}", .row.map(|r| format!(", row {r}")).unwrap_or_default())]
    #[diagnostic(code(harmonid::import::input))]
    Input {
        /// The file.
        path: PathBuf,
        /// 1-based row (header = row 1), when the problem is in one row.
        row: Option<usize>,
        /// What is wrong and what to do.
        message: String,
    },
    /// The mapping file or a command-line option is missing a convention or is wrong.
    #[error("{origin}: {message}")]
    #[diagnostic(
        code(harmonid::import::convention),
        help("docs/data-format.md, \"From your instrument to a dataset\", lists every option")
    )]
    Convention {
        /// The mapping file, or the option.
        origin: String,
        /// What is missing or wrong, naming the key.
        message: String,
    },
    /// The imported data do not make a valid dataset.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Dataset(#[from] DatasetError),
}

/// Reads an input file as text; an I/O failure names it.
fn read_input(path: &Path) -> Result<String, ImportError> {
    std::fs::read_to_string(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Calls `each(row, line)` for every line of the text file `path` (rows 1-based), streamed
/// through one reused buffer: a 70 MB record is never held whole.
fn for_each_line(
    path: &Path,
    mut each: impl FnMut(usize, &str) -> Result<(), ImportError>,
) -> Result<(), ImportError> {
    use std::io::BufRead;
    let io = |source: std::io::Error| ImportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut reader = std::io::BufReader::new(std::fs::File::open(path).map_err(io)?);
    let mut line = String::new();
    let mut row = 0;
    loop {
        line.clear();
        row += 1;
        match reader.read_line(&mut line) {
            Ok(0) => return Ok(()),
            Ok(_) => each(row, line.trim_end_matches(['\n', '\r']))?,
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(ImportError::Input {
                    path: path.to_path_buf(),
                    row: Some(row),
                    message: "not UTF-8 text: is this the file meant (a binary export)?".into(),
                })
            }
            Err(e) => return Err(io(e)),
        }
    }
}

/// One spelling per convention value, the manifest's (serde) one: `name()` and `FromStr`, so
/// the command line, Python and the `[import]` table read and write the same words.
macro_rules! spellings {
    ($t:ty { $($v:ident => $n:literal),+ $(,)? }) => {
        impl $t {
            /// The value's spelling, as the manifest writes it.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$v => $n,)+
                }
            }
        }

        impl std::str::FromStr for $t {
            /// What was expected, for a message that names the option.
            type Err = String;

            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($n => Ok(Self::$v),)+
                    _ => Err(format!(
                        "\"{s}\": expected {}",
                        [$(concat!("\"", $n, "\"")),+].join(" or ")
                    )),
                }
            }
        }
    };
}

/// Peak or RMS amplitudes in the file. harmonid's amplitudes are peak.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Amplitude {
    /// The file's X, Y (or R) are peak amplitudes.
    Peak,
    /// RMS: multiplied by √2.
    Rms,
}

/// The sign of the file's quadrature against harmonid's `Re[X e^{+i2πft}]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Quadrature {
    /// `X = x + i·y` (a weakly driven mode's phase falls through −π/2 going up in frequency).
    #[serde(rename = "x+iy")]
    XPlusIY,
    /// `X = x − i·y` (the file's phase rises through a resonance).
    #[serde(rename = "x-iy")]
    XMinusIY,
}

/// What the sensor measured; harmonid wants displacement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Response {
    /// Displacement (or a signal proportional to it).
    Displacement,
    /// Velocity: divided by `i·2πf`.
    Velocity,
    /// Acceleration: divided by `−(2πf)²` (so its phase shifts by π).
    Acceleration,
}

/// The unit of an angle in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseUnit {
    /// Radians.
    Rad,
    /// Degrees.
    Deg,
    /// Cycles (Moku's "1 V per cycle").
    Cycles,
}

spellings!(Amplitude { Peak => "peak", Rms => "rms" });
spellings!(Quadrature { XPlusIY => "x+iy", XMinusIY => "x-iy" });
spellings!(Response {
    Displacement => "displacement",
    Velocity => "velocity",
    Acceleration => "acceleration",
});
spellings!(PhaseUnit { Rad => "rad", Deg => "deg", Cycles => "cycles" });

impl PhaseUnit {
    /// `x` in this unit, in radians.
    pub fn to_rad(self, x: f64) -> f64 {
        match self {
            PhaseUnit::Rad => x,
            PhaseUnit::Deg => x.to_radians(),
            PhaseUnit::Cycles => 2.0 * PI * x,
        }
    }
}

/// Every convention that turns a file's numbers into harmonid's: none has a default, so a
/// missing one is an error naming its option.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Conventions {
    /// Peak or RMS.
    pub amplitude: Amplitude,
    /// `x+iy` or `x-iy`.
    pub quadrature: Quadrature,
    /// What was sensed (default displacement).
    #[serde(default = "displacement")]
    pub response: Response,
    /// Metres of displacement per unit of the file (after the response conversion), or absent
    /// with `displacement_unit = "V"`: the dataset keeps the instrument's unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metres_per_unit: Option<f64>,
    /// `"m"` (with `metres_per_unit`) or `"V"` (no sensor calibration: every result in volts).
    pub displacement_unit: String,
    /// Unit of the file's phase columns (required when there are any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase_unit: Option<PhaseUnit>,
    /// Hz per unit of the file's frequency column (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frequency_scale: Option<f64>,
}

fn displacement() -> Response {
    Response::Displacement
}

impl Conventions {
    /// Checks the combination, naming `origin` (the mapping file or the options).
    pub fn check(&self, origin: &str) -> Result<(), ImportError> {
        let bad = |message: String| ImportError::Convention {
            origin: origin.to_string(),
            message,
        };
        match (self.displacement_unit.as_str(), self.metres_per_unit) {
            ("V", None) => {}
            ("V", Some(_)) => {
                return Err(bad(
                    "displacement_unit = \"V\" keeps volts: remove metres_per_unit, or set displacement_unit = \"m\"".into(),
                ))
            }
            ("m", Some(k)) if k.is_finite() && k > 0.0 => {}
            ("m", _) => {
                return Err(bad(
                    "displacement_unit = \"m\" needs metres_per_unit (metres of displacement per unit of the file, positive), e.g. metres_per_unit = 5e-8".into(),
                ))
            }
            (u, _) => {
                return Err(bad(format!(
                    "displacement_unit = \"{u}\": use \"m\" (with metres_per_unit) or \"V\""
                )))
            }
        }
        if let Some(s) = self.frequency_scale {
            if !(s.is_finite() && s > 0.0) {
                return Err(bad(format!(
                    "frequency_scale = {s}: expected a positive number of Hz per unit"
                )));
            }
        }
        Ok(())
    }

    /// The file's complex amplitude `z` at `f_hz` as harmonid's peak displacement in the
    /// dataset's unit.
    pub fn apply(&self, z: Complex64, f_hz: f64) -> Complex64 {
        let mut x = match self.quadrature {
            Quadrature::XPlusIY => z,
            Quadrature::XMinusIY => z.conj(),
        };
        if self.amplitude == Amplitude::Rms {
            x *= std::f64::consts::SQRT_2;
        }
        let w = 2.0 * PI * f_hz;
        x = match self.response {
            Response::Displacement => x,
            Response::Velocity => x / Complex64::new(0.0, w),
            Response::Acceleration => x / -(w * w),
        };
        x * self.metres_per_unit.unwrap_or(1.0)
    }
}

/// Which samples of a step are the response settling after the step: dropped.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Settle {
    /// Samples less than this many seconds after the step's first sample.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_s: Option<f64>,
    /// The first this many samples of each step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_samples: Option<usize>,
}

/// One sampled line, as the file gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// The step's drive tone, in the file's frequency unit.
    pub drive: f64,
    /// The measured line, in the file's frequency unit (the drive tone for a single line).
    pub line: f64,
    /// Complex amplitude `x + i·y`, in the file's units.
    pub z: Complex64,
    /// The drive level of the step, if known.
    pub level: Option<f64>,
    /// The drive phase of the step, rad, if known.
    pub drive_phase_rad: Option<f64>,
    /// Which group (input file, struct element, sweep column value) the record belongs to.
    pub group: usize,
    /// The explicit step number, if the file has one.
    pub step: Option<u64>,
    /// Sample time, s (any origin), if known.
    pub time_s: Option<f64>,
    /// Where it came from: input file index and 1-based row (for messages).
    pub origin: (usize, usize),
    /// When the sample is an average the instrument made: the standard deviation per quadrature
    /// of the samples it averaged (the file's units) and how many.
    pub noise: Option<(f64, u32)>,
}

/// How to cut records into sweeps, and what to call them.
#[derive(Debug, Clone, Default)]
pub struct Grouping {
    /// A name per group (input file stem, struct element); empty: named by drive level.
    pub group_names: Vec<String>,
    /// Start a new sweep when the drive level changes between steps of one group (for files
    /// that hold several level sweeps one after the other).
    pub split_on_level: bool,
}

/// What [`build`] records in the manifest's `[import]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportRecord {
    /// The format name (`table`, `zi-csv`, ...).
    pub format: String,
    /// The input files, as given.
    pub inputs: Vec<String>,
    /// The conventions applied.
    pub conventions: Conventions,
    /// The settling rule applied.
    #[serde(default)]
    pub settle: Settle,
    /// Samples dropped as settling, of all read.
    pub settling_dropped: usize,
    /// Samples read.
    pub samples_read: usize,
    /// The format's own settings that were applied (a Moku's channel assignment, output gain
    /// and offset, where the demodulation frequency came from; a LabOne clock base).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub instrument: std::collections::BTreeMap<String, String>,
}

/// A LabOne clock base (ticks per second) is given and usable, else an error naming the option.
fn check_clockbase(hz: f64) -> Result<(), ImportError> {
    if hz.is_finite() && hz > 0.0 {
        return Ok(());
    }
    Err(ImportError::Convention {
        origin: "--clockbase-hz".into(),
        message: "the device's clock base is needed to turn ticks into seconds (60e6 on the MFLI, 1.8e9 on the UHFLI)".into(),
    })
}

/// Records the format's own settings `pairs` in `ds`'s `[import.instrument]` table.
fn record_instrument(ds: &mut Dataset, pairs: &[(&str, String)]) {
    if let Some(imp) = ds.manifest.import.as_mut() {
        for (k, v) in pairs {
            imp.instrument.insert((*k).to_string(), v.clone());
        }
    }
}

/// One step while building: its drive, level, lines, and samples stored flat.
struct Step {
    group: usize,
    drive: f64,
    level: Option<f64>,
    phase: Option<f64>,
    /// The lines, Hz, in the order the step's first sample gave them.
    lines: Vec<f64>,
    /// Per sample, its time.
    times: Vec<Option<f64>>,
    /// `data[sample · lines.len() + line]`.
    data: Vec<Complex64>,
    /// Which lines the last sample has so far.
    seen: Vec<bool>,
    /// The noise given with each value of `data` (converted like the amplitudes), when the
    /// records carry it.
    noise: Option<Vec<(f64, u32)>>,
    /// Where the first record of the step came from (for messages).
    origin: (usize, usize),
}

impl Step {
    /// Whether the last sample has every line.
    fn complete(&self) -> bool {
        self.seen.iter().all(|&b| b)
    }
}

/// The dataset the records make: conventions applied, steps and sweeps cut, settling
/// dropped. `inputs` name the files in messages; `out` names the dataset. Returns the
/// dataset and the one-line note on settling. Records are consumed as they come: a million
/// samples take their 16-byte amplitudes and little else.
pub fn build(
    format: &str,
    inputs: &[PathBuf],
    records: impl IntoIterator<Item = Record>,
    conv: &Conventions,
    settle: Settle,
    grouping: &Grouping,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    let first_input = inputs.first().cloned().unwrap_or_default();
    let path_of = |r: (usize, usize)| inputs.get(r.0).cloned().unwrap_or_default();
    let incomplete = |s: &Step| {
        ImportError::Input {
        path: path_of(s.origin),
        row: Some(s.origin.1),
        message: format!(
            "the step at {} Hz starting here has a sample without every line of its first sample ({} lines); every sample of a step must measure the same lines",
            s.drive,
            s.lines.len()
        ),
    }
    };
    let fscale = conv.frequency_scale.unwrap_or(1.0);
    // Steps: consecutive records with the same group, explicit step, drive and level.
    // Frequencies recorded per sample jitter in their last digits (a PLL, a float
    // conversion): one step's drive, and one line, are the same to FREQ_REL_TOL.
    let same = |a: f64, b: f64| (a - b).abs() <= FREQ_REL_TOL * a.abs().max(b.abs());
    if let Some(t) = settle.settle_s.filter(|t| !(t.is_finite() && *t >= 0.0)) {
        return Err(ImportError::Convention {
            origin: "settle_s".into(),
            message: format!("{t}: the settling time is a number of seconds, 0 or more"),
        });
    }
    let mut steps: Vec<Step> = Vec::new();
    let mut last: Option<Record> = None;
    for r in records {
        if settle.settle_s.is_some() && r.time_s.is_none() {
            return Err(ImportError::Convention {
                origin: "--settle-s".into(),
                message: "the input has no sample times; drop settling samples by count (settle_samples) instead".into(),
            });
        }
        let new_step = match &last {
            None => true,
            Some(p) => {
                p.group != r.group
                    || p.step != r.step
                    || !same(p.drive, r.drive)
                    || p.level.map(f64::to_bits) != r.level.map(f64::to_bits)
            }
        };
        last = Some(r);
        if new_step {
            if let Some(prev) = steps.last() {
                if !prev.complete() {
                    return Err(incomplete(prev));
                }
            }
            steps.push(Step {
                group: r.group,
                drive: r.drive * fscale,
                level: r.level,
                phase: r.drive_phase_rad,
                lines: Vec::new(),
                times: Vec::new(),
                data: Vec::new(),
                seen: Vec::new(),
                noise: r.noise.map(|_| Vec::new()),
                origin: r.origin,
            });
        }
        let step = steps.last_mut().expect("just pushed");
        let f = r.line * fscale;
        // The line as first recorded in this step (see `same`).
        let known = step.lines.iter().position(|&l| same(l, f));
        let line = known.map_or(f, |i| step.lines[i]);
        let x = conv.apply(r.z, line);
        if !(x.re.is_finite() && x.im.is_finite() && line.is_finite() && line > 0.0) {
            return Err(ImportError::Input {
                path: path_of(r.origin),
                row: Some(r.origin.1),
                message: format!(
                    "frequency {} and amplitude {} {} do not make a finite sample at a positive frequency (NaN rows must be removed, not imported)",
                    r.line, r.z.re, r.z.im
                ),
            });
        }
        // A new sample when this line is already in the last one (or there is none yet).
        if step.times.is_empty() || known.is_some_and(|i| step.seen[i]) {
            if !step.times.is_empty() && !step.complete() {
                return Err(incomplete(step));
            }
            step.times.push(r.time_s);
            step.data.extend(std::iter::repeat_n(
                Complex64::new(0.0, 0.0),
                step.lines.len(),
            ));
            if let Some(n) = step.noise.as_mut() {
                n.extend(std::iter::repeat_n((0.0, 0), step.lines.len()));
            }
            step.seen.iter_mut().for_each(|b| *b = false);
        }
        let i = match known {
            Some(i) => i,
            None if step.times.len() == 1 => {
                step.lines.push(line);
                step.seen.push(false);
                step.data.push(Complex64::new(0.0, 0.0));
                if let Some(n) = step.noise.as_mut() {
                    n.push((0.0, 0));
                }
                step.lines.len() - 1
            }
            None => {
                return Err(ImportError::Input {
                    path: path_of(r.origin),
                    row: Some(r.origin.1),
                    message: format!(
                        "line {} Hz is not among the {} lines of its step's first sample; every sample of a step must measure the same lines",
                        r.line,
                        step.lines.len()
                    ),
                })
            }
        };
        let base = (step.times.len() - 1) * step.lines.len();
        step.data[base + i] = x;
        step.seen[i] = true;
        match (step.noise.as_mut(), r.noise) {
            (Some(n), Some((sd, count))) => {
                n[base + i] = (conv.apply(Complex64::new(sd, 0.0), line).norm(), count);
            }
            (None, None) => {}
            _ => {
                return Err(ImportError::Input {
                    path: path_of(r.origin),
                    row: Some(r.origin.1),
                    message: "some samples of this step carry a standard deviation and some do not"
                        .into(),
                })
            }
        }
    }
    let Some(tail) = steps.last() else {
        return Err(ImportError::Input {
            path: first_input,
            row: None,
            message: "no data rows were read".into(),
        });
    };
    if !tail.complete() {
        return Err(incomplete(tail));
    }
    // Settling.
    let read: usize = steps.iter().map(|s| s.times.len()).sum();
    for s in &mut steps {
        let nl = s.lines.len();
        let t0 = s.times[0];
        let mut kept = 0;
        for j in 0..s.times.len() {
            let keep = match (settle.settle_s, settle.settle_samples) {
                // Every sample has its time (checked above).
                (Some(t), _) => s.times[j].zip(t0).is_none_or(|(ti, t0)| ti - t0 >= t),
                (None, Some(k)) => j >= k,
                (None, None) => true,
            };
            if keep {
                s.times[kept] = s.times[j];
                s.data.copy_within(j * nl..(j + 1) * nl, kept * nl);
                if let Some(n) = s.noise.as_mut() {
                    n.copy_within(j * nl..(j + 1) * nl, kept * nl);
                }
                kept += 1;
            }
        }
        s.times.truncate(kept);
        s.data.truncate(kept * nl);
        if let Some(n) = s.noise.as_mut() {
            n.truncate(kept * nl);
        }
    }
    let kept: usize = steps.iter().map(|s| s.times.len()).sum();
    if let Some(k) = steps.iter().position(|s| s.times.is_empty()) {
        return Err(ImportError::Convention {
            origin: "settling".into(),
            message: format!("step {k} (at {} Hz) keeps no sample after settling; lower settle_s or settle_samples", steps[k].drive),
        });
    }
    // Sweeps: a new one at each group change, and at each level change when asked.
    let mut sweeps: Vec<(usize, usize)> = Vec::new(); // [start, end) step ranges
    let mut start = 0;
    for k in 1..=steps.len() {
        let cut = k == steps.len()
            || steps[k].group != steps[k - 1].group
            || (grouping.split_on_level && steps[k].level != steps[k - 1].level);
        if cut {
            sweeps.push((start, k));
            start = k;
        }
    }
    let mut manifest = Manifest::new(format!("imported by harmonid import {format}"));
    manifest.displacement_unit = conv.displacement_unit.clone();
    let mut measurements = Vec::new();
    let mut names: Vec<String> = Vec::new();
    for &(a, b) in &sweeps {
        let part = &steps[a..b];
        let base = match grouping.group_names.get(part[0].group) {
            Some(n) if !grouping.split_on_level => n.clone(),
            _ => format!(
                "level_{}",
                part[0].level.map_or("none".into(), |l| format!("{l}"))
            ),
        };
        let mut name = base.clone();
        let mut i = 2;
        while names.contains(&name) {
            name = format!("{base}_{i}");
            i += 1;
        }
        names.push(name.clone());
        let fs: Vec<f64> = part.iter().map(|s| s.drive).collect();
        let direction = if fs.windows(2).all(|w| w[1] > w[0]) {
            Direction::Up
        } else if fs.windows(2).all(|w| w[1] < w[0]) {
            Direction::Down
        } else {
            Direction::Unordered
        };
        let mut sw = SweepSpec::new(name, direction, fs.iter().map(|&f| vec![f]).collect());
        let levels: Option<Vec<Vec<f64>>> = part.iter().map(|s| s.level.map(|l| vec![l])).collect();
        if let Some(levels) = levels {
            sw.drive_levels_v = Some(crate::dataset::PerStep::Each(levels));
            sw.drive_phases_rad = Some(crate::dataset::PerStep::Each(
                part.iter().map(|s| vec![s.phase.unwrap_or(0.0)]).collect(),
            ));
        }
        for (k, s) in part.iter().enumerate() {
            let spec = sw.step_spec(k);
            // The lines ascending, as a measurement keeps them.
            let mut order: Vec<usize> = (0..s.lines.len()).collect();
            order.sort_by(|&a, &b| s.lines[a].total_cmp(&s.lines[b]));
            let lines: Vec<f64> = order.iter().map(|&i| s.lines[i]).collect();
            let mut m = Measurement::zeros(spec, lines, Vec::new(), s.times.len());
            for (j, sample) in s.data.chunks_exact(s.lines.len()).enumerate() {
                for (to, &from) in order.iter().enumerate() {
                    *m.amplitude_mut(j, to, 0) = sample[from];
                }
            }
            if let Some(n) = &s.noise {
                if s.times.len() != 1 {
                    return Err(ImportError::Input {
                        path: path_of(s.origin),
                        row: Some(s.origin.1),
                        message: format!(
                            "the step at {} Hz has {} averaged samples with their noise; an averaged step is one sample",
                            s.drive,
                            s.times.len()
                        ),
                    });
                }
                m.noise = Some(crate::dataset::GivenNoise {
                    std: order.iter().map(|&i| n[i].0).collect(),
                    samples: order.iter().map(|&i| n[i].1).collect(),
                });
            }
            measurements.push(m);
        }
        manifest.sweeps.push(sw);
    }
    manifest.import = Some(ImportRecord {
        format: format.to_string(),
        inputs: inputs.iter().map(|p| p.display().to_string()).collect(),
        conventions: conv.clone(),
        settle,
        settling_dropped: read - kept,
        samples_read: read,
        instrument: Default::default(),
    });
    let ds = Dataset::from_parts(out, manifest, measurements, None)?;
    let rule = match (settle.settle_s, settle.settle_samples) {
        (Some(t), _) => format!(" (earlier than {t} s into their step)"),
        (None, Some(n)) => format!(" (the first {n} of each step)"),
        _ => String::new(),
    };
    let note = format!(
        "{} sweeps, {} steps; {} of {read} samples dropped as settling{rule}",
        sweeps.len(),
        steps.len(),
        read - kept
    );
    Ok((ds, note))
}

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
mod passes;
pub mod table;
mod text_table;
mod unmeasured;
pub mod zi_csv;
pub mod zi_hdf5;
pub mod zi_sweeper;

pub use crate::conventions::{
    Amplitude, Conventions, ImportRecord, PhaseUnit, Quadrature, Response, Settle,
};
use crate::dataset::{
    Dataset, DatasetError, Direction, GivenNoise, Manifest, Measurement, MeasurementSpec, PerStep,
    SweepSpec, FREQ_REL_TOL, MAX_AMPLITUDE_M, MAX_FREQ_HZ,
};
use harmonid_files::number;
use num_complex::Complex64;
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
/// The text of `path`, a UTF-8 byte order mark (Excel's "CSV UTF-8") dropped: it would be the
/// invisible first character of the first column's name.
fn read_input(path: &Path) -> Result<String, ImportError> {
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(match text.strip_prefix(BOM) {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// The UTF-8 byte order mark, U+FEFF.
const BOM: char = '\u{feff}';

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
            Ok(_) => {
                let line = line.trim_end_matches(['\n', '\r']);
                // A byte order mark before the header is no part of the first name.
                let line = if row == 1 {
                    line.trim_start_matches(BOM)
                } else {
                    line
                };
                each(row, line)?
            }
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
    /// Nothing was measured at this row: every measured value is NaN (a LabOne sweeper stopped
    /// early writes the points it never reached so). Dropped at a sweep's end, refused inside
    /// one unless [`Grouping::drop_nan_rows`]; its other fields are not used but `group`,
    /// `level` and `origin`.
    pub unmeasured: bool,
}

/// The sweep name for `original` (a file stem, a sweep label), kept as the lab wrote it but
/// for the characters a sweep name cannot hold, each replaced by `_`: path separators `/` and
/// `\` and control characters (the name is also its CSV's file name), `[` `]` (a step is
/// `name[k]`), `,` (`--holdout` lists names with commas), and `: * ? " < > |` (not in Windows
/// file names); spaces at either end are dropped. `Measurements_A=0.32%` stays itself. An
/// empty name, `.` or `..` becomes `sweep`.
pub fn readable_name(original: &str) -> String {
    let name: String = original
        .trim()
        .chars()
        .map(|c| {
            if c.is_control() || "/\\[],:*?\"<>|".contains(c) {
                '_'
            } else {
                c
            }
        })
        .collect();
    match name.as_str() {
        "" | "." | ".." => "sweep".into(),
        _ => name,
    }
}

/// How to cut records into sweeps, and what to call them.
#[derive(Debug, Clone, Default)]
pub struct Grouping {
    /// A name per group (input file stem, struct element); empty: named by drive level.
    pub group_names: Vec<String>,
    /// Per group, where it came from as the lab named it (the input file's name, a sweep label
    /// as written), recorded as each of its sweeps' `source`; empty: none recorded.
    pub sources: Vec<String>,
    /// Start a new sweep when the drive level changes between steps of one group (for files
    /// that hold several level sweeps one after the other).
    pub split_on_level: bool,
    /// Drop the rows where nothing was measured ([`Record::unmeasured`]) inside a sweep too,
    /// each run counted in a warning; else only those at a sweep's end are dropped and one
    /// inside is refused with its row.
    pub drop_nan_rows: bool,
    /// Refuse a sweep without drive levels that turns back more than once: it may be several
    /// levels, each swept up and down, merged (a table without its level column).
    pub passes_need_level: bool,
    /// The groups are the passes of one sweep (a sweeper's loops, cut by the format): whether
    /// an unmeasured row is at the sweep's end or inside it is judged over all of them.
    pub one_sweep: bool,
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

/// Frequencies recorded per sample jitter in their last digits (a PLL, a float conversion):
/// one step's drive, and one line, are the same to [`FREQ_REL_TOL`].
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= FREQ_REL_TOL * a.abs().max(b.abs())
}

/// The input file at `origin` (empty when there is none), for messages.
fn input_path(inputs: &[PathBuf], origin: (usize, usize)) -> PathBuf {
    inputs.get(origin.0).cloned().unwrap_or_default()
}

/// An input error at the file and row `origin` names.
fn input_error(inputs: &[PathBuf], origin: (usize, usize), message: String) -> ImportError {
    ImportError::Input {
        path: input_path(inputs, origin),
        row: Some(origin.1),
        message,
    }
}

/// Whether `r` starts a new step after the record `last`: a step is consecutive records with
/// the same group, explicit step, drive and level.
fn starts_step(last: Option<&Record>, r: &Record) -> bool {
    match last {
        None => true,
        Some(p) => {
            p.group != r.group
                || p.step != r.step
                || !same(p.drive, r.drive)
                || p.level.map(f64::to_bits) != r.level.map(f64::to_bits)
        }
    }
}

impl Step {
    /// The empty step that record `r` starts (its drive scaled to Hz by `fscale`).
    fn starting_at(r: &Record, fscale: f64) -> Step {
        Step {
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
        }
    }

    /// Whether the last sample has every line.
    fn complete(&self) -> bool {
        self.seen.iter().all(|&b| b)
    }

    /// The error for a step whose last sample lacks some of its first sample's lines.
    fn incomplete(&self, inputs: &[PathBuf]) -> ImportError {
        input_error(
            inputs,
            self.origin,
            format!(
                "the step at {} Hz starting here has a sample without every line of its first sample ({} lines); every sample of a step must measure the same lines",
                self.drive,
                self.lines.len()
            ),
        )
    }

    /// Opens a new sample at `time_s`: every line zero and not yet seen.
    fn start_sample(&mut self, time_s: Option<f64>) {
        self.times.push(time_s);
        self.data.extend(std::iter::repeat_n(
            Complex64::new(0.0, 0.0),
            self.lines.len(),
        ));
        if let Some(n) = self.noise.as_mut() {
            n.extend(std::iter::repeat_n((0.0, 0), self.lines.len()));
        }
        self.seen.iter_mut().for_each(|b| *b = false);
    }

    /// Adds the line `line` (Hz) while the first sample is read; returns its index.
    fn add_line(&mut self, line: f64) -> usize {
        self.lines.push(line);
        self.seen.push(false);
        self.data.push(Complex64::new(0.0, 0.0));
        if let Some(n) = self.noise.as_mut() {
            n.push((0.0, 0));
        }
        self.lines.len() - 1
    }

    /// Adds record `r` with the conventions applied: a new sample when its line is already in
    /// the last one, a new line only in the first sample, its noise only if every sample has one.
    fn add(
        &mut self,
        r: &Record,
        conv: &Conventions,
        fscale: f64,
        inputs: &[PathBuf],
    ) -> Result<(), ImportError> {
        let f = r.line * fscale;
        // The line as first recorded in this step (see `same`).
        let known = self.lines.iter().position(|&l| same(l, f));
        let line = known.map_or(f, |i| self.lines[i]);
        let x = conv.apply(r.z, line);
        if !(x.re.abs() <= MAX_AMPLITUDE_M && x.im.abs() <= MAX_AMPLITUDE_M) {
            return Err(input_error(
                inputs,
                r.origin,
                format!(
                    "amplitude ({}, {}) is ({}, {}) {unit} with the conventions applied: more than {MAX_AMPLITUDE_M:e} {unit}, not a resonator's displacement; check the row, the amplitude and the units (displacement_unit, metres_per_unit)",
                    number(r.z.re),
                    number(r.z.im),
                    number(x.re),
                    number(x.im),
                    unit = conv.displacement_unit
                ),
            ));
        }
        // A new sample when this line is already in the last one (or there is none yet).
        if self.times.is_empty() || known.is_some_and(|i| self.seen[i]) {
            if !self.times.is_empty() && !self.complete() {
                return Err(self.incomplete(inputs));
            }
            self.start_sample(r.time_s);
        }
        let i = match known {
            Some(i) => i,
            None if self.times.len() == 1 => self.add_line(line),
            None => {
                return Err(input_error(
                    inputs,
                    r.origin,
                    format!(
                        "line {} Hz is not among the {} lines of its step's first sample; every sample of a step must measure the same lines",
                        number(r.line),
                        self.lines.len()
                    ),
                ))
            }
        };
        let base = (self.times.len() - 1) * self.lines.len();
        self.data[base + i] = x;
        self.seen[i] = true;
        match (self.noise.as_mut(), r.noise) {
            (Some(n), Some((sd, count))) => {
                n[base + i] = (conv.apply(Complex64::new(sd, 0.0), line).norm(), count);
            }
            (None, None) => {}
            _ => {
                return Err(input_error(
                    inputs,
                    r.origin,
                    "some samples of this step carry a standard deviation and some do not".into(),
                ))
            }
        }
        Ok(())
    }

    /// Keeps only the samples `settle` does not drop, in order.
    fn drop_settling(&mut self, settle: Settle) {
        let nl = self.lines.len();
        let t0 = self.times[0];
        let mut kept = 0;
        for j in 0..self.times.len() {
            let keep = match (settle.settle_s, settle.settle_samples) {
                // Every sample has its time (checked when the records were read).
                (Some(t), _) => self.times[j].zip(t0).is_none_or(|(ti, t0)| ti - t0 >= t),
                (None, Some(k)) => j >= k,
                (None, None) => true,
            };
            if keep {
                self.times[kept] = self.times[j];
                self.data.copy_within(j * nl..(j + 1) * nl, kept * nl);
                if let Some(n) = self.noise.as_mut() {
                    n.copy_within(j * nl..(j + 1) * nl, kept * nl);
                }
                kept += 1;
            }
        }
        self.times.truncate(kept);
        self.data.truncate(kept * nl);
        if let Some(n) = self.noise.as_mut() {
            n.truncate(kept * nl);
        }
    }

    /// The step as the measurement `spec`: its lines ascending, as a measurement keeps them,
    /// with the noise given when the step is one averaged sample.
    fn measurement(
        &self,
        spec: MeasurementSpec,
        inputs: &[PathBuf],
    ) -> Result<Measurement, ImportError> {
        let mut order: Vec<usize> = (0..self.lines.len()).collect();
        order.sort_by(|&a, &b| self.lines[a].total_cmp(&self.lines[b]));
        let lines: Vec<f64> = order.iter().map(|&i| self.lines[i]).collect();
        let mut m = Measurement::zeros(spec, lines, Vec::new(), self.times.len());
        for (j, sample) in self.data.chunks_exact(self.lines.len()).enumerate() {
            for (to, &from) in order.iter().enumerate() {
                *m.amplitude_mut(j, to, 0) = sample[from];
            }
        }
        if let Some(n) = &self.noise {
            if self.times.len() != 1 {
                return Err(input_error(
                    inputs,
                    self.origin,
                    format!(
                        "the step at {} Hz has {} averaged samples with their noise; an averaged step is one sample",
                        self.drive,
                        self.times.len()
                    ),
                ));
            }
            m.noise = Some(GivenNoise {
                std: order.iter().map(|&i| n[i].0).collect(),
                samples: order.iter().map(|&i| n[i].1).collect(),
            });
        }
        Ok(m)
    }
}

/// A settling time, when given, is a number of seconds, 0 or more.
fn check_settle_s(settle: Settle) -> Result<(), ImportError> {
    if let Some(t) = settle.settle_s.filter(|t| !(t.is_finite() && *t >= 0.0)) {
        return Err(ImportError::Convention {
            origin: "settle_s".into(),
            message: format!("{t}: the settling time is a number of seconds, 0 or more"),
        });
    }
    Ok(())
}

/// A record's frequencies are positive and finite, at most [`MAX_FREQ_HZ`] in Hz, and its
/// amplitude is finite, else an error at its file and row naming the value as written (`inf`,
/// `1e308`): a step is cut by its frequency, so an `inf` would otherwise join its neighbours'
/// step and be blamed on the next row.
fn check_record(r: &Record, fscale: f64, inputs: &[PathBuf]) -> Result<(), ImportError> {
    for (what, f) in [("drive frequency", r.drive), ("frequency", r.line)] {
        if !(f.is_finite() && f > 0.0 && f * fscale <= MAX_FREQ_HZ) {
            return Err(input_error(
                inputs,
                r.origin,
                format!(
                    "{what} {} is not a positive, finite frequency of at most {MAX_FREQ_HZ:e} Hz{}; fix or remove the row",
                    number(f),
                    if fscale == 1.0 { String::new() } else { format!(" (× frequency_scale {})", number(fscale)) }
                ),
            ));
        }
    }
    if !(r.z.re.is_finite() && r.z.im.is_finite()) {
        return Err(input_error(
            inputs,
            r.origin,
            format!(
                "amplitude ({}, {}) is not finite; NaN rows must be removed, not imported (a row with every measured value NaN, a point never measured, is dropped at a sweep's end or with --drop-nan-rows; this one has a value)",
                number(r.z.re),
                number(r.z.im)
            ),
        ));
    }
    Ok(())
}

/// The records cut into complete steps, consumed as they come. Settling by time needs every
/// record's time; an empty input is an error naming the first file.
fn collect_steps(
    records: impl IntoIterator<Item = Record>,
    conv: &Conventions,
    settle: Settle,
    grouping: &Grouping,
    inputs: &[PathBuf],
) -> Result<(Vec<Step>, unmeasured::Gaps), ImportError> {
    let fscale = conv.frequency_scale.unwrap_or(1.0);
    let mut steps: Vec<Step> = Vec::new();
    let mut last: Option<Record> = None;
    let mut gaps = unmeasured::Gaps::default();
    for r in records {
        if r.unmeasured {
            gaps.hold(r);
            continue;
        }
        gaps.settle(last.as_ref(), Some(&r), grouping, inputs)?;
        if settle.settle_s.is_some() && r.time_s.is_none() {
            return Err(ImportError::Convention {
                origin: "--settle-s".into(),
                message: "the input has no sample times; drop settling samples by count (settle_samples) instead".into(),
            });
        }
        check_record(&r, fscale, inputs)?;
        let new_step = starts_step(last.as_ref(), &r);
        last = Some(r);
        if new_step {
            if let Some(prev) = steps.last() {
                if !prev.complete() {
                    return Err(prev.incomplete(inputs));
                }
            }
            steps.push(Step::starting_at(&r, fscale));
        }
        let step = steps.last_mut().expect("just pushed");
        step.add(&r, conv, fscale, inputs)?;
    }
    gaps.settle(last.as_ref(), None, grouping, inputs)?;
    let Some(tail) = steps.last() else {
        return Err(ImportError::Input {
            path: inputs.first().cloned().unwrap_or_default(),
            row: None,
            message: if gaps.dropped > 0 {
                format!(
                    "no measured row: all {} rows have every value NaN",
                    gaps.dropped
                )
            } else {
                "no data rows were read".into()
            },
        });
    };
    if !tail.complete() {
        return Err(tail.incomplete(inputs));
    }
    Ok((steps, gaps))
}

/// Drops every step's settling samples; returns how many samples were read and how many
/// kept. A step left without a sample is an error naming it.
fn drop_settling(steps: &mut [Step], settle: Settle) -> Result<(usize, usize), ImportError> {
    let read: usize = steps.iter().map(|s| s.times.len()).sum();
    for s in steps.iter_mut() {
        s.drop_settling(settle);
    }
    let kept: usize = steps.iter().map(|s| s.times.len()).sum();
    if let Some(k) = steps.iter().position(|s| s.times.is_empty()) {
        return Err(ImportError::Convention {
            origin: "settling".into(),
            message: format!("step {k} (at {} Hz) keeps no sample after settling; lower settle_s or settle_samples", steps[k].drive),
        });
    }
    Ok((read, kept))
}

/// The sweeps as `[start, end)` ranges of steps: a new one at each group change, and at each
/// level change when `grouping` asks (then [`passes::split_passes`] cuts one that turns back).
fn cut_sweeps(steps: &[Step], grouping: &Grouping) -> Vec<(usize, usize)> {
    let mut sweeps: Vec<(usize, usize)> = Vec::new();
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
    sweeps
}

/// The name of the sweep of group `group` at drive level `level` before any suffix: its
/// group's name, else (cut by level, or no name) its drive level, `level_0.1`.
fn base_name(group: usize, level: Option<f64>, grouping: &Grouping) -> String {
    match grouping.group_names.get(group) {
        // A sweep cut by level is named by it; a single input without levels by the input.
        Some(n) if !grouping.split_on_level || level.is_none() => n.clone(),
        _ => format!("level_{}", level.map_or("none".into(), |l| format!("{l}"))),
    }
}

/// The name of the sweep of steps `part`: [`base_name`], then `suffix`, with `_2`, `_3`, ...
/// appended when `names` (the sweeps named so far) already has it.
fn sweep_name(part: &[Step], grouping: &Grouping, suffix: &str, names: &mut Vec<String>) -> String {
    let base = base_name(part[0].group, part[0].level, grouping) + suffix;
    let mut name = base.clone();
    let mut i = 2;
    while names.contains(&name) {
        name = format!("{base}_{i}");
        i += 1;
    }
    names.push(name.clone());
    name
}

/// The sweep `name` of steps `part`: its drives, their direction, and the drive levels and
/// phases when every step has a level.
fn sweep_spec(part: &[Step], name: String) -> SweepSpec {
    let fs: Vec<f64> = part.iter().map(|s| s.drive).collect();
    // One step has no direction (a sweep up or down needs two steps to follow a branch).
    let direction = if fs.len() < 2 {
        Direction::Unordered
    } else if fs.windows(2).all(|w| w[1] > w[0]) {
        Direction::Up
    } else if fs.windows(2).all(|w| w[1] < w[0]) {
        Direction::Down
    } else {
        Direction::Unordered
    };
    let mut sw = SweepSpec::new(name, direction, fs.iter().map(|&f| vec![f]).collect());
    let levels: Option<Vec<Vec<f64>>> = part.iter().map(|s| s.level.map(|l| vec![l])).collect();
    if let Some(levels) = levels {
        sw.drive_levels_v = Some(PerStep::Each(levels));
        sw.drive_phases_rad = Some(PerStep::Each(
            part.iter().map(|s| vec![s.phase.unwrap_or(0.0)]).collect(),
        ));
    }
    sw
}

/// The manifest's sweeps (in `manifest`) and the measurements of their steps, in order.
fn sweeps_and_measurements(
    manifest: &mut Manifest,
    steps: &[Step],
    sweeps: &[passes::Cut],
    grouping: &Grouping,
    inputs: &[PathBuf],
) -> Result<Vec<Measurement>, ImportError> {
    let mut measurements = Vec::new();
    let mut names: Vec<String> = Vec::new();
    for (a, b, suffix) in sweeps {
        let part = &steps[*a..*b];
        let name = sweep_name(part, grouping, suffix, &mut names);
        let mut sw = sweep_spec(part, name);
        sw.source = grouping
            .sources
            .get(part[0].group)
            .filter(|s| !s.is_empty())
            .cloned();
        for (k, s) in part.iter().enumerate() {
            measurements.push(s.measurement(sw.step_spec(k), inputs)?);
        }
        manifest.sweeps.push(sw);
    }
    Ok(measurements)
}

/// The one-line note on what was cut (`passes`: [`passes::passes_note`]) and dropped as
/// settling.
fn settle_note(
    settle: Settle,
    (sweeps, steps, passes): (usize, usize, &str),
    read: usize,
    kept: usize,
) -> String {
    let rule = match (settle.settle_s, settle.settle_samples) {
        (Some(t), _) => format!(" (earlier than {t} s into their step)"),
        (None, Some(n)) => format!(" (the first {n} of each step)"),
        _ => String::new(),
    };
    format!(
        "{sweeps} sweeps, {steps} steps{passes}; {} of {read} samples dropped as settling{rule}",
        read - kept
    )
}

/// The dataset the records make: conventions applied, steps and sweeps cut, settling
/// dropped, rows where nothing was measured dropped or refused (`unmeasured`), sweeps that
/// turn back cut into their passes (`passes`). `inputs` name the files in messages; `out`
/// names the dataset. Returns the dataset, its `notes` holding one warning line per run of
/// unmeasured rows dropped, and the one-line note on the sweeps, their passes and settling.
/// Records are consumed as they come: a million samples take their 16-byte amplitudes and
/// little else.
pub fn build(
    format: &str,
    inputs: &[PathBuf],
    records: impl IntoIterator<Item = Record>,
    conv: &Conventions,
    settle: Settle,
    grouping: &Grouping,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    check_settle_s(settle)?;
    let (mut steps, gaps) = collect_steps(records, conv, settle, grouping, inputs)?;
    let (read, kept) = drop_settling(&mut steps, settle)?;
    let (sweeps, split) = passes::split_passes(&steps, &cut_sweeps(&steps, grouping));
    passes::refuse_levelless_passes(&steps, &split, grouping, inputs)?;
    let mut manifest = Manifest::new(format!("imported by harmonid import {format}"));
    manifest.displacement_unit = conv.displacement_unit.clone();
    let measurements = sweeps_and_measurements(&mut manifest, &steps, &sweeps, grouping, inputs)?;
    manifest.import = Some(ImportRecord {
        format: format.to_string(),
        inputs: inputs.iter().map(|p| p.display().to_string()).collect(),
        conventions: conv.clone(),
        settle,
        settling_dropped: read - kept,
        samples_read: read,
        instrument: Default::default(),
    });
    let mut ds = Dataset::from_parts(out, manifest, measurements, None)?;
    ds.notes.extend(gaps.warnings);
    let passes = passes::passes_note(&steps, &sweeps, &split, grouping);
    let note = settle_note(settle, (sweeps.len(), steps.len(), &passes), read, kept);
    Ok((ds, note))
}

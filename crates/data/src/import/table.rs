//! `harmonid import table`: any delimited text table (CSV, TSV, whitespace) or MATLAB v5/v7
//! file, with a mapping file naming where frequency, X and Y (or R and θ), drive level and
//! phase, step, time and sweep are, and every convention.
//!
//! ```toml
//! [columns]                    # CSV header names, or MAT paths (a.b.c, a.b(*).c)
//! freq_hz = "Frequency_of_MFLI__Hz_"
//! x = "X1__V_"                 # or r = "...", theta = "..."
//! y = "Y1__V_"
//! drive_level = "Amplitude_of_Excitation__V_"   # optional
//! [conventions]
//! amplitude = "rms"            # "peak" or "rms"
//! quadrature = "x+iy"          # or "x-iy"
//! displacement_unit = "V"      # or "m" with metres_per_unit = ...
//! [settle]
//! settle_samples = 40          # or settle_s = 0.5 (needs columns.time_s)
//! ```

pub use super::text_table::Column;
use super::text_table::{read_text, Group};
use super::{
    build, mat, read_input, Conventions, Grouping, ImportError, PhaseUnit, Record, Settle,
};
use crate::dataset::Dataset;
use num_complex::Complex64;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where each quantity is: a header name or a 1-based column number (text tables), or a
/// variable path (MAT files).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Columns {
    /// The drive (and measured) frequency.
    pub freq_hz: Column,
    /// In-phase part (with `y`).
    pub x: Option<Column>,
    /// Quadrature part (with `x`).
    pub y: Option<Column>,
    /// Magnitude (with `theta`).
    pub r: Option<Column>,
    /// Phase (with `r`), in `conventions.phase_unit`.
    pub theta: Option<Column>,
    /// Drive level per row.
    pub drive_level: Option<Column>,
    /// Drive phase per row, in `conventions.phase_unit`.
    pub drive_phase: Option<Column>,
    /// Step number per row (else a step is a run of rows at one frequency and level).
    pub step: Option<Column>,
    /// Sample time per row, s (for `settle.settle_s`).
    pub time_s: Option<Column>,
    /// Sweep label per row (else each input file or struct element is a sweep, and a single
    /// one is cut where the drive level changes).
    pub sweep: Option<Column>,
}

impl Columns {
    /// Every mapped column with its mapping key, in a fixed order.
    fn wanted(&self) -> Vec<(&'static str, &Column)> {
        [
            ("freq_hz", Some(&self.freq_hz)),
            ("x", self.x.as_ref()),
            ("y", self.y.as_ref()),
            ("r", self.r.as_ref()),
            ("theta", self.theta.as_ref()),
            ("drive_level", self.drive_level.as_ref()),
            ("drive_phase", self.drive_phase.as_ref()),
            ("step", self.step.as_ref()),
            ("time_s", self.time_s.as_ref()),
            ("sweep", self.sweep.as_ref()),
        ]
        .into_iter()
        .filter_map(|(k, c)| c.map(|c| (k, c)))
        .collect()
    }
}

/// Constants of the drive when the file has no column for them.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// The drive level of every row.
    pub level: Option<f64>,
    /// The drive phase of every row, rad.
    pub phase_rad: Option<f64>,
}

/// Per-input constants, keyed by the input's file name.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileConstants {
    /// The drive level of every row of this file.
    pub drive_level: Option<f64>,
}

/// The mapping file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// Where each quantity is.
    pub columns: Columns,
    /// Every convention.
    pub conventions: Conventions,
    /// Which samples are settling.
    #[serde(default)]
    pub settle: Settle,
    /// Drive constants.
    #[serde(default)]
    pub drive: Drive,
    /// Per-file constants.
    #[serde(default)]
    pub files: BTreeMap<String, FileConstants>,
    /// Field separator of text tables: "," ";" "\t" or " " (any run of whitespace); default
    /// by extension (`.csv` comma, else whitespace).
    pub delimiter: Option<String>,
    /// Drop rows where nothing was measured (x and y, or r and theta, all NaN) inside a sweep
    /// too, not only at its end (`--drop-nan-rows`); each run is counted in a warning.
    #[serde(default)]
    pub drop_nan_rows: bool,
}

impl Mapping {
    /// Reads and checks the mapping file.
    pub fn load(path: &Path) -> Result<Mapping, ImportError> {
        let text = read_input(path)?;
        let origin = path.display().to_string();
        let m: Mapping = toml::from_str(&text).map_err(|e| ImportError::Convention {
            origin: origin.clone(),
            message: e.to_string(),
        })?;
        m.conventions.check(&origin)?;
        let c = &m.columns;
        let bad = |message: &str| ImportError::Convention {
            origin: origin.clone(),
            message: message.to_string(),
        };
        match (&c.x, &c.y, &c.r, &c.theta) {
            (Some(_), Some(_), None, None) | (None, None, Some(_), Some(_)) => {}
            _ => {
                return Err(bad(
                    "[columns] names x and y, or r and theta (exactly one pair)",
                ))
            }
        }
        if (c.theta.is_some() || c.drive_phase.is_some()) && m.conventions.phase_unit.is_none() {
            return Err(bad(
                "a phase column needs [conventions] phase_unit = \"rad\", \"deg\" or \"cycles\"",
            ));
        }
        check_units(&m, &origin)?;
        if m.settle.settle_s.is_some() && c.time_s.is_none() {
            return Err(bad(
                "[settle] settle_s needs [columns] time_s; or use settle_samples",
            ));
        }
        if m.settle.settle_s.is_some() && m.settle.settle_samples.is_some() {
            return Err(bad("[settle]: give settle_s or settle_samples, not both"));
        }
        Ok(m)
    }
}

/// The unit a column's name carries, if any: `X (V)`, `X [mV]`, or LabVIEW/TDMS's `X1__V_`
/// (also as a component of a MATLAB path, `Data.X1__V_.data`).
fn unit_tag(name: &str) -> Option<String> {
    let t = name.trim();
    for (open, close) in [('(', ')'), ('[', ']')] {
        if let (Some(a), Some(b)) = (t.rfind(open), t.rfind(close)) {
            if a < b {
                return Some(t[a + 1..b].trim().to_string());
            }
        }
    }
    t.split('.').find_map(|part| {
        let inner = part.strip_suffix('_')?;
        let at = inner.rfind("__")?;
        Some(inner[at + 2..].to_string()).filter(|u| !u.is_empty())
    })
}

/// What the column names say against the conventions: x and y (or r) in different units, a
/// phase column named in degrees declared in radians (or the reverse).
fn check_units(m: &Mapping, origin: &str) -> Result<(), ImportError> {
    let c = &m.columns;
    let bad = |message: String| ImportError::Convention {
        origin: origin.to_string(),
        message,
    };
    if let (Some(x), Some(y)) = (
        c.x.as_ref().and_then(Column::name),
        c.y.as_ref().and_then(Column::name),
    ) {
        if let (Some(ux), Some(uy)) = (unit_tag(x), unit_tag(y)) {
            if ux != uy {
                return Err(bad(format!(
                    "mixed units: x is \"{x}\" ({ux}) but y is \"{y}\" ({uy}); both parts of the amplitude must be in one unit (convert one column first)"
                )));
            }
        }
    }
    let Some(declared) = m.conventions.phase_unit else {
        return Ok(());
    };
    for col in [&c.theta, &c.drive_phase]
        .into_iter()
        .flatten()
        .filter_map(Column::name)
    {
        let Some(tag) = unit_tag(col) else { continue };
        let named = match tag.to_ascii_lowercase().as_str() {
            "deg" | "degree" | "degrees" | "°" => PhaseUnit::Deg,
            "rad" | "radian" | "radians" => PhaseUnit::Rad,
            "cycles" | "cycle" | "turns" => PhaseUnit::Cycles,
            _ => continue,
        };
        if named != declared {
            return Err(bad(format!(
                "column \"{col}\" is named in {tag} but phase_unit = \"{}\": set phase_unit to the column's unit",
                declared.name()
            )));
        }
    }
    Ok(())
}

/// A phase column's values against its declared unit: radians within ±2π, cycles within ±1
/// (degrees declared as radians show as values up to 180 or 360). `rows`: each value's line
/// in a text file, for the message.
fn check_phase_range(
    path: &Path,
    key: &Column,
    values: &[f64],
    unit: PhaseUnit,
    rows: Option<&[usize]>,
) -> Result<(), ImportError> {
    let limit = match unit {
        PhaseUnit::Rad => 2.0 * std::f64::consts::PI,
        PhaseUnit::Cycles => 1.0,
        PhaseUnit::Deg => 360.0,
    } * (1.0 + 1e-9);
    let Some((i, v)) = values
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
    else {
        return Ok(());
    };
    if v.abs() <= limit {
        return Ok(());
    }
    Err(ImportError::Input {
        path: path.to_path_buf(),
        row: rows.and_then(|r| r.get(i).copied()),
        message: format!(
            "phase column {key} reaches {v} (value {}), beyond ±{} for phase_unit = \"{}\": degrees declared as {}? Set phase_unit to the column's unit (a phase unwrapped over several turns must be wrapped first)",
            i + 1,
            limit / (1.0 + 1e-9),
            unit.name(),
            unit.name()
        ),
    })
}

type Groups = Vec<Group>;

/// The sweeps' names and sources, gathered as the groups are read: one per group (an input
/// file, a struct element), and one per distinct sweep label.
#[derive(Default)]
struct Names {
    groups: Vec<String>,
    sources: Vec<String>,
    labels: Vec<String>,
    label_sources: Vec<String>,
}

impl Names {
    /// The group of sweep label `label`, a new one the first time it is seen.
    fn label_group(&mut self, label: &str) -> usize {
        let name = sweep_label_name(label);
        match self.labels.iter().position(|l| *l == name) {
            Some(p) => p,
            None => {
                self.labels.push(name);
                self.label_sources.push(label.trim().to_string());
                self.labels.len() - 1
            }
        }
    }
}

/// Imports `inputs` with `mapping` (read from `mapping_path`) into a dataset named `out`.
pub fn import(
    inputs: &[PathBuf],
    mapping: &Mapping,
    out: &Path,
) -> Result<(Dataset, String), ImportError> {
    let c = &mapping.columns;
    let wanted = c.wanted();
    let mut records = Vec::new();
    let mut names = Names::default();
    for (fi, path) in inputs.iter().enumerate() {
        let groups = if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mat"))
        {
            read_mat(path, &wanted, c.sweep.as_ref())?
        } else {
            read_text(
                path,
                &wanted,
                mapping.delimiter.as_deref(),
                c.sweep.as_ref(),
            )?
        };
        for g in groups {
            group_records(&mut records, g, (fi, path), mapping, &mut names)?;
        }
    }
    let split_on_level = c.sweep.is_none() && names.groups.len() == 1;
    let (group_names, sources) = if c.sweep.is_some() {
        (names.labels, names.label_sources)
    } else {
        (names.groups, names.sources)
    };
    let grouping = Grouping {
        split_on_level,
        group_names,
        sources,
        drop_nan_rows: mapping.drop_nan_rows,
        // Without a level column, a sweep that turns back twice may be levels merged.
        passes_need_level: c.drive_level.is_none(),
        one_sweep: false,
    };
    let (ds, note) = build(
        "table",
        inputs,
        records,
        &mapping.conventions,
        mapping.settle,
        &grouping,
        out,
    )?;
    if c.drive_level.is_none() {
        refuse_merged_levels(&ds, inputs)?;
    }
    Ok((ds, note))
}

/// The records of group `g` of input `fi` (the file `path`), appended to `records`: its
/// columns checked (phase range, equal lengths), its name and source added to `names`.
fn group_records(
    records: &mut Vec<Record>,
    g: Group,
    (fi, path): (usize, &PathBuf),
    mapping: &Mapping,
    names: &mut Names,
) -> Result<(), ImportError> {
    let c = &mapping.columns;
    let unit = mapping.conventions.phase_unit;
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let file_level = mapping.files.get(&file_name).and_then(|f| f.drive_level);
    let Group {
        name: gname,
        cols,
        labels,
        rows,
    } = g;
    let get = |k: &Option<Column>| k.as_ref().and_then(|k| cols.get(k));
    // A value's line in a text file, its 1-based index in a MATLAB array.
    let row_of = |i: usize| {
        rows.as_ref()
            .and_then(|r| r.get(i).copied())
            .unwrap_or(i + 1)
    };
    if let Some(u) = unit {
        for key in [&c.theta, &c.drive_phase].into_iter().flatten() {
            if let Some(v) = cols.get(key) {
                check_phase_range(path, key, v, u, rows.as_deref())?;
            }
        }
    }
    let Some(f) = cols.get(&c.freq_hz) else {
        return Err(ImportError::Convention {
            origin: "[columns]".into(),
            message: format!(
                "freq_hz = {} is also the sweep column: map the frequency column",
                c.freq_hz
            ),
        });
    };
    let n = f.len();
    for (key, v) in &cols {
        if v.len() != n {
            return Err(ImportError::Input {
                path: path.clone(),
                row: None,
                message: format!(
                    "{key} has {} values but {} has {n}; the columns must be as long",
                    v.len(),
                    c.freq_hz
                ),
            });
        }
    }
    let group = names.groups.len();
    // A file is its sweep: named by its stem, its name recorded as the source.
    names
        .groups
        .push(super::readable_name(&if gname.is_empty() {
            path.file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default()
        } else {
            gname.clone()
        }));
    names.sources.push(if gname.is_empty() {
        file_name.clone()
    } else {
        String::new()
    });
    for i in 0..n {
        let (z, unmeasured) = match (get(&c.x), get(&c.y), get(&c.r), get(&c.theta)) {
            (Some(x), Some(y), _, _) => {
                (Complex64::new(x[i], y[i]), x[i].is_nan() && y[i].is_nan())
            }
            (_, _, Some(r), Some(t)) => (
                Complex64::from_polar(r[i], unit.map_or(t[i], |u| u.to_rad(t[i]))),
                r[i].is_nan() && t[i].is_nan(),
            ),
            _ => (Complex64::new(f64::NAN, f64::NAN), false),
        };
        let group = match &labels {
            Some(s) => names.label_group(&s[i]),
            None => group,
        };
        records.push(Record {
            drive: f[i],
            line: f[i],
            z,
            level: get(&c.drive_level)
                .map(|v| v[i])
                .or(file_level)
                .or(mapping.drive.level),
            drive_phase_rad: get(&c.drive_phase)
                .map(|v| unit.map_or(v[i], |u| u.to_rad(v[i])))
                .or(mapping.drive.phase_rad),
            group,
            step: get(&c.step).map(|v| v[i] as u64),
            time_s: get(&c.time_s).map(|v| v[i]),
            origin: (fi, row_of(i)),
            noise: None,
            unmeasured,
        });
    }
    Ok(())
}

/// Without a drive level column, a sweep that comes back to a drive frequency (after a sweep
/// that turns back was cut in two) holds several drive levels merged: an error naming the
/// sweep, the frequency, and the mapping key to add.
fn refuse_merged_levels(ds: &Dataset, inputs: &[PathBuf]) -> Result<(), ImportError> {
    for sw in &ds.manifest.sweeps {
        let fs: Vec<f64> = sw.drives_hz.iter().map(|d| d[0]).collect();
        for (k, &f) in fs.iter().enumerate() {
            let Some(j) = fs[..k].iter().position(|&g| super::same(f, g)) else {
                continue;
            };
            return Err(ImportError::Input {
                path: inputs.first().cloned().unwrap_or_default(),
                row: None,
                message: format!(
                    "sweep \"{}\" comes back to {} Hz (steps {} and {}) and the mapping has no drive level column: several drive levels merged into one sweep? Map the level column in the mapping, [columns] drive_level = \"<its header>\" (or label the sweeps: [columns] sweep = \"<column>\")",
                    sw.name,
                    harmonid_files::number(f),
                    j + 1,
                    k + 1
                ),
            });
        }
    }
    Ok(())
}

/// The sweep name of a sweep column's label: `sweep_<n>` for a number (`1` and `1.0` are one
/// sweep, `sweep_1`), the label itself for text (`s00`), but for the characters a sweep name
/// cannot hold ([`super::readable_name`]).
fn sweep_label_name(label: &str) -> String {
    match label.trim().parse::<f64>() {
        Ok(v) => format!("sweep_{v}"),
        Err(_) => super::readable_name(label),
    }
}

/// The groups of a MATLAB file: every wanted column read as numbers, the sweep column's
/// numbers then also kept as its labels.
fn read_mat(
    path: &Path,
    wanted: &[(&str, &Column)],
    sweep: Option<&Column>,
) -> Result<Groups, ImportError> {
    let file = mat::load(path)?;
    let mut groups: Groups = Vec::new();
    for &(mkey, col) in wanted {
        let Column::Name(key) = col else {
            return Err(ImportError::Input {
                path: path.to_path_buf(),
                row: None,
                message: format!(
                    "{mkey} = {col}: a MATLAB file's columns are variable paths, not numbers; write {mkey} = \"struct.field.data\""
                ),
            });
        };
        let per_group = mat::column(&file, key).map_err(|message| ImportError::Input {
            path: path.to_path_buf(),
            row: None,
            message,
        })?;
        if groups.is_empty() {
            let element = key
                .split('.')
                .find(|s| s.ends_with("(*)"))
                .map(|s| s.trim_end_matches("(*)").to_string());
            groups = (0..per_group.len())
                .map(|k| {
                    let name = element
                        .as_ref()
                        .map_or(String::new(), |e| format!("{e}_{}", k + 1));
                    Group {
                        name,
                        cols: BTreeMap::new(),
                        labels: None,
                        rows: None,
                    }
                })
                .collect();
        }
        if per_group.len() != groups.len() && per_group.len() != 1 {
            return Err(ImportError::Input {
                path: path.to_path_buf(),
                row: None,
                message: format!(
                    "\"{key}\" has {} elements where the other columns have {}",
                    per_group.len(),
                    groups.len()
                ),
            });
        }
        for (k, g) in groups.iter_mut().enumerate() {
            let v = per_group
                .get(k)
                .or(per_group.first())
                .cloned()
                .unwrap_or_default();
            g.cols.insert(col.clone(), v);
        }
    }
    if let Some(key) = sweep {
        for g in &mut groups {
            let v = g.cols.get(key).cloned().unwrap_or_default();
            g.labels = Some(v.iter().map(|x| format!("{x}")).collect());
        }
    }
    Ok(groups)
}

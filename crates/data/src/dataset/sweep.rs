//! Stepped sweeps: one `[[sweep]]` of the manifest is a list of steps (each its own drive tones,
//! levels and phases, and its samples), read from one CSV with a `step` column. Each step
//! becomes one [`Measurement`] (named `name[k]`) carrying a [`SweepStep`], so everything
//! downstream sees ordinary measurements and can still tell which sweep and step each is.
//!
//! Settling is explicit: samples taken before `settle_s` after the step began (the CSV's
//! `time_s`), or the first `settle_samples` of each step, are dropped while reading and counted
//! in one note per sweep ([`Dataset::notes`]), never reported as disturbed shots.

use super::csv_read::{assemble, read_cells, Cell, Columns};
use super::*;

/// The order in which a sweep's steps were measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Each step's first drive tone above the previous step's.
    Up,
    /// Each step's first drive tone below the previous step's.
    Down,
    /// Any order (points measured out of order, or both branches).
    Unordered,
    /// A drive ladder: the same tones at every step, the drive turned up step by step (each
    /// step's levels at least the previous step's, when levels are given).
    Level,
}

impl Direction {
    /// `up`, `down` or `unordered`, as the manifest writes it.
    pub fn name(self) -> &'static str {
        match self {
            Direction::Up => "up",
            Direction::Down => "down",
            Direction::Unordered => "unordered",
            Direction::Level => "level",
        }
    }
}

/// A value per drive tone, the same at every step (`[0.1]`) or given per step
/// (`[[0.19], [0.21], ...]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerStep {
    /// One list, in each step's drive-tone order, for every step.
    Same(Vec<f64>),
    /// One list per step.
    Each(Vec<Vec<f64>>),
}

impl PerStep {
    /// The values at step `k` (empty when a per-step list is shorter).
    pub fn at(&self, k: usize) -> &[f64] {
        match self {
            PerStep::Same(v) => v,
            PerStep::Each(v) => v.get(k).map_or(&[], Vec::as_slice),
        }
    }

    /// Number of steps given per step, or `None` for a list shared by every step.
    fn steps(&self) -> Option<usize> {
        match self {
            PerStep::Same(_) => None,
            PerStep::Each(v) => Some(v.len()),
        }
    }
}

/// One `[[sweep]]` of the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Unique name (among sweeps and measurements); step `k` is the measurement `name[k]`.
    pub name: String,
    /// CSV file, relative to the dataset folder and inside it (default `<name>.csv`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Where the sweep came from, as the lab named it: the input file's name
    /// (`Measurements_A=0.32%.txt`) or the sweep label as written in the file (the name may
    /// differ: an escaped character, a level or an `_up`/`_down` suffix). Written by
    /// `harmonid import`; `identify --holdout` accepts it as well as the name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// The order the steps were measured in (checked against `drives_hz`).
    pub direction: Direction,
    /// The drive tones of each step, Hz: one list per step, in measurement order.
    pub drives_hz: Vec<Vec<f64>>,
    /// Drive level of each tone (V, or any consistent unit), the same at every step or per step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_levels_v: Option<PerStep>,
    /// Drive phase of each tone, rad, the same at every step or per step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_phases_rad: Option<PerStep>,
    /// The pump tones, Hz, the same at every step (see [`MeasurementSpec::pumps_hz`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pumps_hz: Vec<f64>,
    /// Level of each pump tone, the same at every step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_levels: Option<Vec<f64>>,
    /// Phase of each pump tone, rad, the same at every step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_phases_rad: Option<Vec<f64>>,
    /// Samples whose `time_s` (time since the step began, s) is below this are the response
    /// settling after the step: dropped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_s: Option<f64>,
    /// The first this many samples (by `shot` number) of each step are dropped as settling.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_samples: Option<usize>,
    /// Measurement bandwidth, Hz (metadata).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_hz: Option<f64>,
}

/// Which sweep and step a measurement is (see [`MeasurementSpec::sweep`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SweepStep {
    /// The sweep's name.
    pub sweep: String,
    /// The step's index, 0-based, in measurement order.
    pub step: usize,
}

impl SweepSpec {
    /// A sweep called `name` over the steps `drives_hz` (one list of tones per step), without
    /// levels, phases, settling or file name.
    pub fn new(name: impl Into<String>, direction: Direction, drives_hz: Vec<Vec<f64>>) -> Self {
        SweepSpec {
            name: name.into(),
            file: None,
            source: None,
            direction,
            drives_hz,
            drive_levels_v: None,
            drive_phases_rad: None,
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            settle_s: None,
            settle_samples: None,
            bandwidth_hz: None,
        }
    }

    /// The CSV file name relative to the dataset folder.
    pub fn file_name(&self) -> String {
        self.file
            .clone()
            .unwrap_or_else(|| format!("{}.csv", self.name))
    }

    /// The name of step `k` as a measurement: `name[k]`.
    pub fn step_name(&self, k: usize) -> String {
        format!("{}[{k}]", self.name)
    }

    /// Step `k` as a measurement entry (its tones, levels, phases, the sweep's file).
    pub fn step_spec(&self, k: usize) -> MeasurementSpec {
        MeasurementSpec {
            name: self.step_name(k),
            file: Some(self.file_name()),
            drives_hz: self.drives_hz.get(k).cloned().unwrap_or_default(),
            drive_levels_v: self.drive_levels_v.as_ref().map(|v| v.at(k).to_vec()),
            drive_phases_rad: self.drive_phases_rad.as_ref().map(|v| v.at(k).to_vec()),
            pumps_hz: self.pumps_hz.clone(),
            pump_levels: self.pump_levels.clone(),
            pump_phases_rad: self.pump_phases_rad.clone(),
            bandwidth_hz: self.bandwidth_hz,
            sweep: Some(SweepStep {
                sweep: self.name.clone(),
                step: k,
            }),
        }
    }
}

/// The checks of a sweep entry beyond each step's own (see `validate::check_spec`): steps
/// present, per-step lists as long as the steps, settling options sane, the direction true.
pub(super) fn check_sweep(sw: &SweepSpec) -> Result<(), String> {
    let name = &sw.name;
    if sw.drives_hz.is_empty() {
        return Err(format!(
            "sweep \"{name}\": drives_hz lists no step; give each step's drive tones, e.g. drives_hz = [[42.70], [42.71]]"
        ));
    }
    for (key, v) in [
        ("drive_levels_v", &sw.drive_levels_v),
        ("drive_phases_rad", &sw.drive_phases_rad),
    ] {
        if let Some(n) = v.as_ref().and_then(PerStep::steps) {
            if n != sw.drives_hz.len() {
                return Err(format!(
                    "sweep \"{name}\": {key} lists {n} steps but drives_hz lists {}; give one list per step, or one list for every step",
                    sw.drives_hz.len()
                ));
            }
        }
    }
    if let Some(t) = sw.settle_s {
        if !(t.is_finite() && t >= 0.0) {
            return Err(format!(
                "sweep \"{name}\": settle_s = {t}, expected a time in seconds (finite, ≥ 0)"
            ));
        }
        if sw.settle_samples.is_some() {
            return Err(format!(
                "sweep \"{name}\": give settle_s or settle_samples, not both"
            ));
        }
    }
    if sw.direction == Direction::Level {
        return check_ladder(sw);
    }
    if matches!(sw.direction, Direction::Up | Direction::Down) && sw.drives_hz.len() < 2 {
        return Err(format!(
            "sweep \"{name}\" is declared direction = \"{}\" but has {} step: a sweep up or down needs at least two steps (a branch is followed from one step to the next); add its other steps, or declare it \"unordered\"",
            sw.direction.name(),
            sw.drives_hz.len()
        ));
    }
    let first = |k: usize| sw.drives_hz[k].first().copied().unwrap_or(f64::NAN);
    for k in 1..sw.drives_hz.len() {
        let (a, b) = (first(k - 1), first(k));
        let wrong = match sw.direction {
            Direction::Up => b <= a,
            Direction::Down => b >= a,
            Direction::Unordered | Direction::Level => false,
        };
        if wrong {
            return Err(format!(
                "sweep \"{name}\" is declared direction = \"{}\", but step {k} is at {b} Hz after step {} at {a} Hz; correct the direction (\"up\", \"down\", \"unordered\" or \"level\") or the steps' order",
                sw.direction.name(),
                k - 1
            ));
        }
    }
    Ok(())
}

/// A drive ladder's steps: the same tones as step 0 (to the dataset's frequency tolerance), and
/// each step's drive levels, when given per step, at least the previous step's.
fn check_ladder(sw: &SweepSpec) -> Result<(), String> {
    let name = &sw.name;
    let first = &sw.drives_hz[0];
    for (k, tones) in sw.drives_hz.iter().enumerate().skip(1) {
        let same = tones.len() == first.len()
            && tones
                .iter()
                .zip(first)
                .all(|(a, b)| (a - b).abs() <= FREQ_REL_TOL * b.abs());
        if !same {
            return Err(format!(
                "sweep \"{name}\" is declared direction = \"level\" (a drive ladder: the same tones at every step), but step {k}'s tones {tones:?} Hz differ from step 0's {first:?} Hz; give the same tones at every step, or declare the sweep \"unordered\""
            ));
        }
    }
    if let Some(PerStep::Each(levels)) = &sw.drive_levels_v {
        for k in 1..levels.len() {
            if levels[k].iter().zip(&levels[k - 1]).any(|(b, a)| b < a) {
                return Err(format!(
                    "sweep \"{name}\" is declared direction = \"level\" (a drive turned up step by step), but step {k}'s drive levels {:?} are below step {}'s {:?}; give the steps in the order they were measured, or declare the sweep \"unordered\"",
                    levels[k],
                    k - 1,
                    levels[k - 1]
                ));
            }
        }
    }
    Ok(())
}

/// Reads one sweep's CSV (`step`, `shot`, `freq_hz`, `re`, `im`, optional `point` and
/// `time_s`) into one measurement per step, the settling samples dropped, and the note that
/// says how many were (none without a settling rule).
pub(super) fn read_sweep_csv<R: std::io::Read>(
    reader: R,
    path: &Path,
    sw: &SweepSpec,
    manifest: &Manifest,
    scale: f64,
) -> Result<(Vec<Measurement>, Option<String>), DatasetError> {
    let n_steps = sw.drives_hz.len();
    let columns = Columns::Sweep {
        steps: n_steps,
        settle_s: sw.settle_s,
    };
    let (mut cells, early) = read_cells(reader, path, manifest, scale, columns)?;
    cells.sort_by_key(|c| c.step);
    let total = cells.len() + early;
    let mut dropped = early;
    let mut out = Vec::with_capacity(n_steps);
    let mut rest: &[Cell] = &cells;
    for k in 0..n_steps {
        let len = rest.iter().take_while(|c| c.step as usize == k).count();
        let (mine, tail) = rest.split_at(len);
        rest = tail;
        let mut shots: Vec<u32> = mine.iter().map(|c| c.shot).collect();
        shots.sort_unstable();
        shots.dedup();
        let skip = sw.settle_samples.unwrap_or(0).min(shots.len());
        let kept_shots = &shots[skip..];
        if kept_shots.is_empty() {
            return Err(DatasetError::Inconsistent {
                path: path.to_path_buf(),
                message: format!(
                    "sweep \"{}\", step {k}: {}",
                    sw.name,
                    if shots.is_empty() && sw.settle_s.is_some() {
                        "no sample is later than settle_s (or the step has no rows); lower settle_s or check the step column".to_string()
                    } else if shots.is_empty() {
                        "no rows; every step of drives_hz needs its samples".to_string()
                    } else {
                        format!(
                            "settle_samples = {skip} drops all {} samples; lower it",
                            shots.len()
                        )
                    }
                ),
            });
        }
        let mut step_cells: Vec<Cell> = mine
            .iter()
            .filter_map(|c| {
                kept_shots.binary_search(&c.shot).ok().map(|i| Cell {
                    // Shots renumbered 0.. after the settling ones.
                    shot: i as u32,
                    ..*c
                })
            })
            .collect();
        dropped += mine.len() - step_cells.len();
        out.push(assemble(&mut step_cells, path, &sw.step_spec(k), manifest)?);
    }
    let rule = match (sw.settle_s, sw.settle_samples) {
        (Some(t), _) => format!("time_s < {t} s"),
        (None, Some(n)) => format!("the first {n} of each step"),
        // Nothing dropped, nothing to say.
        (None, None) => return Ok((out, None)),
    };
    let note = format!(
        "sweep \"{}\": {n_steps} steps ({}); {dropped} of {total} samples dropped as settling ({rule})",
        sw.name,
        sw.direction.name()
    );
    Ok((out, Some(note)))
}

impl Dataset {
    /// The names `given` (of `--holdout`, say) as this dataset's names: a measurement's or a
    /// sweep's name is kept; a name the lab gave, a sweep's [`SweepSpec::source`] (its input
    /// file's name, with or without the folder or extension, or its label as written), becomes
    /// the name of every sweep from that source (both legs of an up-and-down sweep). Any other
    /// name is kept as given, so that the caller's error lists the dataset's names.
    pub fn resolve_names(&self, given: &[String]) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for g in given {
            let known = self.manifest.sweeps.iter().any(|s| &s.name == g)
                || self.measurements.iter().any(|m| &m.spec.name == g);
            let from_source: Vec<&String> = if known {
                Vec::new()
            } else {
                self.manifest
                    .sweeps
                    .iter()
                    .filter(|s| s.source.as_deref().is_some_and(|src| same_source(src, g)))
                    .map(|s| &s.name)
                    .collect()
            };
            if from_source.is_empty() {
                out.push(g.clone());
            } else {
                out.extend(from_source.into_iter().cloned());
            }
        }
        out.dedup();
        out
    }
}

/// Whether `given` names the source `src`: equal, or (for a file) its path or stem.
fn same_source(src: &str, given: &str) -> bool {
    let g = Path::new(given);
    src == given
        || g.file_name().is_some_and(|n| n.to_string_lossy() == src)
        || Path::new(src)
            .file_stem()
            .is_some_and(|s| s.to_string_lossy() == given)
}

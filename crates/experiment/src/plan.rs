//! The measurement plan: points, drive configurations and the lock-in noise, as the TOML file
//! `harmonid simulate --plan` reads (docs/simulation.md), checked once when read.

use crate::PlanError;
use harmonid_data::{metres_per, Point};
use harmonid_files::QuotedSource;
use harmonid_spectral::FREQ_TOLERANCE_HZ;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Most drive tones in one measurement (a lock-in records at most 32 frequencies, the drive
/// tones among them; the harmonic-balance lattice grows as tones^order).
pub const MAX_TONES: usize = 32;
/// Most measured frequencies in one measurement.
pub const MAX_MEASURED: usize = 512;
/// Most shots (noise realisations) per measurement.
pub const MAX_SHOTS: usize = 100_000;
/// Most measurements in one plan.
pub const MAX_MEASUREMENTS: usize = 1000;
/// Most measurement points.
pub const MAX_POINTS: usize = 256;
/// Most levels of one measurement's drive ladder.
pub const MAX_LEVELS: usize = 16;

/// A measurement plan (`harmonid simulate --plan`). Fields are public so planners can build
/// one in code; [`Plan::check`] states the rules, and [`Plan::from_toml`] and
/// [`Plan::simulate`](crate::Plan::simulate) apply them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// Free text, copied into `dataset.toml`.
    #[serde(default)]
    pub description: String,
    /// Unit of the amplitudes in the written dataset and of `[noise] sigma_per_quadrature`:
    /// `m`, `um`, `nm` or `pm`.
    #[serde(default = "unit_m")]
    pub displacement_unit: String,
    /// Measurement points with their mode shapes (none: one point where every shape is 1).
    #[serde(default, rename = "point", skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<Point>,
    /// Nominal resonance per mode, Hz, for the manifest (default: the model's frequencies).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub nominal_hz: BTreeMap<String, f64>,
    /// Lock-in noise and shots.
    #[serde(default)]
    pub noise: PlanNoise,
    /// The drive configurations.
    #[serde(default, rename = "measurement")]
    pub measurements: Vec<PlanMeasurement>,
    /// The lock-in the plan was designed for and its settings per level (`plan --instrument`);
    /// metadata the simulation does not read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument: Option<crate::lockin::PlanInstrument>,
}

fn unit_m() -> String {
    "m".into()
}

fn one() -> usize {
    1
}

/// `[noise]`: Gaussian noise on every complex amplitude, as a lock-in records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanNoise {
    /// Standard deviation of the noise on the real and on the imaginary part of every
    /// amplitude (per quadrature), in `displacement_unit`; 0 for none. From an amplitude
    /// spectral density see [`crate::sigma_from_asd`].
    #[serde(default)]
    pub sigma_per_quadrature: f64,
    /// Shots (independent noise realisations) per measurement, ≥ 1.
    #[serde(default = "one")]
    pub shots: usize,
}

impl Default for PlanNoise {
    fn default() -> Self {
        Self {
            sigma_per_quadrature: 0.0,
            shots: 1,
        }
    }
}

/// One `[[measurement]]`: a drive configuration and what the lock-in reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanMeasurement {
    /// Unique name (also the CSV's stem).
    pub name: String,
    /// Drive tones, Hz (positive, distinct).
    pub drives_hz: Vec<f64>,
    /// Peak force amplitude per tone on each mode, N/kg (`q1 = [3.5, 3.5, 0.0]`); modes not
    /// listed feel no force.
    pub force: BTreeMap<String, Vec<f64>>,
    /// Force phase per tone on each mode, rad (default 0).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub phase_rad: BTreeMap<String, Vec<f64>>,
    /// Measured frequencies, Hz; default: every drive tone and every lattice line near a
    /// resonance ([`harmonid_sim::measured_lines`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measure_hz: Option<Vec<f64>>,
    /// Drive level per tone as the instrument knows it (V), copied into `dataset.toml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_levels_v: Option<Vec<f64>>,
    /// Drive phase per tone as the instrument knows it (rad), copied into `dataset.toml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_phases_rad: Option<Vec<f64>>,
    /// Pump tones, Hz (parametric pumping: the model's `pump` signal is
    /// `Σ_k pump_levels[k] cos(2π pumps_hz[k] t + pump_phases_rad[k])`), copied into
    /// `dataset.toml`; empty: no pump.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pumps_hz: Vec<f64>,
    /// Level of each pump tone, in the unit the model's pump coefficients are per.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_levels: Option<Vec<f64>>,
    /// Phase of each pump tone, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pump_phases_rad: Option<Vec<f64>>,
    /// Lock-in bandwidth, Hz (metadata), copied into `dataset.toml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_hz: Option<f64>,
    /// A drive ladder: the measurement is recorded at each of these fractions of its forces
    /// (and of its `drive_levels_v`), rising, each in (0, 1], as a drive turned up step by step
    /// (the method paper's ramp of drive voltages). A level whose state jumps then costs that
    /// level, not the measurement. Empty: once, at the forces given.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub levels: Vec<f64>,
}

/// One step of a key path in the plan (`measurement`, `[2]`, `drives_hz`, `[1]`).
#[derive(Debug, Clone)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

fn key(k: &str) -> Seg {
    Seg::Key(k.to_string())
}

/// A broken rule before it is located in a file.
#[derive(Debug, Clone)]
pub(crate) struct Issue {
    pub(crate) path: Vec<Seg>,
    pub(crate) message: String,
    pub(crate) help: Option<String>,
}

fn issue(path: Vec<Seg>, message: impl Into<String>) -> Issue {
    Issue {
        path,
        message: message.into(),
        help: None,
    }
}

fn path_text(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    if s.is_empty() {
        "plan".into()
    } else {
        s
    }
}

/// The byte span of `path` in the TOML `text` (the deepest part of it that exists).
fn span_of(text: &str, path: &[Seg]) -> Option<std::ops::Range<usize>> {
    use toml::de::{DeTable, DeValue};
    let doc = DeTable::parse(text).ok()?;
    let mut span = None;
    let mut table: Option<&DeTable<'_>> = Some(doc.get_ref());
    let mut value: Option<&DeValue<'_>> = None;
    for seg in path {
        match seg {
            Seg::Key(k) => {
                let t = match (table, value) {
                    (Some(t), _) => t,
                    (None, Some(DeValue::Table(t))) => t,
                    _ => break,
                };
                let Some((kk, v)) = t.iter().find(|(kk, _)| kk.get_ref() == k) else {
                    break;
                };
                span = Some(
                    if matches!(v.get_ref(), DeValue::Array(_) | DeValue::Table(_)) {
                        kk.span()
                    } else {
                        v.span()
                    },
                );
                table = None;
                value = Some(v.get_ref());
            }
            Seg::Index(i) => {
                let Some(DeValue::Array(a)) = value else {
                    break;
                };
                let Some(v) = a.get(*i) else { break };
                if !matches!(v.get_ref(), DeValue::Table(_)) {
                    span = Some(v.span());
                }
                value = Some(v.get_ref());
            }
        }
    }
    span
}

impl Issue {
    pub(crate) fn locate(self, origin: &str, text: Option<&str>) -> PlanError {
        let src = text.map(|t| QuotedSource::new(origin, t));
        let span = text.and_then(|t| span_of(t, &self.path));
        PlanError {
            origin: origin.to_string(),
            path: path_text(&self.path),
            message: self.message,
            help: self.help,
            span: src.as_ref().zip(span).map(|(s, span)| s.label(span)),
            src,
        }
    }
}

fn finite_list(
    path: Vec<Seg>,
    xs: &[f64],
    rule: &str,
    ok: impl Fn(f64) -> bool,
) -> Result<(), Issue> {
    for (i, &x) in xs.iter().enumerate() {
        if !(x.is_finite() && ok(x)) {
            let mut p = path.clone();
            p.push(Seg::Index(i));
            return Err(issue(p, format!("{x} is not allowed: expected {rule}")));
        }
    }
    Ok(())
}

/// Positive, finite, pairwise distinct frequencies (no two within the lattice tolerance).
fn frequencies(path: Vec<Seg>, xs: &[f64], what: &str) -> Result<(), Issue> {
    finite_list(path.clone(), xs, "a finite positive frequency in Hz", |x| {
        x > 0.0
    })?;
    for (i, &f) in xs.iter().enumerate() {
        if let Some(j) = xs[..i]
            .iter()
            .position(|&g| (g - f).abs() <= FREQ_TOLERANCE_HZ.max(1e-12 * f))
        {
            let mut p = path.clone();
            p.push(Seg::Index(i));
            return Err(Issue {
                path: p,
                message: format!(
                    "{what} {i} ({f} Hz) coincides with {what} {j} ({} Hz)",
                    xs[j]
                ),
                help: Some(if what == "tone" {
                    "give one tone with the summed force".into()
                } else {
                    "list each frequency once".into()
                }),
            });
        }
    }
    Ok(())
}

impl PlanMeasurement {
    /// Checks the measurement at `path` of the plan, one group of keys after the other; the
    /// first problem found is the issue.
    fn check(&self, path: Vec<Seg>) -> Result<(), Issue> {
        let at = |k: &str| {
            let mut p = path.clone();
            p.push(key(k));
            p
        };
        self.check_name_and_drives(&at)?;
        self.check_forces(&at)?;
        self.check_measured(&at)?;
        self.check_drive_levels(&at)?;
        self.check_pumps(&at)?;
        self.check_ladder(&at)?;
        self.check_bandwidth(&at)
    }

    /// A name, and 1 to [`MAX_TONES`] distinct positive drive tones.
    fn check_name_and_drives(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        let nd = self.drives_hz.len();
        if self.name.trim().is_empty() {
            return Err(issue(at("name"), "a measurement needs a name"));
        }
        if nd == 0 {
            return Err(issue(at("drives_hz"), "no drive tone; give at least one"));
        }
        if nd > MAX_TONES {
            return Err(Issue {
                path: at("drives_hz"),
                message: format!("{nd} drive tones; at most {MAX_TONES} are simulated"),
                help: Some("a lock-in records at most 32 frequencies; split the tones into several measurements".into()),
            });
        }
        frequencies(at("drives_hz"), &self.drives_hz, "tone")?;
        Ok(())
    }

    /// A force and a phase per drive tone for each mode listed (forces ≥ 0, at least one
    /// mode), and every tone pushing some mode.
    fn check_forces(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        let nd = self.drives_hz.len();
        if self.force.is_empty() {
            return Err(issue(
                at("force"),
                "no force given (`force = { q1 = [..] }`, N/kg per tone)",
            ));
        }
        for (table, rule) in [(&self.force, "force"), (&self.phase_rad, "phase_rad")] {
            for (mode, xs) in table {
                let mut p = at(rule);
                p.push(key(mode));
                if xs.len() != nd {
                    return Err(issue(
                        p,
                        format!("{} entries; expected one per drive tone ({nd})", xs.len()),
                    ));
                }
                if rule == "force" {
                    finite_list(
                        p,
                        xs,
                        "a finite force amplitude ≥ 0 in N/kg (a sign goes into phase_rad)",
                        |x| x >= 0.0,
                    )?;
                } else {
                    finite_list(p, xs, "a finite phase in rad", |_| true)?;
                }
            }
        }
        for (d, &f) in self.drives_hz.iter().enumerate() {
            if self.force.values().all(|xs| xs[d] == 0.0) {
                let mut p = at("drives_hz");
                p.push(Seg::Index(d));
                return Err(issue(
                    p,
                    format!(
                        "tone {d} ({f} Hz) exerts no force on any mode; drop it or give it a force"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The measured frequencies, when listed: 1 to [`MAX_MEASURED`], distinct, every drive
    /// tone among them.
    fn check_measured(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        if let Some(m) = &self.measure_hz {
            if m.is_empty() {
                return Err(issue(at("measure_hz"), "empty: list the measured frequencies, or leave measure_hz out for the default lines"));
            }
            if m.len() > MAX_MEASURED {
                return Err(issue(
                    at("measure_hz"),
                    format!(
                        "{} frequencies; at most {MAX_MEASURED} per measurement",
                        m.len()
                    ),
                ));
            }
            frequencies(at("measure_hz"), m, "measured frequency")?;
            if let Some(d) = self
                .drives_hz
                .iter()
                .position(|&d| !m.iter().any(|&f| (f - d).abs() <= FREQ_TOLERANCE_HZ))
            {
                return Err(issue(
                    at("measure_hz"),
                    format!("drive tone {d} ({} Hz) is not measured; a dataset measures every drive tone", self.drives_hz[d]),
                ));
            }
        }
        Ok(())
    }

    /// Drive levels and phases, when given: both, one per tone, levels non-zero.
    fn check_drive_levels(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        let nd = self.drives_hz.len();
        if let Some(l) = &self.drive_levels_v {
            if l.len() != nd {
                return Err(issue(
                    at("drive_levels_v"),
                    format!("{} entries; expected one per drive tone ({nd})", l.len()),
                ));
            }
            finite_list(
                at("drive_levels_v"),
                l,
                "a finite non-zero drive level",
                |x| x != 0.0,
            )?;
        }
        if let Some(l) = &self.drive_phases_rad {
            if l.len() != nd {
                return Err(issue(
                    at("drive_phases_rad"),
                    format!("{} entries; expected one per drive tone ({nd})", l.len()),
                ));
            }
            finite_list(at("drive_phases_rad"), l, "a finite phase in rad", |_| true)?;
        }
        if self.drive_levels_v.is_some() != self.drive_phases_rad.is_some() {
            return Err(issue(
                at(if self.drive_levels_v.is_some() {
                    "drive_levels_v"
                } else {
                    "drive_phases_rad"
                }),
                "drive_levels_v and drive_phases_rad go together; give both or neither",
            ));
        }
        Ok(())
    }

    /// Pump tones: distinct positive frequencies, each with a level and a phase.
    fn check_pumps(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        if !self.pumps_hz.is_empty() {
            frequencies(at("pumps_hz"), &self.pumps_hz, "pump frequency")?;
        }
        let np = self.pumps_hz.len();
        for (k, v) in [
            ("pump_levels", &self.pump_levels),
            ("pump_phases_rad", &self.pump_phases_rad),
        ] {
            match v {
                None if np > 0 => {
                    return Err(issue(
                        at(k),
                        format!("missing: pumps_hz lists {np} pump tones; give their pump_levels and pump_phases_rad, one per tone"),
                    ))
                }
                Some(_) if np == 0 => {
                    return Err(issue(at(k), "given without pumps_hz; list the pump tones in Hz, or remove it"))
                }
                Some(l) if l.len() != np => {
                    return Err(issue(
                        at(k),
                        format!("{} entries; expected one per pump tone ({np})", l.len()),
                    ))
                }
                Some(l) => finite_list(at(k), l, "a finite number", |_| true)?,
                None => {}
            }
        }
        Ok(())
    }

    /// The drive ladder: at most [`MAX_LEVELS`] fractions in (0, 1], rising.
    fn check_ladder(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        if self.levels.len() > MAX_LEVELS {
            return Err(issue(
                at("levels"),
                format!(
                    "{} levels; a drive ladder has at most {MAX_LEVELS}",
                    self.levels.len()
                ),
            ));
        }
        finite_list(
            at("levels"),
            &self.levels,
            "a fraction of the forces in (0, 1]",
            |x| x > 0.0 && x <= 1.0,
        )?;
        if let Some(k) = (1..self.levels.len()).find(|&k| self.levels[k] <= self.levels[k - 1]) {
            let mut p = at("levels");
            p.push(Seg::Index(k));
            return Err(Issue {
                path: p,
                message: format!(
                    "level {k} ({}) does not rise above level {} ({}); a drive ladder's levels rise",
                    self.levels[k],
                    k - 1,
                    self.levels[k - 1]
                ),
                help: Some("list the levels in the order the drive is turned up, each once".into()),
            });
        }
        Ok(())
    }

    /// The bandwidth, when given: finite and positive (the issue names the key itself).
    fn check_bandwidth(&self, at: &impl Fn(&str) -> Vec<Seg>) -> Result<(), Issue> {
        if let Some(b) = self.bandwidth_hz {
            finite_list(
                at("bandwidth_hz"),
                &[b],
                "a finite positive bandwidth in Hz",
                |x| x > 0.0,
            )
            .map_err(|mut e| {
                e.path.pop();
                e
            })?;
        }
        Ok(())
    }
}

impl PlanMeasurement {
    /// The measurements the drive ladder records: one per level, named `name[k]`, with the
    /// forces and drive levels scaled (none of them a ladder); the measurement itself without
    /// a ladder.
    pub fn rungs(&self) -> Vec<PlanMeasurement> {
        if self.levels.is_empty() {
            return vec![self.clone()];
        }
        self.levels
            .iter()
            .enumerate()
            .map(|(k, &s)| {
                let scale = |v: &Vec<f64>| v.iter().map(|x| s * x).collect::<Vec<f64>>();
                PlanMeasurement {
                    name: format!("{}[{k}]", self.name),
                    force: self
                        .force
                        .iter()
                        .map(|(m, v)| (m.clone(), scale(v)))
                        .collect(),
                    drive_levels_v: self.drive_levels_v.as_ref().map(scale),
                    levels: Vec::new(),
                    ..self.clone()
                }
            })
            .collect()
    }
}

impl Plan {
    /// Reads a plan from TOML `text` (`origin` names it in errors) and checks it
    /// ([`Plan::check`]). Errors point at the offending key.
    pub fn from_toml(text: &str, origin: &str) -> Result<Plan, PlanError> {
        let plan: Plan = toml::from_str(text).map_err(|e| {
            let src = QuotedSource::new(origin, text);
            PlanError {
                origin: origin.to_string(),
                path: "plan".into(),
                message: e.message().to_string(),
                help: Some("see the plan format in docs/simulation.md".into()),
                span: e.span().map(|s| src.label(s)),
                src: Some(src),
            }
        })?;
        plan.issues().map_err(|i| i.locate(origin, Some(text)))?;
        Ok(plan)
    }

    /// The plan as TOML, in the format [`Plan::from_toml`] reads.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot write the plan: {e}\n"))
    }

    /// Checks the rules of a plan (without a model): a known `displacement_unit`; noise σ finite
    /// and ≥ 0, 1 ≤ shots ≤ [`MAX_SHOTS`]; at least one measurement, unique names; per
    /// measurement 1 ≤ tones ≤ [`MAX_TONES`], positive distinct frequencies, one finite force
    /// ≥ 0 (and phase) per tone and mode, every tone pushing some mode, a non-empty measured
    /// list (≤ [`MAX_MEASURED`]) of distinct positive frequencies holding every tone, drive
    /// levels finite and non-zero; finite shapes and nominal frequencies. `origin` names the
    /// plan in the error.
    pub fn check(&self, origin: &str) -> Result<(), PlanError> {
        self.issues().map_err(|i| i.locate(origin, None))
    }

    pub(crate) fn issues(&self) -> Result<(), Issue> {
        if metres_per(&self.displacement_unit).is_none() {
            return Err(issue(
                vec![key("displacement_unit")],
                format!(
                    "`{}`: expected a length unit ({}) or V",
                    self.displacement_unit,
                    harmonid_data::units::length_unit_names()
                ),
            ));
        }
        let s = self.noise.sigma_per_quadrature;
        if !(s.is_finite() && s >= 0.0) {
            return Err(issue(
                vec![key("noise"), key("sigma_per_quadrature")],
                format!(
                    "{s}: expected a finite standard deviation ≥ 0 in {}",
                    self.displacement_unit
                ),
            ));
        }
        if self.noise.shots == 0 || self.noise.shots > MAX_SHOTS {
            return Err(issue(
                vec![key("noise"), key("shots")],
                format!(
                    "{}: expected between 1 and {MAX_SHOTS} shots",
                    self.noise.shots
                ),
            ));
        }
        if self.measurements.is_empty() {
            return Err(issue(
                vec![],
                "no [[measurement]]; a plan needs at least one",
            ));
        }
        if self.measurements.len() > MAX_MEASUREMENTS {
            return Err(issue(
                vec![key("measurement")],
                format!(
                    "{} measurements; at most {MAX_MEASUREMENTS}",
                    self.measurements.len()
                ),
            ));
        }
        if self.points.len() > MAX_POINTS {
            return Err(issue(
                vec![key("point")],
                format!("{} points; at most {MAX_POINTS}", self.points.len()),
            ));
        }
        for (i, p) in self.points.iter().enumerate() {
            let at = vec![key("point"), Seg::Index(i)];
            if self.points[..i].iter().any(|q| q.name == p.name) {
                let mut a = at.clone();
                a.push(key("name"));
                return Err(issue(a, format!("point `{}` is listed twice", p.name)));
            }
            for (m, &v) in &p.shape {
                if !v.is_finite() {
                    let mut a = at.clone();
                    a.extend([key("shape"), key(m)]);
                    return Err(issue(a, format!("{v}: expected a finite mode-shape value")));
                }
            }
        }
        if let Some(why) = self.instrument.as_ref().and_then(|i| i.check()) {
            return Err(issue(vec![key("instrument")], why));
        }
        for (m, &f) in &self.nominal_hz {
            if !(f.is_finite() && f > 0.0) {
                return Err(issue(
                    vec![key("nominal_hz"), key(m)],
                    format!("{f}: expected a finite positive frequency in Hz"),
                ));
            }
        }
        for (i, m) in self.measurements.iter().enumerate() {
            let at = vec![key("measurement"), Seg::Index(i)];
            if let Some(j) = self.measurements[..i].iter().position(|n| n.name == m.name) {
                let mut a = at.clone();
                a.push(key("name"));
                return Err(issue(
                    a,
                    format!(
                        "the name `{}` is also measurement {j}'s; names must be unique",
                        m.name
                    ),
                ));
            }
            m.check(at)?;
        }
        Ok(())
    }

    /// Metres per `displacement_unit` (checked by [`Plan::check`]; 1 for an unknown unit).
    pub fn unit_m(&self) -> f64 {
        metres_per(&self.displacement_unit).unwrap_or(1.0)
    }

    /// The noise's per-quadrature σ, metres.
    pub fn sigma_m(&self) -> f64 {
        self.noise.sigma_per_quadrature * self.unit_m()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PLAN: &str = r#"
description = "two tones"
displacement_unit = "nm"

[noise]
sigma_per_quadrature = 0.05
shots = 20

[[measurement]]
name = "single_q1"
drives_hz = [207572.5, 207592.5]
force = { q1 = [3.5, 3.5] }
drive_levels_v = [1.4, 1.4]
drive_phases_rad = [0.0, 0.0]

[[measurement]]
name = "couple"
drives_hz = [207572.5, 207592.5, 415841.5]
force = { q1 = [3.5, 3.5, 0.0], q2 = [0.0, 0.0, 1.81] }
measure_hz = [207552.5, 207572.5, 207592.5, 207612.5, 415841.5]
"#;

    fn refused(text: &str) -> PlanError {
        Plan::from_toml(text, "plan.toml").expect_err("refused")
    }

    #[test]
    fn reads_writes_and_reads_back_equal() {
        let p = Plan::from_toml(PLAN, "plan.toml").expect("valid");
        assert_eq!(p.noise.shots, 20);
        assert!((p.sigma_m() - 0.05e-9).abs() < 1e-24);
        assert_eq!(p.measurements[1].force["q2"], vec![0.0, 0.0, 1.81]);
        let back = Plan::from_toml(&p.to_toml(), "written").expect("reads back");
        assert_eq!(back, p);
        // Defaults: one shot, no noise, metres.
        let q = Plan::from_toml(
            "[[measurement]]\nname = \"a\"\ndrives_hz = [1.0]\nforce = { q1 = [1.0] }\n",
            "p",
        )
        .expect("valid");
        assert_eq!(
            (q.noise.shots, q.noise.sigma_per_quadrature, q.unit_m()),
            (1, 0.0, 1.0)
        );
    }

    #[test]
    fn refusals_name_the_key_and_point_at_it() {
        let cases: [(&str, &str, &str, &str); 12] = [
            ("shots = 20", "shots = 0", "noise.shots", "between 1 and"),
            (
                "sigma_per_quadrature = 0.05",
                "sigma_per_quadrature = -0.05",
                "noise.sigma_per_quadrature",
                "≥ 0",
            ),
            (
                "sigma_per_quadrature = 0.05",
                "sigma_per_quadrature = nan",
                "noise.sigma_per_quadrature",
                "finite",
            ),
            (
                "drives_hz = [207572.5, 207592.5, 415841.5]",
                "drives_hz = [207572.5, 207572.5, 415841.5]",
                "measurement[1].drives_hz[1]",
                "coincides with tone 0",
            ),
            (
                "drives_hz = [207572.5, 207592.5, 415841.5]",
                "drives_hz = [-207572.5, 207592.5, 415841.5]",
                "measurement[1].drives_hz[0]",
                "positive",
            ),
            (
                "measure_hz = [207552.5, 207572.5, 207592.5, 207612.5, 415841.5]",
                "measure_hz = []",
                "measurement[1].measure_hz",
                "empty",
            ),
            (
                "measure_hz = [207552.5, 207572.5, 207592.5, 207612.5, 415841.5]",
                "measure_hz = [207552.5, 207572.5, 207592.5, 207612.5, 207612.5, 415841.5]",
                "measurement[1].measure_hz[4]",
                "coincides",
            ),
            (
                "measure_hz = [207552.5, 207572.5, 207592.5, 207612.5, 415841.5]",
                "measure_hz = [207552.5, 207572.5, 207612.5, 415841.5]",
                "measurement[1].measure_hz",
                "207592.5 Hz) is not measured",
            ),
            (
                "q2 = [0.0, 0.0, 1.81]",
                "q2 = [0.0, 0.0, inf]",
                "measurement[1].force.q2[2]",
                "finite force",
            ),
            (
                "q2 = [0.0, 0.0, 1.81]",
                "q2 = [0.0, 1.81]",
                "measurement[1].force.q2",
                "one per drive tone",
            ),
            (
                "drive_levels_v = [1.4, 1.4]",
                "drive_levels_v = [0.0, 1.4]",
                "measurement[0].drive_levels_v[0]",
                "non-zero",
            ),
            (
                "name = \"couple\"",
                "name = \"single_q1\"",
                "measurement[1].name",
                "unique",
            ),
        ];
        for (from, to, path, says) in cases {
            assert!(PLAN.contains(from), "{from}");
            let text = PLAN.replacen(from, to, 1);
            let e = refused(&text);
            assert_eq!(e.path, path, "{to}: {e}");
            assert!(e.message.contains(says), "{to}: {e}");
            // The span points into the offending line.
            let span = e.span.expect("located");
            let line = text[..span.offset()].lines().last().unwrap_or("");
            let here = &text[span.offset()..span.offset() + span.len()];
            let key_name = path
                .rsplit('.')
                .next()
                .unwrap_or(path)
                .split('[')
                .next()
                .unwrap_or("");
            assert!(
                line.contains(key_name) || here.contains(key_name) || to.contains(here),
                "{to}: span `{here}` on `{line}`"
            );
        }
    }

    #[test]
    fn bounded_work_and_empty_plans_are_refused() {
        let tones: Vec<String> = (0..1000).map(|k| format!("{}.0", 1000 + k)).collect();
        let forces = vec!["1.0"; 1000].join(", ");
        let text = format!(
            "[[measurement]]\nname = \"many\"\ndrives_hz = [{}]\nforce = {{ q1 = [{forces}] }}\n",
            tones.join(", ")
        );
        let e = refused(&text);
        assert!(e.message.contains("1000 drive tones; at most 32"), "{e}");
        let e = refused("description = \"nothing\"\n");
        assert!(e.message.contains("no [[measurement]]"), "{e}");
        let e = refused(
            "[[measurement]]\nname = \"a\"\ndrives_hz = [1.0, 2.0]\nforce = { q1 = [1.0, 0.0] }\n",
        );
        assert!(e.message.contains("tone 1 (2 Hz) exerts no force"), "{e}");
        let e = refused("displacement_unit = \"furlong\"\n[[measurement]]\nname = \"a\"\ndrives_hz = [1.0]\nforce = { q1 = [1.0] }\n");
        assert_eq!(e.path, "displacement_unit");
        let e = refused("[[measurement]]\nname = \"a\"\ndrives_hz = [1.0]\nforce = { q1 = [1.0] }\nmystery = 1\n");
        assert!(e.message.contains("mystery"), "{e}");
        assert!(e.span.is_some());
    }
}

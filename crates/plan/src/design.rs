//! Designs a plan: per mode a tone pair near its resonance at the strongest drive that stays
//! on the drive-up branch (no jump) and stable, with the spacing that minimises the bounds of
//! that mode's unknowns; then, for each parameter coupling several modes, one measurement with
//! tones near the modes of its terms (or near all but one whose frequency is a sum or
//! difference of the others', whose line then appears through the coupling), the variant
//! with the smaller bounds. Lines: the drive tones and the largest predicted lines near any
//! resonance, at most `max_frequencies`; every tone on the instrument grid, so every line is.

use crate::coupled::{coupled_variants, preference_order, Tones, Variant, COMPARABLE};
use crate::devices::{feasible_on, SolverPool};
use crate::evaluate::{joint_bounds, robustness_within, Evaluation};
use crate::info::{
    info_of, is_infeasible, ladder_info, restrict_lines, simulate, too_large, truncation_unchecked,
    Fidelity, MeasInfo, Target,
};
use crate::level::{pair_fold_estimate, strongest};
use crate::range::GuessRange;
use crate::terms::param_modes;
use crate::PlanError;
use harmonid_data::{Dataset, Point};
use harmonid_experiment::{Plan, PlanMeasurement, PlanNoise};
use harmonid_ident::Unknown;
use harmonid_model::{Linear, Model};
use harmonid_sim::{ModelValues, NumericModel};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

/// Limits and noise of a design.
#[derive(Debug, Clone)]
pub struct DesignSettings {
    /// Per-quadrature noise of every amplitude, m.
    pub sigma_m: f64,
    /// Shots per measurement.
    pub shots: usize,
    /// Most measured lines per measurement (the lock-in's limit).
    pub max_frequencies: usize,
    /// Most measurements (`None`: as many as the unknowns need).
    pub max_measurements: Option<usize>,
    /// Instrument frequency grid, Hz: every tone (and so every line) is a multiple of it.
    pub grid_hz: f64,
    /// Largest force per tone, N/kg.
    pub max_force: f64,
    /// Actuator gains, N/kg per volt, by mode (empty: levels are forces). With gains, every
    /// driven mode needs one; drive levels are written in volts (`force = gain × level`).
    pub gains: BTreeMap<String, f64>,
    /// Largest drive level per tone, V (needs [`Self::gains`]): caps mode `n`'s force at
    /// `max_voltage × gain_n`.
    pub max_voltage: Option<f64>,
    /// Measurement points (mode shapes); empty: modal amplitudes.
    pub points: Vec<Point>,
    /// Wall-clock budget of the whole design, s (`None`: none). Once spent, each measurement
    /// still to design keeps the first feasible candidate (or the best of those already
    /// tried); the final pass scores the measurements it has not reached at the search's
    /// lattice order (no truncation check); the devices drawn from the range are scored until
    /// it is spent (at least one device; the median and worst bounds are over those). Each cut
    /// is noted in the plan's [`Evaluation::notes`]. A design always completes: the budget
    /// bounds its options, not its result, so it can overrun by the first feasible candidates
    /// of the measurements left and the first device drawn.
    pub time_budget_s: Option<f64>,
    /// The devices the plan must survive (`None`: the guess only). Every candidate drive is
    /// checked at the corners of this range ([`GuessRange::corners`]) as well as at the guess,
    /// and the plan's bounds are reported over [`Self::draws`] devices drawn from it.
    pub range: Option<GuessRange>,
    /// Devices drawn from the range for the plan's worst-case bounds.
    pub draws: usize,
    /// A drive ladder for every measurement: fractions of its designed forces, rising, each
    /// in (0, 1] (the plan's `levels`; empty: each measurement once, at its forces). A level
    /// that has no stable state on the device then costs that level, not the measurement,
    /// and the bounds count every level kept.
    pub ladder: Vec<f64>,
}

impl Default for DesignSettings {
    fn default() -> Self {
        Self {
            sigma_m: 5e-11,
            shots: 20,
            max_frequencies: 32,
            max_measurements: None,
            grid_hz: 0.5,
            max_force: f64::INFINITY,
            gains: BTreeMap::new(),
            max_voltage: None,
            points: Vec::new(),
            time_budget_s: None,
            range: None,
            draws: DEFAULT_DRAWS,
            ladder: Vec::new(),
        }
    }
}

/// Devices drawn from the guess's range for a plan's worst-case bounds, by default.
pub const DEFAULT_DRAWS: usize = 10;

/// The drive ladder `harmonid plan` gives every measurement of a design over a guess's range,
/// by default: half, three quarters and all of the designed forces.
pub const DEFAULT_LADDER: [f64; 3] = [0.5, 0.75, 1.0];

/// The drive ladder a design gets unless one is asked for: [`DEFAULT_LADDER`] over a guess's
/// range (a device off the guess may lose a level), none at the guess alone.
pub fn default_ladder(over_range: bool) -> Vec<f64> {
    if over_range {
        DEFAULT_LADDER.to_vec()
    } else {
        Vec::new()
    }
}

/// A scored candidate measurement: worst bound, the measurement, its information, and its tone
/// spacing, level and centre.
type Candidate = (f64, PlanMeasurement, MeasInfo, Pair);

/// Most candidates of a coupled measurement whose truncation is checked before the design
/// keeps the preferred one unchecked.
const MAX_TRUNCATION_TRIES: usize = 4;

/// Whether `e` is `harmonid simulate`'s refusal of a state whose lattice never settles.
fn is_truncated(e: &PlanError) -> bool {
    matches!(e, PlanError::Experiment(x) if matches!(**x, harmonid_experiment::ExperimentError::Truncated { .. }))
}

/// The fraction of the strongest feasible level a single-mode pair is planned at.
const LEVEL_MARGIN: f64 = 0.8;

/// The fraction of the strongest feasible level a single-mode pair is planned at under
/// settings `s`: [`LEVEL_MARGIN`], or all of it as the top of a drive ladder (whose lower
/// levels keep the margin; losing the top costs one level).
fn level_margin(s: &DesignSettings) -> f64 {
    if s.ladder.len() > 1 {
        1.0
    } else {
        LEVEL_MARGIN
    }
}

/// Tone-pair spacings tried per mode, in linewidths, narrowest first.
const SPACINGS: [f64; 3] = [3.0, 6.0, 12.0];
/// A spacing whose worst bound exceeds the best so far by this factor ends the search: the
/// bounds only grow with wider pairs from there.
const CLEARLY_WORSE: f64 = 1.5;

/// Candidates whose lattice at the guess has more lines than this are screened over the range at
/// [`Fidelity::Screen`] before the search's order (a few lines' lattice costs little either way).
const SCREEN_ABOVE_LINES: usize = 200;

/// A worst relative bound of a group's unknowns this small ends the search for drives of that
/// group with more tones: the three-tone variants are kept when they reach it.
const GOOD_ENOUGH: f64 = 0.1;

/// `Some` of a usable result, `None` when the drive is infeasible (fold, instability, no steady
/// state), the error otherwise.
fn feasible<T>(r: Result<T, PlanError>) -> Result<Option<T>, PlanError> {
    match r {
        Ok(x) => Ok(Some(x)),
        Err(e) if is_infeasible(&e) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Rounds `x` to a multiple of `g`.
fn on_grid(x: f64, g: f64) -> f64 {
    (x / g).round() * g
}

/// Rounds a force to 3 significant digits (through its decimal form, so the plan file shows
/// `10.7`, not `10.700000000000001`).
fn round3(x: f64) -> f64 {
    format!("{x:.2e}").parse().unwrap_or(x)
}

/// Rounds a positive `x` down to 3 significant digits (`0.4499` → `0.449`).
fn floor3(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let e = 10f64.powi(x.log10().floor() as i32 - 2);
    // Through the decimal form, as `round3`, so the level reads `0.449`.
    // (A level a float step below its 3-digit value, 0.22499999…, keeps 0.225.)
    let d = ((x / e) * (1.0 + 1e-9)).floor();
    format!("{:.2e}", d * e).parse().unwrap_or(d * e)
}

/// A measurement with `tones` (`(Hz, mode, force N/kg)`), phase 0, drive levels through the
/// actuator gains `gains` (N/kg per level unit, per mode): each level rounded to 3 significant
/// digits, the force the level times the gain (with gains 1, levels = forces).
fn measurement(
    name: &str,
    tones: &[(f64, usize, f64)],
    names: &[String],
    gains: &[f64],
) -> PlanMeasurement {
    let mut force: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut levels = Vec::with_capacity(tones.len());
    for (d, &(_, n, f)) in tones.iter().enumerate() {
        let level = if gains[n] == 1.0 {
            f
        } else {
            round3(f / gains[n])
        };
        levels.push(level);
        force
            .entry(names[n].clone())
            .or_insert_with(|| vec![0.0; tones.len()])[d] = level * gains[n];
    }
    PlanMeasurement {
        name: name.to_string(),
        drives_hz: tones.iter().map(|t| t.0).collect(),
        force,
        phase_rad: BTreeMap::new(),
        measure_hz: None,
        drive_levels_v: Some(levels),
        drive_phases_rad: Some(vec![0.0; tones.len()]),
        pumps_hz: Vec::new(),
        pump_levels: None,
        pump_phases_rad: None,
        bandwidth_hz: None,
        levels: Vec::new(),
    }
}

/// The drive tones and the largest lines (over points) of `data` (the noise-free simulation of
/// `pm`), at most `max` in all, ascending: the lines the lock-in reads.
fn choose_lines(pm: &PlanMeasurement, data: &Dataset, max: usize) -> Vec<f64> {
    let m = &data.measurements[0];
    let np = m.points.len();
    let mut lines: Vec<(f64, f64)> = m
        .freqs_hz
        .iter()
        .enumerate()
        .map(|(r, &f)| {
            let a = (0..np)
                .map(|p| m.amplitude(0, r, p).norm())
                .fold(0.0, f64::max);
            let tone = pm.drives_hz.iter().any(|&d| (d - f).abs() < 1e-6);
            (f, if tone { f64::INFINITY } else { a })
        })
        .collect();
    lines.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut keep: Vec<f64> = lines.iter().take(max).map(|l| l.0).collect();
    keep.sort_by(f64::total_cmp);
    keep
}

/// Worst relative bound of `names` (quantity names) in `ev` (infinite when one is missing or
/// not identifiable).
fn worst_of(ev: &Evaluation, names: &[String]) -> f64 {
    names
        .iter()
        .map(|n| ev.bounds.get(n).map_or(f64::INFINITY, |b| b.rel))
        .fold(0.0, f64::max)
}

/// Quantity names of the free unknowns among `unknowns`.
fn quantity_names(model: &Model, unknowns: &[Unknown]) -> Vec<String> {
    unknowns
        .iter()
        .filter_map(|u| match *u {
            Unknown::OmegaSq(n) if model.modes[n].f_hz == Linear::Unknown => {
                Some(format!("f_hz:{}", model.modes[n].name))
            }
            Unknown::Gamma(n) if model.modes[n].q_factor == Linear::Unknown => {
                Some(format!("Q:{}", model.modes[n].name))
            }
            Unknown::Param(p) if model.params[p].kind == harmonid_model::ParamKind::Unknown => {
                Some(model.params[p].name.clone())
            }
            _ => None,
        })
        .collect()
}

/// Designs a plan for `model` at the guessed `values`; returns it with its evaluation.
/// Errors: an unknown no drive within the limits reveals, a budget too small, values the
/// simulation refuses. Nothing is returned unless every unknown is identifiable.
pub fn design(
    model: &Model,
    values: &ModelValues,
    settings: &DesignSettings,
) -> Result<(Plan, Evaluation), PlanError> {
    design_with_progress(model, values, settings, &mut |_| {})
}

/// Where a design is: `done` of `total` steps are done, the last of them (or the work under
/// way) named `name`.
#[derive(Debug, Clone, Copy)]
pub struct DesignStep<'a> {
    /// Steps done so far (measurements designed, then scored, then devices drawn).
    pub done: usize,
    /// Steps the design needs.
    pub total: usize,
    /// The measurement just designed (`single_q1`, `couple_q1_q2`; the measurements of a
    /// stage are designed side by side), or the work under way.
    pub name: &'a str,
}

/// [`design`], calling `progress` as each measurement's design starts (a design can take
/// minutes; the command line shows a progress bar).
pub fn design_with_progress(
    model: &Model,
    values: &ModelValues,
    settings: &DesignSettings,
    progress: &mut dyn FnMut(DesignStep<'_>),
) -> Result<(Plan, Evaluation), PlanError> {
    design_inner(model, values, settings, None, progress)
}

/// [`design_with_progress`] with the drive's tones on one output whose summed amplitude is at
/// most `output_cap` V (`crate::instrument`): every tone of a pair at most half of it, every
/// measurement's levels scaled down (rounded down) to sum to at most it. `None`: the settings'
/// per-tone limits alone.
pub(crate) fn design_inner(
    model: &Model,
    values: &ModelValues,
    settings: &DesignSettings,
    output_cap: Option<f64>,
    progress: &mut dyn FnMut(DesignStep<'_>),
) -> Result<(Plan, Evaluation), PlanError> {
    let s = settings;
    check_settings(s)?;
    let num = NumericModel::from_model(model, values)?;
    if num.has_pump_terms() {
        return Err(PlanError::PumpTerms {
            model: model.source.clone(),
            terms: num.pump_term_names().join(", "),
        });
    }
    let names = num.mode_names.clone();
    let mut base = base_plan(model, &num, s);
    let stages = Stages::new(model, &names, s.max_measurements)?;
    let needed = stages.needed();
    let instrument = Instrument::new(&num, s, &stages.single, output_cap)?;
    let target = Target {
        model,
        num: &num,
        values,
        sigma_m: s.sigma_m,
        shots: s.shots,
    };
    let designer = Designer {
        model,
        num: &num,
        base: &base,
        target: &target,
        s,
        names: &names,
        limits: limits_text(s),
        notes: Mutex::new(Vec::new()),
        search_notes: Mutex::new(BTreeMap::new()),
        deadline: s
            .time_budget_s
            .map(|t| std::time::Instant::now() + std::time::Duration::from_secs_f64(t.max(0.0))),
        corners: Mutex::new(BTreeMap::new()),
        pool: SolverPool::new(2 * rayon::current_num_threads()),
        gains: instrument.gains,
        caps: instrument.caps,
        output_cap,
    };
    // One bar over the whole work: the search's measurements, the final pass over them, the
    // devices drawn.
    let draws = s.range.as_ref().map_or(0, |_| s.draws);
    let total = 2 * needed + draws;
    let mut progress = |st: DesignStep<'_>| progress(DesignStep { total, ..st });
    let mut plan_ms = designer.measurements_by_stage(&stages, needed, &mut progress)?;
    for pm in &mut plan_ms {
        // A ladder of one level at the full forces is the measurement itself.
        if s.ladder != [1.0] {
            pm.levels = s.ladder.clone();
        }
    }
    let infos = designer.final_information(&plan_ms, &mut |k| {
        progress(DesignStep {
            done: needed + k,
            total,
            name: "scoring the plan at simulate's fidelity",
        })
    })?;
    let deadline = designer.deadline;
    let limits = designer.limits;
    let notes = designer
        .notes
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    base.measurements = plan_ms;
    let refs: Vec<&MeasInfo> = infos.iter().collect();
    let mut ev = joint_bounds(model, &refs, s.shots)?;
    ev.notes = notes;
    if let Some(f) = ev.findings.first() {
        return Err(PlanError::Unidentifiable {
            parameter: f.unknown.clone(),
            reason: f.reason.clone(),
            limits,
        });
    }
    if let Some(range) = &s.range {
        let what = "scoring the devices drawn from the range";
        let (mut r, skipped) = robustness_within(
            model,
            range,
            &base,
            (s.sigma_m, s.shots),
            s.draws,
            deadline,
            &mut |k| {
                progress(DesignStep {
                    done: 2 * needed + k,
                    total,
                    name: what,
                })
            },
        )?;
        if skipped > 0 {
            ev.notes.push(format!(
                "the time budget ({} s) was spent: the median and worst bounds are over the first {} of the {} devices drawn from the range, {skipped} were not scored (a larger --time-budget scores them all)",
                s.time_budget_s.unwrap_or_default(),
                r.draws,
                s.draws
            ));
        }
        r.corners = Some(corners_text(s));
        ev.robustness = Some(r);
    }
    progress(DesignStep {
        done: total,
        total,
        name: "",
    });
    Ok((base, ev))
}

/// The plan's frame before any measurement: description, points, nominal frequencies and
/// noise, shared by every candidate the search simulates.
fn base_plan(model: &Model, num: &NumericModel, s: &DesignSettings) -> Plan {
    Plan {
        description: format!("designed by harmonid plan for {}", model.source),
        displacement_unit: "m".into(),
        points: s.points.clone(),
        nominal_hz: num
            .mode_names
            .iter()
            .cloned()
            .zip(num.f_hz.iter().copied())
            .collect(),
        noise: PlanNoise {
            sigma_per_quadrature: s.sigma_m,
            shots: s.shots,
        },
        measurements: Vec::new(),
        instrument: None,
    }
}

/// The instrument's limits in words, for the message when an unknown cannot be identified.
fn limits_text(s: &DesignSettings) -> String {
    format!(
        "forces ≤ {} N/kg per tone{}, {} lines per measurement, grid {} Hz, no jump while driving up, stable",
        s.max_force,
        s.max_voltage.map_or(String::new(), |v| format!(", drive levels ≤ {v} V")),
        s.max_frequencies,
        s.grid_hz
    )
}

/// What the robustness report says the range checks of the design covered.
fn corners_text(s: &DesignSettings) -> String {
    format!(
        "every measurement reaches its level without a jump and is stable at the guess and on \
         devices of the range with every Q at its upper end: each driven mode's frequency at \
         either end and stepped across its range by a half-width, parameters at their larger \
         magnitude; and the guess's frequencies with parameters at their smaller magnitude. \
         {}",
        if s.ladder.len() > 1 {
            format!(
                "Single-mode pairs are then planned at the strongest such level, the top of \
                 their drive ladder {:?}",
                s.ladder
            )
        } else {
            format!(
                "Single-mode pairs are then planned {:.0} % below the strongest such level",
                100.0 * (1.0 - LEVEL_MARGIN)
            )
        }
    )
}

/// The settings a design cannot start without: a positive noise, shots, grid, and room for
/// two lines per measurement.
fn check_settings(s: &DesignSettings) -> Result<(), PlanError> {
    let setting = |what, found: String, expected| PlanError::Setting {
        what,
        found,
        expected,
    };
    if !(s.sigma_m.is_finite() && s.sigma_m > 0.0) {
        return Err(setting(
            "the noise σ",
            format!("{:e} m", s.sigma_m),
            "positive",
        ));
    }
    if s.shots == 0 {
        return Err(setting("shots", "0".into(), "at least 1"));
    }
    if !(s.grid_hz.is_finite() && s.grid_hz > 0.0) {
        return Err(setting("the grid", format!("{} Hz", s.grid_hz), "positive"));
    }
    if s.max_frequencies < 2 {
        let found = s.max_frequencies.to_string();
        return Err(setting("the lines per measurement", found, "at least 2"));
    }
    crate::check_draws(s.draws)?;
    let rising = s.ladder.windows(2).all(|w| w[1] > w[0]);
    if !(rising
        && s.ladder.len() <= harmonid_experiment::MAX_LEVELS
        && s.ladder.iter().all(|&x| x > 0.0 && x <= 1.0))
    {
        return Err(setting(
            "the drive ladder",
            format!("{:?}", s.ladder),
            "rising fractions of the forces, each in (0, 1], at most 16",
        ));
    }
    Ok(())
}

/// The coarsest grid, in linewidths of a driven mode, a plan is designed on.
const MAX_GRID_LINEWIDTHS: f64 = 2.0;

/// The instrument's reach per mode: actuator gains and force caps, checked against the modes
/// the plan drives.
struct Instrument {
    gains: Vec<f64>,
    caps: Vec<f64>,
}

impl Instrument {
    /// Errors: gains or a voltage limit without a gain for a driven mode, a gain that is not
    /// positive, a grid coarser than two linewidths of a driven mode (no tone pair fits it).
    fn new(
        num: &NumericModel,
        s: &DesignSettings,
        driven: &[usize],
        output_cap: Option<f64>,
    ) -> Result<Self, PlanError> {
        let names = &num.mode_names;
        let err = |message: String| PlanError::Instrument { message };
        if let Some(k) = s.gains.keys().find(|k| !names.contains(k)) {
            return Err(err(format!(
                "a gain for {k}, which the model does not have (modes: {})",
                names.join(", ")
            )));
        }
        if let Some((k, g)) = s.gains.iter().find(|(_, g)| !(g.is_finite() && **g > 0.0)) {
            return Err(err(format!(
                "the gain of {k} is {g} N/kg per V: it must be positive"
            )));
        }
        if let Some(v) = s.max_voltage {
            if !(v.is_finite() && v > 0.0) {
                return Err(err(format!(
                    "the largest drive level is {v} V: it must be positive"
                )));
            }
        }
        if !s.gains.is_empty() || s.max_voltage.is_some() {
            let missing: Vec<&str> = driven
                .iter()
                .map(|&n| names[n].as_str())
                .filter(|n| !s.gains.contains_key(*n))
                .collect();
            if !missing.is_empty() {
                return Err(err(format!(
                    "drive levels in volts need the actuator gain of every driven mode; none for {} (give --gain {}=N_PER_KG_PER_V, or --gains-from a result)",
                    missing.join(", "),
                    missing[0]
                )));
            }
        }
        // A pair is at least two grid steps wide and its centre up to half a step off the
        // resonance: beyond two linewidths a step leaves no tone on the resonance.
        for &n in driven {
            let linewidth = num.f_hz[n] / num.q_factor[n];
            if s.grid_hz > MAX_GRID_LINEWIDTHS * linewidth {
                return Err(err(format!(
                    "the grid of {} Hz is coarser than {MAX_GRID_LINEWIDTHS} linewidths of {} ({linewidth:.3} Hz each): no tone pair fits its resonance; use a finer grid (--grid-hz {:.3} or less)",
                    s.grid_hz,
                    names[n],
                    MAX_GRID_LINEWIDTHS * linewidth
                )));
            }
        }
        let gains: Vec<f64> = names
            .iter()
            .map(|k| s.gains.get(k).copied().unwrap_or(1.0))
            .collect();
        // A pair's two tones share a summed output cap.
        let caps = gains
            .iter()
            .map(|g| {
                s.max_force
                    .min(s.max_voltage.map_or(f64::INFINITY, |v| v * g))
                    .min(output_cap.map_or(f64::INFINITY, |v| 0.5 * v * g))
            })
            .collect();
        Ok(Self { gains, caps })
    }
}

/// A mode's designed tone pair: centre (Hz), spacing (Hz), force per tone (N/kg).
type Pair = (f64, f64, f64);

/// The unknowns by stage: each mode's own (f, Q, parameters of terms in it alone), measured
/// by a single-mode pair, then the parameters by the set of modes they couple.
struct Stages {
    own: Vec<Vec<Unknown>>,
    groups: BTreeMap<Vec<usize>, Vec<Unknown>>,
    /// The modes that get a single-mode measurement.
    single: Vec<usize>,
}

impl Stages {
    /// Errors: more measurements needed than `max_measurements` (listed by name).
    fn new(
        model: &Model,
        names: &[String],
        max_measurements: Option<usize>,
    ) -> Result<Self, PlanError> {
        let nm = names.len();
        let mut own: Vec<Vec<Unknown>> = (0..nm)
            .map(|n| vec![Unknown::OmegaSq(n), Unknown::Gamma(n)])
            .collect();
        let mut groups: BTreeMap<Vec<usize>, Vec<Unknown>> = BTreeMap::new();
        for p in 0..model.params.len() {
            let modes: Vec<usize> = param_modes(model, p).into_iter().collect();
            match modes.len() {
                0 => {}
                1 => own[modes[0]].push(Unknown::Param(p)),
                _ => groups.entry(modes).or_default().push(Unknown::Param(p)),
            }
        }
        let single: Vec<usize> = (0..nm)
            .filter(|&n| {
                !quantity_names(model, &own[n]).is_empty() || groups.keys().any(|k| k.contains(&n))
            })
            .collect();
        let stages = Self {
            own,
            groups,
            single,
        };
        let needed = stages.needed();
        if let Some(limit) = max_measurements {
            if needed > limit {
                let list: Vec<String> = stages
                    .single
                    .iter()
                    .map(|&n| format!("single_{}", names[n]))
                    .chain(stages.groups.keys().map(|k| {
                        format!(
                            "couple_{}",
                            k.iter()
                                .map(|&n| names[n].as_str())
                                .collect::<Vec<_>>()
                                .join("_")
                        )
                    }))
                    .collect();
                return Err(PlanError::Budget {
                    needed,
                    limit,
                    list: list.join(", "),
                });
            }
        }
        Ok(stages)
    }

    /// Measurements the plan needs.
    fn needed(&self) -> usize {
        self.single.len() + self.groups.len()
    }
}

/// How many linewidths of damping a mode's own velocity terms may add at the strongest drive
/// the designer tries (see [`velocity_damping_amplitude`]).
const DAMPING_CAP: f64 = 3.0;

/// The amplitude (m) at which the velocity terms of mode `n`'s own equation (`c q^k q̇^j`,
/// `j ≥ 1`, degree `k + j ≥ 2`) reach the damping rate `rate` (1/s), by the size of their
/// single-harmonic damping `|c| a^(k+j−1) ω^(j−1)`; `None` without such terms. A non-smooth
/// factor counts as its variable to the power of its growth: `abs(x)` as `x` (quadratic drag
/// `|q̇| q̇` is `j = 2`, degree 2: damping `|c| a ω`), `sign(x)` and `tanh(x/c)` as none (their
/// damping falls with the amplitude, so they never cap the drive).
fn velocity_damping_amplitude(num: &NumericModel, n: usize, rate: f64) -> Option<f64> {
    let nm = num.n_modes();
    let w = num.omega(n);
    let own = |v: usize| v == n || v == nm + n;
    // (coefficient, polynomial factors, non-smooth factors as (variable, growth power)).
    let poly = num.eq_terms(n).iter().map(|t| (t.coef, t.factors.clone()));
    let rough = num.rough_terms().iter().filter(|t| t.eq == n).map(|t| {
        let mut f = t.factors.clone();
        for &(g, k) in &t.nonsmooth {
            if matches!(g, harmonid_model::NonSmooth::Abs(_)) {
                f.push((g.var().index(), k));
            } else {
                // A bounded factor of its own variable: growth 0, but it stays the mode's own.
                f.push((g.var().index(), 0));
            }
        }
        (t.coef, f)
    });
    let terms: Vec<(f64, i32, i32)> = poly
        .chain(rough)
        .filter(|(_, f)| f.iter().all(|&(v, _)| own(v)))
        .filter_map(|(coef, f)| {
            let j: u32 = f.iter().filter(|x| x.0 == nm + n).map(|x| x.1).sum();
            let deg: u32 = f.iter().map(|x| x.1).sum();
            (j >= 1 && deg >= 2 && coef != 0.0).then_some((
                coef.abs(),
                deg as i32 - 1,
                j as i32 - 1,
            ))
        })
        .collect();
    if terms.is_empty() {
        return None;
    }
    let damping = |a: f64| -> f64 {
        terms
            .iter()
            .map(|&(c, p, q)| c * a.powi(p) * w.powi(q))
            .sum()
    };
    // Increasing in a: bisect in log a.
    let (mut lo, mut hi) = (1e-18_f64.ln(), 1.0_f64.ln());
    if damping(1.0) < rate {
        return None;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if damping(mid.exp()) < rate {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(hi.exp())
}

/// What every stage of a design reads: the model at the guessed values, the plan's frame
/// (points, noise) and the instrument's limits.
struct Designer<'a> {
    model: &'a Model,
    num: &'a NumericModel,
    base: &'a Plan,
    target: &'a Target<'a>,
    s: &'a DesignSettings,
    names: &'a [String],
    /// The limits, for messages.
    limits: String,
    /// The design's notes ([`Evaluation::notes`]): candidates skipped because their harmonic
    /// balance is beyond a size bound, measurements the time budget cut, unchecked truncations.
    notes: Mutex<Vec<String>>,
    /// The search's notes by measurement: its measurements are designed side by side, so
    /// their notes join [`Self::notes`] in the plan's order when the search ends.
    search_notes: Mutex<BTreeMap<String, Vec<String>>>,
    /// When the search's time budget runs out.
    deadline: Option<std::time::Instant>,
    /// Per mode: its actuator gain (N/kg per level unit; 1 without gains) and largest force
    /// per tone (N/kg).
    gains: Vec<f64>,
    caps: Vec<f64>,
    /// The largest summed drive level of a measurement's tones, V (one output).
    output_cap: Option<f64>,
    /// The devices of the range checked per set of tones (frequency bits, mode), built when
    /// first needed, with the one that failed last (tried first: a drive too strong for one
    /// device is usually too strong for the same one at the next level).
    corners: Mutex<BTreeMap<Vec<(u64, usize)>, CornerSet>>,
    /// Ramp solvers kept across the range checks: a drive's tones keep their lattice while the
    /// search moves its level, so its solvers serve every level (and both fidelities) instead
    /// of being planned and allocated per check.
    pool: SolverPool,
}

/// The devices checked for one set of tones and the index of the one that failed last.
type CornerSet = Arc<(Vec<(String, NumericModel)>, AtomicUsize)>;

impl Designer<'_> {
    /// The plan's measurements in design order: stage 1, a tone pair per mode; stage 2, one
    /// measurement per set of coupled modes, built on stage 1's pairs and scored with stage
    /// 1's information. The measurements of a stage do not depend on each other: they are
    /// designed side by side, and the plan is the same whatever the threads (the order of the
    /// results and of their notes is the plan's).
    fn measurements_by_stage(
        &self,
        stages: &Stages,
        needed: usize,
        progress: &mut dyn FnMut(DesignStep<'_>),
    ) -> Result<Vec<PlanMeasurement>, PlanError> {
        let names = self.names;
        let singles: Vec<(usize, String)> = stages
            .single
            .iter()
            .map(|&n| (n, format!("single_{}", names[n])))
            .collect();
        let mut step = Steps {
            done: 0,
            total: needed,
            progress,
        };
        let designed = step.in_parallel(&singles, |(n, name)| {
            (name.as_str(), self.single(*n, &stages.own[*n], name))
        })?;
        let mut pairs: Vec<Option<Pair>> = vec![None; names.len()];
        let mut infos: Vec<MeasInfo> = Vec::with_capacity(singles.len());
        let mut plan_ms: Vec<PlanMeasurement> = Vec::with_capacity(needed);
        for ((n, _), (pm, info, pair)) in singles.iter().zip(designed) {
            pairs[*n] = Some(pair);
            infos.push(info);
            plan_ms.push(pm);
        }
        let groups: Vec<(&Vec<usize>, &Vec<Unknown>, String)> = stages
            .groups
            .iter()
            .map(|(modes, unknowns)| {
                let label: Vec<&str> = modes.iter().map(|&n| names[n].as_str()).collect();
                (modes, unknowns, label.join("_"))
            })
            .collect();
        let coupled = step.in_parallel(&groups, |(modes, unknowns, label)| {
            let r = self.coupling(modes, unknowns, label, &pairs, &infos);
            (label.as_str(), r.map(|(pm, _)| pm))
        })?;
        plan_ms.extend(coupled);
        let mut by_measurement = std::mem::take(&mut *lock(&self.search_notes));
        let mut notes = lock(&self.notes);
        for pm in &plan_ms {
            notes.extend(by_measurement.remove(&pm.name).unwrap_or_default());
        }
        Ok(plan_ms)
    }

    /// The information of the plan's measurements as `harmonid simulate --plan` will simulate
    /// them (the truncation check may raise the lattice order the search used). A measurement
    /// whose wider lattice is beyond a size bound keeps the search's lattice, with a note: the
    /// check is not possible, which is not evidence of truncation. The measurements are
    /// independent: scored side by side (`progress` told how many are done), noted in order.
    /// Once the time budget is spent, the measurements not yet started are scored at the
    /// search's fidelity (no truncation check), with a note naming them.
    fn final_information(
        &self,
        plan_ms: &[PlanMeasurement],
        progress: &mut dyn FnMut(usize),
    ) -> Result<Vec<MeasInfo>, PlanError> {
        let (target, base) = (self.target, self.base);
        let mut steps = Steps {
            done: 0,
            total: plan_ms.len(),
            progress: &mut |st: DesignStep<'_>| progress(st.done),
        };
        // Each measurement checks the deadline as it starts: once spent, at the search's
        // fidelity.
        let scored = steps.in_parallel(plan_ms, |pm| {
            let spent = self
                .deadline
                .is_some_and(|d| std::time::Instant::now() >= d);
            let fidelity = if spent {
                Fidelity::Search
            } else {
                Fidelity::User
            };
            let (unchecked, r) = match ladder_info(target, base, pm, fidelity) {
                Err(e) if truncation_unchecked(&e) => (
                    Some(e.to_string()),
                    ladder_info(target, base, pm, Fidelity::Search),
                ),
                r => (None, r),
            };
            (pm.name.as_str(), r.map(|scored| (spent, unchecked, scored)))
        })?;
        let mut infos = Vec::with_capacity(plan_ms.len());
        let mut unchecked_by_budget = Vec::new();
        for (pm, (spent, unchecked, (info, lost))) in plan_ms.iter().zip(scored) {
            if spent {
                unchecked_by_budget.push(pm.name.as_str());
            }
            if let Some(e) = unchecked {
                self.note(format!(
                    "{}: its harmonic balance's truncation is not checked at a wider lattice ({e})",
                    pm.name
                ));
            }
            infos.extend(info);
            for k in lost {
                self.note(crate::evaluate::lost_note(pm, k));
            }
        }
        if !unchecked_by_budget.is_empty() {
            self.note(format!(
                "the time budget ({} s) was spent before the final pass: {} are scored at the search's lattice order, without the truncation check `harmonid simulate` makes (a larger --time-budget checks them)",
                self.s.time_budget_s.unwrap_or_default(),
                unchecked_by_budget.join(", ")
            ));
        }
        Ok(infos)
    }

    /// [`measurement`] with the instrument's gains; with an output cap, the levels scaled to
    /// sum to at most it and rounded down to 3 digits (rounding up could pass the cap).
    fn measurement(&self, name: &str, tones: &[(f64, usize, f64)]) -> PlanMeasurement {
        let Some(cap) = self.output_cap else {
            return measurement(name, tones, self.names, &self.gains);
        };
        let sum: f64 = tones.iter().map(|&(_, n, f)| f / self.gains[n]).sum();
        let k = if sum > cap { cap / sum } else { 1.0 };
        let capped: Vec<(f64, usize, f64)> = tones
            .iter()
            .map(|&(hz, n, f)| (hz, n, floor3(k * f / self.gains[n]) * self.gains[n]))
            .collect();
        measurement(name, &capped, self.names, &self.gains)
    }

    /// A candidate measurement simulated once at search fidelity, its lines chosen, its
    /// information computed on those lines; `None` for an infeasible drive (at the guess or on
    /// a corner of the range).
    fn candidate(
        &self,
        pm: PlanMeasurement,
    ) -> Result<Option<(PlanMeasurement, MeasInfo)>, PlanError> {
        let Some(c) = self.candidate_at_guess(pm)? else {
            return Ok(None);
        };
        let lines = c.1.lattice_lines;
        Ok(self.survives_range(&c.0, lines)?.then_some(c))
    }

    /// `None` when `harmonid simulate` can check `pm`'s truncation at the guess (the lattice
    /// widened until the measured lines settle), else why not.
    fn truncation_checks(&self, pm: &PlanMeasurement) -> Result<Option<String>, PlanError> {
        match simulate(self.num, self.base, pm, Fidelity::User) {
            Ok(_) => Ok(None),
            Err(e) if truncation_unchecked(&e) || is_truncated(&e) => Ok(Some(e.to_string())),
            // Feasibility was checked at the search's order; a wider lattice that finds no
            // state says the same as a truncation that cannot be checked.
            Err(e) if is_infeasible(&e) => Ok(Some(e.to_string())),
            Err(e) => Err(e),
        }
    }

    /// [`Self::candidate`] at the guess only.
    fn candidate_at_guess(
        &self,
        mut pm: PlanMeasurement,
    ) -> Result<Option<(PlanMeasurement, MeasInfo)>, PlanError> {
        let Some((data, lattice)) = self.bounded_at_guess(&pm)? else {
            return Ok(None);
        };
        let keep = choose_lines(&pm, &data, self.s.max_frequencies);
        let data = restrict_lines(&data, &pm, &keep);
        pm.measure_hz = Some(keep);
        let info = feasible(info_of(self.target, &pm, &data, lattice))?;
        Ok(info.map(|i| (pm, i)))
    }

    /// Whether the time budget is spent; when it is, notes once per measurement that `name`
    /// kept what it had (the budget's note says which candidates were left untried).
    fn out_of_time(&self, name: &str) -> bool {
        if self.deadline.is_none_or(|d| std::time::Instant::now() < d) {
            return false;
        }
        self.note_on(name, format!(
            "{name}: the time budget ({} s) was spent, so it keeps the best of the candidates tried so far (a larger --time-budget may find better bounds)",
            self.s.time_budget_s.unwrap_or_default()
        ));
        true
    }

    /// Adds a note once (the searches revisit the same candidates and measurements).
    fn note(&self, note: String) {
        let mut list = lock(&self.notes);
        if !list.contains(&note) {
            list.push(note);
        }
    }

    /// Adds a note of the search on `measurement` once (see [`Self::search_notes`]).
    fn note_on(&self, measurement: &str, note: String) {
        let mut map = lock(&self.search_notes);
        let list = map.entry(measurement.to_string()).or_default();
        if !list.contains(&note) {
            list.push(note);
        }
    }

    /// Whether `pm` is feasible on every device of the range it is checked at
    /// ([`GuessRange::corners`]; `true` without a range). A device whose harmonic balance is
    /// beyond a size bound counts as failed: the drive is not shown to survive it.
    fn survives_range(
        &self,
        pm: &PlanMeasurement,
        lattice_lines: usize,
    ) -> Result<bool, PlanError> {
        let Some(range) = &self.s.range else {
            return Ok(true);
        };
        let mut tones: Vec<(f64, usize)> = Vec::new();
        for (n, name) in self.names.iter().enumerate() {
            if let Some(f) = pm.force.get(name) {
                tones.extend(
                    f.iter()
                        .zip(&pm.drives_hz)
                        .filter(|(&x, _)| x != 0.0)
                        .map(|(_, &hz)| (hz, n)),
                );
            }
        }
        let key: Vec<(u64, usize)> = tones.iter().map(|&(f, n)| (f.to_bits(), n)).collect();
        let cached = lock(&self.corners).get(&key).cloned();
        let corners = match cached {
            Some(c) => c,
            None => {
                let c = Arc::new((range.corners(self.model, &tones)?, AtomicUsize::new(0)));
                lock(&self.corners).insert(key, c.clone());
                c
            }
        };
        let (devices, last_failed) = (&corners.0, &corners.1);
        // The device that failed last first, then the others in turn, stopping at the first
        // failure (the measurements of a stage keep the cores busy). A large lattice is
        // screened at a low order first: most drives fail on some device.
        let first = last_failed.load(Ordering::Relaxed);
        let order = std::iter::once(first)
            .chain((0..devices.len()).filter(|&k| k != first))
            .filter(|&k| k < devices.len());
        let fidelities: &[Fidelity] = if lattice_lines > SCREEN_ABOVE_LINES {
            &[Fidelity::Screen, Fidelity::Search]
        } else {
            &[Fidelity::Search]
        };
        for &fidelity in fidelities {
            for k in order.clone() {
                // The devices share the tones: a solver planned on a lattice serves every
                // device with it.
                match feasible_on(&devices[k].1, pm, fidelity, &self.pool) {
                    Ok(()) => {}
                    Err(e) if is_infeasible(&e) || too_large(&e).is_some() => {
                        last_failed.store(k, Ordering::Relaxed);
                        return Ok(false);
                    }
                    // The screen's low order failing otherwise proves nothing: the search's
                    // order decides.
                    Err(_) if fidelity == Fidelity::Screen => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(true)
    }

    /// [`simulate`] at search fidelity, `None` for an infeasible drive (at the guess or at a
    /// corner of the range) and for one whose harmonic balance is beyond a size bound
    /// (skipped, with a note in [`Evaluation::notes`]): one oversized candidate costs the
    /// design that candidate, not the plan.
    fn bounded(&self, pm: &PlanMeasurement) -> Result<Option<(Dataset, usize)>, PlanError> {
        let found = self.bounded_at_guess(pm)?;
        if let Some((_, lines)) = &found {
            if !self.survives_range(pm, *lines)? {
                return Ok(None);
            }
        }
        Ok(found)
    }

    /// [`Self::bounded`] at the guess only.
    fn bounded_at_guess(
        &self,
        pm: &PlanMeasurement,
    ) -> Result<Option<(Dataset, usize)>, PlanError> {
        match simulate(self.num, self.base, pm, Fidelity::Search) {
            Err(e) => match too_large(&e) {
                Some(why) => {
                    let tones: Vec<String> = pm.drives_hz.iter().map(|f| format!("{f}")).collect();
                    self.note_on(
                        &pm.name,
                        format!(
                            "skipped {} with tones at {} Hz: {why}",
                            pm.name,
                            tones.join(", ")
                        ),
                    );
                    Ok(None)
                }
                None => feasible(Err(e)),
            },
            ok => feasible(ok),
        }
    }

    /// Stage 1 for mode `n`: the tone pair around its resonance, over the spacings, driven
    /// as strongly as it can be without a jump, that bounds its own unknowns best.
    fn single(
        &self,
        n: usize,
        own: &[Unknown],
        name: &str,
    ) -> Result<(PlanMeasurement, MeasInfo, Pair), PlanError> {
        let (s, num, names) = (self.s, self.num, self.names);
        let f = num.f_hz[n];
        let kappa = f / num.q_factor[n];
        let w2 = (std::f64::consts::TAU * f).powi(2);
        let centre = on_grid(f, s.grid_hz);
        let wanted = quantity_names(self.model, own);
        // The weakest useful drive: a linear peak response of 100 σ.
        let cap = self.caps[n];
        let f_lin = (100.0 * s.sigma_m * w2 / num.q_factor[n]).min(cap);
        // A mode its own velocity terms damp may have no fold to stop the search for the
        // strongest drive: cap it where they add DAMPING_CAP linewidths of damping.
        let hi = match velocity_damping_amplitude(num, n, DAMPING_CAP * num.gamma(n)) {
            Some(a) => cap.min(a * w2 / num.q_factor[n]).max(f_lin),
            None => cap,
        };
        let mut best: Option<Candidate> = None;
        for mult in SPACINGS {
            if best.is_some() && self.out_of_time(name) {
                break;
            }
            let half = (on_grid(0.5 * mult * kappa, s.grid_hz)).max(s.grid_hz);
            let tones = |force: f64| [(centre - half, n, force), (centre + half, n, force)];
            let ok = |force: f64| -> Result<bool, PlanError> {
                let pm = self.measurement(name, &tones(force));
                Ok(self.bounded(&pm)?.is_some())
            };
            let start = pair_fold_estimate(num, n, 2.0 * half / kappa).unwrap_or(f_lin);
            let Some((good, folds)) = strongest(start, f_lin, hi, &ok)? else {
                continue;
            };
            // A margin below the fold: the guess is a guess.
            let force = round3(if folds { level_margin(s) * good } else { good });
            // The search probed upwards from its first guess: a level reached only past a
            // region where the ramp fails (a fold the ramp's steps happened to hop over, the
            // state then on another branch) is not a drive a lab can ramp up to.
            if !(ok(0.25 * force)? && ok(0.5 * force)?) {
                continue;
            }
            let Some((pm, info)) = self.candidate(self.measurement(name, &tones(force)))? else {
                continue;
            };
            let ev = joint_bounds(self.model, &[&info], s.shots)?;
            let score = worst_of(&ev, &wanted);
            let best_score = best.as_ref().map_or(f64::INFINITY, |b| b.0);
            if score < best_score {
                best = Some((score, pm, info, (centre, 2.0 * half, force)));
            } else if score > CLEARLY_WORSE * best_score {
                // The bounds rise with the spacing from here on: wider pairs only lose more.
                break;
            }
        }
        let Some((_, pm, info, pair)) = best else {
            return Err(PlanError::Unidentifiable {
                parameter: format!("the linear data of {}", names[n]),
                reason: "no tone pair near its resonance has a stable steady state without a jump"
                    .into(),
                limits: self.limits.clone(),
            });
        };
        Ok((pm, info, pair))
    }

    /// Stage 2 for the coupling of `modes`: the modes' stage-1 pairs combined (three tones
    /// first, both pairs when those leave the unknowns poorly determined), scaled down until
    /// feasible, the cheapest of the comparably good.
    fn coupling(
        &self,
        modes: &[usize],
        unknowns: &[Unknown],
        label: &str,
        pairs: &[Option<Pair>],
        infos: &[MeasInfo],
    ) -> Result<(PlanMeasurement, MeasInfo), PlanError> {
        let wanted = quantity_names(self.model, unknowns);
        let name = format!("couple_{label}");
        // (score, lattice lines, measurement, information) of every feasible variant.
        let mut scored: Vec<(f64, usize, (PlanMeasurement, MeasInfo))> = Vec::new();
        let mut try_variant = |variant: &Variant| -> Result<f64, PlanError> {
            let mut scale = 1.0;
            for _ in 0..8 {
                let mut tones = Vec::new();
                for &(n, how) in variant {
                    if let Some((c, d, f)) = pairs[n] {
                        let f = round3(f * scale);
                        match how {
                            Tones::Pair => {
                                tones.push((c - 0.5 * d, n, f));
                                tones.push((c + 0.5 * d, n, f));
                            }
                            Tones::Centre => tones.push((c, n, f)),
                        }
                    }
                }
                tones.sort_by(|a, b| a.0.total_cmp(&b.0));
                let pm = self.measurement(&name, &tones);
                if let Some((pm, info)) = self.candidate_at_guess(pm)? {
                    let mut all: Vec<&MeasInfo> = infos.iter().collect();
                    all.push(&info);
                    let ev = joint_bounds(self.model, &all, self.s.shots)?;
                    let score = worst_of(&ev, &wanted);
                    // Checking the range's corners costs a simulation per corner: only for a
                    // candidate that could still be chosen (a weaker drive scores no better).
                    if !could_win(&scored, score, info.lattice_lines) {
                        return Ok(score);
                    }
                    if self.survives_range(&pm, info.lattice_lines)? {
                        scored.push((score, info.lattice_lines, (pm, info)));
                        return Ok(score);
                    }
                }
                scale *= 0.7;
            }
            Ok(f64::INFINITY)
        };
        let mut tried = false;
        'sets: for set in coupled_variants(self.num, modes) {
            let mut best = f64::INFINITY;
            for v in &set.three_tone {
                if tried && self.out_of_time(&name) {
                    break 'sets;
                }
                let score = try_variant(v)?;
                tried |= score.is_finite();
                best = best.min(score);
            }
            // Two pairs cost a lattice several times larger: only when fewer tones fail or
            // leave the group's unknowns poorly determined.
            if best.is_nan() || best > GOOD_ENOUGH {
                if tried && self.out_of_time(&name) {
                    break 'sets;
                }
                tried |= try_variant(&set.pairs)?.is_finite();
            }
        }
        // The preferred candidate whose truncation `harmonid simulate` can check at the guess
        // (a plan it refuses costs the lab the measurement); the first, with a note, if none.
        let mut first = None;
        for (k, (pm, info)) in preference_order(scored).into_iter().enumerate() {
            if k < MAX_TRUNCATION_TRIES {
                match self.truncation_checks(&pm)? {
                    None => return Ok((pm, info)),
                    Some(why) => self.note_on(&name, format!(
                        "{name}: tones {:?} Hz not taken first, simulate cannot check their truncation at the guess: {why}",
                        pm.drives_hz
                    )),
                }
            }
            first.get_or_insert((pm, info));
        }
        first.ok_or_else(|| {
            let skipped: Vec<String> = lock(&self.search_notes)
                .get(&name)
                .into_iter()
                .flatten()
                .filter(|n| n.starts_with(&format!("skipped {name} ")))
                .cloned()
                .collect();
            let reason = if skipped.is_empty() {
                format!("no drive of {label} together has a stable steady state without a jump")
            } else {
                format!(
                    "no drive of {label} together has a stable steady state without a jump within the size bounds of the harmonic balance (skipped: {})",
                    skipped.join("; ")
                )
            };
            PlanError::Unidentifiable {
                parameter: wanted.join(", "),
                reason,
                limits: self.limits.clone(),
            }
        })
    }
}

/// `m`'s guard; a lock poisoned by a panicked thread still holds usable notes and caches.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The search's progress across its stages: `done` of `total` measurements designed.
struct Steps<'p> {
    done: usize,
    total: usize,
    progress: &'p mut dyn FnMut(DesignStep<'_>),
}

impl Steps<'_> {
    /// `design` of every item on rayon's threads, the results in the items' order (the first
    /// error in that order is returned, so the outcome does not depend on the threads);
    /// `design` returns the measurement's name with its result. The progress callback is
    /// called on this thread as each finishes (it need not be `Send`).
    fn in_parallel<T: Sync, R: Send>(
        &mut self,
        items: &[T],
        design: impl Fn(&T) -> (&str, Result<R, PlanError>) + Sync,
    ) -> Result<Vec<R>, PlanError> {
        let (tx, rx) = std::sync::mpsc::channel::<String>();
        let design = &design;
        let results = std::thread::scope(|scope| {
            let worker = scope.spawn(move || {
                items
                    .par_iter()
                    .map(|item| {
                        let (name, r) = design(item);
                        // The receiver outlives the workers; a failed send loses a tick only.
                        let _ = tx.send(name.to_string());
                        r
                    })
                    .collect::<Vec<_>>()
            });
            for name in rx {
                self.done += 1;
                (self.progress)(DesignStep {
                    done: self.done,
                    total: self.total,
                    name: &name,
                });
            }
            worker
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        });
        results.into_iter().collect()
    }
}

/// Whether a candidate of worst bound `score` and `lattice` lines could still be chosen by
/// [`preference_order`]'s first among `scored` and the candidates to come: not when its bound is
/// beyond [`COMPARABLE`] of the best so far (the best only improves), nor when a candidate
/// already has as small a lattice and as good a bound.
fn could_win<T>(scored: &[(f64, usize, T)], score: f64, lattice: usize) -> bool {
    let best = scored.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
    score.is_finite()
        && score <= COMPARABLE * best
        && !scored.iter().any(|v| v.1 <= lattice && v.0 <= score)
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_sim::Term;

    #[test]
    fn the_damping_cap_solves_the_single_harmonic_damping() {
        let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
        // eta q^2 q': damping eta a^2 = rate at a = sqrt(rate / eta); Duffing, a coupling's
        // velocity term and a linear velocity term do not count.
        let m = NumericModel::new(
            vec!["a".into(), "b".into()],
            vec![1e6, 1.6e6],
            vec![2e4, 2e4],
            vec![
                t(0, 5e18, vec![(0, 2), (2, 1)]),
                t(0, 2.6e25, vec![(0, 3)]),
                t(0, 1e30, vec![(1, 2), (2, 1)]),
                t(0, -3.0, vec![(2, 1)]),
            ],
        )
        .expect("model");
        let rate = 3.0 * m.gamma(0);
        let a = velocity_damping_amplitude(&m, 0, rate).expect("a cap");
        let want = (rate / 5e18).sqrt();
        assert!((a / want - 1.0).abs() < 1e-12, "{a:e} vs {want:e}");
        assert!(velocity_damping_amplitude(&m, 1, rate).is_none());
    }

    /// Quadratic drag `drag |q̇| q̇` caps the drive where `|drag| a ω` reaches the rate (before,
    /// the non-smooth terms were not seen, and a drag-damped mode with no fold was driven to
    /// 1e8 N/kg); `|q| q` stiffness and Coulomb friction do not cap it.
    #[test]
    fn quadratic_drag_caps_the_drive() {
        let model = harmonid_model::parse_str(
            "mode q1 at 10 kHz\nparam kappa1, drag1, mu1\neom q1 += kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1) + mu1*sign(d(q1))\n",
            "t.hb",
        )
        .expect("parses");
        let values = harmonid_experiment::values_from_toml(
            "[modes.q1]\nf_hz = 1e4\nQ = 2000\n[parameters]\nkappa1 = -9.3e12\ndrag1 = 5.9e2\nmu1 = 1e-3\n",
            "v.toml",
        )
        .expect("values");
        let num = NumericModel::from_model(&model, &values).expect("numeric");
        let rate = 3.0 * num.gamma(0);
        let a = velocity_damping_amplitude(&num, 0, rate).expect("a cap");
        let want = rate / (5.9e2 * num.omega(0));
        assert!((a / want - 1.0).abs() < 1e-12, "{a:e} vs {want:e}");
        let no_drag = harmonid_experiment::values_from_toml(
            "[modes.q1]\nf_hz = 1e4\nQ = 2000\n[parameters]\nkappa1 = -9.3e12\ndrag1 = 0\nmu1 = 1e-3\n",
            "v.toml",
        )
        .expect("values");
        let num = NumericModel::from_model(&model, &no_drag).expect("numeric");
        assert!(velocity_damping_amplitude(&num, 0, rate).is_none());
    }
}

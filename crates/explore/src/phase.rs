//! Phase diagrams: the number of stable and unstable single-harmonic steady states over a grid
//! of two parameters.
//!
//! Each row (one value of the y axis) is solved in order of x: the first point by the
//! total-degree homotopy, every next one from its neighbour's complex solutions, first by
//! Newton from each of them and, when that does not give as many distinct solutions as the
//! generic count (the most any full homotopy found), by the parameter homotopy with the gamma
//! trick from the neighbour, and when that fails too, by the total-degree homotopy again. A
//! point's solutions are therefore all of them whenever it has the generic count, so no branch
//! is lost between neighbours. Rows run in parallel (rayon).
//!
//! The counts are those of the single-harmonic system (see [`crate::SingleHarmonic`]); the
//! lattice continuation is [`crate::states`]'s.

use crate::harmonic::{SingleHarmonic, Tone};
use crate::homotopy::{parameter, push_distinct, total_degree, Polisher};
use crate::states::{classify, is_stable, tone_of, unstable_through_complex_pair, SEED};
use crate::system::PolySystem;
use crate::ExploreError;
use harmonid_model::Model;
use harmonid_sim::{Excitation, ModelValues, NumericModel};
use num_complex::Complex64;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

/// Most grid points.
pub const MAX_GRID_POINTS: usize = 1_000_000;

/// What an axis of a phase diagram varies.
#[derive(Debug, Clone, PartialEq)]
pub enum Axis {
    /// The drive tone, Hz (with a pump at twice the tone, the pump moves with it).
    Freq,
    /// The force of the tone on a mode (by name), N/kg (the phase of the force given is kept).
    Force(String),
    /// The pump frequency, Hz (the response at half of it; a drive tone moves with it).
    PumpHz,
    /// The pump level, in the unit of the model's pump coefficients (the phase given is kept).
    PumpLevel,
    /// A parameter of the model, by name.
    Param(String),
}

impl std::str::FromStr for Axis {
    type Err = std::convert::Infallible;
    /// `freq`, `force:q1`, `pump_hz`, `pump_level`, or any other word: a parameter.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.trim() {
            "freq" => Axis::Freq,
            "pump_hz" => Axis::PumpHz,
            "pump_level" => Axis::PumpLevel,
            t => match t.strip_prefix("force:") {
                Some(m) => Axis::Force(m.trim().to_string()),
                None => Axis::Param(t.to_string()),
            },
        })
    }
}

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Axis::Freq => write!(f, "freq"),
            Axis::Force(m) => write!(f, "force:{m}"),
            Axis::PumpHz => write!(f, "pump_hz"),
            Axis::PumpLevel => write!(f, "pump_level"),
            Axis::Param(p) => write!(f, "{p}"),
        }
    }
}

/// An axis and its `n` evenly spaced values from `from` to `to` (both included).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisRange {
    /// What it varies.
    pub axis: Axis,
    /// First value.
    pub from: f64,
    /// Last value.
    pub to: f64,
    /// Number of values (≥ 2).
    pub n: usize,
}

impl AxisRange {
    /// The values.
    pub fn values(&self) -> Vec<f64> {
        (0..self.n)
            .map(|i| self.from + (self.to - self.from) * i as f64 / (self.n - 1) as f64)
            .collect()
    }
}

/// How a phase diagram runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhaseSettings {
    /// Stop starting new rows after this many seconds (the rows done are returned).
    pub time_budget_s: Option<f64>,
    /// Keep every point's states (amplitudes and stability) in [`PhaseDiagram::states`].
    pub keep_states: bool,
}

/// Stable and unstable states at one grid point.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Count {
    /// Stable real states.
    pub stable: u32,
    /// Unstable real states.
    pub unstable: u32,
    /// Of the unstable states, those unstable through a complex pair of the slow flow
    /// (oscillatory, Hopf type: [`crate::unstable_through_complex_pair`]); the rest are
    /// saddles.
    pub oscillatory: u32,
}

/// One steady state of a grid point.
#[derive(Debug, Clone, PartialEq)]
pub struct PointState {
    /// Complex amplitude per mode at the response frequency, m (peak).
    pub amplitudes: Vec<Complex64>,
    /// Stable in the single-harmonic slow flow.
    pub stable: bool,
    /// Unstable through a complex pair ([`crate::unstable_through_complex_pair`]).
    pub oscillatory: bool,
}

/// A phase diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseDiagram {
    /// The x values.
    pub x: Vec<f64>,
    /// The y values.
    pub y: Vec<f64>,
    /// `counts[iy · nx + ix]`; `None` for rows the time budget left out.
    pub counts: Vec<Option<Count>>,
    /// With [`PhaseSettings::keep_states`]: per point, each state's amplitude per mode (m)
    /// and its stability.
    pub states: Vec<Vec<PointState>>,
    /// The most finite complex solutions a point had (the generic count).
    pub generic_count: usize,
    /// Points solved by the total-degree homotopy (the rest were continued).
    pub full_solves: usize,
    /// Points where Newton from the neighbour's solutions fell short of the generic count and
    /// the parameter homotopy ran.
    pub parameter_homotopies: usize,
    /// Every row was done within the time budget.
    pub complete: bool,
}

/// The problem a phase diagram varies: a checked model with its values (to rebuild it when an
/// axis is a parameter) and the excitation at which the axes not varied stay.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its values.
    pub values: &'a ModelValues,
    /// The drive and pump.
    pub drive: &'a Excitation,
}

/// Checks the axes before any work: the grid size, each axis's range, that it names something
/// of the model and excitation.
fn check_axes(
    p: &Problem<'_>,
    base: &NumericModel,
    base_tone: &Tone,
    axes: [&AxisRange; 2],
) -> Result<(), ExploreError> {
    let bad = |a: &AxisRange, why: String, help: &str| ExploreError::BadAxis {
        what: format!("axis {}", a.axis),
        why,
        help: help.to_string(),
    };
    let points = axes[0].n.saturating_mul(axes[1].n);
    if points > MAX_GRID_POINTS {
        return Err(ExploreError::TooComplex {
            what: format!("a grid of {} × {} = {points} points", axes[0].n, axes[1].n),
            limit: "10^6 points",
        });
    }
    if axes[0].axis == axes[1].axis {
        return Err(bad(
            axes[0],
            "both axes vary the same quantity".into(),
            "give two different axes",
        ));
    }
    let forced = base_tone.force.iter().any(|z| z.norm() > 0.0);
    for a in axes {
        if a.n < 2 {
            return Err(bad(
                a,
                format!("{} points; an axis needs at least 2", a.n),
                "give N ≥ 2 in AXIS:FROM:TO:N",
            ));
        }
        if !(a.from.is_finite() && a.to.is_finite()) || a.from == a.to {
            return Err(bad(
                a,
                format!(
                    "the range {} to {} is not two distinct finite numbers",
                    a.from, a.to
                ),
                "give FROM and TO as two different finite numbers",
            ));
        }
        match &a.axis {
            Axis::Freq | Axis::PumpHz if a.from <= 0.0 || a.to <= 0.0 => {
                return Err(bad(
                    a,
                    "frequencies must be positive".into(),
                    "give a range of positive frequencies in Hz",
                ))
            }
            Axis::Freq if !forced => {
                return Err(bad(
                    a,
                    "there is no drive tone to move (no force)".into(),
                    "give --force MODE=N, or vary pump_hz",
                ))
            }
            Axis::PumpHz | Axis::PumpLevel if !base.has_pump_terms() => {
                return Err(bad(
                    a,
                    "the model has no pump terms, so the pump acts on nothing".into(),
                    "add a pump term (e.g. `eom q1 += lambda*pump*q1`) or vary another axis",
                ))
            }
            Axis::Force(m) if !base.mode_names.contains(m) => {
                return Err(bad(
                    a,
                    format!("`{m}` is not a mode ({})", base.mode_names.join(", ")),
                    "name a mode of the model, e.g. force:q1",
                ))
            }
            Axis::Param(name) if p.model.param_index(name).is_none() => {
                return Err(bad(
                    a,
                    format!(
                        "`{name}` names nothing in the model (parameters: {})",
                        p.model.param_names().join(", ")
                    ),
                    "use freq, force:MODE, pump_hz, pump_level or a parameter of the model",
                ))
            }
            _ => {}
        }
    }
    Ok(())
}

/// One point's model (rebuilt when an axis is a parameter) and tone.
fn point(
    p: &Problem<'_>,
    base: &NumericModel,
    base_tone: &Tone,
    set: [(&Axis, f64); 2],
) -> Result<(Option<NumericModel>, Tone), ExploreError> {
    let mut tone = base_tone.clone();
    let mut values: Option<ModelValues> = None;
    for (axis, v) in set {
        match axis {
            Axis::Freq => tone.hz = v,
            Axis::PumpHz => tone.hz = 0.5 * v,
            Axis::Force(m) => {
                let n = base.mode_names.iter().position(|x| x == m).unwrap_or(0);
                let f = tone.force[n];
                let phase = if f.norm() > 0.0 { f.arg() } else { 0.0 };
                tone.force[n] = Complex64::from_polar(v, phase);
            }
            Axis::PumpLevel => {
                let phase = if tone.pump.norm() > 0.0 {
                    tone.pump.arg()
                } else {
                    0.0
                };
                tone.pump = Complex64::from_polar(v, phase);
            }
            Axis::Param(name) => {
                values
                    .get_or_insert_with(|| p.values.clone())
                    .parameters
                    .insert(name.clone(), v);
            }
        }
    }
    let model = match values {
        Some(v) => Some(NumericModel::from_model(p.model, &v)?),
        None => None,
    };
    Ok((model, tone))
}

/// The complex solutions at `sys` from a neighbour's: Newton from each, then the parameter
/// homotopy; `None` when neither gives `generic` distinct solutions.
fn continued(
    sys: &PolySystem,
    from: &PolySystem,
    starts: &[Vec<Complex64>],
    generic: usize,
    seed: u64,
    tracked: &AtomicUsize,
) -> Option<Vec<Vec<Complex64>>> {
    let mut polish = Polisher::new(sys);
    let mut out = Vec::with_capacity(starts.len());
    for s in starts {
        let mut x = s.clone();
        if polish.newton(&mut x, 8) {
            push_distinct(&mut out, x);
        }
    }
    if out.len() >= generic && generic > 0 {
        return Some(out);
    }
    tracked.fetch_add(1, Ordering::Relaxed);
    // Two tries with different γ: a path may jump where two solutions nearly meet.
    (0..2).find_map(|k| {
        let out = parameter(sys, from, starts, seed + 1000 * k);
        (out.len() >= generic && generic > 0).then_some(out)
    })
}

/// What every point of one grid shares.
struct Grid<'a> {
    problem: &'a Problem<'a>,
    base: NumericModel,
    base_tone: Tone,
    sh: SingleHarmonic,
    scale: f64,
    axes: [&'a Axis; 2],
    /// The most finite complex solutions a full homotopy found.
    generic: AtomicUsize,
    fulls: AtomicUsize,
    tracked: AtomicUsize,
}

/// One point's system and complex solutions (the next point's start), and its states.
type Solution = (PolySystem, Vec<Vec<Complex64>>, Vec<PointState>);

impl Grid<'_> {
    /// Solves the point `(xv, yv)`: continued from `prev` when it gives the generic count,
    /// by the total-degree homotopy otherwise.
    fn solve(
        &self,
        xv: f64,
        yv: f64,
        prev: Option<&(PolySystem, Vec<Vec<Complex64>>)>,
        seed: u64,
    ) -> Result<Solution, ExploreError> {
        let (m, tone) = point(
            self.problem,
            &self.base,
            &self.base_tone,
            [(self.axes[0], xv), (self.axes[1], yv)],
        )?;
        let model = m.as_ref().unwrap_or(&self.base);
        let (sys, norms) = self.sh.system(model, &tone, self.scale, true)?;
        let g = self.generic.load(Ordering::Relaxed);
        let sols = match prev.and_then(|(ps, pz)| continued(&sys, ps, pz, g, seed, &self.tracked)) {
            Some(s) => s,
            None => {
                self.fulls.fetch_add(1, Ordering::Relaxed);
                let s = total_degree(&sys, SEED).ok_or_else(|| ExploreError::TooComplex {
                    what: format!("a single-harmonic system of degrees {:?}", sys.degrees()),
                    limit: "the total-degree homotopy's path budget",
                })?;
                self.generic.fetch_max(s.points.len(), Ordering::Relaxed);
                s.points
            }
        };
        let solved = classify(model, &tone, &sys, &norms, self.scale, sols);
        let states = solved
            .amplitudes
            .into_iter()
            .zip(&solved.eigenvalues)
            .map(|(amplitudes, e)| PointState {
                amplitudes,
                stable: is_stable(model, e),
                oscillatory: unstable_through_complex_pair(model, e),
            })
            .collect();
        Ok((sys, solved.complex, states))
    }
}

/// The phase diagram of `problem` over `x` and `y` (see the module docs). Errors, before any
/// work: over [`MAX_GRID_POINTS`] points, an axis with `n < 2` or a range that is not two
/// distinct finite numbers (positive for frequencies), an axis naming no mode or parameter of
/// the model, a pump axis on a model without pump terms, a drive frequency axis without a
/// drive; and the errors of [`crate::states`]'s single-harmonic system. `progress` is called
/// with the number of rows done.
pub fn phase_diagram(
    problem: &Problem<'_>,
    x: &AxisRange,
    y: &AxisRange,
    settings: &PhaseSettings,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<PhaseDiagram, ExploreError> {
    let base = NumericModel::from_model(problem.model, problem.values)?;
    let base_tone = tone_of(&base, problem.drive)?;
    check_axes(problem, &base, &base_tone, [x, y])?;
    let sh = SingleHarmonic::new(&base)?;
    let (xs, ys) = (x.values(), y.values());
    // One amplitude scale for the whole grid, from its centre.
    let (cm, ct) = point(
        problem,
        &base,
        &base_tone,
        [(&x.axis, xs[xs.len() / 2]), (&y.axis, ys[ys.len() / 2])],
    )?;
    let scale = sh.natural_scale(cm.as_ref().unwrap_or(&base), &ct);
    let grid = Grid {
        problem,
        base,
        base_tone,
        sh,
        scale,
        axes: [&x.axis, &y.axis],
        generic: AtomicUsize::new(0),
        fulls: AtomicUsize::new(0),
        tracked: AtomicUsize::new(0),
    };
    // The first column in order of y, from one full homotopy: every row then starts from a
    // continued point.
    let mut column: Vec<Solution> = Vec::with_capacity(ys.len());
    for (iy, &yv) in ys.iter().enumerate() {
        let prev = column.last().map(|(s, z, _)| (s.clone(), z.clone()));
        column.push(grid.solve(xs[0], yv, prev.as_ref(), SEED + iy as u64)?);
    }
    let rows_done = AtomicUsize::new(0);
    let over = AtomicBool::new(false);
    let t0 = Instant::now();
    type Row = Option<Vec<Vec<PointState>>>;
    let rows: Vec<Result<Row, ExploreError>> = column
        .into_par_iter()
        .zip(ys.par_iter())
        .map(|((sys, sols, first), &yv)| {
            if over.load(Ordering::Relaxed)
                || settings
                    .time_budget_s
                    .is_some_and(|b| t0.elapsed().as_secs_f64() > b)
            {
                over.store(true, Ordering::Relaxed);
                return Ok(None);
            }
            let mut row = Vec::with_capacity(xs.len());
            row.push(first);
            let mut prev = (sys, sols);
            for (ix, &xv) in xs.iter().enumerate().skip(1) {
                let (s, z, st) = grid.solve(xv, yv, Some(&prev), SEED + ix as u64)?;
                row.push(st);
                prev = (s, z);
            }
            progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1);
            Ok(Some(row))
        })
        .collect();
    let mut out = PhaseDiagram {
        counts: Vec::with_capacity(xs.len() * ys.len()),
        states: Vec::new(),
        generic_count: grid.generic.load(Ordering::Relaxed),
        full_solves: grid.fulls.load(Ordering::Relaxed),
        parameter_homotopies: grid.tracked.load(Ordering::Relaxed),
        complete: true,
        x: xs.clone(),
        y: ys,
    };
    for r in rows {
        match r? {
            Some(row) => {
                for pts in row {
                    let stable = pts.iter().filter(|p| p.stable).count() as u32;
                    out.counts.push(Some(Count {
                        stable,
                        unstable: pts.len() as u32 - stable,
                        oscillatory: pts.iter().filter(|p| p.oscillatory).count() as u32,
                    }));
                    if settings.keep_states {
                        out.states.push(pts);
                    }
                }
            }
            None => {
                out.complete = false;
                out.counts.extend(std::iter::repeat_n(None, xs.len()));
                if settings.keep_states {
                    out.states.extend(std::iter::repeat_n(Vec::new(), xs.len()));
                }
            }
        }
    }
    Ok(out)
}

//! The dataset-shaped forward model: what a dataset's every measured amplitude should be for
//! given values of the identification's unknowns, by harmonic balance, with its Jacobian by
//! implicit differentiation ([`harmonid_sim::sensitivity`]). The output-error estimator and
//! the Cramér–Rao bounds ([`crate::uncertainty`]) and the planner are built on it.
//!
//! **Unknowns** are [`Unknown`]s, the layout of the linear fit ([`crate::Problem`]): per mode
//! `ω_n²` (rad²/s²) and `γ_n = ω_n/Q_n` (rad/s), every model parameter (SI units of its
//! terms), then the force model's unknowns per measurement (N/kg, or N/kg per drive-level unit
//! for gains). A vector `θ` holds a value for each of them, fixed ones included
//! ([`ForwardModel::fixed`]: values the model gives; a mode whose `Q` is fixed while `f` is
//! unknown has `γ = √ω²/Q` derived from `θ[ω²]`, and its `γ` entry is ignored).
//!
//! **Forces.** Each drive tone pushes the mode whose nominal resonance is spectrally closest
//! (the linear fit's attribution), and no other mode. Free forces: the tone's complex force is
//! `F = θ[Force{re}] + i θ[Force{im}]`. Drive levels: `F = G_n V e^{iφ}` with the complex gain
//! `G_n = θ[Gain{re}] + i θ[Gain{im}]` of that mode (per measurement, or per mode for the
//! whole dataset) and the tone's level `V` and phase `φ` from the manifest.
//!
//! **Observations** are every (measurement, measured frequency, point) of the dataset, in the
//! order measurement → frequency → point (a shot's layout in [`crate::Measurement::data`]).
//! The prediction at a point is the complex amplitude (m, peak, `DATA_FORMAT.md` phase
//! convention) of `x = Σ_n shape_n q_n` with the manifest's shapes, so a line two modes
//! contribute to is modelled exactly; without points the data are modal amplitudes and each
//! frequency observes the mode it is attributed to.
//!
//! Each measurement has its own harmonic-balance problem on a lattice chosen at the first
//! evaluation (and kept, so predictions are smooth in `θ`) that holds every measured
//! frequency. Its steady state is warm-started from the previous evaluation's (or from a start
//! set by [`ForwardModel::start_from_data`]); the drive ramp from rest is the fall-back.
//! A step of a stepped sweep measured in order (a `[[sweep]]` going up or down) has a history
//! instead: without a state of its own it starts where the experiment had it, from the
//! previous step's state at the same `θ` ([`harmonid_sim::ReducedSolver::solve_after`]: the
//! transient from there), so up- and down-sweeps stay on their branches through a bistable
//! range and jump where the model's fold is; it is never ramped from rest.

use crate::background::BackgroundLine;
use crate::layout::{Unknown, UnknownTable};
use crate::problem::{nearest_mode, nominal_frequencies, IdentError};
use crate::settings::ForceModel;
use harmonid_data::Dataset;
use harmonid_model::{Linear, Model, ParamKind};
use harmonid_sim::{
    choose_lattice, Excitation, HbSettings, LatticeSettings, ModeValues, ModelValues, NumericModel,
    Observation, PumpTone, ReducedSensitivity, ReducedSolver, SensParam, SteadyState,
};
use num_complex::Complex64;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f64::consts::TAU;

const Z: Complex64 = Complex64::new(0.0, 0.0);

/// Errors of the forward model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ForwardError {
    /// No nominal frequency to attribute drive tones to a mode.
    #[error("mode {mode} has no nominal resonance frequency: give it in the model (`mode {mode} at ... kHz`), in the dataset's [nominal_hz], or in the settings")]
    NoNominal {
        /// Mode name.
        mode: String,
    },
    /// The drive-level force model without levels and phases in a measurement.
    #[error("measurement \"{measurement}\" has no drive_levels_v and drive_phases_rad, which the force model {force_model} needs (use the free-force model)")]
    NoDriveLevels {
        /// Measurement name.
        measurement: String,
        /// The force model asked for.
        force_model: ForceModel,
    },
    /// A value of `θ` outside its physical range (or of the wrong length).
    #[error("{unknown} = {value:e} is not allowed: {why}")]
    BadValue {
        /// The unknown (readable label).
        unknown: String,
        /// Its value.
        value: f64,
        /// The rule it breaks.
        why: String,
    },
    /// The harmonic balance of a measurement could not be set up or did not converge.
    #[error("measurement \"{measurement}\": harmonic balance failed: {why}")]
    Hb {
        /// Measurement name.
        measurement: String,
        /// What happened.
        why: String,
    },
    /// Output buffers of the wrong size.
    #[error("{0}")]
    Shape(String),
}

/// A measurement whose lattice [`ForwardModel::widen_where_truncated`] widened.
#[derive(Debug, Clone, PartialEq)]
pub struct Widened {
    /// The measurement.
    pub measurement: String,
    /// The lattice's intermodulation order now.
    pub order: usize,
    /// Its lines now.
    pub lines: usize,
    /// How far the truncation had moved a measured line, in tolerances.
    pub moved: f64,
}

/// Settings of the forward model.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ForwardSettings {
    /// Harmonic-balance settings (lattice, tolerance, ramp); the measured frequencies are added
    /// to the lattice.
    pub hb: HbSettings,
    /// Nominal resonance frequencies, Hz, that override the dataset's and the model's (they
    /// attribute drive tones to modes).
    pub nominal_hz: BTreeMap<String, f64>,
}

/// How a sensitivity of the harmonic balance enters the unknowns' columns.
#[derive(Debug, Clone)]
enum Chain {
    /// `∂X/∂θ_col += c · ∂X/∂s` for each `(col, c)`.
    Linear(Vec<(usize, f64)>),
    /// `γ_n` of a mode with fixed `Q`: into the `ω_n²` column times `∂γ/∂ω² = 1/(2Q√ω²)`.
    FixedQ {
        /// Column of `ω_n²`.
        col: usize,
        /// The fixed `Q`.
        q: f64,
        /// The mode.
        mode: usize,
    },
}

/// One measurement's harmonic-balance problem.
#[derive(Debug, Clone)]
struct MeasFwd {
    name: String,
    /// Its index in the dataset (the unknowns' layout names its forces and gains by it; a
    /// [`ForwardModel::subset`] keeps it).
    index: usize,
    tones_hz: Vec<f64>,
    /// Mode each tone pushes.
    tone_mode: Vec<usize>,
    /// `V e^{iφ}` of each tone (drive-level force models).
    drive_c: Option<Vec<Complex64>>,
    /// The pump tones (parametric pumping; empty without a pump).
    pumps: Vec<PumpTone>,
    obs: Vec<Observation>,
    /// Global index of the first observation.
    offset: usize,
    /// The measurement background on its observations ([`crate::background`]; empty
    /// without one).
    background: Vec<BackgroundLine>,
    sens_params: Vec<SensParam>,
    chains: Vec<Chain>,
    lattice: Option<Vec<f64>>,
    /// How many times the lattice was widened because its truncation showed in the data
    /// ([`ForwardModel::widen_where_truncated`]): each time the order +2, the window ×1.5 and
    /// the direct harmonics added.
    widened: usize,
    /// Last converged state (warm start).
    state: Option<SteadyState>,
    /// Start amplitudes per mode at measured frequencies (from data).
    start: Option<Vec<(f64, Vec<Complex64>)>>,
    /// The measurement just before this one in its stepped sweep (an ordered `[[sweep]]`'s
    /// previous step; always an earlier index): its state at the same `θ` is where this
    /// step's transient starts, as it was in the experiment.
    follows: Option<usize>,
    buf: Vec<Complex64>,
    /// The solver of this measurement's lattice, kept across evaluations (values reset by
    /// [`ReducedSolver::set_values`]) with its sensitivity set-up. It solves the modes the
    /// drive reaches, the modes the tones push counted as forced (their forces are unknowns);
    /// a single-mode measurement of a twenty-mode string solves one mode, not twenty.
    solver: Option<(ReducedSolver, Option<ReducedSensitivity>)>,
}

/// The forward model of a dataset; see the module documentation.
#[derive(Debug, Clone)]
pub struct ForwardModel {
    model: Model,
    mode_names: Vec<String>,
    /// The unknowns' layout, nominal resonances (they attribute tones and modal data to
    /// modes) and the force model.
    table: UnknownTable,
    meas: Vec<MeasFwd>,
    n_obs: usize,
    settings: ForwardSettings,
    /// `θ` of the last successful evaluation (the steady states kept are at it).
    at: Option<Vec<f64>>,
}

/// Per measurement, the index of the one before it in its stepped sweep, when the sweep's
/// steps were measured in order (up or down) and that step is in the dataset at an earlier
/// index (as a sweep's steps are read).
fn previous_steps(ds: &Dataset) -> Vec<Option<usize>> {
    let ordered = |name: &str| {
        ds.manifest
            .sweeps
            .iter()
            .any(|s| s.name == name && s.direction != harmonid_data::Direction::Unordered)
    };
    let index: BTreeMap<(&str, usize), usize> = ds
        .measurements
        .iter()
        .enumerate()
        .filter_map(|(mi, m)| {
            m.spec
                .sweep
                .as_ref()
                .map(|s| ((s.sweep.as_str(), s.step), mi))
        })
        .collect();
    ds.measurements
        .iter()
        .enumerate()
        .map(|(mi, m)| {
            let s = m.spec.sweep.as_ref()?;
            let before = s.step.checked_sub(1)?;
            ordered(&s.sweep)
                .then(|| index.get(&(s.sweep.as_str(), before)).copied())
                .flatten()
                .filter(|&p| p < mi)
        })
        .collect()
}

impl ForwardModel {
    /// Sets the forward model up for `model` and the shape of `ds` (its measurements, drive
    /// tones, levels, measured frequencies and points; the amplitudes are not used).
    /// `ForceModel::Auto` becomes drive levels when every measurement gives them, free forces
    /// otherwise; each drive tone pushes the mode whose nominal resonance is closest.
    pub fn new(
        model: &Model,
        ds: &Dataset,
        force_model: ForceModel,
        settings: &ForwardSettings,
    ) -> Result<Self, ForwardError> {
        let overrides = crate::Settings {
            nominal_hz: settings.nominal_hz.clone(),
            ..crate::Settings::default()
        };
        let nominal = nominal_frequencies(model, ds, &overrides).map_err(|e| match e {
            IdentError::NoNominal { mode } => ForwardError::NoNominal { mode },
            e => ForwardError::Shape(e.to_string()),
        })?;
        let all_levels = ds
            .measurements
            .iter()
            .all(|m| m.spec.drive_levels_and_phases().is_some());
        let force_model = force_model.resolved_for(
            all_levels,
            ds.measurements.iter().any(|m| m.spec.sweep.is_some()),
        );
        let tone_modes = ds
            .measurements
            .iter()
            .map(|m| {
                m.spec
                    .drives_hz
                    .iter()
                    .map(|&f| nearest_mode(&nominal, f))
                    .collect()
            })
            .collect();
        let table = UnknownTable::new(model, nominal, force_model, tone_modes);
        Self::with_table(model, ds, table, settings)
    }

    /// The forward model on a given layout of the unknowns (the linear fit's,
    /// [`crate::Problem::table`]), for `model` and the shape of `ds`.
    pub fn with_table(
        model: &Model,
        ds: &Dataset,
        table: UnknownTable,
        settings: &ForwardSettings,
    ) -> Result<Self, ForwardError> {
        let nm = model.modes.len();
        let mode_names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
        let force_model = table.force_model();
        let gains = matches!(
            force_model,
            ForceModel::GainPerMeasurement | ForceModel::GainPerMode
        );
        let nearest = |f: f64| nearest_mode(table.nominal_hz(), f);
        let mut meas = Vec::with_capacity(ds.measurements.len());
        let mut n_obs = 0;
        let previous = previous_steps(ds);
        for (mi, m) in ds.measurements.iter().enumerate() {
            let tone_mode = table.tone_modes(mi).to_vec();
            let drive_c: Option<Vec<Complex64>> = m.spec.drive_levels_and_phases().map(|(l, p)| {
                l.iter()
                    .zip(p)
                    .map(|(&v, &ph)| Complex64::from_polar(v, ph))
                    .collect()
            });
            if gains && drive_c.is_none() {
                return Err(ForwardError::NoDriveLevels {
                    measurement: m.spec.name.clone(),
                    force_model,
                });
            }
            // Observations.
            let np = m.points.len();
            let mut obs = Vec::with_capacity(m.freqs_hz.len() * np);
            for &f in &m.freqs_hz {
                for &p in &m.points {
                    let shape = if ds.manifest.points.is_empty() {
                        let mut s = vec![0.0; nm];
                        s[nearest(f)] = 1.0;
                        s
                    } else {
                        mode_names
                            .iter()
                            .map(|name| ds.manifest.points[p].shape_of(name))
                            .collect()
                    };
                    obs.push(Observation { f_hz: f, shape });
                }
            }
            let background =
                crate::background::lines(&table, &m.spec.drives_hz, drive_c.as_deref(), &obs);
            meas.push(MeasFwd {
                background,
                name: m.spec.name.clone(),
                index: mi,
                tones_hz: m.spec.drives_hz.clone(),
                tone_mode,
                drive_c,
                pumps: m
                    .spec
                    .pump_tones()
                    .into_iter()
                    .map(PumpTone::from)
                    .collect(),
                offset: n_obs,
                sens_params: Vec::new(),
                chains: Vec::new(),
                lattice: None,
                widened: 0,
                state: None,
                start: None,
                follows: previous[mi],
                buf: Vec::new(),
                solver: None,
                obs,
            });
            n_obs += meas[mi].obs.len();
        }
        let mut fwd = ForwardModel {
            model: model.clone(),
            mode_names,
            table,
            meas,
            n_obs,
            settings: settings.clone(),
            at: None,
        };
        fwd.plan_chains();
        Ok(fwd)
    }

    /// Per measurement: the harmonic-balance parameters and how they enter the columns.
    fn plan_chains(&mut self) {
        let nm = self.mode_names.len();
        let col = |u: &Unknown| self.table.index_of(u);
        let mut all = Vec::new();
        for (mi, m) in self.meas.iter().enumerate() {
            let mut params = Vec::new();
            let mut chains = Vec::new();
            for n in 0..nm {
                params.push(SensParam::OmegaSq(n));
                chains.push(Chain::Linear(
                    col(&Unknown::OmegaSq(n))
                        .map(|c| vec![(c, 1.0)])
                        .unwrap_or_default(),
                ));
                params.push(SensParam::Gamma(n));
                chains.push(match (self.table.fixed_q(n), col(&Unknown::OmegaSq(n))) {
                    (Some(q), Some(c)) => Chain::FixedQ { col: c, q, mode: n },
                    _ => Chain::Linear(
                        col(&Unknown::Gamma(n))
                            .map(|c| vec![(c, 1.0)])
                            .unwrap_or_default(),
                    ),
                });
            }
            for p in 0..self.model.params.len() {
                params.push(SensParam::Param(p));
                chains.push(Chain::Linear(
                    col(&Unknown::Param(p))
                        .map(|c| vec![(c, 1.0)])
                        .unwrap_or_default(),
                ));
            }
            for (tone, &mode) in m.tone_mode.iter().enumerate() {
                for quad in 0..2u8 {
                    params.push(SensParam::Force { tone, mode, quad });
                    let cols = match (&m.drive_c, self.table.force_model()) {
                        (Some(d), ForceModel::GainPerMeasurement | ForceModel::GainPerMode) => {
                            let meas = (self.table.force_model() == ForceModel::GainPerMeasurement)
                                .then_some(mi);
                            let g = |quad| Unknown::Gain { meas, mode, quad };
                            let d = d[tone];
                            // F = (a + ib) D: ∂F/∂a = D, ∂F/∂b = iD.
                            let (ca, cb) = if quad == 0 {
                                (d.re, -d.im)
                            } else {
                                (d.im, d.re)
                            };
                            [(col(&g(0)), ca), (col(&g(1)), cb)]
                                .into_iter()
                                .filter_map(|(c, v)| c.map(|c| (c, v)))
                                .collect()
                        }
                        _ => col(&Unknown::Force {
                            meas: mi,
                            tone,
                            quad,
                        })
                        .map(|c| vec![(c, 1.0)])
                        .unwrap_or_default(),
                    };
                    chains.push(Chain::Linear(cols));
                }
            }
            all.push((params, chains));
        }
        for (m, (params, chains)) in self.meas.iter_mut().zip(all) {
            m.buf = vec![Z; params.len() * m.obs.len()];
            m.sens_params = params;
            m.chains = chains;
        }
    }

    /// Mode names, declaration order.
    pub fn mode_names(&self) -> &[String] {
        &self.mode_names
    }

    /// `γ_n = ω_n/Q_n` at `θ` (rad/s): `θ`'s own entry, or `√ω²/Q` for a mode whose `Q` is
    /// fixed while its `f` is identified.
    pub fn gamma(&self, theta: &[f64], n: usize) -> f64 {
        match self.table.fixed_q(n) {
            Some(q) => theta[2 * n].sqrt() / q,
            None => theta[2 * n + 1],
        }
    }

    /// The unknowns, in the order of `θ` and of the Jacobian's columns.
    pub fn unknowns(&self) -> &[Unknown] {
        self.table.unknowns()
    }

    /// Values the model fixes (`None`: to be identified). A mode with fixed `Q` and unknown
    /// `f` has its `γ` marked fixed (it is derived from `ω²`).
    pub fn fixed(&self) -> &[Option<f64>] {
        self.table.fixed()
    }

    /// Indices of the unknowns not fixed by the model.
    pub fn free(&self) -> Vec<usize> {
        self.table.free()
    }

    /// The force model in use (`Auto` resolved).
    pub fn force_model(&self) -> ForceModel {
        self.table.force_model()
    }

    /// Number of observations (complex amplitudes predicted).
    pub fn n_observations(&self) -> usize {
        self.n_obs
    }

    /// Range of the observations of measurement `mi` (order: frequency, then point).
    pub fn observations_of(&self, mi: usize) -> std::ops::Range<usize> {
        let m = &self.meas[mi];
        m.offset..m.offset + m.obs.len()
    }

    /// Number of measurements.
    pub(crate) fn n_measurements(&self) -> usize {
        self.meas.len()
    }

    /// The forward model of the measurements `keep` only (indices into this one's,
    /// increasing), on the same layout of the unknowns, with their lattices and steady states:
    /// the output-error fit of a group of measurements before the joint one
    /// ([`crate::output_error`]'s staged start). A sweep step whose previous step is not kept
    /// is solved on its own.
    pub(crate) fn subset(&self, keep: &[usize]) -> ForwardModel {
        let mut n_obs = 0;
        let meas = keep
            .iter()
            .map(|&mi| {
                let mut m = self.meas[mi].clone();
                m.offset = n_obs;
                m.follows = m.follows.and_then(|p| keep.iter().position(|&k| k == p));
                n_obs += m.obs.len();
                m
            })
            .collect();
        ForwardModel {
            model: self.model.clone(),
            mode_names: self.mode_names.clone(),
            table: self.table.clone(),
            meas,
            n_obs,
            settings: self.settings.clone(),
            at: None,
        }
    }

    /// Per measurement, the one before it in its stepped sweep (see `MeasFwd::follows`).
    pub(crate) fn follows(&self) -> Vec<Option<usize>> {
        self.meas.iter().map(|m| m.follows).collect()
    }

    /// Every measurement's name.
    pub(crate) fn measurement_names(&self) -> Vec<&str> {
        self.meas.iter().map(|m| m.name.as_str()).collect()
    }

    /// Takes the lattices and steady states of `sub`'s measurements (made by
    /// [`ForwardModel::subset`] with `keep`) as these measurements' own: their warm starts for
    /// the next evaluation.
    pub(crate) fn adopt(&mut self, sub: &ForwardModel, keep: &[usize]) {
        for (m, &mi) in sub.meas.iter().zip(keep) {
            let own = &self.meas[mi];
            let (offset, follows) = (own.offset, own.follows);
            self.meas[mi] = m.clone();
            self.meas[mi].offset = offset;
            self.meas[mi].follows = follows;
        }
        self.at = None;
    }

    /// Frequency (Hz) and shapes of every observation of measurement `mi`.
    pub fn observation_points(&self, mi: usize) -> &[Observation] {
        &self.meas[mi].obs
    }

    /// The last converged steady state of measurement `mi` (after an evaluation).
    pub fn state(&self, mi: usize) -> Option<&SteadyState> {
        self.meas[mi].state.as_ref()
    }

    /// Mode each drive tone of measurement `mi` pushes.
    pub fn tone_modes(&self, mi: usize) -> &[usize] {
        &self.meas[mi].tone_mode
    }

    /// Readable name of unknown `k` (`f`-style names are for reports; these name the
    /// parametrisation: `omega^2 of q1`, `gain of q2 in "single_q2" (re)`).
    pub fn label(&self, k: usize) -> String {
        match &self.table.unknowns()[k] {
            Unknown::OmegaSq(n) => format!("omega^2 of {}", self.mode_names[*n]),
            Unknown::Gamma(n) => format!("omega/Q of {}", self.mode_names[*n]),
            Unknown::Param(p) => self.model.params[*p].name.clone(),
            Unknown::Force { meas, tone, quad } => format!(
                "force of tone {tone} in \"{}\" ({})",
                self.meas[*meas].name,
                if *quad == 0 { "re" } else { "im" }
            ),
            Unknown::Gain { meas, mode, quad } => format!(
                "gain of {}{} ({})",
                self.mode_names[*mode],
                meas.map(|m| format!(" in \"{}\"", self.meas[m].name))
                    .unwrap_or_default(),
                if *quad == 0 { "re" } else { "im" }
            ),
            Unknown::Background { mode, term, quad } => format!(
                "background {} of {} ({})",
                term.name(),
                self.mode_names[*mode],
                if *quad == 0 { "re" } else { "im" }
            ),
        }
    }

    /// `θ` from modal data and parameters (`values`: `[modes]` and `[parameters]`, anything
    /// `simulate --values` reads, `[eom]` not used) and the true forces of each measurement,
    /// `forces[mi][n][d]` (N/kg, tone `d` on mode `n`, the layout of
    /// [`harmonid_sim::Excitation::force`]). With drive levels the gain of a mode is its first
    /// tone's force over that tone's `V e^{iφ}` (GainPerMode: of the first measurement that
    /// drives it). Forces on modes other than a tone's own are not representable and ignored.
    pub fn theta_from(
        &self,
        values: &ModelValues,
        forces: &[Vec<Vec<Complex64>>],
    ) -> Result<Vec<f64>, ForwardError> {
        let mut theta = vec![f64::NAN; self.table.len()];
        let missing = |what: String| ForwardError::BadValue {
            unknown: what,
            value: f64::NAN,
            why: "no value given".into(),
        };
        for (n, m) in self.model.modes.iter().enumerate() {
            let given = values.modes.get(&m.name).copied().unwrap_or_default();
            let f = given
                .f_hz
                .or(match m.f_hz {
                    Linear::Fixed(v) => Some(v),
                    Linear::Unknown => None,
                })
                .ok_or_else(|| missing(format!("f_hz of {}", m.name)))?;
            let q = given
                .q
                .or(match m.q_factor {
                    Linear::Fixed(v) => Some(v),
                    Linear::Unknown => None,
                })
                .ok_or_else(|| missing(format!("Q of {}", m.name)))?;
            theta[2 * n] = (TAU * f).powi(2);
            theta[2 * n + 1] = TAU * f / q;
        }
        let nm = self.mode_names.len();
        for (p, par) in self.model.params.iter().enumerate() {
            theta[2 * nm + p] = match (values.parameters.get(&par.name), par.kind) {
                (Some(&v), _) | (None, ParamKind::Fixed(v)) => v,
                (None, ParamKind::Unknown) => return Err(missing(par.name.clone())),
            };
        }
        if forces.len() != self.meas.len() {
            return Err(ForwardError::Shape(format!(
                "forces are given for {} measurements, the dataset has {}",
                forces.len(),
                self.meas.len()
            )));
        }
        for (mi, m) in self.meas.iter().enumerate() {
            for (tone, &n) in m.tone_mode.iter().enumerate() {
                let f = forces[mi]
                    .get(n)
                    .and_then(|row| row.get(tone))
                    .copied()
                    .ok_or_else(|| {
                        ForwardError::Shape(format!(
                            "measurement \"{}\": no force given for tone {tone} on mode {}",
                            m.name, self.mode_names[n]
                        ))
                    })?;
                let (u, z) = match (&m.drive_c, self.table.force_model()) {
                    (Some(d), ForceModel::GainPerMeasurement | ForceModel::GainPerMode) => {
                        if d[tone].norm() == 0.0 {
                            continue;
                        }
                        let meas = (self.table.force_model() == ForceModel::GainPerMeasurement)
                            .then_some(mi);
                        (
                            [0u8, 1].map(|quad| Unknown::Gain {
                                meas,
                                mode: n,
                                quad,
                            }),
                            f / d[tone],
                        )
                    }
                    _ => (
                        [0u8, 1].map(|quad| Unknown::Force {
                            meas: mi,
                            tone,
                            quad,
                        }),
                        f,
                    ),
                };
                for (q, v) in u.iter().zip([z.re, z.im]) {
                    if let Some(k) = self.table.index_of(q) {
                        if theta[k].is_nan() {
                            theta[k] = v;
                        }
                    }
                }
            }
        }
        // Gains no tone set (every level zero): zero.
        for v in theta.iter_mut().filter(|v| v.is_nan()) {
            *v = 0.0;
        }
        Ok(theta)
    }

    /// Warm-starts every measurement's first solve from the dataset's amplitudes (mean over
    /// shots), converted to the amplitude of the mode each frequency is nearest to by least
    /// squares over the points; lattice lines that are not measured start at zero. Useful when
    /// the drive ramp from rest would land on another branch than the measured one.
    pub fn start_from_data(&mut self, ds: &Dataset) {
        let nm = self.mode_names.len();
        for (m, dm) in self.meas.iter_mut().zip(&ds.measurements) {
            let np = dm.points.len();
            let mut start = Vec::with_capacity(dm.freqs_hz.len());
            for (r, &f) in dm.freqs_hz.iter().enumerate() {
                let obs = &m.obs[r * np..(r + 1) * np];
                let n = nearest_mode(self.table.nominal_hz(), f);
                let s2: f64 = obs.iter().map(|o| o.shape[n].powi(2)).sum();
                let mut q = Z;
                if s2 > 0.0 {
                    for (p, o) in obs.iter().enumerate() {
                        let mean: Complex64 = (0..dm.n_shots)
                            .map(|s| dm.amplitude(s, r, p))
                            .sum::<Complex64>()
                            / dm.n_shots.max(1) as f64;
                        q += mean * (o.shape[n] / s2);
                    }
                }
                let mut amps = vec![Z; nm];
                amps[n] = q;
                start.push((f, amps));
            }
            m.start = Some(start);
            m.state = None;
        }
        self.at = None;
    }

    /// The numeric model at `θ`.
    fn numeric(&self, theta: &[f64]) -> Result<NumericModel, ForwardError> {
        let mut values = ModelValues::default();
        for (n, name) in self.mode_names.iter().enumerate() {
            let w2 = theta[2 * n];
            if !(w2.is_finite() && w2 > 0.0) {
                return Err(ForwardError::BadValue {
                    unknown: self.label(2 * n),
                    value: w2,
                    why: "omega^2 must be a finite positive number".into(),
                });
            }
            let w = w2.sqrt();
            let g = self.gamma(theta, n);
            if !(g.is_finite() && g > 0.0 && w / g > 0.5) {
                return Err(ForwardError::BadValue {
                    unknown: self.label(2 * n + 1),
                    value: g,
                    why: format!("omega/Q must be positive with Q = omega/gamma above 1/2 (omega = {w:e} rad/s)"),
                });
            }
            values.modes.insert(
                name.clone(),
                ModeValues {
                    f_hz: Some(w / TAU),
                    q: Some(w / g),
                },
            );
        }
        let nm = self.mode_names.len();
        for (p, par) in self.model.params.iter().enumerate() {
            let v = theta[2 * nm + p];
            if !v.is_finite() {
                return Err(ForwardError::BadValue {
                    unknown: par.name.clone(),
                    value: v,
                    why: "parameters must be finite".into(),
                });
            }
            values.parameters.insert(par.name.clone(), v);
        }
        NumericModel::from_model(&self.model, &values).map_err(|e| ForwardError::BadValue {
            unknown: "the model at these values".into(),
            value: f64::NAN,
            why: e.to_string(),
        })
    }

    /// The drive of measurement `mi` at `θ`.
    fn excitation(&self, mi: usize, theta: &[f64]) -> Excitation {
        let m = &self.meas[mi];
        // The measurement's index in the layout (not in a subset).
        let mi = m.index;
        let nm = self.mode_names.len();
        let mut force = vec![vec![Z; m.tones_hz.len()]; nm];
        let get = |u: Unknown| self.table.index_of(&u).map_or(0.0, |k| theta[k]);
        for (tone, &n) in m.tone_mode.iter().enumerate() {
            force[n][tone] = match (&m.drive_c, self.table.force_model()) {
                (Some(d), ForceModel::GainPerMeasurement | ForceModel::GainPerMode) => {
                    let meas =
                        (self.table.force_model() == ForceModel::GainPerMeasurement).then_some(mi);
                    let g = |quad| {
                        get(Unknown::Gain {
                            meas,
                            mode: n,
                            quad,
                        })
                    };
                    Complex64::new(g(0), g(1)) * d[tone]
                }
                _ => {
                    let f = |quad| {
                        get(Unknown::Force {
                            meas: mi,
                            tone,
                            quad,
                        })
                    };
                    Complex64::new(f(0), f(1))
                }
            };
        }
        Excitation {
            pumps: m.pumps.clone(),
            tones_hz: m.tones_hz.clone(),
            force,
        }
    }

    /// Predicts every observation at `θ` into `out_x` (m; length
    /// [`ForwardModel::n_observations`]) and, with `out_jac`, the Jacobian
    /// `out_jac[o·K + k] = ∂X_o/∂θ_k` (`K = unknowns().len()`, every unknown, fixed ones
    /// included; units m per unit of `θ_k`).
    ///
    /// Errors name the measurement (a harmonic balance that does not converge from the warm
    /// start nor by the drive ramp) or the unknown (a value outside its range); the outputs
    /// are then unspecified but never NaN-filled silently: the caller must not use them.
    pub fn evaluate(
        &mut self,
        theta: &[f64],
        out_x: &mut [Complex64],
        out_jac: Option<&mut [Complex64]>,
    ) -> Result<(), ForwardError> {
        self.check_jacobian_len(out_jac.as_deref())?;
        self.solve_all(theta, out_x, true)?;
        match out_jac {
            Some(jac) => self.jacobian(theta, jac),
            None => Ok(()),
        }
    }

    /// As [`ForwardModel::evaluate`] without the Jacobian, for a fit's trial point near the
    /// last evaluation: every steady state by Newton from the last one (or from the data)
    /// only, a failure being an error at once (the trial step was too long, or the start too
    /// far) instead of the drive ramp from rest, which costs far more and may land on another
    /// branch than the one being followed.
    pub fn evaluate_trial(
        &mut self,
        theta: &[f64],
        out_x: &mut [Complex64],
    ) -> Result<(), ForwardError> {
        self.solve_all(theta, out_x, false)
    }

    /// Every measurement's steady state at `θ` into `out_x` (shapes checked first).
    fn solve_all(
        &mut self,
        theta: &[f64],
        out_x: &mut [Complex64],
        ramp: bool,
    ) -> Result<(), ForwardError> {
        let nk = self.table.len();
        if theta.len() != nk || out_x.len() != self.n_obs {
            return Err(ForwardError::Shape(format!(
                "evaluate: θ has {} entries ({nk} unknowns), out_x {} ({} observations)",
                theta.len(),
                out_x.len(),
                self.n_obs
            )));
        }
        self.at = None;
        let numeric = self.numeric(theta)?;
        if self.meas.iter().any(|m| m.follows.is_some()) {
            // A stepped sweep's step starts from the previous step's state: in order.
            for mi in 0..self.meas.len() {
                let drive = self.excitation(mi, theta);
                self.solve_measurement(mi, &numeric, &drive, out_x, ramp)?;
            }
        } else {
            self.solve_independent(theta, &numeric, out_x, ramp)?;
        }
        for m in &self.meas {
            for b in &m.background {
                out_x[m.offset + b.obs] += Complex64::new(theta[b.re], theta[b.im]) * b.factor;
            }
        }
        self.at = Some(theta.to_vec());
        Ok(())
    }

    /// Every measurement's steady state at `θ` (`numeric`) into `out_x`, the measurements
    /// side by side on rayon's threads: none starts from another's state, and a
    /// measurement's harmonic balance is its own (the twenty-mode string: 210 of them per
    /// evaluation of the output-error fit). Every measurement is solved; the error is the
    /// first measurement's in dataset order, as the solve one after the other reports.
    fn solve_independent(
        &mut self,
        theta: &[f64],
        numeric: &NumericModel,
        out_x: &mut [Complex64],
        ramp: bool,
    ) -> Result<(), ForwardError> {
        let work: Vec<(Excitation, LatticeSettings)> = (0..self.meas.len())
            .map(|mi| {
                (
                    self.excitation(mi, theta),
                    self.lattice_settings(mi, self.meas[mi].widened),
                )
            })
            .collect();
        let hb = &self.settings.hb;
        let outs = split_rows(out_x, self.meas.iter().map(|m| m.obs.len()), 1);
        self.meas
            .par_iter_mut()
            .zip(outs)
            .zip(&work)
            .map(|((m, out), (drive, ls))| {
                solve_one(m, None, (ls, hb), (numeric, drive), out, ramp)
            })
            .collect::<Vec<_>>()
            .into_iter()
            .collect()
    }

    /// The Jacobian `out_jac[o·K + k] = ∂X_o/∂θ_k` at `θ` (layout of
    /// [`ForwardModel::evaluate`]), from the steady states of the last evaluation when it was
    /// at this `θ` (a fit evaluates its trial points without the Jacobian and asks for it only
    /// at the points it accepts); otherwise it evaluates first.
    pub fn jacobian(
        &mut self,
        theta: &[f64],
        out_jac: &mut [Complex64],
    ) -> Result<(), ForwardError> {
        self.check_jacobian_len(Some(out_jac))?;
        if self.at.as_deref() != Some(theta) {
            let mut x = vec![Z; self.n_obs];
            return self.evaluate(theta, &mut x, Some(out_jac));
        }
        let nk = self.table.len();
        let rows = split_rows(out_jac, self.meas.iter().map(|m| m.obs.len()), nk);
        // Each measurement's sensitivities are its own: side by side on rayon's threads,
        // the error being the first measurement's in dataset order.
        self.meas
            .par_iter_mut()
            .zip(rows)
            .map(|(m, rows)| jacobian_one(m, theta, nk, rows))
            .collect::<Vec<_>>()
            .into_iter()
            .collect()
    }

    fn check_jacobian_len(&self, jac: Option<&[Complex64]>) -> Result<(), ForwardError> {
        let nk = self.table.len();
        match jac {
            Some(j) if j.len() != self.n_obs * nk => Err(ForwardError::Shape(format!(
                "evaluate: the Jacobian holds {} entries, {} × {nk} expected",
                j.len(),
                self.n_obs
            ))),
            _ => Ok(()),
        }
    }

    /// The lattice settings of measurement `mi` widened `times` times (see `MeasFwd::widened`),
    /// every measured frequency kept.
    fn lattice_settings(&self, mi: usize, times: usize) -> LatticeSettings {
        let mut ls = self.settings.hb.lattice.clone();
        ls.order += 2 * times;
        ls.window_rel *= 1.5_f64.powi(times as i32);
        ls.harmonics |= times > 0;
        ls.extra_hz.extend(self.meas[mi].obs.iter().map(|o| o.f_hz));
        ls
    }

    /// Widens the lattice of every measurement whose truncation shows in the data: at `θ`
    /// (the last evaluation's, whose steady states are kept), each measurement is solved
    /// again on a lattice widened once more (order +2, window ×1.5, the direct harmonics
    /// added), warm-started from its state; where a measured line moves by more than its
    /// tolerance `tol[o]` (m, one per observation; a fraction of the data's noise), the
    /// measurement keeps the widened lattice and state. Returns each widened measurement. A fixed lattice is exact only to its truncation, and a long record's mean
    /// is precise enough to see it: 10⁵ shots at 0.05 nm resolve 1e-13 m, where order 9 on a
    /// strongly driven Duffing mode misses the outer sidebands by 1e-12 m.
    pub fn widen_where_truncated(
        &mut self,
        theta: &[f64],
        tol: &[f64],
    ) -> Result<Vec<Widened>, ForwardError> {
        if tol.len() != self.n_obs {
            return Err(ForwardError::Shape(format!(
                "widen_where_truncated: {} tolerances for {} observations",
                tol.len(),
                self.n_obs
            )));
        }
        let numeric = self.numeric(theta)?;
        let mut widened = Vec::new();
        for mi in 0..self.meas.len() {
            let Some(state) = self.meas[mi].state.as_ref() else {
                continue;
            };
            let drive = self.excitation(mi, theta);
            let times = self.meas[mi].widened + 1;
            let ls = self.lattice_settings(mi, times);
            let m = &self.meas[mi];
            // A lattice too large to widen is left as it is (the fit's residuals still say
            // whether the model fits).
            let Ok(wide) = choose_lattice(&numeric, &drive, &ls) else {
                continue;
            };
            let Ok(mut solver) =
                ReducedSolver::with_lattice(&numeric, &drive, wide.clone(), &m.tone_mode)
            else {
                continue;
            };
            let start: Vec<Vec<Complex64>> = (0..numeric.n_modes())
                .map(|n| wide.iter().map(|&f| state.amplitude(n, f)).collect())
                .collect();
            let st = solver.solve_continued(&start, &self.settings.hb);
            if !st.converged() {
                continue;
            }
            let worst = m
                .obs
                .iter()
                .enumerate()
                .map(|(o, ob)| {
                    let d = (st.at_point(&ob.shape, ob.f_hz) - state.at_point(&ob.shape, ob.f_hz))
                        .norm();
                    d / tol[m.offset + o]
                })
                .fold(0.0, f64::max);
            if worst > 1.0 {
                widened.push(Widened {
                    measurement: m.name.clone(),
                    order: ls.order,
                    lines: wide.len(),
                    moved: worst,
                });
                let m = &mut self.meas[mi];
                m.widened = times;
                m.lattice = Some(wide);
                m.solver = None;
                m.state = Some(st);
            }
        }
        if !widened.is_empty() {
            self.at = None;
        }
        Ok(widened)
    }

    /// Solves measurement `mi`'s steady state under `numeric` and `drive` (warm-started from
    /// its last state, or the data; the ramp from rest as the fall-back when `ramp`), writes
    /// its predictions into `out_x` and keeps the state.
    fn solve_measurement(
        &mut self,
        mi: usize,
        numeric: &NumericModel,
        drive: &Excitation,
        out_x: &mut [Complex64],
        ramp: bool,
    ) -> Result<(), ForwardError> {
        let ls = self.lattice_settings(mi, self.meas[mi].widened);
        let hb = &self.settings.hb;
        let (before, rest) = self.meas.split_at_mut(mi);
        let m = &mut rest[0];
        let previous = m.follows.and_then(|p| before[p].state.as_ref());
        let range = m.offset..m.offset + m.obs.len();
        solve_one(
            m,
            previous,
            (&ls, hb),
            (numeric, drive),
            &mut out_x[range],
            ramp,
        )
    }
}

/// Solves the steady state of `m` under `numeric` and `drive` (warm-started from its last
/// state, or the data; after `previous`, the state of the step before it in its sweep; the
/// ramp from rest as the fall-back when `ramp`) on its lattice (chosen with `ls` at the first
/// solve), writes its predictions into `out` (its own observations) and keeps the state.
fn solve_one(
    m: &mut MeasFwd,
    previous: Option<&SteadyState>,
    (ls, hb): (&LatticeSettings, &HbSettings),
    (numeric, drive): (&NumericModel, &Excitation),
    out: &mut [Complex64],
    ramp: bool,
) -> Result<(), ForwardError> {
    let hb_err = |why: String| ForwardError::Hb {
        measurement: m.name.clone(),
        why,
    };
    let lattice = match &m.lattice {
        Some(l) => l.clone(),
        None => {
            let l = choose_lattice(numeric, drive, ls).map_err(|e| hb_err(e.to_string()))?;
            m.lattice = Some(l.clone());
            l
        }
    };
    let solver = match m.solver.as_mut() {
        Some((solver, _)) => {
            solver
                .set_values(numeric, drive)
                .map_err(|e| hb_err(e.to_string()))?;
            solver
        }
        None => {
            let solver = ReducedSolver::with_lattice(numeric, drive, lattice.clone(), &m.tone_mode)
                .map_err(|e| hb_err(e.to_string()))?;
            &mut m.solver.insert((solver, None)).0
        }
    };
    let warm: Option<Vec<Vec<Complex64>>> = match (&m.state, &m.start) {
        (Some(st), _) => Some(st.amplitudes.clone()),
        (None, Some(start)) => {
            let nm = numeric.n_modes();
            let mut a = vec![vec![Z; lattice.len()]; nm];
            for (f, amps) in start {
                if let Some(r) = lattice.iter().position(|&x| (x - f).abs() <= 1e-6) {
                    for n in 0..nm {
                        a[n][r] = amps[n];
                    }
                }
            }
            Some(a)
        }
        (None, None) => None,
    };
    let warm_started = warm.is_some();
    let mut state = match warm {
        Some(a) => Some(solver.solve_continued(&a, hb)),
        None if previous.is_none() => Some(solver.solve(hb)),
        None => None,
    };
    let converged = |s: &Option<SteadyState>| s.as_ref().is_some_and(SteadyState::converged);
    // A sweep's step started from the data may converge onto the unstable middle branch,
    // where no experiment is: that start did not find the measured branch at this θ.
    let fresh = m.state.is_none();
    if previous.is_some() && fresh && converged(&state) {
        let stable = state
            .as_ref()
            .is_some_and(|s| solver.stability(s).is_ok_and(|st| st.stable));
        if !stable {
            state = None;
        }
    }
    // Then, or when its own state is lost, the step starts where the experiment had it:
    // at the previous step's state at this θ. Never the ramp from rest, which may cross a
    // fold the sweep did not.
    if let Some(prev) = previous.filter(|_| (ramp || fresh) && !converged(&state)) {
        state = Some(solver.solve_after(&prev.carried_to(&lattice), hb));
    }
    // The ramp from rest as the fall-back, unless it was the first try already.
    if ramp && previous.is_none() && warm_started && !converged(&state) {
        state = Some(solver.solve(hb));
    }
    let state = match state {
        Some(s) if s.converged() => s,
        Some(s) => {
            return Err(hb_err(format!(
                "no steady state (status: {}, relative residual {:.2e})",
                s.status, s.residual
            )))
        }
        None => {
            return Err(hb_err(
                "no steady state: the previous step of its sweep has none to start from".into(),
            ))
        }
    };
    for (o, ob) in m.obs.iter().enumerate() {
        out[o] = state.at_point(&ob.shape, ob.f_hz);
    }
    m.state = Some(state);
    Ok(())
}

/// `m`'s rows of the Jacobian at `θ` (`rows[o·nk + k]`, its observations `o` in order) from
/// its last steady state: the harmonic balance's sensitivities chained into the unknowns'
/// columns, and the background's own.
fn jacobian_one(
    m: &mut MeasFwd,
    theta: &[f64],
    nk: usize,
    rows: &mut [Complex64],
) -> Result<(), ForwardError> {
    let hb_err = |why: String| ForwardError::Hb {
        measurement: m.name.clone(),
        why,
    };
    let (Some((solver, sens)), Some(state)) = (m.solver.as_mut(), m.state.as_ref()) else {
        return Err(hb_err("no steady state to differentiate".into()));
    };
    let sens = match sens {
        Some(s) => s,
        None => sens.insert(
            ReducedSensitivity::new(solver, &m.tones_hz, &m.sens_params, &m.obs)
                .map_err(|e| hb_err(e.to_string()))?,
        ),
    };
    sens.compute(solver, state, &mut m.buf)
        .map_err(|e| hb_err(e.to_string()))?;
    let no = m.obs.len();
    rows.fill(Z);
    for (k, chain) in m.chains.iter().enumerate() {
        let d = &m.buf[k * no..(k + 1) * no];
        match chain {
            Chain::Linear(cols) => {
                for &(c, w) in cols {
                    for o in 0..no {
                        rows[o * nk + c] += d[o] * w;
                    }
                }
            }
            Chain::FixedQ { col, q, mode } => {
                let w = 1.0 / (2.0 * q * theta[2 * mode].sqrt());
                for o in 0..no {
                    rows[o * nk + col] += d[o] * w;
                }
            }
        }
    }
    // The background is linear: ∂X/∂re = factor, ∂X/∂im = i·factor.
    for b in &m.background {
        let row = b.obs * nk;
        rows[row + b.re] += b.factor;
        rows[row + b.im] += b.factor * Complex64::i();
    }
    Ok(())
}

/// `data` cut into consecutive pieces of `len · width` entries, one per `len` (a
/// measurement's observations, `width` entries each).
fn split_rows(
    mut data: &mut [Complex64],
    lens: impl Iterator<Item = usize>,
    width: usize,
) -> Vec<&mut [Complex64]> {
    let mut out = Vec::new();
    for len in lens {
        let (head, tail) = std::mem::take(&mut data).split_at_mut(len * width);
        out.push(head);
        data = tail;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_data::{Manifest, Measurement, MeasurementSpec, Point};
    use std::f64::consts::PI;

    const MODEL: &str =
        "mode a at 1 kHz\nmode b at 3 kHz\nparam beta, g\npotential: beta/4*a^4 + g/2*a^2*b^2\n";

    /// Three measurements of a two-mode model (two tones on `a`, one on `b`, and both), one
    /// point; amplitudes zero (the shape only).
    fn dataset() -> Dataset {
        let mut manifest = Manifest::new("three");
        manifest.points.push(Point {
            name: "p0".into(),
            shape: [("a".to_string(), 0.5), ("b".to_string(), 0.8)]
                .into_iter()
                .collect(),
        });
        let designs: [(&str, Vec<f64>, Vec<f64>); 3] = [
            (
                "single_a",
                vec![995.0, 1005.0],
                vec![985.0, 995.0, 1005.0, 1015.0],
            ),
            ("single_b", vec![3005.0], vec![3005.0]),
            (
                "couple_a_b",
                vec![1005.0, 3005.0],
                vec![995.0, 1005.0, 3005.0, 3015.0],
            ),
        ];
        let measurements: Vec<Measurement> = designs
            .into_iter()
            .map(|(name, drives, freqs)| {
                let spec = MeasurementSpec {
                    name: name.to_string(),
                    file: None,
                    drive_levels_v: Some(vec![1.0; drives.len()]),
                    drive_phases_rad: Some(vec![0.0; drives.len()]),
                    drives_hz: drives,
                    pumps_hz: Vec::new(),
                    pump_levels: None,
                    pump_phases_rad: None,
                    bandwidth_hz: None,
                    sweep: None,
                };
                Measurement::zeros(spec, freqs, vec![0], 1)
            })
            .collect();
        manifest.measurements = measurements.iter().map(|m| m.spec.clone()).collect();
        Dataset {
            dir: "three".into(),
            manifest,
            measurements,
            truth: None,
            notes: Vec::new(),
        }
    }

    /// The measurements solved side by side ([`ForwardModel::evaluate`]) give every line
    /// exactly as one after the other (the stepped sweeps' path) does, and the Jacobian's rows
    /// of each measurement are those of the measurement alone.
    #[test]
    fn side_by_side_equals_one_after_the_other() {
        let model = harmonid_model::parse_str(MODEL, "three.hb").expect("model");
        let ds = dataset();
        let mut fwd = ForwardModel::new(&model, &ds, ForceModel::Auto, &ForwardSettings::default())
            .expect("forward model");
        let theta: Vec<f64> = fwd
            .unknowns()
            .iter()
            .map(|u| match *u {
                Unknown::OmegaSq(n) => (2.0 * PI * [1000.0, 3000.0][n]).powi(2),
                Unknown::Gamma(n) => 2.0 * PI * [1000.0, 3000.0][n] / [100.0, 200.0][n],
                Unknown::Param(p) => [4e15, 2e15][p],
                Unknown::Gain { mode, quad, .. } => {
                    [[3.0, 1.0], [-2.0, 4.0]][mode][usize::from(quad)]
                }
                _ => 0.0,
            })
            .collect();
        let (n_obs, nk) = (fwd.n_observations(), fwd.unknowns().len());
        let mut seq = fwd.clone();
        let mut x = vec![Z; n_obs];
        let mut jac = vec![Z; n_obs * nk];
        fwd.evaluate(&theta, &mut x, Some(&mut jac))
            .expect("evaluate");
        let numeric = seq.numeric(&theta).expect("numeric");
        let mut x_seq = vec![Z; n_obs];
        for mi in 0..seq.n_measurements() {
            let drive = seq.excitation(mi, &theta);
            seq.solve_measurement(mi, &numeric, &drive, &mut x_seq, true)
                .expect("solve");
        }
        assert_eq!(x, x_seq);
        assert!(x.iter().any(|z| z.norm() > 0.0));
        for mi in 0..fwd.n_measurements() {
            let mut alone = fwd.subset(&[mi]);
            let no = alone.n_observations();
            let (mut xa, mut ja) = (vec![Z; no], vec![Z; no * nk]);
            alone
                .evaluate(&theta, &mut xa, Some(&mut ja))
                .expect("alone");
            let r = fwd.observations_of(mi);
            // Newton from the converged state: the same state to rounding.
            let close = |a: &[Complex64], b: &[Complex64]| {
                let scale = b.iter().map(|z| z.norm()).fold(0.0, f64::max);
                a.iter()
                    .zip(b)
                    .all(|(p, q)| (p - q).norm() <= 1e-10 * scale)
            };
            assert!(close(&x[r.clone()], &xa), "{mi}: predictions");
            for o in 0..no {
                let row = |j: &[Complex64], at: usize| j[at * nk..(at + 1) * nk].to_vec();
                assert!(
                    close(&row(&jac, r.start + o), &row(&ja, o)),
                    "{mi}, {o}: Jacobian"
                );
            }
            assert!(ja.iter().any(|z| z.norm() > 0.0));
        }
    }
}

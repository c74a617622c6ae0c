//! [`Plan::simulate`]: a plan, a model and its values → the dataset a lab would record, with
//! each steady state checked (convergence, truncation, stability) before it is written.

use crate::{ExperimentError, Plan, PlanError, PlanMeasurement};
use harmonid_data::dataset::{
    Dataset, Direction, Manifest, Measurement, MeasurementSpec, PerStep, SweepSpec, SweepStep,
    Truth, TruthForce, TruthMode, TruthNoise,
};
use harmonid_sim::{
    self as sim, Excitation, HbSettings, HbStatus, ModelValues, NoiseGen, NumericModel, Stability,
    Start, SteadyState, TdSettings,
};
use num_complex::Complex64;
use std::collections::BTreeMap;

/// The share of the noise of the mean over a plan's shots below which a truncation change
/// passes ([`Truncation::noise_floor_m`]).
pub const TRUNCATION_NOISE_SHARE: f64 = 0.1;

/// Highest intermodulation order asked for or reached by the truncation check.
pub const MAX_ORDER: usize = 31;
/// Most time-domain runs of one simulation (one per shot with per-sample noise).
pub const MAX_TD_RUNS: usize = 1000;

/// How the truncation of the harmonic-balance spectrum is checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Truncation {
    /// Check at all (off: the state at the given order is used as it is).
    pub check: bool,
    /// Largest allowed change of the measured lines when the lattice is widened (order + 2,
    /// window × 1.5, the direct harmonics), relative to the largest measured amplitude.
    pub tol: f64,
    /// Raise the order (by 2 per step, with the widened lattice) up to this one before giving up.
    pub max_order: usize,
    /// A state that misses `tol` at `max_order` is an error (else a note in the report).
    pub required: bool,
    /// A change of the measured lines below this size (m, modal amplitude) passes whatever
    /// `tol`: [`Plan::simulate_numeric`] sets a tenth of the noise of the mean over the plan's
    /// shots, `0.1 σ/√shots`, below which the truncation cannot move the fit (identification
    /// widens its own lattice by the same rule); 0 (the default): `tol` alone.
    pub noise_floor_m: f64,
}

impl Default for Truncation {
    fn default() -> Self {
        Self {
            check: true,
            tol: 1e-6,
            max_order: 17,
            required: true,
            noise_floor_m: 0.0,
        }
    }
}

impl Truncation {
    /// No check (planners scanning many drives).
    pub fn off() -> Self {
        Self {
            check: false,
            ..Self::default()
        }
    }
}

/// Time-domain simulation with lock-in demodulation.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeDomain {
    /// Start from rest instead of from the harmonic-balance state.
    pub from_rest: bool,
    /// Integration steps per period of the highest frequency (≥ 4; refined automatically).
    pub steps_per_period: usize,
    /// Local error tolerance per step, relative to each mode's linear response.
    pub rtol: f64,
    /// RMS of white noise added to every sample of the measured signal, m (every shot is then its
    /// own run); adds to the plan's per-quadrature noise.
    pub noise_rms_m: f64,
}

impl Default for TimeDomain {
    fn default() -> Self {
        Self {
            from_rest: false,
            steps_per_period: 16,
            rtol: 1e-9,
            noise_rms_m: 0.0,
        }
    }
}

/// Which solver makes the amplitudes.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Engine {
    /// Harmonic balance (the default).
    #[default]
    HarmonicBalance,
    /// Time integration and lock-in demodulation.
    TimeDomain(TimeDomain),
}

/// Settings of [`Plan::simulate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Harmonic balance or time domain.
    pub engine: Engine,
    /// Intermodulation order of the harmonic-balance lattice to start from.
    pub order: usize,
    /// The truncation check.
    pub truncation: Truncation,
    /// Check each steady state's stability (Hill's method).
    pub check_stability: bool,
    /// Write unstable states anyway (noted in the report) instead of refusing.
    pub allow_unstable: bool,
    /// Add the plan's noise (`false`: every shot is the clean amplitude).
    pub noise: bool,
    /// Seed of the noise.
    pub seed: u64,
    /// With the default measured lines (no `measure_hz`): leave out lines other than the drive
    /// tones whose amplitude at every point is at most this fraction of the measurement's
    /// largest (lines a lock-in would not resolve; 0 keeps every line).
    pub min_line_rel: f64,
    /// Stop a measurement's drive ramp at a fold (an error naming it) instead of following
    /// the jump, which costs far more: for a planner probing for the strongest drive without
    /// a jump. Default `false`.
    pub stop_at_fold: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            engine: Engine::HarmonicBalance,
            order: 9,
            truncation: Truncation::default(),
            check_stability: true,
            allow_unstable: false,
            noise: true,
            seed: 0,
            min_line_rel: 0.0,
            stop_at_fold: false,
        }
    }
}

impl Settings {
    /// Noise-free harmonic balance without the truncation and stability checks: the fastest
    /// route, for planners that check the states they keep.
    pub fn noise_free() -> Self {
        Self {
            noise: false,
            truncation: Truncation::off(),
            check_stability: false,
            ..Self::default()
        }
    }

    fn check(&self, plan: &Plan) -> Result<(), ExperimentError> {
        let bad = |what: &str, value: String, why: String| {
            Err(ExperimentError::Setting {
                what: what.into(),
                value,
                why,
            })
        };
        if !(1..=MAX_ORDER).contains(&self.order) {
            return bad(
                "--order",
                self.order.to_string(),
                format!("expected 1 to {MAX_ORDER}"),
            );
        }
        if !(self.min_line_rel.is_finite() && (0.0..1.0).contains(&self.min_line_rel)) {
            return bad(
                "min_line_rel",
                self.min_line_rel.to_string(),
                "expected a fraction in [0, 1)".into(),
            );
        }
        let t = &self.truncation;
        if t.check && !(t.tol.is_finite() && t.tol > 0.0) {
            return bad(
                "truncation tolerance",
                t.tol.to_string(),
                "expected a finite positive relative change".into(),
            );
        }
        if let Engine::TimeDomain(td) = &self.engine {
            let max = TdSettings::default().max_steps_per_period;
            if !(4..=max).contains(&td.steps_per_period) {
                return bad(
                    "--steps-per-period",
                    td.steps_per_period.to_string(),
                    format!("expected 4 to {max} steps per period of the highest frequency"),
                );
            }
            if !(td.rtol.is_finite() && td.rtol > 0.0 && td.rtol < 0.1) {
                return bad(
                    "--rtol",
                    td.rtol.to_string(),
                    "expected a finite tolerance between 0 and 0.1".into(),
                );
            }
            if !(td.noise_rms_m.is_finite() && td.noise_rms_m >= 0.0) {
                return bad(
                    "--noise-rms-nm",
                    format!("{:e} m", td.noise_rms_m),
                    "expected a finite RMS ≥ 0".into(),
                );
            }
            let runs = td_runs(self, plan) * plan.measurements.len();
            if runs > MAX_TD_RUNS {
                return bad("shots", plan.noise.shots.to_string(), format!("with per-sample noise every shot is a time-domain run (about a second each): {runs} runs asked, at most {MAX_TD_RUNS}; use fewer shots or the plan's per-quadrature [noise]"));
            }
        }
        Ok(())
    }
}

fn td_runs(s: &Settings, plan: &Plan) -> usize {
    match &s.engine {
        Engine::TimeDomain(td) if td.noise_rms_m > 0.0 && s.noise => plan.noise.shots,
        _ => 1,
    }
}

/// What happened to one measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementReport {
    /// Measurement name.
    pub name: String,
    /// Order of the lattice used.
    pub order: usize,
    /// Its lines.
    pub lattice_lines: usize,
    /// Relative force-balance error of the state.
    pub residual: f64,
    /// Change of the measured lines when the lattice is widened, relative to the largest (None:
    /// not checked).
    pub truncation_change: Option<f64>,
    /// Stability verdict (None: not checked).
    pub stability: Option<Stability>,
    /// Drive fractions where the ramp met a fold and the state jumped.
    pub drive_jumps: Vec<f64>,
    /// Measured frequencies.
    pub measured: usize,
    /// Time domain: integration steps, lock-in samples per window, last window-to-window change.
    pub time_domain: Option<(u64, u64, f64)>,
    /// Notes for the user (states written although a check failed, on request).
    pub notes: Vec<String>,
}

/// The simulated dataset and what happened per measurement.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// The dataset (amplitudes in metres, the plan's unit in its manifest, with `truth.toml`).
    pub dataset: Dataset,
    /// One report per measurement recorded (a drive ladder's kept levels each), in plan order.
    pub reports: Vec<MeasurementReport>,
    /// The levels of drive ladders that had no stable steady state, left out of the dataset.
    pub lost_levels: Vec<LostLevel>,
}

/// A level of a drive ladder with no stable steady state on the device: the ramp stopped, or
/// the state it reached is unstable, so the lab sees the response jump or drift there. The
/// ladder's other levels are recorded without it.
#[derive(Debug, Clone, PartialEq)]
pub struct LostLevel {
    /// The laddered measurement.
    pub measurement: String,
    /// The level's index in the plan's `levels`.
    pub level: usize,
    /// Its fraction of the measurement's forces.
    pub fraction: f64,
    /// What happened there.
    pub why: String,
}

impl PlanMeasurement {
    /// The drive this measurement applies to `model`'s modes (forces N/kg, phases rad).
    pub fn excitation(&self, model: &NumericModel) -> Result<Excitation, ExperimentError> {
        let nd = self.drives_hz.len();
        for (table, k) in self
            .force
            .keys()
            .map(|k| ("force", k))
            .chain(self.phase_rad.keys().map(|k| ("phase_rad", k)))
        {
            if !model.mode_names.contains(k) {
                return Err(not_a_mode(
                    format!("measurement `{}`.{table}.{k}", self.name),
                    k,
                    model,
                ));
            }
        }
        let zeros = vec![0.0; nd];
        let force = model
            .mode_names
            .iter()
            .map(|n| {
                let a = self.force.get(n).unwrap_or(&zeros);
                let p = self.phase_rad.get(n).unwrap_or(&zeros);
                a.iter()
                    .zip(p)
                    .map(|(&a, &p)| Complex64::from_polar(a, p))
                    .collect()
            })
            .collect();
        let drive = Excitation {
            // The pump as the dataset will record it.
            pumps: self
                .spec()
                .pump_tones()
                .into_iter()
                .map(sim::PumpTone::from)
                .collect(),
            tones_hz: self.drives_hz.clone(),
            force,
        };
        drive
            .check(model.n_modes())
            .map_err(|source| ExperimentError::Sim {
                context: format!("measurement {}", self.name),
                source,
            })?;
        Ok(drive)
    }

    /// The dataset's entry for this measurement.
    pub fn spec(&self) -> MeasurementSpec {
        MeasurementSpec {
            name: self.name.clone(),
            file: None,
            drives_hz: self.drives_hz.clone(),
            drive_levels_v: self.drive_levels_v.clone(),
            drive_phases_rad: self.drive_phases_rad.clone(),
            pumps_hz: self.pumps_hz.clone(),
            pump_levels: self.pump_levels.clone(),
            pump_phases_rad: self.pump_phases_rad.clone(),
            bandwidth_hz: self.bandwidth_hz,
            sweep: None,
        }
    }

    /// The frequencies this measurement reads: `measure_hz`, or by default the drive tones and
    /// the lattice lines within `window_rel` of a resonance ([`sim::measured_lines`]).
    pub fn measured_hz(
        &self,
        model: &NumericModel,
        drive: &Excitation,
        state: &SteadyState,
        window_rel: f64,
    ) -> Vec<f64> {
        self.measure_hz
            .clone()
            .unwrap_or_else(|| sim::measured_lines(model, drive, &state.lattice_hz, window_rel))
    }

    /// The harmonic-balance steady state under `drive`, with the truncation check of
    /// `settings` (the order raised until the measured lines change by less than its tolerance,
    /// or by less than its noise floor); also returns the order used, the change found relative
    /// to the largest measured line, and whether it passed. Non-convergence is an error.
    pub fn steady_state(
        &self,
        model: &NumericModel,
        drive: &Excitation,
        order: usize,
        truncation: &Truncation,
        stop_at_fold: bool,
    ) -> Result<Settled, ExperimentError> {
        let mut hs = HbSettings {
            stop_at_fold,
            ..HbSettings::default()
        };
        hs.lattice.order = order;
        if let Some(f) = &self.measure_hz {
            hs.lattice.extra_hz = f.clone();
        }
        let window0 = hs.lattice.window_rel;
        // From rest by the drive ramp, or (a wider lattice) continued from the state found.
        let solve =
            |hs: &HbSettings, from: Option<&SteadyState>| -> Result<SteadyState, ExperimentError> {
                let st = match from {
                    None => sim::steady_state(model, drive, hs),
                    Some(start) => sim::steady_state_from(model, drive, hs, start),
                }
                .map_err(|source| ExperimentError::Sim {
                    context: format!("measurement {}", self.name),
                    source,
                })?;
                if let HbStatus::NotConverged { drive_fraction } = st.status {
                    return Err(ExperimentError::NotConverged {
                        measurement: self.name.clone(),
                        drive_fraction,
                        residual: st.residual,
                    });
                }
                Ok(st)
            };
        let mut st = solve(&hs, None)?;
        if !truncation.check {
            return Ok((st, order, None));
        }
        let at = self.measured_hz(model, drive, &st, window0);
        // The tolerance relative to the largest measured line, with the noise floor.
        let big = largest(&st, &at);
        let tol = truncation
            .tol
            .max(truncation.noise_floor_m / big.max(f64::MIN_POSITIVE));
        loop {
            let mut wide = hs.clone();
            wide.lattice.order += 2;
            wide.lattice.window_rel *= 1.5;
            wide.lattice.harmonics = true;
            let fail = |change: f64, wider: usize, why: String| ExperimentError::Truncated {
                measurement: self.name.clone(),
                order: hs.lattice.order,
                lines: st.lattice_hz.len(),
                wider_order: wide.lattice.order,
                wider_lines: wider,
                change,
                tol,
                why,
            };
            let st2 = match solve(&wide, Some(&st)) {
                Ok(s) => s,
                Err(e) if truncation.required => {
                    return Err(fail(
                        f64::NAN,
                        0,
                        format!("; the widened lattice could not be solved: {e}"),
                    ))
                }
                Err(_) => return Ok((st, hs.lattice.order, Some((f64::NAN, false)))),
            };
            let change = lines_change(&st, &st2, &at);
            if change < tol {
                return Ok((st, hs.lattice.order, Some((change, true))));
            }
            if wide.lattice.order > truncation.max_order.min(MAX_ORDER) {
                if truncation.required {
                    return Err(fail(change, st2.lattice_hz.len(), String::new()));
                }
                return Ok((st2, wide.lattice.order, Some((change, false))));
            }
            hs = wide;
            st = st2;
        }
    }
}

/// A plan key naming a mode the model does not declare.
fn not_a_mode(path: String, mode: &str, model: &NumericModel) -> ExperimentError {
    PlanError {
        origin: "the plan".into(),
        path,
        message: format!(
            "`{mode}` is not a mode of the model ({})",
            model.mode_names.join(", ")
        ),
        help: None,
        src: None,
        span: None,
    }
    .into()
}

/// `max |X − X'| / max |X|` over every mode at the frequencies `at_hz`.
/// The largest modal amplitude of `st` at `at_hz`, m.
fn largest(st: &SteadyState, at_hz: &[f64]) -> f64 {
    (0..st.amplitudes.len())
        .flat_map(|n| at_hz.iter().map(move |&f| st.amplitude(n, f).norm()))
        .fold(0.0, f64::max)
}

fn lines_change(a: &SteadyState, b: &SteadyState, at_hz: &[f64]) -> f64 {
    let (mut big, mut diff) = (0.0f64, 0.0f64);
    for n in 0..a.amplitudes.len() {
        for &f in at_hz {
            let x = a.amplitude(n, f);
            big = big.max(x.norm());
            diff = diff.max((x - b.amplitude(n, f)).norm());
        }
    }
    diff / big.max(f64::MIN_POSITIVE)
}

/// Adds independent Gaussian noise of per-quadrature `sigma_m` (m) to every amplitude of every
/// shot of `m`, from `gen`.
pub fn add_noise(m: &mut Measurement, sigma_m: f64, gen: &mut NoiseGen) {
    if sigma_m > 0.0 {
        for z in &mut m.data {
            *z += gen.complex(sigma_m);
        }
    }
}

impl Plan {
    /// Mode shapes of the plan's points, `[point][mode]` (one point of unit shapes when none is
    /// given).
    pub fn point_shapes(&self, model: &NumericModel) -> Vec<Vec<f64>> {
        if self.points.is_empty() {
            vec![vec![1.0; model.n_modes()]]
        } else {
            self.points
                .iter()
                .map(|p| model.mode_names.iter().map(|n| p.shape_of(n)).collect())
                .collect()
        }
    }

    /// The dataset manifest of the plan (measurements included).
    pub fn manifest(&self, model: &NumericModel) -> Manifest {
        let mut manifest = Manifest::new(self.description.clone());
        manifest.displacement_unit = self.displacement_unit.clone();
        manifest.points = self.points.clone();
        manifest.nominal_hz = if self.nominal_hz.is_empty() {
            model
                .mode_names
                .iter()
                .cloned()
                .zip(model.f_hz.iter().copied())
                .collect()
        } else {
            self.nominal_hz.clone()
        };
        manifest.measurements = self
            .measurements
            .iter()
            .map(PlanMeasurement::spec)
            .collect();
        manifest
    }

    /// Simulates the plan with `model` evaluated at `values`; see [`Plan::simulate_numeric`].
    pub fn simulate(
        &self,
        model: &harmonid_model::Model,
        values: &ModelValues,
        settings: &Settings,
    ) -> Result<Simulation, ExperimentError> {
        let num =
            NumericModel::from_model(model, values).map_err(|source| ExperimentError::Sim {
                context: format!("cannot evaluate the model {}", model.source),
                source,
            })?;
        self.simulate_numeric(&num, settings)
    }

    /// Simulates every measurement: the steady state (harmonic balance with the truncation
    /// check, refused when Newton does not converge), its stability (refused when unstable
    /// unless `allow_unstable`), the amplitudes at the measured frequencies and points (from the
    /// state, or by time integration and demodulation), then `shots` copies with the plan's
    /// per-quadrature noise (seeded). Nothing is returned unless every measurement succeeds.
    pub fn simulate_numeric(
        &self,
        model: &NumericModel,
        settings: &Settings,
    ) -> Result<Simulation, ExperimentError> {
        self.check("the plan")?;
        settings.check(self)?;
        // A self-excited mode has no steady state at the drive's frequencies to simulate (and
        // the lock-in windows would not settle on its limit cycle either).
        let mut net = (0..model.n_modes()).map(|n| (n, model.net_linear_damping(n)));
        if let Some((n, net_damping)) = net.find(|&(_, d)| d <= 0.0) {
            let cycle = match harmonid_sim::limit_cycle(model, 9) {
                Ok(lc) => format!(
                    " on {} limit cycle of {:.3e} m at {:.6e} Hz (autonomous harmonic balance)",
                    if lc.stable { "a stable" } else { "an unstable" },
                    lc.amplitude(),
                    lc.f_hz,
                ),
                Err(e) => format!(" ({e})"),
            };
            return Err(ExperimentError::SelfExcited {
                mode: model.mode_names[n].clone(),
                net_damping,
                cycle,
            });
        }
        let shapes = self.point_shapes(model);
        for (i, p) in self.points.iter().enumerate() {
            if let Some(k) = p.shape.keys().find(|k| !model.mode_names.contains(k)) {
                return Err(not_a_mode(format!("point[{i}].shape.{k}"), k, model));
            }
        }
        let shots = self.noise.shots;
        let sigma_m = if settings.noise { self.sigma_m() } else { 0.0 };
        let mut run = Run {
            model,
            settings,
            shapes: &shapes,
            shots,
            sigma_m,
            runs: td_runs(settings, self),
            points: self.points.len(),
            noise: NoiseGen::new(settings.seed),
            index: 0,
            truncation_floor_m: TRUNCATION_NOISE_SHARE * self.sigma_m() / (shots as f64).sqrt(),
        };
        let mut measurements = Vec::with_capacity(self.measurements.len());
        let mut reports = Vec::with_capacity(self.measurements.len());
        let mut forces = BTreeMap::new();
        let mut sweeps = Vec::new();
        let mut lost_levels = Vec::new();
        for pm in &self.measurements {
            if pm.levels.is_empty() {
                let (meas, force, report) = run.measurement(pm)?;
                forces.insert(pm.name.clone(), force);
                measurements.push(meas);
                reports.push(report);
                continue;
            }
            let (kept, sweep) = run.ladder(pm, &mut lost_levels)?;
            for (meas, force, report) in kept {
                forces.insert(meas.spec.name.clone(), force);
                measurements.push(meas);
                reports.push(report);
            }
            sweeps.push(sweep);
        }
        let sigma = if settings.noise {
            self.noise.sigma_per_quadrature
        } else {
            0.0
        };
        let truth = truth(model, forces, sigma, shots);
        let mut manifest = self.manifest(model);
        manifest.measurements = measurements
            .iter()
            .filter(|m| m.spec.sweep.is_none())
            .map(|m| m.spec.clone())
            .collect();
        manifest.sweeps = sweeps;
        Ok(Simulation {
            dataset: Dataset {
                dir: std::path::PathBuf::from("simulated"),
                manifest,
                measurements,
                truth: Some(truth),
                notes: Vec::new(),
            },
            reports,
            lost_levels,
        })
    }
}

/// A checked steady state: the state, its lattice order, and the truncation check's change
/// relative to the largest measured line with whether it passed (`None`: not checked).
type Settled = (SteadyState, usize, Option<(f64, bool)>);

/// One simulated measurement: its data, its true forces per mode, and what happened.
type Simulated = (Measurement, BTreeMap<String, TruthForce>, MeasurementReport);

/// One simulation's fixed inputs and running state (noise generator, measurement index).
struct Run<'a> {
    model: &'a NumericModel,
    settings: &'a Settings,
    shapes: &'a [Vec<f64>],
    shots: usize,
    sigma_m: f64,
    runs: usize,
    points: usize,
    noise: NoiseGen,
    /// Measurements simulated so far (seeds the time-domain runs).
    index: usize,
    /// The truncation check's noise floor ([`Truncation::noise_floor_m`]), from the plan's
    /// noise whether or not it is added.
    truncation_floor_m: f64,
}

impl Run<'_> {
    /// A drive ladder's levels, each simulated as a measurement: a level without a stable
    /// steady state costs that level (the lab sees its response jump or drift there and
    /// records the others) and is pushed onto `lost`; the kept levels become the steps of a
    /// `direction = "level"` sweep, numbered in order as the dataset reads them back. Every
    /// level lost: the first loss's error.
    fn ladder(
        &mut self,
        pm: &PlanMeasurement,
        lost_levels: &mut Vec<LostLevel>,
    ) -> Result<(Vec<Simulated>, SweepSpec), ExperimentError> {
        let mut kept = Vec::new();
        let mut first_loss = None;
        for (k, rung) in pm.rungs().iter().enumerate() {
            match self.measurement(rung) {
                Ok(done) => kept.push(done),
                Err(e) if e.is_lost_level() => {
                    lost_levels.push(LostLevel {
                        measurement: pm.name.clone(),
                        level: k,
                        fraction: pm.levels[k],
                        why: e.to_string(),
                    });
                    first_loss.get_or_insert(e);
                }
                Err(e) => return Err(e),
            }
        }
        if let Some(e) = first_loss.filter(|_| kept.is_empty()) {
            return Err(e);
        }
        let mut sweep = SweepSpec::new(
            pm.name.clone(),
            Direction::Level,
            vec![pm.drives_hz.clone(); kept.len()],
        );
        sweep.pumps_hz = pm.pumps_hz.clone();
        sweep.pump_levels = pm.pump_levels.clone();
        sweep.pump_phases_rad = pm.pump_phases_rad.clone();
        sweep.bandwidth_hz = pm.bandwidth_hz;
        let per_step = |f: fn(&MeasurementSpec) -> &Option<Vec<f64>>| {
            kept.iter()
                .map(|(m, _, _)| f(&m.spec).clone())
                .collect::<Option<Vec<_>>>()
                .map(PerStep::Each)
        };
        sweep.drive_levels_v = per_step(|s| &s.drive_levels_v);
        sweep.drive_phases_rad = per_step(|s| &s.drive_phases_rad);
        let mut steps = Vec::with_capacity(kept.len());
        for (j, (mut meas, force, mut report)) in kept.into_iter().enumerate() {
            // Steps are numbered as the dataset reads them back: the kept levels in order.
            meas.spec.name = sweep.step_name(j);
            meas.spec.file = Some(sweep.file_name());
            meas.spec.sweep = Some(SweepStep {
                sweep: pm.name.clone(),
                step: j,
            });
            report.name = meas.spec.name.clone();
            steps.push((meas, force, report));
        }
        Ok((steps, sweep))
    }

    /// Simulates one measurement (no ladder): its data with noise, its true forces and what
    /// happened.
    fn measurement(&mut self, pm: &PlanMeasurement) -> Result<Simulated, ExperimentError> {
        let drive = pm.excitation(self.model)?;
        let truncation = Truncation {
            noise_floor_m: self.truncation_floor_m,
            ..self.settings.truncation.clone()
        };
        let (st, order, checked) = pm.steady_state(
            self.model,
            &drive,
            self.settings.order,
            &truncation,
            self.settings.stop_at_fold,
        )?;
        let change = checked.map(|c| c.0);
        let mut notes = Vec::new();
        if let Some((c, passed)) = checked {
            if !passed {
                notes.push(format!("widening the lattice beyond order {order} still changes the measured lines by {c:.2e} of the largest (written on request)"));
            }
        }
        if st.pump_sustained {
            notes.push("above the parametric threshold: the pump sustains an oscillation (the state the drive alone would hold is unstable), and this is the state the resonator settles on".to_string());
        }
        let stability = pm.stability(self.model, &drive, &st, self.settings, &mut notes)?;
        let mut freqs = pm.measured_hz(
            self.model,
            &drive,
            &st,
            HbSettings::default().lattice.window_rel,
        );
        if pm.measure_hz.is_none() && self.settings.min_line_rel > 0.0 {
            keep_visible_lines(
                &mut freqs,
                self.shapes,
                &st,
                &drive,
                self.settings.min_line_rel,
            );
        }
        let mut td_info = None;
        let per_run: Vec<Vec<Vec<Complex64>>> = match &self.settings.engine {
            Engine::HarmonicBalance => vec![self
                .shapes
                .iter()
                .map(|s| freqs.iter().map(|&f| st.at_point(s, f)).collect())
                .collect()],
            Engine::TimeDomain(td) => {
                let start = if td.from_rest {
                    Start::Rest
                } else {
                    let (q, v) = st.state_at(0.0);
                    Start::State { q, v }
                };
                let mut out = Vec::with_capacity(self.runs);
                for r in 0..self.runs {
                    let ts = TdSettings {
                        steps_per_period: td.steps_per_period,
                        rtol: td.rtol,
                        noise_rms: if self.settings.noise {
                            td.noise_rms_m
                        } else {
                            0.0
                        },
                        seed: self
                            .settings
                            .seed
                            .wrapping_add(1 + r as u64)
                            .wrapping_add((self.index as u64) << 32),
                        ..TdSettings::default()
                    };
                    let res =
                        sim::simulate_lockin(self.model, &drive, &freqs, self.shapes, &start, &ts)
                            .map_err(|source| ExperimentError::Sim {
                                context: format!("measurement {}", pm.name),
                                source,
                            })?;
                    td_info = Some((res.steps, res.samples, res.settle_change));
                    out.push(res.points);
                }
                out
            }
        };
        let mut meas = Measurement::zeros(
            pm.spec(),
            freqs.clone(),
            (0..self.points).collect(),
            self.shots,
        );
        for s in 0..self.shots {
            let values = &per_run[s.min(per_run.len() - 1)];
            for (f, _) in freqs.iter().enumerate() {
                for (p, row) in values.iter().enumerate() {
                    *meas.amplitude_mut(s, f, p) = row[f];
                }
            }
        }
        add_noise(&mut meas, self.sigma_m, &mut self.noise);
        if meas
            .data
            .iter()
            .any(|z| !(z.re.is_finite() && z.im.is_finite()))
        {
            return Err(ExperimentError::NonFinite {
                measurement: pm.name.clone(),
            });
        }
        self.index += 1;
        let force = truth_forces(self.model, &drive);
        let report = MeasurementReport {
            name: pm.name.clone(),
            order,
            lattice_lines: st.lattice_hz.len(),
            residual: st.residual,
            truncation_change: change,
            stability,
            drive_jumps: st.drive_jumps.clone(),
            measured: freqs.len(),
            time_domain: td_info,
            notes,
        };
        Ok((meas, force, report))
    }
}

/// Each driven mode's true forces of `drive` (amplitude and phase per tone), for `truth.toml`.
fn truth_forces(model: &NumericModel, drive: &Excitation) -> BTreeMap<String, TruthForce> {
    let mut per_mode = BTreeMap::new();
    for (n, name) in model.mode_names.iter().enumerate() {
        if drive.force[n].iter().any(|z| z.norm() > 0.0) {
            per_mode.insert(
                name.clone(),
                TruthForce {
                    amplitude: drive.force[n].iter().map(|z| z.norm()).collect(),
                    phase_rad: drive.force[n].iter().map(|z| z.arg()).collect(),
                },
            );
        }
    }
    per_mode
}

/// The truth of a simulation: `model`'s frequencies, Q and equations, the forces per
/// measurement, and the noise (σ per quadrature, m, over `shots` shots).
fn truth(
    model: &NumericModel,
    forces: BTreeMap<String, BTreeMap<String, TruthForce>>,
    sigma: f64,
    shots: usize,
) -> Truth {
    Truth {
        modes: model
            .mode_names
            .iter()
            .enumerate()
            .map(|(n, name)| {
                (
                    name.clone(),
                    TruthMode {
                        f_hz: model.f_hz[n],
                        q: model.q_factor[n],
                    },
                )
            })
            .collect(),
        eom: (0..model.n_modes())
            .map(|n| (model.mode_names[n].clone(), model.eom_map(n)))
            .collect(),
        forces,
        noise: Some(TruthNoise {
            sigma_per_quadrature: sigma,
            shots: Some(shots),
        }),
    }
}

impl PlanMeasurement {
    /// The steady state's stability when `settings.check_stability`: an unstable state is an
    /// error unless `settings.allow_unstable`, then a note in `notes`.
    fn stability(
        &self,
        model: &NumericModel,
        drive: &Excitation,
        st: &SteadyState,
        settings: &Settings,
        notes: &mut Vec<String>,
    ) -> Result<Option<Stability>, ExperimentError> {
        Ok(if settings.check_stability {
            let v =
                sim::check_stability(model, drive, st).map_err(|source| ExperimentError::Sim {
                    context: format!("measurement {}: stability check", self.name),
                    source,
                })?;
            if !v.stable {
                if !settings.allow_unstable && model.has_pump_terms() {
                    return Err(ExperimentError::ParametricInstability {
                        measurement: self.name.clone(),
                        growth_rate: v.growth_rate,
                    });
                }
                if !settings.allow_unstable {
                    return Err(ExperimentError::Unstable {
                        measurement: self.name.clone(),
                        growth_rate: v.growth_rate,
                        linear_decay_rate: v.linear_decay_rate,
                    });
                }
                notes.push(format!("the steady state is unstable (perturbations grow at {:.3e} 1/s): written on request", v.growth_rate));
            }
            Some(v)
        } else {
            None
        })
    }
}

/// Keeps the drive tones and the lines whose amplitude at some point exceeds `min_line_rel`
/// of the largest line's (the sideband clusters a lock-in would record).
fn keep_visible_lines(
    freqs: &mut Vec<f64>,
    shapes: &[Vec<f64>],
    st: &SteadyState,
    drive: &Excitation,
    min_line_rel: f64,
) {
    let size = |f: f64| {
        shapes
            .iter()
            .map(|s| st.at_point(s, f).norm())
            .fold(0.0, f64::max)
    };
    let big = freqs.iter().map(|&f| size(f)).fold(0.0, f64::max);
    freqs.retain(|&f| {
        drive
            .tones_hz
            .iter()
            .any(|&d| (d - f).abs() <= sim::LINE_TOL_HZ)
            || size(f) > min_line_rel * big
    });
}

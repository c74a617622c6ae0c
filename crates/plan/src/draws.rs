//! A plan scored on devices drawn from a guess's range, with the work per device bounded.
//!
//! Each device costs every level of every measurement: a ramp from rest with its stability
//! check and the forward model's Jacobian. Done device by device ([`crate::info::ladder_info`]),
//! every level of every device plans its lattice and allocates its solvers afresh (three
//! dense Jacobians and their factors per level, hundreds of MB on a ten-mode lattice, zeroed
//! and page-faulted each time: most of the time went there). Here the work is turned around:
//! one task per level of a measurement scores it on every device of a chunk of draws, keeping
//! one ramp solver ([`SolverPool`]) and one forward model for all of them. A device's data
//! are the first device's simulated dataset with the amplitudes of its own ramped state, so
//! the forward model starts on the branch the ramp reached, as the simulation's would.
//! The verdicts and the errors are those of [`crate::info::simulate`] (a test compares the
//! bounds with the device-by-device path).

use crate::devices::{solve_on, SolverPool};
use crate::info::{
    forward_of, info_of, is_infeasible, n_shared, profiled_info, simulate, too_large, Fidelity,
    MeasInfo, Target,
};
use crate::range::GuessRange;
use crate::PlanError;
use harmonid_data::Dataset;
use harmonid_experiment::{ExperimentError, Plan, PlanMeasurement};
use harmonid_ident::ForwardModel;
use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel, SteadyState};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Most bytes of per-level information held at once: the draws are scored in chunks of at
/// most this much (one `S × S` matrix per level and device); each chunk plans every level's
/// solvers once.
const CHUNK_BYTES: usize = 256 << 20;

/// One device drawn from the range: a measurement it cannot run (which, why, the device), or
/// the information its levels add up to, named by the first level's forward model and θ,
/// with the ladder levels it loses.
pub(crate) enum Draw {
    Failed(String),
    Summed {
        sum: Vec<f64>,
        named: Box<MeasInfo>,
        lost: Vec<String>,
    },
}

/// One level's template dataset (the first device's simulated data) and its outcome per
/// device (`None` once taken, or for a device past the deadline).
type RungScores = (Option<Dataset>, Vec<Option<Result<Level, PlanError>>>);

/// One level of one measurement on one device: its information on the shared unknowns and θ
/// at the device, with the dataset it was simulated to when it is not the level's template.
struct Level {
    info: Vec<f64>,
    theta: Vec<f64>,
    data: Option<Dataset>,
}

/// What the draws of [`score_draws`] came to: each scored device in draw order, and how many
/// were left unscored by the deadline.
pub(crate) struct Scored {
    pub draws: Vec<Result<Draw, PlanError>>,
    pub skipped: usize,
}

/// The shared inputs of the draws: the model, the plan with drive levels on every
/// measurement, its levels (`(measurement, level, rung)` in plan order) and the noise.
struct Work<'a> {
    model: &'a Model,
    range: &'a GuessRange,
    plan: &'a Plan,
    rungs: Vec<(usize, usize, PlanMeasurement)>,
    sigma_m: f64,
    shots: usize,
}

/// Scores `plan` (drive levels on every measurement) on the devices `draws` of `range`: per
/// device, [`Draw::Failed`] at the first measurement none of whose levels it can run (in plan
/// order, as [`crate::robustness`] reports it), else the relative bounds of the levels kept.
/// Once `deadline` has passed, the draws every level has reached are kept (at least one) and
/// the others are left unscored (counted); `progress` is told how many draws are scored after
/// each chunk.
#[allow(clippy::too_many_arguments)]
pub(crate) fn score_draws(
    model: &Model,
    range: &GuessRange,
    plan: &Plan,
    draws: &[ModelValues],
    sigma_m: f64,
    shots: usize,
    deadline: Option<Instant>,
    progress: &mut dyn FnMut(usize),
) -> Result<Scored, PlanError> {
    let mut rungs = Vec::new();
    for (j, pm) in plan.measurements.iter().enumerate() {
        if pm.levels.is_empty() {
            rungs.push((j, 0, pm.clone()));
        } else {
            rungs.extend(pm.rungs().into_iter().enumerate().map(|(k, r)| (j, k, r)));
        }
    }
    let w = Work {
        model,
        range,
        plan,
        rungs,
        sigma_m,
        shots,
    };
    let s = n_shared(model);
    let per_draw = (w.rungs.len() * s * s * 8).max(1);
    let chunk = (CHUNK_BYTES / per_draw).max(1);
    let mut out = Vec::with_capacity(draws.len());
    for (c, devices) in draws.chunks(chunk).enumerate() {
        if c > 0 && deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        let nums = devices
            .iter()
            .map(|v| NumericModel::from_model(model, v))
            .collect::<Result<Vec<_>, _>>()?;
        // Past the deadline, each level stops at the draws it has reached; `limit`, the fewest
        // any level has reached when it saw the deadline (at least one), is where all stop.
        let limit = AtomicUsize::new(nums.len());
        let per_rung: Vec<RungScores> = w
            .rungs
            .par_iter()
            .map(|(_, _, rung)| w.rung_on(rung, &nums, devices, deadline, &limit))
            .collect();
        let done = limit.load(Ordering::SeqCst);
        let first = c * chunk;
        out.extend(w.assemble(per_rung, &devices[..done], first)?);
        progress(out.len());
        if done < devices.len() {
            break;
        }
    }
    Ok(Scored {
        skipped: draws.len() - out.len(),
        draws: out,
    })
}

impl Work<'_> {
    /// One level `rung` on every device of a chunk (`nums` the devices' numeric models):
    /// its template dataset (the first device's simulated data) and per device its level or
    /// why it failed.
    fn rung_on(
        &self,
        rung: &PlanMeasurement,
        nums: &[NumericModel],
        devices: &[ModelValues],
        deadline: Option<Instant>,
        limit: &AtomicUsize,
    ) -> RungScores {
        let pool = SolverPool::new(1);
        let mut template: Option<Dataset> = None;
        let mut fwd: Option<ForwardModel> = None;
        let shapes = self.plan.point_shapes(&nums[0]);
        let mut levels = Vec::with_capacity(nums.len());
        for (d, (num, values)) in nums.iter().zip(devices).enumerate() {
            if deadline.is_some_and(|t| Instant::now() >= t) {
                limit.fetch_min(d.max(1), Ordering::SeqCst);
            }
            if d >= limit.load(Ordering::SeqCst) {
                break;
            }
            let t = Target {
                model: self.model,
                num,
                values,
                sigma_m: self.sigma_m,
                shots: self.shots,
            };
            let level = match (&mut template, &rung.measure_hz) {
                // Lines chosen by the state (no measure_hz): each device its own dataset.
                (_, None) => self.fresh(&t, rung).map(|(info, theta, data)| Level {
                    info,
                    theta,
                    data: Some(data),
                }),
                (None, Some(_)) => self.fresh(&t, rung).map(|(info, theta, data)| {
                    template = Some(data);
                    Level {
                        info,
                        theta,
                        data: None,
                    }
                }),
                (Some(data), Some(_)) => {
                    reused(&t, rung, &pool, &shapes, data, &mut fwd).map(|(info, theta)| Level {
                        info,
                        theta,
                        data: None,
                    })
                }
            };
            levels.push(Some(level));
        }
        (template, levels)
    }

    /// `rung` simulated on the device as [`crate::info::measurement_info`] does: its
    /// information, θ and dataset.
    fn fresh(
        &self,
        t: &Target<'_>,
        rung: &PlanMeasurement,
    ) -> Result<(Vec<f64>, Vec<f64>, Dataset), PlanError> {
        let (data, lines) = simulate(t.num, self.plan, rung, Fidelity::Search)?;
        let MeasInfo { info, theta, .. } = info_of(t, rung, &data, lines)?;
        Ok((info, theta, data))
    }

    /// Each device's outcome from the levels' outcomes, in draw order (`first`: the chunk's
    /// first draw number): as [`crate::info::ladder_info`] and [`crate::robustness`] judge
    /// them one device at a time.
    fn assemble(
        &self,
        mut per_rung: Vec<RungScores>,
        devices: &[ModelValues],
        first: usize,
    ) -> Result<Vec<Result<Draw, PlanError>>, PlanError> {
        let s = n_shared(self.model);
        let mut out = Vec::with_capacity(devices.len());
        for (d, values) in devices.iter().enumerate() {
            let k = first + d;
            let mut sum = vec![0.0; s * s];
            let mut named: Option<Box<MeasInfo>> = None;
            let mut lost = Vec::new();
            let mut failed: Option<Result<Draw, PlanError>> = None;
            let mut r = 0;
            for (j, pm) in self.plan.measurements.iter().enumerate() {
                let (mut kept, mut lost_here, mut first_loss) = (0, Vec::new(), None);
                let mut error = None;
                while r < self.rungs.len() && self.rungs[r].0 == j {
                    let level_no = self.rungs[r].1;
                    let (template, levels) = &mut per_rung[r];
                    r += 1;
                    if error.is_some() {
                        continue;
                    }
                    match levels[d].take() {
                        Some(Ok(level)) => {
                            for (a, b) in sum.iter_mut().zip(&level.info) {
                                *a += b;
                            }
                            if named.is_none() {
                                let data = level.data.as_ref().or(template.as_ref());
                                if let Some(data) = data {
                                    named = Some(Box::new(MeasInfo {
                                        fwd: forward_of(self.model, data)?,
                                        theta: level.theta,
                                        info: Vec::new(),
                                        lattice_lines: 0,
                                    }));
                                }
                            }
                            kept += 1;
                        }
                        Some(Err(e)) if is_infeasible(&e) => {
                            lost_here.push(level_no);
                            first_loss.get_or_insert(e);
                        }
                        Some(Err(e)) => error = Some(e),
                        None => {}
                    }
                }
                let e = match (error, first_loss) {
                    (Some(e), _) => e,
                    (None, Some(e)) if kept == 0 => e,
                    _ => {
                        if !pm.levels.is_empty() {
                            lost.extend(
                                lost_here
                                    .iter()
                                    .map(|l| format!("draw {k}: {} level {l}", pm.name)),
                            );
                        }
                        continue;
                    }
                };
                failed = Some(if is_infeasible(&e) || too_large(&e).is_some() {
                    Ok(Draw::Failed(format!(
                        "draw {k} ({}): {}: {e}",
                        self.range.describe_device(self.model, values, pm),
                        pm.name
                    )))
                } else {
                    Err(e)
                });
                break;
            }
            if let Some(f) = failed {
                out.push(f);
                continue;
            }
            let named = named.ok_or(PlanError::EmptyPlan)?;
            out.push(Ok(Draw::Summed { sum, named, lost }));
        }
        Ok(out)
    }
}

/// `rung` on the device of `t` by the pooled ramp solver, its data the template's with this
/// device's amplitudes, its information from the reused forward model `fwd`.
fn reused(
    t: &Target<'_>,
    rung: &PlanMeasurement,
    pool: &SolverPool,
    shapes: &[Vec<f64>],
    template: &mut Dataset,
    fwd: &mut Option<ForwardModel>,
) -> Result<(Vec<f64>, Vec<f64>), PlanError> {
    let st = solve_on(t.num, rung, Fidelity::Search, pool)?;
    fill(template, &st, shapes, &rung.name)?;
    let f = match fwd {
        Some(f) => f,
        None => fwd.insert(forward_of(t.model, template)?),
    };
    profiled_info(t, rung, template, f)
}

/// Writes the noise-free amplitudes of `st` at every line and point of `data`'s one
/// measurement (every shot), as the simulation does; refuses a non-finite amplitude as it
/// does.
fn fill(
    data: &mut Dataset,
    st: &SteadyState,
    shapes: &[Vec<f64>],
    name: &str,
) -> Result<(), PlanError> {
    let m = &mut data.measurements[0];
    let freqs = m.freqs_hz.clone();
    for s in 0..m.n_shots {
        for (r, &f) in freqs.iter().enumerate() {
            for (p, shape) in shapes.iter().enumerate().take(m.points.len()) {
                *m.amplitude_mut(s, r, p) = st.at_point(shape, f);
            }
        }
    }
    if m.data
        .iter()
        .any(|z| !(z.re.is_finite() && z.im.is_finite()))
    {
        return Err(PlanError::from(ExperimentError::NonFinite {
            measurement: name.to_string(),
        }));
    }
    Ok(())
}

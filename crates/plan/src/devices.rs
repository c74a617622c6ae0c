//! Whether a drive is feasible on the devices of a guess's range, without the simulation's
//! dataset and with one harmonic-balance solver per lattice shared by the devices that have it.
//!
//! A design checks each candidate drive on tens of devices (the corners and frequency steps of
//! [`crate::range::GuessRange::corners`]): the same tones on models that differ only in their
//! coefficients. [`crate::info::simulate`] builds two solvers per device (the ramp's and the
//! stability check's, each planning the lattice's products and allocating its Jacobian) and
//! the measurement's dataset; here a solver whose lattice is the device's is reused with new
//! values ([`ReducedSolver::set_values`]), its stability judged on the same solver, and nothing
//! is kept but the verdict. The solvers solve the modes the drive reaches (a coupling's three
//! tones on a ten-mode string: two modes), the idle ones entering the stability verdict
//! through their own block. The verdict is [`crate::info::simulate`]'s: the same lattice, the same
//! ramp from rest, the same errors (a test compares both on every device of a range).

use crate::info::{Fidelity, SCREEN_ORDER};
use crate::PlanError;
use harmonid_experiment::{ExperimentError, PlanMeasurement, Settings};
use harmonid_sim::{
    choose_lattice, HbSettings, HbStatus, NumericModel, ReducedSolver, SimError, SteadyState,
};
use std::sync::Mutex;

/// Solvers kept for reuse, each with the lattice it was planned on. At most `cap` are kept
/// (a solver of a few hundred lines holds tens of MB of Jacobian): one per thread checking
/// devices at once is enough for the devices of one drive.
pub(crate) struct SolverPool {
    solvers: Mutex<Vec<ReducedSolver>>,
    cap: usize,
}

impl SolverPool {
    /// An empty pool keeping at most `cap` solvers.
    pub(crate) fn new(cap: usize) -> Self {
        Self {
            solvers: Mutex::new(Vec::new()),
            cap: cap.max(1),
        }
    }

    /// A kept solver planned on exactly `lattice`, taken out of the pool.
    fn take(&self, lattice: &[f64]) -> Option<ReducedSolver> {
        let mut list = self.solvers.lock().ok()?;
        let k = list.iter().position(|s| s.lattice() == lattice)?;
        Some(list.swap_remove(k))
    }

    /// Gives a solver back; the oldest is dropped beyond the cap.
    fn put(&self, solver: ReducedSolver) {
        if let Ok(mut list) = self.solvers.lock() {
            list.push(solver);
            if list.len() > self.cap {
                list.remove(0);
            }
        }
    }
}

/// `Ok(())` when `pm` (one level, no ladder) reaches its drive without a jump and settles on a
/// stable state on the device `num`, at `fidelity`'s lattice order without a truncation check
/// ([`Fidelity::Search`] or [`Fidelity::Screen`]); otherwise the error
/// [`crate::info::simulate`] returns for it (a fold, an unfound or unstable state, a lattice
/// beyond a size bound, bad input).
pub(crate) fn feasible_on(
    num: &NumericModel,
    pm: &PlanMeasurement,
    fidelity: Fidelity,
    pool: &SolverPool,
) -> Result<(), PlanError> {
    solve_on(num, pm, fidelity, pool).map(|_| ())
}

/// [`feasible_on`], returning the stable steady state it reached (the state
/// [`crate::info::simulate`] finds: the same lattice, the same ramp from rest).
pub(crate) fn solve_on(
    num: &NumericModel,
    pm: &PlanMeasurement,
    fidelity: Fidelity,
    pool: &SolverPool,
) -> Result<SteadyState, PlanError> {
    let drive = pm.excitation(num)?;
    let mut hs = HbSettings {
        stop_at_fold: true,
        ..HbSettings::default()
    };
    hs.lattice.order = match fidelity {
        Fidelity::Screen => SCREEN_ORDER,
        Fidelity::Search | Fidelity::User => Settings::default().order,
    };
    if let Some(f) = &pm.measure_hz {
        hs.lattice.extra_hz = f.clone();
    }
    let sim = |context: String| {
        move |source: SimError| PlanError::from(ExperimentError::Sim { context, source })
    };
    let context = format!("measurement {}", pm.name);
    let lattice = choose_lattice(num, &drive, &hs.lattice).map_err(sim(context.clone()))?;
    let mut solver = match pool.take(&lattice) {
        Some(mut s) => {
            s.set_values(num, &drive).map_err(sim(context.clone()))?;
            s
        }
        None => {
            ReducedSolver::with_lattice(num, &drive, lattice, &[]).map_err(sim(context.clone()))?
        }
    };
    let st = solver.solve(&hs);
    let verdict = if let HbStatus::NotConverged { drive_fraction } = st.status {
        Err(PlanError::from(ExperimentError::NotConverged {
            measurement: pm.name.clone(),
            drive_fraction,
            residual: st.residual,
        }))
    } else if let Some(&s) = st.drive_jumps.first() {
        Err(PlanError::Fold {
            measurement: pm.name.clone(),
            percent: 100.0 * s,
        })
    } else {
        match solver.unstable(&st) {
            Ok(None) => Ok(()),
            Ok(Some(v)) => Err(PlanError::from(ExperimentError::Unstable {
                measurement: pm.name.clone(),
                growth_rate: v.growth_rate,
                linear_decay_rate: v.linear_decay_rate,
            })),
            Err(source) => Err(sim(format!("{context}: stability check"))(source)),
        }
    };
    pool.put(solver);
    verdict.map(|()| st)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::info::{is_infeasible, simulate};
    use crate::range::GuessRange;
    use harmonid_experiment::Plan;
    use std::collections::BTreeMap;

    fn example(name: &str) -> (harmonid_model::Model, harmonid_sim::ModelValues) {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples")
            .join(name);
        let model = harmonid_model::load(&dir.join("model.hb")).expect("model");
        let values = harmonid_experiment::read_values(&dir.join("values.toml")).expect("values");
        (model, values)
    }

    fn measurement(tones: &[(f64, &str, f64)]) -> PlanMeasurement {
        let mut force: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for (d, &(_, mode, f)) in tones.iter().enumerate() {
            force
                .entry(mode.to_string())
                .or_insert_with(|| vec![0.0; tones.len()])[d] = f;
        }
        PlanMeasurement {
            name: "m".into(),
            drives_hz: tones.iter().map(|t| t.0).collect(),
            force,
            phase_rad: BTreeMap::new(),
            measure_hz: None,
            drive_levels_v: None,
            drive_phases_rad: None,
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            bandwidth_hz: None,
            levels: Vec::new(),
        }
    }

    /// On every device a design checks a drive at (the two-mode string's range, a pair on q1
    /// and a coupled drive, weak and strong enough to fold), the shared solvers give the
    /// verdict of a fresh simulation, device by device.
    #[test]
    fn the_shared_solvers_judge_every_device_as_a_fresh_simulation() {
        let (model, values) = example("nanostring_2mode");
        let range = GuessRange::new(&model, &values, &BTreeMap::new()).expect("range");
        // From its text, so the test does not depend on the plan's optional fields.
        let base = Plan::from_toml(
            "description = \"t\"\ndisplacement_unit = \"m\"\n[noise]\nsigma_per_quadrature = 1e-10\nshots = 30\n\
             [[measurement]]\nname = \"x\"\ndrives_hz = [1000.0]\nforce = { q1 = [1.0] }\n",
            "t",
        )
        .expect("plan");
        let base = Plan {
            measurements: Vec::new(),
            ..base
        };
        let (f1, f2) = (207582.0, 415849.0);
        let mut outcomes = (0, 0);
        for (tones, modes) in [
            (
                vec![(f1 - 3.0, "q1", 0.5), (f1 + 3.0, "q1", 0.5)],
                vec![(f1, 0)],
            ),
            (
                vec![(f1 - 3.0, "q1", 8.0), (f1 + 3.0, "q1", 8.0)],
                vec![(f1, 0)],
            ),
            (
                vec![
                    (f1, "q1", 1.0),
                    (f2 - 4.0, "q2", 0.3),
                    (f2 + 4.0, "q2", 0.3),
                ],
                vec![(f1, 0), (f2, 1)],
            ),
        ] {
            let pm = measurement(&tones);
            let devices = range.corners(&model, &modes).expect("corners");
            // The screen's order on the weak pair only (each check here costs two simulations).
            let fidelities: &[Fidelity] = if tones[0].2 < 1.0 {
                &[Fidelity::Search, Fidelity::Screen]
            } else {
                &[Fidelity::Search]
            };
            for &fidelity in fidelities {
                let pool = SolverPool::new(1);
                for (label, num) in &devices {
                    let fresh = simulate(num, &base, &pm, fidelity).map(|_| ());
                    let shared = feasible_on(num, &pm, fidelity, &pool);
                    match (&fresh, &shared) {
                        (Ok(()), Ok(())) => outcomes.0 += 1,
                        (Err(a), Err(b)) => {
                            assert!(is_infeasible(a) && is_infeasible(b), "{a} / {b}");
                            assert_eq!(a.to_string(), b.to_string(), "{label}");
                            outcomes.1 += 1;
                        }
                        _ => panic!("{label}: {fresh:?} vs {shared:?}"),
                    }
                }
            }
        }
        // Both verdicts occur.
        assert!(outcomes.0 > 0 && outcomes.1 > 0, "{outcomes:?}");
    }
}

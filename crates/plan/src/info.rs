//! Fisher information of one planned measurement on the shared unknowns.

use crate::PlanError;
use harmonid_data::Dataset;
use harmonid_experiment::{ExperimentError, Plan, PlanMeasurement, Settings, Truncation};
use harmonid_ident::{information, Noise};
use harmonid_ident::{ForceModel, ForwardModel, ForwardSettings, Unknown};
use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// One measurement's contribution: the information on the shared unknowns (`ω²`, `γ`,
/// parameters: the first `S` unknowns of every forward model of the model), its gains
/// profiled out, with the forward model and values it was computed with.
pub(crate) struct MeasInfo {
    /// `S × S`, row-major, zero rows for unknowns the model fixes.
    pub info: Vec<f64>,
    /// The forward model of the one-measurement dataset (labels, γ of fixed-Q modes), never
    /// evaluated: it holds no solver.
    pub fwd: ForwardModel,
    /// `θ` of `fwd`.
    pub theta: Vec<f64>,
    /// Lines of the harmonic-balance lattice the state was solved on: the cost of simulating
    /// and identifying the measurement grows with it.
    pub lattice_lines: usize,
}

/// Number of shared unknowns of `model`.
pub(crate) fn n_shared(model: &Model) -> usize {
    2 * model.modes.len() + model.params.len()
}

/// The single-measurement plan of `pm` with `base`'s points and nominal frequencies.
pub(crate) fn single(base: &Plan, pm: &PlanMeasurement) -> Plan {
    Plan {
        measurements: vec![pm.clone()],
        ..base.clone()
    }
}

/// How a measurement is simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fidelity {
    /// While searching drives: the lattice at its starting order, no truncation check (the
    /// ranking of candidates does not need the last digits, and a search simulates dozens).
    Search,
    /// A quick look before the range's devices are checked at [`Fidelity::Search`]: the
    /// lattice at order [`SCREEN_ORDER`], no truncation check. A drive that fails on a device
    /// here is not checked further (most fail on some device, and a four-tone lattice of 500
    /// lines costs a second or two per device at the search's order); one that passes still is.
    Screen,
    /// What `harmonid simulate --plan` does (the truncation check raises the order until the
    /// measured lines settle): the final plan's bounds are computed on this.
    User,
}

/// The lattice order of [`Fidelity::Screen`]: the drive tones' products up to fifth order, where
/// folds and instabilities of the main lines show (the drive ramp itself runs on them).
pub(crate) const SCREEN_ORDER: usize = 5;

/// Simulates `pm` noise-free (harmonic balance, Hill stability) and refuses a jump while the
/// drive ramps up; returns the dataset and the lattice size.
pub(crate) fn simulate(
    num: &NumericModel,
    base: &Plan,
    pm: &PlanMeasurement,
    fidelity: Fidelity,
) -> Result<(Dataset, usize), PlanError> {
    // A fold is infeasible here: stop the ramp at it rather than follow the jump.
    let settings = Settings {
        check_stability: true,
        stop_at_fold: true,
        truncation: match fidelity {
            Fidelity::Screen | Fidelity::Search => Truncation::off(),
            Fidelity::User => Settings::default().truncation,
        },
        order: match fidelity {
            Fidelity::Screen => SCREEN_ORDER,
            Fidelity::Search | Fidelity::User => Settings::default().order,
        },
        ..Settings::noise_free()
    };
    let sim = single(base, pm).simulate_numeric(num, &settings)?;
    let report = sim.reports.first();
    if let Some(&s) = report.and_then(|r| r.drive_jumps.first()) {
        return Err(PlanError::Fold {
            measurement: pm.name.clone(),
            percent: 100.0 * s,
        });
    }
    Ok((sim.dataset, report.map_or(0, |r| r.lattice_lines)))
}

/// `dataset` (one measurement) with only the lines at `keep_hz`: what simulating the
/// measurement with `measure_hz = keep_hz` gives when every kept line is on the lattice
/// already (the lattice, and so the state, is the same), without solving it again.
pub(crate) fn restrict_lines(dataset: &Dataset, pm: &PlanMeasurement, keep_hz: &[f64]) -> Dataset {
    let mut out = dataset.clone();
    let m = &dataset.measurements[0];
    let idx: Vec<usize> = keep_hz.iter().filter_map(|&f| m.freq_index(f)).collect();
    let r = m.select_lines(pm.spec(), &idx);
    out.manifest.measurements = vec![pm.spec()];
    out.measurements = vec![r];
    out
}

/// Why a candidate's harmonic balance cannot be set up within the size bounds (its lattice or
/// product plan too large), when that is the error: the design skips such a candidate with a
/// note instead of failing.
pub(crate) fn too_large(e: &PlanError) -> Option<String> {
    use harmonid_sim::SimError;
    use harmonid_spectral::SpectralError;
    let sim = match e {
        PlanError::Experiment(x) => match &**x {
            ExperimentError::Sim { source, .. } => source,
            _ => return None,
        },
        PlanError::Sim(s) => s,
        _ => return None,
    };
    match sim {
        SimError::Spectral(SpectralError::TooLarge { .. }) | SimError::TooLarge { .. } => {
            Some(sim.to_string())
        }
        _ => None,
    }
}

/// Whether the error is a truncation check that could not widen the lattice (the wider one is
/// beyond a size bound or did not solve): the check was not possible, which says nothing of the
/// truncation.
pub(crate) fn truncation_unchecked(e: &PlanError) -> bool {
    matches!(e, PlanError::Experiment(x)
        if matches!(**x, ExperimentError::Truncated { change, .. } if change.is_nan()))
}

/// Whether an error means the drive configuration is not usable (fold, instability, no
/// steady state), as opposed to bad input.
pub(crate) fn is_infeasible(e: &PlanError) -> bool {
    match e {
        PlanError::Fold { .. } | PlanError::Forward(harmonid_ident::ForwardError::Hb { .. }) => {
            true
        }
        PlanError::Experiment(x) => matches!(
            **x,
            ExperimentError::Unstable { .. } | ExperimentError::NotConverged { .. }
        ),
        _ => false,
    }
}

/// What every measurement's information is computed for: the model at the guessed values,
/// and the noise (`shots` shots of per-quadrature `sigma_m`, m).
#[derive(Clone, Copy)]
pub(crate) struct Target<'a> {
    /// The model.
    pub model: &'a Model,
    /// It at the guessed values.
    pub num: &'a NumericModel,
    /// The guessed values.
    pub values: &'a ModelValues,
    /// Per-quadrature noise, m.
    pub sigma_m: f64,
    /// Shots per measurement.
    pub shots: usize,
}

/// The information of measurement `pm` (simulated at the target's values with `fidelity`)
/// for the target's noise, gains profiled out.
pub(crate) fn measurement_info(
    t: &Target<'_>,
    base: &Plan,
    pm: &PlanMeasurement,
    fidelity: Fidelity,
) -> Result<MeasInfo, PlanError> {
    let (dataset, lattice_lines) = simulate(t.num, base, pm, fidelity)?;
    info_of(t, pm, &dataset, lattice_lines)
}

/// The information of `pm`'s drive ladder, one entry per level (`pm` alone without a ladder),
/// and the levels lost: a level whose drive passes a fold, or whose state is unstable or not
/// found, contributes nothing, as `harmonid simulate` leaves it out. Every level lost: the
/// first loss's error.
pub(crate) fn ladder_info(
    t: &Target<'_>,
    base: &Plan,
    pm: &PlanMeasurement,
    fidelity: Fidelity,
) -> Result<(Vec<MeasInfo>, Vec<usize>), PlanError> {
    if pm.levels.is_empty() {
        return Ok((vec![measurement_info(t, base, pm, fidelity)?], Vec::new()));
    }
    let (mut infos, mut lost, mut first_loss) = (Vec::new(), Vec::new(), None);
    for (k, rung) in pm.rungs().iter().enumerate() {
        match measurement_info(t, base, rung, fidelity) {
            Ok(i) => infos.push(i),
            Err(e) if is_infeasible(&e) => {
                lost.push(k);
                first_loss.get_or_insert(e);
            }
            Err(e) => return Err(e),
        }
    }
    match first_loss.filter(|_| infos.is_empty()) {
        Some(e) => Err(e),
        None => Ok((infos, lost)),
    }
}

/// The information of measurement `pm` whose noise-free data is `dataset` (its lattice of
/// `lattice_lines` lines): see [`measurement_info`].
pub(crate) fn info_of(
    t: &Target<'_>,
    pm: &PlanMeasurement,
    dataset: &Dataset,
    lattice_lines: usize,
) -> Result<MeasInfo, PlanError> {
    let mut fwd = forward_of(t.model, dataset)?;
    let (info, theta) = profiled_info(t, pm, dataset, &mut fwd)?;
    // The evaluated forward model keeps its harmonic-balance solver (a dense Jacobian and its
    // factors, tens to hundreds of MB on a large lattice): a plan keeps one `MeasInfo` per
    // measurement and level, so it keeps a fresh one, which only names the unknowns.
    drop(fwd);
    Ok(MeasInfo {
        info,
        fwd: forward_of(t.model, dataset)?,
        theta,
        lattice_lines,
    })
}

/// A forward model of `dataset`'s measurements (the gains free), not yet evaluated.
pub(crate) fn forward_of(model: &Model, dataset: &Dataset) -> Result<ForwardModel, PlanError> {
    Ok(ForwardModel::new(
        model,
        dataset,
        ForceModel::Auto,
        &ForwardSettings::default(),
    )?)
}

/// The information on the shared unknowns (`S × S`, row-major, the gains profiled out) of
/// `pm` on the target's device, whose noise-free data is `dataset`, and `θ` there: `fwd` is a
/// forward model of that one measurement ([`forward_of`]), fresh or already used for the same
/// measurement on another device (it keeps its solver and lattice, so a caller scoring one
/// measurement on many devices allocates them once); it is started from `dataset`.
pub(crate) fn profiled_info(
    t: &Target<'_>,
    pm: &PlanMeasurement,
    dataset: &Dataset,
    fwd: &mut ForwardModel,
) -> Result<(Vec<f64>, Vec<f64>), PlanError> {
    let (model, num, values, sigma_m, shots) = (t.model, t.num, t.values, t.sigma_m, t.shots);
    let drive = pm.excitation(num)?;
    let theta = fwd.theta_from(values, &[drive.force])?;
    fwd.start_from_data(dataset);
    let (no, nk) = (fwd.n_observations(), fwd.unknowns().len());
    let mut x = vec![Complex64::new(0.0, 0.0); no];
    let mut jac = vec![Complex64::new(0.0, 0.0); no * nk];
    fwd.evaluate(&theta, &mut x, Some(&mut jac))?;
    let free = fwd.free();
    let full = information(&jac, nk, &free, &Noise::Uniform(sigma_m), shots);
    let s = n_shared(model);
    let c = free.len();
    let (keep, nuis): (Vec<usize>, Vec<usize>) = (0..c).partition(|&i| {
        !matches!(
            fwd.unknowns()[free[i]],
            Unknown::Gain { .. } | Unknown::Force { .. }
        )
    });
    let a = DMatrix::from_fn(keep.len(), keep.len(), |i, j| full[keep[i] * c + keep[j]]);
    let b = DMatrix::from_fn(keep.len(), nuis.len(), |i, j| full[keep[i] * c + nuis[j]]);
    let d = DMatrix::from_fn(nuis.len(), nuis.len(), |i, j| full[nuis[i] * c + nuis[j]]);
    let eff = if nuis.is_empty() {
        a
    } else {
        // Schur complement with an equilibrated pseudo-inverse of the gains' block.
        let scale: Vec<f64> = (0..nuis.len())
            .map(|i| 1.0 / d[(i, i)].max(f64::MIN_POSITIVE).sqrt())
            .collect();
        let ds = DMatrix::from_fn(nuis.len(), nuis.len(), |i, j| {
            d[(i, j)] * scale[i] * scale[j]
        });
        let pinv = ds.pseudo_inverse(1e-13).map_err(|e| PlanError::Profile {
            reason: e.to_string(),
        })?;
        let dinv = DMatrix::from_fn(nuis.len(), nuis.len(), |i, j| {
            pinv[(i, j)] * scale[i] * scale[j]
        });
        &a - &b * dinv * b.transpose()
    };
    let mut info = vec![0.0; s * s];
    for (i, &ki) in keep.iter().enumerate() {
        for (j, &kj) in keep.iter().enumerate() {
            info[free[ki] * s + free[kj]] = eff[(i, j)];
        }
    }
    Ok((info, theta))
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_experiment::PlanNoise;

    /// Keeping some lines of a simulation equals simulating with those lines as `measure_hz`:
    /// the search relies on it to solve each candidate once.
    #[test]
    fn restricting_the_lines_equals_measuring_only_them() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/nanostring_2mode");
        let model = harmonid_model::load(&dir.join("model.hb")).expect("model");
        let values = harmonid_experiment::read_values(&dir.join("values.toml")).expect("values");
        let num = NumericModel::from_model(&model, &values).expect("numeric");
        let base = Plan {
            description: "test".into(),
            displacement_unit: "m".into(),
            points: Vec::new(),
            nominal_hz: Default::default(),
            noise: PlanNoise {
                sigma_per_quadrature: 5e-11,
                shots: 2,
            },
            measurements: Vec::new(),
            instrument: None,
        };
        let pm = PlanMeasurement {
            name: "couple_q1_q2".into(),
            drives_hz: vec![207582.0, 415838.0, 415846.0],
            // 40 % of the levels the design chose before the ramp saw the fold at 42 % of them.
            force: [
                ("q1".to_string(), vec![1.65, 0.0, 0.0]),
                ("q2".to_string(), vec![0.0, 0.296, 0.296]),
            ]
            .into(),
            phase_rad: Default::default(),
            measure_hz: None,
            drive_levels_v: None,
            drive_phases_rad: None,
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            bandwidth_hz: None,
            levels: Vec::new(),
        };
        let (all, lines) = simulate(&num, &base, &pm, Fidelity::Search).expect("simulates");
        let m = &all.measurements[0];
        assert!(m.freqs_hz.len() > 8, "{:?}", m.freqs_hz);
        // Every drive tone (a dataset measures them) and every other line.
        let keep: Vec<f64> = m
            .freqs_hz
            .iter()
            .enumerate()
            .filter(|&(i, f)| i % 2 == 0 || pm.drives_hz.iter().any(|d| (d - f).abs() < 1e-6))
            .map(|(_, &f)| f)
            .collect();
        assert!(keep.len() < m.freqs_hz.len());
        let cut = restrict_lines(&all, &pm, &keep);
        let only = PlanMeasurement {
            measure_hz: Some(keep.clone()),
            ..pm.clone()
        };
        let (direct, lines2) = simulate(&num, &base, &only, Fidelity::Search).expect("simulates");
        assert_eq!(lines, lines2);
        let (a, b) = (&cut.measurements[0], &direct.measurements[0]);
        assert_eq!(a.freqs_hz, b.freqs_hz);
        assert_eq!(a.freqs_hz, keep);
        let big = b.data.iter().map(|z| z.norm()).fold(0.0, f64::max);
        for (x, y) in a.data.iter().zip(&b.data) {
            assert!((x - y).norm() <= 1e-12 * big, "{x} vs {y}");
        }
        assert_eq!(cut.manifest.measurements, direct.manifest.measurements);
    }
}

#[cfg(test)]
mod size_bound_tests {
    use super::*;
    use harmonid_sim::SimError;
    use harmonid_spectral::SpectralError;

    #[test]
    fn only_a_size_bound_skips_a_candidate() {
        let sim = |source| {
            PlanError::from(ExperimentError::Sim {
                context: "measurement couple_q1_q2_q3".into(),
                source,
            })
        };
        let big = sim(SimError::Spectral(SpectralError::TooLarge {
            what: "a product plan's intermediate frequency set",
            needed: 13_089_924,
            limit: 8_388_608,
        }));
        let why = too_large(&big).expect("skipped");
        assert!(why.contains("13089924") && why.contains("8388608"), "{why}");
        let lattice = sim(SimError::TooLarge {
            what: "combination frequencies of the lattice",
            count: 2_000_001,
            limit: 2_000_000,
            help: "use a lower order or fewer tones",
        });
        assert!(too_large(&lattice).is_some());
        // Anything else is not a size bound: a fold is infeasible, a bad value an error.
        let fold = PlanError::Fold {
            measurement: "m".into(),
            percent: 50.0,
        };
        assert!(too_large(&fold).is_none());
        let bad = sim(SimError::NoTone);
        assert!(too_large(&bad).is_none());
    }
}

#[cfg(test)]
mod truncation_check_tests {
    use super::*;

    #[test]
    fn only_an_impossible_widening_is_an_unchecked_truncation() {
        let truncated = |change: f64| {
            PlanError::from(ExperimentError::Truncated {
                measurement: "couple_q1_q2_q3".into(),
                order: 9,
                lines: 905,
                wider_order: 11,
                wider_lines: 0,
                change,
                tol: 1e-6,
                why: "; the widened lattice could not be solved".into(),
            })
        };
        assert!(truncation_unchecked(&truncated(f64::NAN)));
        // A widening that moved the lines is a real truncation.
        assert!(!truncation_unchecked(&truncated(3e-4)));
    }
}

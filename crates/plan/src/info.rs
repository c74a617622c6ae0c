//! Fisher information of one planned measurement on the shared unknowns.

use crate::PlanError;
use harmonid_experiment::{ExperimentError, Plan, PlanMeasurement, Settings};
use harmonid_ident::fisher::{information, Noise};
use harmonid_ident::{Dataset, ForceModel, ForwardModel, ForwardSettings, Unknown};
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
    /// The forward model of the one-measurement dataset (labels, γ of fixed-Q modes).
    pub fwd: ForwardModel,
    /// `θ` of `fwd`.
    pub theta: Vec<f64>,
    /// The noise-free dataset (measured lines and amplitudes).
    pub dataset: Dataset,
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

/// Simulates `pm` noise-free (harmonic balance, Hill stability) and refuses a jump while the
/// drive ramps up.
pub(crate) fn simulate(
    num: &NumericModel,
    base: &Plan,
    pm: &PlanMeasurement,
) -> Result<Dataset, PlanError> {
    // A fold is infeasible here: stop the ramp at it rather than follow the jump.
    let settings = Settings {
        check_stability: true,
        stop_at_fold: true,
        ..Settings::noise_free()
    };
    let sim = single(base, pm).simulate_numeric(num, &settings)?;
    if let Some(&s) = sim.reports.first().and_then(|r| r.drive_jumps.first()) {
        return Err(PlanError::Fold {
            measurement: pm.name.clone(),
            percent: 100.0 * s,
        });
    }
    Ok(sim.dataset)
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

/// The information of measurement `pm` (simulated at `values`) for `shots` shots of
/// per-quadrature noise `sigma_m`, gains profiled out.
pub(crate) fn measurement_info(
    model: &Model,
    num: &NumericModel,
    values: &ModelValues,
    base: &Plan,
    pm: &PlanMeasurement,
    sigma_m: f64,
    shots: usize,
) -> Result<MeasInfo, PlanError> {
    let dataset = simulate(num, base, pm)?;
    let mut fwd = ForwardModel::new(
        model,
        &dataset,
        ForceModel::Auto,
        &ForwardSettings::default(),
    )?;
    let drive = pm.excitation(num)?;
    let theta = fwd.theta_from(values, &[drive.force])?;
    fwd.start_from_data(&dataset);
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
        let pinv = ds
            .pseudo_inverse(1e-13)
            .map_err(|e| PlanError::Input(format!("profiling the gains out: {e}")))?;
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
    Ok(MeasInfo {
        info,
        fwd,
        theta,
        dataset,
    })
}

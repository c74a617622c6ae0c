//! The identified model's response over a family's range: the continuation curve through the
//! folds with its stability, and the steady state at every measured step.

use super::MeasuredSweep;
use harmonid_data::Dataset;
use harmonid_sim::{Excitation, HbSettings, NumericModel, SweepSettings};
use num_complex::Complex64;

/// Points of a model curve (arclength steps; more near folds).
pub const CURVE_POINTS: usize = 300;

/// The model's response curve of one family.
#[derive(Debug, Clone)]
pub struct ModelCurve {
    /// Drive frequency of each point, Hz, in arclength order (it turns back at folds).
    pub f_hz: Vec<f64>,
    /// The response at the drive frequency (the fundamental) at the first point, in the
    /// dataset's unit, its phase against the driven mode's force.
    pub x: Vec<Complex64>,
    /// Stability of each point.
    pub stable: Vec<bool>,
    /// The force the curve is drawn at, on each mode (the model's order), N/kg, phase 0 on
    /// the most strongly driven mode: the median over the family's steps.
    pub force: Vec<Complex64>,
    /// The highest harmonic of the drive kept in the harmonic balance ([`harmonics_kept`]).
    pub harmonics: usize,
}

/// The first point's shape of each mode of `model` (1 for a dataset without points).
pub fn shape(ds: &Dataset, model: &NumericModel) -> Vec<f64> {
    model
        .mode_names
        .iter()
        .map(|n| ds.manifest.points.first().map_or(1.0, |p| p.shape_of(n)))
        .collect()
}

/// The highest harmonic of a drive in `[f0, f1]` that the identification's harmonic balance
/// keeps: its lattice ([`harmonid_sim::LatticeSettings`]' defaults) keeps the combinations
/// within `window_rel · f_n` of some resonance `f_n`, up to its order; the drive itself always.
/// So 1 for a drive near one resonance, 3 when a mode lies near three times the drive (a 1:3
/// internal resonance): the curve is the response the fit's model gives.
pub fn harmonics_kept(model: &NumericModel, f0: f64, f1: f64) -> usize {
    let lat = harmonid_sim::LatticeSettings::default();
    (1..=lat.order)
        .filter(|&h| {
            model.f_hz.iter().any(|&fnn| {
                let w = lat.window_rel * fnn;
                h as f64 * f0 <= fnn + w && h as f64 * f1 >= fnn - w
            })
        })
        .max()
        .unwrap_or(1)
}

/// The componentwise median of real numbers.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The model's curve over the range of `sweeps` (padded by 3 % of the span each side) at
/// the median of their steps' referenced forces, and a note when those forces differ by more
/// than 1 % (a force-controlled sweep whose level varies): the curve is then the response to
/// the median force only.
pub fn model_curve(
    model: &NumericModel,
    ds: &Dataset,
    sweeps: &[MeasuredSweep],
) -> Result<(ModelCurve, Option<String>), String> {
    let nm = model.n_modes();
    let referenced: Vec<Vec<Complex64>> = sweeps
        .iter()
        .flat_map(|s| s.force.iter().zip(&s.reference_rad))
        .filter_map(|(f, &r)| {
            f.as_ref().map(|f| {
                f.iter()
                    .map(|z| z * Complex64::from_polar(1.0, -r))
                    .collect()
            })
        })
        .collect();
    if referenced.is_empty() {
        return Err("the result has no forces for its steps".into());
    }
    let force: Vec<Complex64> = (0..nm)
        .map(|n| {
            Complex64::new(
                median(referenced.iter().map(|f| f[n].re).collect()),
                median(referenced.iter().map(|f| f[n].im).collect()),
            )
        })
        .collect();
    let mags: Vec<f64> = referenced
        .iter()
        .map(|f| f.iter().map(|z| z.norm()).fold(0.0, f64::max))
        .collect();
    let (lo, hi) = mags
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &m| (a.min(m), b.max(m)));
    let note = (hi > 1.01 * lo).then(|| {
        format!(
            "the model curve is drawn at the median force of the steps ({} N/kg); their forces span {} to {} N/kg, and the model at each step uses its own",
            harmonid_plot::style::num(median(mags.clone()), 3),
            harmonid_plot::style::num(lo, 3),
            harmonid_plot::style::num(hi, 3)
        )
    });
    let fs = sweeps.iter().flat_map(|s| s.f_hz.iter().copied());
    let (f0, f1) = fs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), f| {
        (a.min(f), b.max(f))
    });
    let pad = 0.03 * (f1 - f0).max(1e-6 * f1.abs());
    let harmonics = harmonics_kept(model, f0, f1);
    let settings = SweepSettings {
        f_start_hz: f0 - pad,
        f_stop_hz: f1 + pad,
        points: CURVE_POINTS,
        harmonics,
        ..SweepSettings::default()
    };
    let r = harmonid_sim::sweep(model, &force, &settings).map_err(|e| e.to_string())?;
    let h1 = r
        .harmonics
        .iter()
        .position(|&h| h == 1)
        .ok_or("no fundamental")?;
    let sh = shape(ds, model);
    let scale = ds.manifest.unit_scale().unwrap_or(1.0);
    let x = r
        .points
        .iter()
        .map(|p| {
            (0..nm)
                .map(|n| p.amplitudes[n][h1] * sh[n])
                .sum::<Complex64>()
                / scale
        })
        .collect();
    let note = match (note, r.complete) {
        (n, true) => n,
        (n, false) => Some(
            n.map_or(String::new(), |n| format!("{n}; "))
                + "the continuation stopped before the end of the range",
        ),
    };
    Ok((
        ModelCurve {
            f_hz: r.points.iter().map(|p| p.f_hz).collect(),
            x,
            stable: r.points.iter().map(|p| p.stable).collect(),
            force,
            harmonics,
        },
        note,
    ))
}

/// The model's steady state at every step of `sw`, the first step ramped from rest and each
/// later one started from the step before (harmonid_sim::stepped_sweep: the branch the
/// experiment followed), each at its own force; in the dataset's unit, with the step's phase
/// reference.
pub fn model_at_steps(
    model: &NumericModel,
    ds: &Dataset,
    sw: &MeasuredSweep,
) -> Result<Vec<Complex64>, String> {
    let pumps: Vec<harmonid_sim::PumpTone> = ds
        .measurement(sw.steps.first().ok_or("no steps")?)
        .map(|m| {
            m.spec
                .pump_tones()
                .into_iter()
                .map(harmonid_sim::PumpTone::from)
                .collect()
        })
        .unwrap_or_default();
    let drives = sw
        .f_hz
        .iter()
        .zip(&sw.force)
        .map(|(&f, force)| {
            let force = force.as_ref().ok_or("the result has no force for a step")?;
            Ok(Excitation {
                pumps: pumps.clone(),
                tones_hz: vec![f],
                force: force.iter().map(|&z| vec![z]).collect(),
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    let states = harmonid_sim::stepped_sweep(model, &drives, &HbSettings::default())
        .map_err(|e| e.to_string())?;
    let sh = shape(ds, model);
    let scale = ds.manifest.unit_scale().unwrap_or(1.0);
    sw.f_hz
        .iter()
        .zip(&states)
        .zip(&sw.reference_rad)
        .map(|((&f, st), &r)| {
            if !st.converged() {
                return Err(format!(
                    "harmonic balance did not converge at {f} Hz ({})",
                    st.status
                ));
            }
            Ok(st.at_point(&sh, f) / scale * Complex64::from_polar(1.0, -r))
        })
        .collect()
}

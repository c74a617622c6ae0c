//! `harmonid.linear_response`: the response of every mode to a weak probe tone about a steady
//! state, and the noise spectrum (`harmonid response`), as numpy arrays. (`harmonid.response`
//! is the frequency-response figure of a fit, another thing.)

use crate::errors::SimulationError;
use crate::model::Model;
use crate::sweep::numeric_model;
use harmonid_sim::{self as sim, Excitation, HbSettings, NumericModel, PumpTone};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

fn mode_index(nm: &NumericModel, name: &str, what: &str) -> PyResult<usize> {
    nm.mode_names.iter().position(|m| m == name).ok_or_else(|| {
        SimulationError::new_err(format!(
            "{what} `{name}` is not a mode ({})",
            nm.mode_names.join(", ")
        ))
    })
}

/// The drive of `drives` (`{mode: [Hz, ...]}`) with `force` (`{mode: N/kg}`) and the pumps;
/// `None` without drives. `harmonid.states` reads its drive the same way.
pub(crate) fn excitation(
    nm: &NumericModel,
    drives: &BTreeMap<String, Vec<f64>>,
    force: &BTreeMap<String, f64>,
    pumps: &[PumpTone],
) -> PyResult<Option<Excitation>> {
    if drives.is_empty() {
        if !force.is_empty() {
            return Err(SimulationError::new_err(
                "force given without drives: pass drives={\"q1\": [1008.0]} (Hz)",
            ));
        }
        return Ok(None);
    }
    let mut tones: Vec<f64> = Vec::new();
    let mut on = Vec::new();
    for (m, list) in drives {
        let n = mode_index(nm, m, "drives on")?;
        let a = *force.get(m).ok_or_else(|| {
            SimulationError::new_err(format!(
                "drives on `{m}` without a force: add force={{\"{m}\": N/kg}}"
            ))
        })?;
        if !a.is_finite() {
            return Err(SimulationError::new_err(format!(
                "force on `{m}`: {a} is not finite"
            )));
        }
        for &hz in list {
            if !(hz.is_finite() && hz > 0.0) {
                return Err(SimulationError::new_err(format!(
                    "drives on `{m}`: {hz} is not a positive frequency in Hz"
                )));
            }
            let d = match tones.iter().position(|&x| (x - hz).abs() <= 1e-9 * hz) {
                Some(d) => d,
                None => {
                    tones.push(hz);
                    tones.len() - 1
                }
            };
            on.push((n, d, a));
        }
    }
    for m in force.keys() {
        mode_index(nm, m, "force on")?;
    }
    let mut f = vec![vec![Complex64::new(0.0, 0.0); tones.len()]; nm.n_modes()];
    for (n, d, a) in on {
        f[n][d] = Complex64::new(a, 0.0);
    }
    Ok(Some(Excitation {
        tones_hz: tones,
        force: f,
        pumps: pumps.to_vec(),
    }))
}

/// The linear response of every mode to a weak probe tone on mode `probe` at each of
/// `probe_hz` (Hz), about the steady state the drive ramp reaches under `drives`
/// (`{mode: [Hz, ...]}`) with `force` (`{mode: N/kg}`, peak, one per driven mode) and `pumps`
/// (`[(Hz, level), ...]` or `(Hz, level, phase_rad)`), or about rest without drives. Exact
/// within the harmonic truncation (not the slow flow): docs/simulation.md.
///
/// Returns numpy arrays `probe_hz` (N,), `offsets_hz` (L,): the response lines at
/// `f_p + offsets_hz` (the first 0, the probe's own line; a negative total is an idler at
/// `|f_p + offset|` with the conjugate amplitude), `amplitudes` (N, modes, L; complex, m, for a
/// probe of `probe_force` N/kg peak: the analytic amplitudes, `Re[X e^{i2π(f_p + o)t}]`),
/// `idler_offset_hz` (`−f_pump`, or `−2 f_d` of the first drive; None at rest), `modes`,
/// `stable` (of the driven state; None at rest) and, with `noise_psd=S_F` ((N/kg)²/Hz,
/// one-sided white force noise on every mode), `noise_psd` (N, modes; m²/Hz at `probe_hz`).
/// Runs without holding the GIL.
#[pyfunction]
#[pyo3(signature = (model, values, probe, probe_hz, *, drives = BTreeMap::new(), force = BTreeMap::new(), pumps = Vec::new(), probe_force = 1.0, noise_psd = None))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn linear_response<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    probe: &str,
    probe_hz: Vec<f64>,
    drives: BTreeMap<String, Vec<f64>>,
    force: BTreeMap<String, f64>,
    pumps: Vec<Vec<f64>>,
    probe_force: f64,
    noise_psd: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let nm = numeric_model(model, values)?;
    let p = mode_index(&nm, probe, "probe")?;
    if let Some(s) = noise_psd {
        if !(s.is_finite() && s > 0.0) {
            return Err(SimulationError::new_err(format!(
                "noise_psd={s}: expected a finite positive one-sided PSD in (N/kg)^2/Hz"
            )));
        }
    }
    let pumps = pump_tones(&pumps)?;
    let drive = excitation(&nm, &drives, &force, &pumps)?;
    let run = || -> Result<_, String> {
        let (state, stable) = match &drive {
            Some(d) => {
                d.check(nm.n_modes()).map_err(|e| e.to_string())?;
                let st =
                    sim::steady_state(&nm, d, &HbSettings::default()).map_err(|e| e.to_string())?;
                if !st.converged() {
                    return Err(format!(
                        "the drive ramp found no steady state ({}): no state to probe",
                        st.status
                    ));
                }
                let stable = sim::check_stability(&nm, d, &st).ok().map(|s| s.stable);
                (Some(st), stable)
            }
            None => (None, None),
        };
        let r = sim::probe_response(
            &nm,
            state.as_ref(),
            &pumps,
            p,
            &probe_hz,
            Complex64::new(probe_force, 0.0),
            noise_psd.is_some(),
        )
        .map_err(|e| e.to_string())?;
        Ok((r, stable))
    };
    let (r, stable) = py.detach(run).map_err(SimulationError::new_err)?;
    let (n, m, l) = (r.probe_hz.len(), nm.n_modes(), r.offsets_hz.len());
    let d = PyDict::new(py);
    let amps: Vec<Complex64> = r.amplitudes.iter().flatten().flatten().copied().collect();
    d.set_item("probe_hz", r.probe_hz.clone().into_pyarray(py))?;
    d.set_item("offsets_hz", r.offsets_hz.clone().into_pyarray(py))?;
    d.set_item("amplitudes", amps.into_pyarray(py).reshape([n, m, l])?)?;
    let idler = match (
        pumps.first(),
        drive.as_ref().and_then(|d| d.tones_hz.first()),
    ) {
        (Some(p), _) => Some(-p.hz),
        (None, Some(&f)) => Some(-2.0 * f),
        _ => None,
    };
    d.set_item("idler_offset_hz", idler)?;
    d.set_item("modes", nm.mode_names.clone())?;
    d.set_item("stable", stable)?;
    if let (Some(s), Some(psd)) = (noise_psd, &r.noise_psd) {
        let v: Vec<f64> = psd.iter().flatten().map(|x| x * s).collect();
        d.set_item("noise_psd", v.into_pyarray(py).reshape([n, m])?)?;
    }
    Ok(d)
}

/// `pumps=[(Hz, level), (Hz, level, phase_rad), ...]` as pump tones.
pub(crate) fn pump_tones(pumps: &[Vec<f64>]) -> PyResult<Vec<PumpTone>> {
    pumps
        .iter()
        .map(|t| match t.as_slice() {
            [hz, level] => Ok(PumpTone {
                hz: *hz,
                amplitude: Complex64::new(*level, 0.0),
            }),
            [hz, level, phase] => Ok(PumpTone {
                hz: *hz,
                amplitude: Complex64::from_polar(*level, *phase),
            }),
            _ => Err(SimulationError::new_err(
                "pumps: each is (Hz, level) or (Hz, level, phase_rad)",
            )),
        })
        .collect()
}

//! `harmonid.sweep`: frequency-response curves with continuation through folds
//! (`harmonid sweep`), returned as numpy arrays.

use crate::errors::SimulationError;
use crate::model::Model;
use crate::values::model_values;
use harmonid_sim::{self as sim, NumericModel, SweepSettings, TwoToneSettings};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

fn sim_error(e: &sim::SimError) -> PyErr {
    SimulationError::new_err(e.to_string())
}

/// The model evaluated with `values` (see [`crate::values`]).
pub fn numeric_model(model: &Model, values: &Bound<'_, PyAny>) -> PyResult<NumericModel> {
    let values = model_values(values.py(), values)?;
    NumericModel::from_model(&model.inner, &values).map_err(|e| {
        SimulationError::new_err(format!(
            "cannot evaluate {} with these values: {e}",
            model.inner.source
        ))
    })
}

/// Force per mode (N/kg, peak, phase 0) from `{mode: amplitude}`, in the model's mode order.
fn force_vector(model: &NumericModel, force: &BTreeMap<String, f64>) -> PyResult<Vec<Complex64>> {
    let mut out = vec![Complex64::new(0.0, 0.0); model.n_modes()];
    for (m, &a) in force {
        let n = model
            .mode_names
            .iter()
            .position(|x| x == m)
            .ok_or_else(|| {
                SimulationError::new_err(format!(
                    "force on `{m}`, which is not a mode ({})",
                    model.mode_names.join(", ")
                ))
            })?;
        out[n] = Complex64::new(a, 0.0);
    }
    if force.is_empty() {
        return Err(SimulationError::new_err(
            "no force given: pass force={\"q1\": 3.5} (N/kg, peak)",
        ));
    }
    Ok(out)
}

/// Puts a curve's frequency axis (`key`), stability and amplitudes (shape points × modes ×
/// lines, complex, m) into `d` as numpy arrays; the vectors move into numpy without a copy.
fn put_curve<'py, 'a>(
    d: &Bound<'py, PyDict>,
    key: &str,
    points: impl ExactSizeIterator<Item = (f64, bool, &'a [Vec<Complex64>])>,
    n_modes: usize,
    n_lines: usize,
) -> PyResult<()> {
    let py = d.py();
    let n = points.len();
    let (mut axis, mut stable) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut amps = Vec::with_capacity(n * n_modes * n_lines);
    for (f, s, rows) in points {
        axis.push(f);
        stable.push(s);
        for row in rows {
            amps.extend_from_slice(row);
        }
    }
    d.set_item(key, axis.into_pyarray(py))?;
    d.set_item("stable", stable.into_pyarray(py))?;
    d.set_item(
        "amplitudes",
        amps.into_pyarray(py).reshape([n, n_modes, n_lines])?,
    )?;
    Ok(())
}

/// A frequency-response curve, followed through folds (`harmonid sweep`).
///
/// `values` gives the model's numbers: a dict in the layout of a values file
/// (`{"modes": {"q1": {"f_hz": ..., "Q": ...}}, "parameters": {"beta1": ...}}`), the path of a
/// values TOML file or of a result JSON, or an `IdentifyResult`. `force` is `{mode: N/kg}` (peak, phase 0) of the tone on each mode.
///
/// `points` is a resolution: consecutive points are at most `|f_to_hz − f_from_hz| / points`
/// apart in frequency (a few per cent more where the corrector carries a step further), so a
/// single-tone curve gets at least about `points + 1` points, more on steep flanks and around
/// folds (at most `8 · points`); two-tone: grid steps of the centre each way.
///
/// Single tone (default): the tone is swept from `f_from_hz` to `f_to_hz` by pseudo-arclength
/// continuation; returns numpy arrays `f_hz` (N,), `stable` (N,) and `amplitudes` (N, modes,
/// harmonics; complex, m, `Re[X e^{i2πkft}]`), with `modes`, `harmonics`, `folds_hz`,
/// `jumps_up_hz`, `jumps_down_hz` (where an up or down sweep jumps), `hopf` (per Hopf point
/// `(f_hz, offset_hz, gains_stability)`: a complex pair of slow-flow eigenvalues crosses zero,
/// a self-oscillation `offset_hz` from the drive's lines stops or starts) and `complete`.
/// With `limit_cycles=True`, `limit_cycles`: per Hopf point (as `harmonid sweep --limit-cycles`)
/// a dict with `hopf_hz`, and either `why` (the branch could not start) or the quasi-periodic
/// branch: `f_hz` (drive), `f2_hz` (the self-oscillation), `f2_abs`, `f_abs` (N, modes: |X|,
/// m, on the lines `f2` and `f`), `stable` (list: True, False or None where not judged) and
/// `end` (why it ended).
///
/// `two_tone_spacing_hz=Δ`: a pair of tones at `c ± Δ/2` (each with `force`) whose centre `c`
/// is swept up and down; returns `up` and `down`, each with `centre_hz`, `stable`,
/// `amplitudes` (a dict: mode → (N, that mode's lines); complex, m), `jumps_hz` and `stopped`
/// (None, or where and why). Each mode is reported at its own lines, `mode_lines[mode]`:
/// `(label, centre_factor, offset_hz)`, the line at `centre_factor · c + offset_hz` (a mode the
/// pair sweeps past at the offsets `lines_offset_hz`, `−3Δ/2, −Δ/2, Δ/2, 3Δ/2`; another at the
/// mixing products that reach its resonance).
///
/// Runs without holding the GIL.
#[pyfunction]
#[pyo3(signature = (model, values, f_from_hz, f_to_hz, force, *, points = 2000, harmonics = 3, two_tone_spacing_hz = None, limit_cycles = false))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn sweep<'py>(
    py: Python<'py>,
    model: &Model,
    values: &Bound<'py, PyAny>,
    f_from_hz: f64,
    f_to_hz: f64,
    force: BTreeMap<String, f64>,
    points: usize,
    harmonics: usize,
    two_tone_spacing_hz: Option<f64>,
    limit_cycles: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let nm = numeric_model(model, values)?;
    let f = force_vector(&nm, &force)?;
    if let Some(spacing_hz) = two_tone_spacing_hz {
        let s = TwoToneSettings {
            c_start_hz: f_from_hz,
            c_end_hz: f_to_hz,
            spacing_hz,
            force_low: f.clone(),
            force_high: f,
            points,
            ..TwoToneSettings::default()
        };
        return two_tone(py, &nm, &s);
    }
    let s = SweepSettings {
        f_start_hz: f_from_hz,
        f_stop_hz: f_to_hz,
        points,
        harmonics,
        ..SweepSettings::default()
    };
    let r = py
        .detach(|| sim::sweep(&nm, &f, &s))
        .map_err(|e| sim_error(&e))?;
    let (up, down) = r.jumps();
    let d = PyDict::new(py);
    let pts = r
        .points
        .iter()
        .map(|p| (p.f_hz, p.stable, p.amplitudes.as_slice()));
    put_curve(&d, "f_hz", pts, nm.n_modes(), r.harmonics.len())?;
    d.set_item("modes", nm.mode_names.clone())?;
    d.set_item("harmonics", r.harmonics.clone())?;
    d.set_item("jumps_up_hz", up)?;
    d.set_item("jumps_down_hz", down)?;
    d.set_item(
        "folds_hz",
        r.folds.iter().map(|f| f.f_hz).collect::<Vec<_>>(),
    )?;
    d.set_item("complete", r.complete)?;
    if limit_cycles {
        let s = sim::QuasiPeriodicSettings::for_sweep(&r, (f_from_hz, f_to_hz), points);
        let branches = py.detach(|| {
            (0..r.hopf.len())
                .map(|i| sim::quasi_periodic_branch(&nm, &f, &r, i, &s))
                .collect::<Vec<_>>()
        });
        let list = pyo3::types::PyList::empty(py);
        for (h, b) in r.hopf.iter().zip(branches) {
            list.append(branch_dict(py, h.f_hz, b, nm.n_modes())?)?;
        }
        d.set_item("limit_cycles", list)?;
    }
    // Hopf points: (Hz, offset of the self-oscillation from the drive's lines in Hz, whether
    // the state gains stability there along the curve).
    d.set_item(
        "hopf",
        r.hopf
            .iter()
            .map(|h| (h.f_hz, h.offset_hz, h.gains_stability))
            .collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// One limit-cycle branch (or why it could not start) as a dict of numpy arrays.
fn branch_dict<'py>(
    py: Python<'py>,
    hopf_hz: f64,
    b: Result<sim::QuasiPeriodicBranch, sim::SimError>,
    n_modes: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("hopf_hz", hopf_hz)?;
    let b = match b {
        Ok(b) => b,
        Err(e) => {
            d.set_item("why", e.to_string())?;
            return Ok(d);
        }
    };
    let n = b.points.len();
    let abs_on = |k: (i64, i64)| -> Vec<f64> {
        let l = b.line(k);
        b.points
            .iter()
            .flat_map(|p| {
                p.amplitudes
                    .iter()
                    .map(move |row| l.map_or(f64::NAN, |l| row[l].norm()))
            })
            .collect()
    };
    let f: Vec<f64> = b.points.iter().map(|p| p.f_hz).collect();
    let f2: Vec<f64> = b.points.iter().map(|p| p.f2_hz).collect();
    d.set_item("f_hz", f.into_pyarray(py))?;
    d.set_item("f2_hz", f2.into_pyarray(py))?;
    d.set_item(
        "f2_abs",
        abs_on((0, 1)).into_pyarray(py).reshape([n, n_modes])?,
    )?;
    d.set_item(
        "f_abs",
        abs_on((1, 0)).into_pyarray(py).reshape([n, n_modes])?,
    )?;
    let stable: Vec<Option<bool>> = b
        .points
        .iter()
        .map(|p| p.stability.map(|s| s.stable))
        .collect();
    d.set_item("stable", stable)?;
    d.set_item("end", b.end.to_string())?;
    Ok(d)
}

/// Two-tone sweep of a pair's centre, up and down.
fn two_tone<'py>(
    py: Python<'py>,
    nm: &NumericModel,
    s: &TwoToneSettings,
) -> PyResult<Bound<'py, PyDict>> {
    let r = py
        .detach(|| sim::sweep_two_tone(nm, s))
        .map_err(|e| sim_error(&e))?;
    let out = PyDict::new(py);
    out.set_item("lines_offset_hz", r.lines_offset_hz.clone())?;
    out.set_item("modes", nm.mode_names.clone())?;
    // Each mode is reported at its own lines (`mode_lines`), so the amplitudes are one array
    // per mode, (N, that mode's lines), with the lines' labels and centre factors/offsets.
    let lines = PyDict::new(py);
    for (name, ls) in nm.mode_names.iter().zip(&r.mode_lines) {
        let rows: Vec<(String, f64, f64)> = ls
            .iter()
            .map(|l| (l.label.clone(), l.centre_factor, l.offset_hz))
            .collect();
        lines.set_item(name, rows)?;
    }
    out.set_item("mode_lines", lines)?;
    for c in [&r.up, &r.down] {
        let d = PyDict::new(py);
        let n = c.points.len();
        let centre: Vec<f64> = c.points.iter().map(|p| p.centre_hz).collect();
        let stable: Vec<bool> = c.points.iter().map(|p| p.stable).collect();
        d.set_item("centre_hz", centre.into_pyarray(py))?;
        d.set_item("stable", stable.into_pyarray(py))?;
        let amps = PyDict::new(py);
        for (m, name) in nm.mode_names.iter().enumerate() {
            let width = r.mode_lines[m].len();
            let mut a: Vec<Complex64> = Vec::with_capacity(n * width);
            for p in &c.points {
                a.extend_from_slice(&p.amplitudes[m]);
            }
            amps.set_item(name, a.into_pyarray(py).reshape([n, width])?)?;
        }
        d.set_item("amplitudes", amps)?;
        d.set_item(
            "jumps_hz",
            c.jumps
                .iter()
                .map(|j| (j.from_hz, j.to_hz))
                .collect::<Vec<_>>(),
        )?;
        match &c.status {
            sim::TwoToneStatus::Complete => d.set_item("stopped", py.None())?,
            sim::TwoToneStatus::Stopped { at_hz, why } => {
                d.set_item("stopped", (*at_hz, why.to_string()))?
            }
        }
        out.set_item(if c.up { "up" } else { "down" }, d)?;
    }
    Ok(out)
}

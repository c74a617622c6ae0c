//! `harmonid.Dataset`: measurements in the layout of `DATA_FORMAT.md`, read from a folder, built
//! from numpy arrays, written back.

use crate::convert::json_to_py;
use crate::errors::{dataset_error, DatasetError};
use harmonid_data::{Direction, Manifest, Measurement, MeasurementSpec, PerStep, Point, SweepSpec};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArray3, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

/// A dataset: the manifest, and per measurement the complex amplitudes of every shot at every
/// measured frequency and point.
///
/// Amplitudes are held in metres whatever `displacement_unit` the data came in (the folder is
/// written back in its declared unit). A complex amplitude `X` at `f` is `Re[X e^{i2πft}]`, peak.
#[pyclass(module = "harmonid._harmonid", frozen)]
pub struct Dataset {
    pub(crate) inner: Arc<harmonid_data::Dataset>,
}

impl Dataset {
    pub(crate) fn wrap(ds: harmonid_data::Dataset) -> Self {
        Dataset {
            inner: Arc::new(ds),
        }
    }
}

/// `d[key]` extracted, or None when absent or None.
fn opt<'py, T: FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<Option<T>> {
    match d.get_item(key)? {
        Some(v) if !v.is_none() => v.extract::<T>().map(Some).map_err(|e| {
            let e: PyErr = e.into();
            PyTypeError::new_err(format!("\"{key}\": {e}"))
        }),
        _ => Ok(None),
    }
}

fn measurement_error(name: &str, message: String) -> PyErr {
    DatasetError::new_err(format!("measurement \"{name}\": {message}"))
}

/// One measurement's record from `from_arrays`.
fn measurement_from_dict(
    py: Python<'_>,
    name: String,
    d: &Bound<'_, PyDict>,
    manifest: &Manifest,
    scale: f64,
) -> PyResult<Measurement> {
    const KEYS: [&str; 13] = [
        "drives_hz",
        "freqs_hz",
        "amplitudes",
        "points",
        "drive_levels_v",
        "drive_phases_rad",
        "pumps_hz",
        "pump_levels",
        "pump_phases_rad",
        "bandwidth_hz",
        "file",
        "std",
        "samples",
    ];
    for k in d.keys() {
        let k: String = k.extract()?;
        if !KEYS.contains(&k.as_str()) && k != "name" {
            return Err(measurement_error(
                &name,
                format!("unknown key \"{k}\" (expected: {})", KEYS.join(", ")),
            ));
        }
    }
    let need = |key: &str| measurement_error(&name, format!("\"{key}\" is required"));
    let drives_hz: Vec<f64> = opt(d, "drives_hz")?.ok_or_else(|| need("drives_hz"))?;
    let freqs_hz: Vec<f64> = opt(d, "freqs_hz")?.ok_or_else(|| need("freqs_hz"))?;
    let amps = d
        .get_item("amplitudes")?
        .ok_or_else(|| need("amplitudes"))?;
    let np = py.import("numpy")?;
    let kw = PyDict::new(py);
    kw.set_item("dtype", np.getattr("complex128")?)?;
    let amps = np.call_method("ascontiguousarray", (amps,), Some(&kw))?;
    let amps = amps.cast::<PyArrayDyn<Complex64>>()?.readonly();
    let point_names: Option<Vec<String>> = opt(d, "points")?;
    let points: Vec<usize> = match point_names {
        None => (0..manifest.points.len().max(1)).collect(),
        Some(names) => names
            .iter()
            .map(|p| {
                manifest
                    .points
                    .iter()
                    .position(|q| &q.name == p)
                    .ok_or_else(|| {
                        measurement_error(&name, format!("point \"{p}\" is not among `points`"))
                    })
            })
            .collect::<PyResult<_>>()?,
    };
    let shape = amps.shape().to_vec();
    let (nf, npt) = (freqs_hz.len(), points.len());
    let ok = match shape.as_slice() {
        [_, f] => *f == nf && npt == 1,
        [_, f, p] => *f == nf && *p == npt,
        _ => false,
    };
    if !ok {
        return Err(measurement_error(
            &name,
            format!(
                "amplitudes have shape {shape:?}; expected (shots, {nf}){} for {nf} frequencies and {npt} point{}",
                if npt == 1 { format!(" or (shots, {nf}, 1)") } else { format!(" → (shots, {nf}, {npt})") },
                if npt == 1 { "" } else { "s" }
            ),
        ));
    }
    let n_shots = shape[0];
    let data: Vec<Complex64> = amps.as_slice()?.iter().map(|x| x * scale).collect();
    // A noise given with the data: `std` (per quadrature of one averaged sample) and `samples`
    // (how many were averaged), one per frequency and point; checked by `from_parts`.
    let std: Option<Vec<f64>> = opt(d, "std")?;
    let samples: Option<Vec<u32>> = opt(d, "samples")?;
    let noise = match (std, samples) {
        (Some(std), Some(samples)) => Some(harmonid_data::GivenNoise {
            std: std.iter().map(|s| s * scale).collect(),
            samples,
        }),
        (None, None) => None,
        _ => {
            return Err(DatasetError::new_err(
                "\"std\" and \"samples\" go together: the standard deviation per quadrature of the averaged samples and how many were averaged",
            ))
        }
    };
    Ok(Measurement {
        spec: MeasurementSpec {
            name,
            file: opt(d, "file")?,
            drives_hz,
            drive_levels_v: opt(d, "drive_levels_v")?,
            drive_phases_rad: opt(d, "drive_phases_rad")?,
            pumps_hz: opt(d, "pumps_hz")?.unwrap_or_default(),
            pump_levels: opt(d, "pump_levels")?,
            pump_phases_rad: opt(d, "pump_phases_rad")?,
            bandwidth_hz: opt(d, "bandwidth_hz")?,
            sweep: None,
        },
        freqs_hz,
        points,
        n_shots,
        data,
        noise,
    })
}

/// One stepped sweep from its dict (`name`, `steps`, optional `direction`): its manifest entry
/// and its steps as measurements `name[k]`.
fn sweep_from_dict(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    manifest: &Manifest,
    scale: f64,
) -> PyResult<(SweepSpec, Vec<Measurement>)> {
    let name: String =
        opt(d, "name")?.ok_or_else(|| PyTypeError::new_err("a sweep needs a \"name\""))?;
    let steps = d.get_item("steps")?.ok_or_else(|| {
        measurement_error(&name, "a sweep needs \"steps\" (a list of dicts)".into())
    })?;
    let mut ms = Vec::new();
    for (k, st) in steps.try_iter()?.enumerate() {
        let st = st?.cast_into::<PyDict>()?;
        ms.push(measurement_from_dict(
            py,
            format!("{name}[{k}]"),
            &st,
            manifest,
            scale,
        )?);
    }
    let drives: Vec<Vec<f64>> = ms.iter().map(|m| m.spec.drives_hz.clone()).collect();
    let firsts: Vec<f64> = drives
        .iter()
        .map(|d| d.first().copied().unwrap_or(0.0))
        .collect();
    let direction = match opt::<String>(d, "direction")?.as_deref() {
        Some("up") => Direction::Up,
        Some("down") => Direction::Down,
        Some("unordered") => Direction::Unordered,
        Some("level") => Direction::Level,
        Some(other) => {
            return Err(measurement_error(
                &name,
                format!(
                    "direction \"{other}\": expected \"up\", \"down\", \"unordered\" or \"level\""
                ),
            ))
        }
        None if firsts.windows(2).all(|w| w[1] > w[0]) => Direction::Up,
        None if firsts.windows(2).all(|w| w[1] < w[0]) => Direction::Down,
        None => Direction::Unordered,
    };
    let mut spec = SweepSpec::new(name.clone(), direction, drives);
    let per_step = |get: fn(&Measurement) -> &Option<Vec<f64>>, key: &str| {
        let v: Vec<Option<Vec<f64>>> = ms.iter().map(|m| get(m).clone()).collect();
        if v.iter().all(Option::is_none) {
            Ok(None)
        } else if v.iter().all(Option::is_some) {
            Ok(Some(PerStep::Each(v.into_iter().flatten().collect())))
        } else {
            Err(measurement_error(
                &name,
                format!("\"{key}\" is given for some steps only: give it for every step or none"),
            ))
        }
    };
    spec.drive_levels_v = per_step(|m| &m.spec.drive_levels_v, "drive_levels_v")?;
    spec.drive_phases_rad = per_step(|m| &m.spec.drive_phases_rad, "drive_phases_rad")?;
    // A sweep's pump is the same at every step.
    if let Some(first) = ms.first() {
        let pump = |m: &Measurement| {
            (
                m.spec.pumps_hz.clone(),
                m.spec.pump_levels.clone(),
                m.spec.pump_phases_rad.clone(),
            )
        };
        let p0 = pump(first);
        if ms.iter().any(|m| pump(m) != p0) {
            return Err(measurement_error(
                &name,
                "the pump (\"pumps_hz\", \"pump_levels\", \"pump_phases_rad\") differs between steps: a sweep has one pump for every step".to_string(),
            ));
        }
        (spec.pumps_hz, spec.pump_levels, spec.pump_phases_rad) = p0;
    }
    for (k, m) in ms.iter_mut().enumerate() {
        m.spec = spec.step_spec(k);
    }
    Ok((spec, ms))
}

#[pymethods]
impl Dataset {
    /// Reads a dataset folder (`dataset.toml`, one CSV per measurement, optional `truth.toml`).
    #[staticmethod]
    fn from_folder(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let ds = py
            .detach(|| harmonid_data::Dataset::load(&path))
            .map_err(|e| dataset_error(&e))?;
        Ok(Dataset::wrap(ds))
    }

    /// Builds a dataset from arrays. `measurements` maps each measurement's name to a dict:
    ///
    /// - `drives_hz`: every drive tone, Hz (each must be among `freqs_hz`);
    /// - `freqs_hz`: the measured frequencies, Hz (1-D);
    /// - `amplitudes`: complex amplitudes in `displacement_unit`, shape `(shots, freqs)` or
    ///   `(shots, freqs, points)`;
    /// - optional `points` (names, default all declared points), `drive_levels_v`,
    ///   `drive_phases_rad` (both or neither, one per drive tone), `pumps_hz` with
    ///   `pump_levels` and `pump_phases_rad` (a parametric pump), `bandwidth_hz`, `file`;
    /// - optional `std` and `samples` (together, one shot): each row an average with its noise,
    ///   one value per frequency and point, frequency-major, `std` in `displacement_unit`.
    ///
    /// `sweeps` lists stepped sweeps: dicts with `name`, `steps` (a list of measurement dicts as
    /// above, without names: step `k` is measurement `name[k]`) and optional `direction`
    /// (`"up"`, `"down"`, `"unordered"`; default: from the steps' first drive tones).
    ///
    /// `points` maps point names to mode shapes (`{"p0": {"q1": 0.31, "q2": 0.59}}`; none: the
    /// amplitudes are modal). `nominal_hz` gives approximate resonances per mode. The arrays are
    /// checked as a folder's files are; errors name the measurement and what is wrong.
    #[staticmethod]
    #[pyo3(signature = (measurements, *, displacement_unit = "m", points = None, nominal_hz = None, description = "", sweeps = None))]
    fn from_arrays(
        py: Python<'_>,
        measurements: &Bound<'_, PyAny>,
        displacement_unit: &str,
        points: Option<&Bound<'_, PyDict>>,
        nominal_hz: Option<BTreeMap<String, f64>>,
        description: &str,
        sweeps: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut manifest = Manifest::new(description);
        manifest.displacement_unit = displacement_unit.to_string();
        let scale = manifest.unit_scale().ok_or_else(|| {
            DatasetError::new_err(format!(
                "displacement_unit=\"{displacement_unit}\" is not one of \"m\", \"um\", \"nm\", \"pm\""
            ))
        })?;
        if let Some(points) = points {
            for (name, shape) in points.iter() {
                manifest.points.push(Point {
                    name: name.extract()?,
                    shape: shape.extract()?,
                });
            }
        }
        manifest.nominal_hz = nominal_hz.unwrap_or_default();
        let items: Vec<(String, Bound<'_, PyDict>)> = if let Ok(d) = measurements.cast::<PyDict>() {
            d.iter()
                .map(|(k, v)| Ok((k.extract()?, v.cast_into::<PyDict>()?)))
                .collect::<PyResult<_>>()?
        } else {
            measurements
                .try_iter()?
                .map(|v| {
                    let v = v?.cast_into::<PyDict>()?;
                    let name: String = opt(&v, "name")?.ok_or_else(|| {
                        PyTypeError::new_err("a measurement given in a list needs a \"name\"")
                    })?;
                    Ok((name, v))
                })
                .collect::<PyResult<_>>()?
        };
        let mut ms = items
            .into_iter()
            .map(|(name, d)| measurement_from_dict(py, name, &d, &manifest, scale))
            .collect::<PyResult<Vec<_>>>()?;
        if let Some(sweeps) = sweeps {
            for sw in sweeps.try_iter()? {
                let sw = sw?.cast_into::<PyDict>()?;
                let (spec, steps) = sweep_from_dict(py, &sw, &manifest, scale)?;
                ms.extend(steps);
                manifest.sweeps.push(spec);
            }
        }
        let ds = py
            .detach(|| harmonid_data::Dataset::from_parts("<arrays>", manifest, ms, None))
            .map_err(|e| dataset_error(&e))?;
        Ok(Dataset::wrap(ds))
    }

    /// Pools datasets of one device (the rounds of the lab loop) into one, in memory.
    ///
    /// The datasets must agree on `displacement_unit`, the points and their mode shapes,
    /// `nominal_hz` and the import conventions; the first disagreement raises `DatasetError`
    /// naming the file, the key and both values. A measurement or sweep name found in several
    /// datasets is renamed `<folder>_<name>` in each (the folder the dataset was read from;
    /// `ds<i>`, 1-based, for one built from arrays); sweeps keep their steps. `truth` is kept
    /// only when identical in all; `notes` says what was renamed or dropped. Write the result
    /// with `to_folder` (as `harmonid merge DS... --out DIR` does).
    #[staticmethod]
    fn merge(py: Python<'_>, datasets: Vec<PyRef<'_, Dataset>>) -> PyResult<Self> {
        let inputs: Vec<harmonid_data::Dataset> =
            datasets.iter().map(|d| (*d.inner).clone()).collect();
        let ds = py
            .detach(|| harmonid_data::Dataset::merge(&inputs))
            .map_err(|e| dataset_error(&e))?;
        Ok(Dataset::wrap(ds))
    }

    /// Writes the dataset folder (replacing `path` if it exists; written atomically).
    fn to_folder(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let ds = Arc::clone(&self.inner);
        py.detach(|| ds.write(&path)).map_err(|e| dataset_error(&e))
    }

    /// Where the dataset was read from (`"<arrays>"` when built from arrays).
    #[getter]
    fn path(&self) -> String {
        self.inner.dir.display().to_string()
    }

    /// What reading or importing did that a user should know of (settling samples dropped), one
    /// line each.
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.inner.notes.clone()
    }

    /// The measurement names, in manifest order.
    #[getter]
    fn measurements(&self) -> Vec<String> {
        self.inner
            .measurements
            .iter()
            .map(|m| m.spec.name.clone())
            .collect()
    }

    /// One measurement: `drives_hz`, `freqs_hz` (numpy, increasing), `amplitudes` (numpy complex,
    /// metres, shape `(shots, freqs, points)`), `points` (names), and `drive_levels_v`,
    /// `drive_phases_rad`, `pumps_hz`, `pump_levels`, `pump_phases_rad`, `bandwidth_hz` when
    /// given. The arrays are copies.
    fn measurement<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let m = self.inner.measurement(name).ok_or_else(|| {
            pyo3::exceptions::PyKeyError::new_err(format!(
                "no measurement \"{name}\" (measurements: {})",
                self.measurements().join(", ")
            ))
        })?;
        let d = PyDict::new(py);
        d.set_item("name", &m.spec.name)?;
        d.set_item("drives_hz", m.spec.drives_hz.clone().into_pyarray(py))?;
        d.set_item("freqs_hz", m.freqs_hz.clone().into_pyarray(py))?;
        let shape = [m.n_shots, m.freqs_hz.len(), m.points.len()];
        let amps = m.data.clone().into_pyarray(py).reshape(shape)?;
        let amps: Bound<'py, PyArray3<Complex64>> = amps;
        d.set_item("amplitudes", amps)?;
        let names: Vec<&str> = m
            .points
            .iter()
            .map(|&p| {
                self.inner
                    .manifest
                    .points
                    .get(p)
                    .map_or("(modal)", |q| q.name.as_str())
            })
            .collect();
        d.set_item("points", PyList::new(py, names)?)?;
        d.set_item("drive_levels_v", &m.spec.drive_levels_v)?;
        d.set_item("drive_phases_rad", &m.spec.drive_phases_rad)?;
        if !m.spec.pumps_hz.is_empty() {
            d.set_item("pumps_hz", m.spec.pumps_hz.clone())?;
            d.set_item("pump_levels", &m.spec.pump_levels)?;
            d.set_item("pump_phases_rad", &m.spec.pump_phases_rad)?;
        }
        d.set_item("bandwidth_hz", m.spec.bandwidth_hz)?;
        // A noise given with the data: per frequency and point, in data order (metres).
        if let Some(g) = &m.noise {
            d.set_item("std", g.std.clone().into_pyarray(py))?;
            d.set_item("samples", g.samples.clone().into_pyarray(py))?;
        }
        Ok(d)
    }

    /// The manifest (`dataset.toml`) as a dict.
    #[getter]
    fn manifest<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = serde_json::to_value(&self.inner.manifest)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        json_to_py(py, &v)
    }

    /// The true values (`truth.toml`, synthetic data only) as a dict, or None.
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.inner.truth {
            None => Ok(py.None().into_bound(py)),
            Some(t) => {
                let v = serde_json::to_value(t)
                    .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
                json_to_py(py, &v)
            }
        }
    }

    fn __repr__(&self) -> String {
        let shots: Vec<String> = self
            .inner
            .measurements
            .iter()
            .map(|m| {
                format!(
                    "{} ({} shots × {} freqs)",
                    m.spec.name,
                    m.n_shots,
                    m.freqs_hz.len()
                )
            })
            .collect();
        format!("Dataset({:?}, [{}])", self.path(), shots.join(", "))
    }
}

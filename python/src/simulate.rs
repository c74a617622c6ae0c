//! `harmonid.simulate`: the virtual experiment (`harmonid simulate`): a plan, a model and its
//! values → the dataset a lab would record.

use crate::dataset::Dataset;
use crate::errors::{render, SimulationError};
use crate::model::Model;
use crate::plan::plan_from;
use crate::values::model_values;
use harmonid_experiment::{Engine, Settings, TimeDomain, Truncation};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The time-domain settings from `time_domain`: False/None (harmonic balance), True (the
/// defaults) or a dict of `from_rest`, `steps_per_period`, `rtol`, `noise_rms_nm`.
fn time_domain_from(td: Option<&Bound<'_, PyAny>>) -> PyResult<Option<TimeDomain>> {
    let Some(td) = td else { return Ok(None) };
    if let Ok(on) = td.extract::<bool>() {
        return Ok(on.then(TimeDomain::default));
    }
    let d = td.cast::<PyDict>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "time_domain: expected True, False or a dict of from_rest, steps_per_period, rtol, noise_rms_nm",
        )
    })?;
    let mut out = TimeDomain::default();
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "from_rest" => out.from_rest = v.extract()?,
            "steps_per_period" => out.steps_per_period = v.extract()?,
            "rtol" => out.rtol = v.extract()?,
            "noise_rms_nm" => out.noise_rms_m = v.extract::<f64>()? * 1e-9,
            other => {
                return Err(SimulationError::new_err(format!(
                    "time_domain: unknown setting \"{other}\" (expected from_rest, steps_per_period, rtol, noise_rms_nm)"
                )))
            }
        }
    }
    Ok(Some(out))
}

/// Simulates the measurements of `plan` on `model` with `values` and returns the `Dataset` a
/// lab would record (amplitudes in metres, with the true values as `.truth`), as
/// `harmonid simulate MODEL --values V --plan P` writes it.
///
/// `values`: a dict in the values file's layout (`{"modes": {"q1": {"f_hz": .., "Q": ..}},
/// "parameters": {..}}`), the path of a values TOML file or of a result JSON, or an
/// `IdentifyResult`. `plan`: the path of a plan TOML file, a dict in its layout or a `PlanResult`
/// (docs/simulation.md). `time_domain=True` integrates in time and demodulates as a lock-in
/// instead of harmonic balance; a dict sets that run as the command line's flags do:
/// `{"from_rest": False, "steps_per_period": 16, "rtol": 1e-9, "noise_rms_nm": 0.0}` (the
/// defaults; `--from-rest`, `--steps-per-period`, `--rtol`, `--noise-rms-nm`). `seed` seeds
/// the noise; `noise=False` gives clean amplitudes;
/// each steady state is checked for stability (Hill's method) and an unstable one refused
/// unless `allow_unstable` (`check_stability=False` skips the check); a state whose spectrum
/// is still truncated at order 17 is refused unless `allow_truncation`; `order` is the
/// harmonic-balance lattice's intermodulation order to start from. The defaults are the
/// command line's. Runs without holding the GIL.
#[pyfunction]
#[pyo3(signature = (model, values, plan, *, time_domain = None, seed = 0, noise = true, check_stability = true, allow_unstable = false, allow_truncation = false, order = None))]
#[allow(clippy::too_many_arguments)] // the Python signature, keyword arguments included
pub fn simulate(
    py: Python<'_>,
    model: &Model,
    values: &Bound<'_, PyAny>,
    plan: &Bound<'_, PyAny>,
    time_domain: Option<&Bound<'_, PyAny>>,
    seed: u64,
    noise: bool,
    check_stability: bool,
    allow_unstable: bool,
    allow_truncation: bool,
    order: Option<usize>,
) -> PyResult<Dataset> {
    let values = model_values(py, values)?;
    let plan = plan_from(py, plan, SimulationError::new_err)?;
    let time_domain = time_domain_from(time_domain)?;
    let mut settings = Settings {
        seed,
        noise,
        check_stability,
        allow_unstable,
        truncation: Truncation {
            required: !allow_truncation,
            ..Truncation::default()
        },
        ..Settings::default()
    };
    if let Some(td) = time_domain {
        settings.engine = Engine::TimeDomain(td);
    }
    if let Some(o) = order {
        settings.order = o;
    }
    let m = std::sync::Arc::clone(&model.inner);
    let sim = py
        .detach(|| {
            plan.simulate(&m, &values, &settings)
                .map_err(|e| render(&e))
        })
        .map_err(SimulationError::new_err)?;
    Ok(Dataset::wrap(sim.dataset))
}

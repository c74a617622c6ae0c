//! The measured response of one sweep: each step's drive line (median over shots) at the
//! first point, in the dataset's unit, its phase against the step's identified force.

use harmonid_data::result::Report;
use harmonid_data::{Dataset, Direction};
use num_complex::Complex64;

/// One sweep's measured response, and the forces the identification gave its steps.
#[derive(Debug, Clone)]
pub struct MeasuredSweep {
    /// The sweep's name.
    pub name: String,
    /// Its direction.
    pub direction: Direction,
    /// Each step's measurement name (`name[k]`), in measurement order.
    pub steps: Vec<String>,
    /// Each step's drive frequency, Hz.
    pub f_hz: Vec<f64>,
    /// Each step's response at the drive frequency (median over shots), in the dataset's
    /// unit, times `e^{-i·reference_rad}`.
    pub x: Vec<Complex64>,
    /// Each step's force on each mode (in the model's mode order), N/kg, as the result gives
    /// it (`None` when the result has no forces for the step, e.g. a held-out step).
    pub force: Vec<Option<Vec<Complex64>>>,
    /// Each step's phase reference: `arg F` of its most strongly driven mode (0 without
    /// forces), rad.
    pub reference_rad: Vec<f64>,
    /// The model's steady state at each step, followed from step to step as the sweep was, in
    /// the dataset's unit with the same phase reference (filled by
    /// [`super::model_at_steps`]).
    pub model: Option<Vec<Complex64>>,
}

/// The median of the real and of the imaginary parts.
pub(crate) fn complex_median(z: impl Iterator<Item = Complex64>) -> Complex64 {
    crate::spectra::complex_median(z)
}

/// The result's force of measurement `name` at the tone `f_hz` on every mode of `names`.
fn step_force(result: &Report, name: &str, f_hz: f64, names: &[String]) -> Option<Vec<Complex64>> {
    let per_mode = result.forces.get(name)?;
    Some(
        names
            .iter()
            .map(|n| {
                per_mode
                    .get(n)
                    .into_iter()
                    .flatten()
                    .find(|fr| (fr.f_hz - f_hz).abs() <= 1e-9 * f_hz.abs().max(1.0))
                    .map_or(Complex64::new(0.0, 0.0), |fr| {
                        Complex64::from_polar(fr.amplitude, fr.phase_rad)
                    })
            })
            .collect(),
    )
}

/// The measured response of sweep `s` (an index in `manifest.sweeps`), with the forces on the
/// modes `names`; `None` when none of its steps is in the dataset.
pub fn measured(
    ds: &Dataset,
    result: &Report,
    names: &[String],
    s: usize,
) -> Option<MeasuredSweep> {
    let spec = ds.manifest.sweeps.get(s)?;
    let scale = ds.manifest.unit_scale().unwrap_or(1.0);
    let mut steps: Vec<(usize, &harmonid_data::Measurement)> = ds
        .measurements
        .iter()
        .filter_map(|m| {
            let st = m.spec.sweep.as_ref()?;
            (st.sweep == spec.name).then_some((st.step, m))
        })
        .collect();
    steps.sort_by_key(|(k, _)| *k);
    let mut out = MeasuredSweep {
        name: spec.name.clone(),
        direction: spec.direction,
        steps: Vec::new(),
        f_hz: Vec::new(),
        x: Vec::new(),
        force: Vec::new(),
        reference_rad: Vec::new(),
        model: None,
    };
    for (_, m) in steps {
        let Some(&f) = m.spec.drives_hz.first() else {
            continue;
        };
        // The dataset's first point (local index of manifest point 0).
        let (Some(fi), Some(p)) = (m.freq_index(f), m.points.iter().position(|&q| q == 0)) else {
            continue;
        };
        let x = complex_median((0..m.n_shots).map(|sh| m.amplitude(sh, fi, p))) / scale;
        let force = step_force(result, &m.spec.name, f, names);
        let reference = force
            .as_ref()
            .and_then(|fv| fv.iter().max_by(|a, b| a.norm().total_cmp(&b.norm())))
            .filter(|z| z.norm() > 0.0)
            .map_or(0.0, |z| z.arg());
        out.steps.push(m.spec.name.clone());
        out.f_hz.push(f);
        out.x.push(x * Complex64::from_polar(1.0, -reference));
        out.force.push(force);
        out.reference_rad.push(reference);
    }
    (!out.steps.is_empty()).then_some(out)
}

//! A stepped-sine frequency response at a lab's scale (issue 35): a softening Duffing mode with
//! nonlinear damping, 12 drive levels each swept up and down through its folds, 48 steps a
//! sweep (1,152 steps, one line each, 5 samples a step), identified with the error floor as
//! real sweeps are. The estimates must hold the truth within 4 standard errors. Set
//! `HARMONID_KEEP_STEPPED=DIR` to keep the dataset (for profiling the command line on it).

use harmonid::data::Dataset;
use harmonid::ident::{identify, ForceModel, Report, Settings};
use harmonid_testgen as gen;

/// Noise per quadrature of a step, m (the response is 1-20 nm at its peak).
pub const SIGMA: f64 = 2e-11;

/// Samples (shots) a step.
pub const SHOTS: usize = 5;

/// The model, its values and the noisy dataset of `levels` up and down sweeps of `steps` steps.
pub fn dataset(
    levels: usize,
    steps: usize,
    seed: u64,
) -> (harmonid::model::Model, gen::Values, Dataset) {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "softening.hb").expect("model");
    let (v, sweeps) = gen::hysteretic_sweeps(levels, steps);
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps, &[1.0], SHOTS);
    (model, v, gen::add_noise(&clean, SIGMA, seed))
}

fn settings() -> Settings {
    Settings {
        force_model: ForceModel::GainPerMode,
        error_floor: true,
        ..Settings::default()
    }
}

fn within(rep: &Report, v: &gen::Values) -> Vec<(String, f64)> {
    let est = [
        ("f", &rep.modes["q1"].f_hz, v.f_hz[0]),
        ("Q", &rep.modes["q1"].q, v.q[0]),
        ("beta1", &rep.parameters["beta1"], v.params["beta1"]),
        ("eta1", &rep.parameters["eta1"], v.params["eta1"]),
    ];
    est.iter()
        .map(|(n, e, t)| (n.to_string(), (e.value - t) / e.stderr))
        .collect()
}

#[test]
fn a_thousand_steps_identify_within_their_error_bars() {
    let (model, v, ds) = dataset(12, 48, 3);
    assert_eq!(ds.measurements.len(), 1152);
    assert_eq!(ds.manifest.sweeps.len(), 24);
    if let Ok(dir) = std::env::var("HARMONID_KEEP_STEPPED") {
        ds.write(&dir).expect("dataset written");
        std::fs::write(format!("{dir}/model.hb"), gen::DAMPED_DUFFING).expect("model written");
    }
    let rep = identify(&model, &ds, &settings()).expect("identify");
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    let dev = within(&rep, &v);
    println!("deviations in stderr: {dev:?}");
    for (name, d) in &dev {
        assert!(d.abs() < 4.0, "{name}: {d} stderr off ({dev:?})");
    }
}

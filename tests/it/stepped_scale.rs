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
    // The misfit per sweep: every step in one of the 24 sweeps, their χ² summing the fit's,
    // each percentage in the summary as in the result.
    let g = rep.goodness_of_fit.as_ref().expect("verdict");
    assert_eq!(g.sweeps.len(), 24);
    assert_eq!(g.sweeps.iter().map(|s| s.steps).sum::<usize>(), 1152);
    let chi2: f64 = g.sweeps.iter().map(|s| s.chi2).sum();
    assert!((chi2 / g.chi2 - 1.0).abs() < 1e-9, "{chi2} vs {}", g.chi2);
    // A correct model misses a sweep by its noise: about 1.15 sigmas RMS with the noise of
    // 5 shots (χ²/dof ν/(ν − 2) = 4/3), a sweep's 96 residuals scattering by ~0.1.
    let mut rms: Vec<f64> = g.sweeps.iter().map(|s| s.rms_residual_sigma).collect();
    rms.sort_by(f64::total_cmp);
    assert!(
        (1.0..1.3).contains(&rms[12]),
        "median {} of {rms:?}",
        rms[12]
    );
    let summary = rep.summary(None);
    for s in &g.sweeps {
        let text = format!(
            "{} {} %",
            s.name,
            harmonid::data::result::sig3(100.0 * s.relative_rms)
        );
        assert!(summary.contains(&text), "{text} not in\n{summary}");
        // Every sweep is fitted to about its noise (a step at a fold, where the model's
        // branch may jump one step from the data's, costs a sweep a few tenths).
        assert!(
            s.rms_residual_sigma < 2.0,
            "{}: {} sigmas",
            s.name,
            s.rms_residual_sigma
        );
    }
}

/// A dataset beyond what one identification holds is refused before any work, saying why and
/// what to do (100,000 steps would take about 2.7 GB).
#[test]
fn too_many_steps_are_refused_before_any_work() {
    let (model, _, mut ds) = dataset(1, 2, 0);
    let one = ds.measurements[0].clone();
    ds.measurements = vec![one; harmonid::ident::MAX_MEASUREMENTS + 1];
    let e = identify(&model, &ds, &settings()).expect_err("refused");
    let text = e.to_string();
    assert!(
        text.contains("50001 measurements, above the 50000")
            && text.contains("27 kB per one-line step")
            && text.contains("1.4 GB"),
        "{text}"
    );
}

//! Stepped sweeps through folds identify: up- and down-sweeps of a hardening resonance with
//! nonlinear damping, simulated the way the experiment runs them (each step from the previous
//! step's state, so the two directions are on different branches in the bistable range), reach
//! the output-error estimate: every coefficient within a few standard errors of the truth and
//! a fit at the noise. Each step's forward solve starts where the experiment had it, never
//! ramped from rest through a fold the sweep did not cross.

use harmonid::data::Direction;
use harmonid::ident::{identify, ForceModel, ForwardModel, ForwardSettings, Settings};
use harmonid_testgen as gen;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Up and down at three levels (linear peak response 5, 15 and 30 nm; the two higher ones
/// bistable), 61 steps from −5 to +15 linewidths each.
fn sweeps(v: &gen::Values) -> Vec<gen::SteppedSweep> {
    let (f, q) = (v.f_hz[0], v.q[0]);
    let (w, lw) = (TAU * f, f / q);
    let mut out = Vec::new();
    for (l, x) in [5e-9, 1.5e-8, 3e-8].iter().enumerate() {
        let force = x * w * w / q;
        let up: Vec<(f64, f64)> = (0..=60)
            .map(|s| (f + lw * (f64::from(s) / 3.0 - 5.0), force))
            .collect();
        let down = up.iter().rev().copied().collect();
        for (dir, steps) in [(Direction::Up, up), (Direction::Down, down)] {
            out.push(gen::SteppedSweep {
                name: format!("l{l}_{}", dir.name()),
                direction: dir,
                steps,
            });
        }
    }
    out
}

fn setup() -> (harmonid::model::Model, gen::Values, harmonid::data::Dataset) {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let v = gen::damped_duffing_values(1.0e18);
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v), &[1.0], 10);
    (model, v, clean)
}

#[test]
fn at_the_truth_the_forward_model_follows_each_sweep_onto_its_branch() {
    // No start from the data: each step's first solve is the forward model's own. Ramped
    // from rest, the up-sweeps' steps in the bistable range would land on the low branch.
    let (model, v, clean) = setup();
    let mut fwd = ForwardModel::new(
        &model,
        &clean,
        ForceModel::GainPerMode,
        &ForwardSettings::default(),
    )
    .expect("forward model");
    let forces: Vec<Vec<Vec<Complex64>>> = clean
        .measurements
        .iter()
        .map(|m| {
            vec![vec![Complex64::new(
                m.spec.drive_levels_v.as_ref().expect("level")[0],
                0.0,
            )]]
        })
        .collect();
    let theta = fwd
        .theta_from(&gen::model_values(&model, &v), &forces)
        .expect("theta");
    let mut x = vec![Complex64::new(0.0, 0.0); fwd.n_observations()];
    fwd.evaluate(&theta, &mut x, None).expect("evaluate");
    for (m, xm) in clean.measurements.iter().zip(&x) {
        let want = m.data[0];
        assert!(
            (xm - want).norm() <= 1e-6 * want.norm(),
            "{}: {xm} where the sweep is at {want}",
            m.spec.name
        );
    }
}

#[test]
fn up_and_down_sweeps_through_folds_reach_the_output_error_estimate() {
    let (model, v, clean) = setup();
    // The data hold both branches: at the top level the up-sweep is far above the down-sweep
    // somewhere in the bistable range.
    let amp = |name: &str| -> Vec<f64> {
        clean
            .measurements
            .iter()
            .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| s.sweep == name))
            .map(|m| m.data[0].norm())
            .collect()
    };
    let (up, mut down) = (amp("l2_up"), amp("l2_down"));
    down.reverse();
    let split = up.iter().zip(&down).map(|(a, b)| a / b).fold(0.0, f64::max);
    assert!(
        split > 3.0,
        "up/down ratio at most {split}: no bistable range"
    );
    let ds = gen::add_noise(&clean, 1e-11, 7);
    let settings = Settings {
        force_model: ForceModel::GainPerMode,
        ..Settings::default()
    };
    let rep = identify(&model, &ds, &settings).expect("identify");
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    let gof = rep.goodness_of_fit.as_ref().expect("verdict");
    println!(
        "χ²/dof {:.3} (expected {:.3})",
        gof.chi2_per_dof, gof.expected_chi2_per_dof
    );
    assert_eq!(gof.fits, Some(true), "{gof:?}");
    let mode = &rep.modes["q1"];
    for (name, est, truth) in [
        ("f", &mode.f_hz, v.f_hz[0]),
        ("Q", &mode.q, v.q[0]),
        ("beta1", &rep.parameters["beta1"], v.params["beta1"]),
        ("eta1", &rep.parameters["eta1"], v.params["eta1"]),
    ] {
        let dev = (est.value - truth) / est.stderr;
        println!(
            "{name}: {:.6e} ± {:.2e} ({dev:+.2} stderr)",
            est.value, est.stderr
        );
        assert!(est.stderr < 0.05 * truth.abs(), "{name}: {est:?}");
        assert!(dev.abs() < 4.0, "{name}: {dev:+.2} stderr off");
    }
}

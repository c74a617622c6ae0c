//! The two-mode nanostring's guess off the device, shared by the tests of planning from an
//! uncertain guess (`plan_robust_mc`, `plan_closed_loop`, `plan_cli`), and the measurement
//! point of the planner's Monte Carlo (`plan_mc_support`), and the ratio of two plans' bounds
//! (`plan_closed_loop`, `lab_loop`).

// Each test file uses part of it.
#![allow(dead_code)]

use harmonid_data::Point;
use harmonid_plan::DesignSettings;

/// The guess of `examples/nanostring_2mode` as a lab might hold it: Q1 and Q2 25 % low, β1 and
/// β2 20–25 % low, both frequencies 0.3 Hz off, g12 right (values file, no uncertainties).
pub const TWO_MODE_GUESS: &str = "[modes.q1]\nf_hz = 207582.3\nQ = 8.5e4\n\
    [modes.q2]\nf_hz = 415841.7\nQ = 4.5e5\n\
    [parameters]\nbeta1 = 2.0e22\nbeta2 = 3.0e23\ng12 = 8.57e22\n";

/// One point named `p0` with the given shape values of modes `q1`, `q2`, ... (none for an
/// empty shape: modal amplitudes). `plan_mc_support` uses it too.
pub fn point(shape: &[f64]) -> Vec<Point> {
    if shape.is_empty() {
        return Vec::new();
    }
    vec![Point {
        name: "p0".into(),
        shape: shape
            .iter()
            .enumerate()
            .map(|(n, &s)| (format!("q{}", n + 1), s))
            .collect(),
    }]
}

/// The two-mode designs of these tests: 0.05 nm, 20 shots, at most 3 measurements, the laser
/// spot at L/10 (shapes 0.309, 0.588), at the guess alone (set `range` for the guess's range).
pub fn two_mode_settings() -> DesignSettings {
    DesignSettings {
        sigma_m: 5e-11,
        shots: 20,
        max_measurements: Some(3),
        points: point(&[0.309, 0.588]),
        ..DesignSettings::default()
    }
}

/// The largest ratio of `ev`'s relative bounds to `reference`'s, and its quantity.
pub fn worst_ratio(
    ev: &harmonid_plan::Evaluation,
    reference: &harmonid_plan::Evaluation,
) -> (f64, String) {
    ev.bounds
        .quantities
        .iter()
        .map(|b| {
            let r = reference
                .bounds
                .quantities
                .iter()
                .find(|x| x.name == b.name)
                .map_or(f64::NAN, |x| b.rel / x.rel);
            (r, b.name.clone())
        })
        .fold((0.0, String::new()), |a, b| {
            if b.0 > a.0 || b.0.is_nan() {
                b
            } else {
                a
            }
        })
}

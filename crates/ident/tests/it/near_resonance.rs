//! The near-resonance test scales with the data: a low-Q resonance swept over more than 5 % of
//! its frequency (the sloshing tank of `../shared/realdata`: Q about 20, drives 0.93 to 1.015
//! of the linear frequency) is identified with the default `near_rel` 0.05, its tones near the
//! sweep's own resonance; a lone tone as far from the nominal one is still refused.

use harmonid_data::{Dataset, Direction, Manifest, Measurement, SweepSpec};
use harmonid_ident::{identify, IdentError, Settings};
use harmonid_sim::NoiseGen;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// The nominal resonance (the model's) 100 Hz; the device's 97 Hz, Q 20.
const MODEL: &str = "mode q1 at 100 Hz\n";
const F0: f64 = 97.0;
const Q: f64 = 20.0;

/// The linear response at `f` (m), 5 shots with 0.1 % noise.
fn measurement(spec: harmonid_data::MeasurementSpec, f: f64, noise: &mut NoiseGen) -> Measurement {
    let mut m = Measurement::zeros(spec, vec![f], vec![], 5);
    let (w0, w) = (TAU * F0, TAU * f);
    let x = 1e3 / Complex64::new(w0 * w0 - w * w, w * w0 / Q);
    for s in 0..5 {
        *m.amplitude_mut(s, 0, 0) = x + noise.complex(1e-3 * x.norm());
    }
    m
}

/// One up sweep over `drives` (Hz), drive level 1 at every step.
fn sweep(drives: &[f64]) -> Dataset {
    let mut sw = SweepSpec::new(
        "slosh",
        Direction::Up,
        drives.iter().map(|&f| vec![f]).collect(),
    );
    sw.drive_levels_v = Some(harmonid_data::PerStep::Same(vec![1.0]));
    sw.drive_phases_rad = Some(harmonid_data::PerStep::Same(vec![0.0]));
    let mut noise = NoiseGen::new(3);
    let ms = drives
        .iter()
        .enumerate()
        .map(|(k, &f)| measurement(sw.step_spec(k), f, &mut noise))
        .collect();
    let mut manifest = Manifest::new("low Q");
    manifest.sweeps.push(sw);
    Dataset::from_parts("slosh", manifest, ms, None).expect("dataset")
}

#[test]
fn a_low_q_sweep_is_near_its_own_resonance() {
    let model = harmonid_model::parse_str(MODEL, "m.hb").expect("model");
    // 93 to 101.5 Hz: the lowest tone 7 % from the nominal 100 Hz, 4.1 % from the sweep's peak.
    let drives: Vec<f64> = (0..18).map(|k| 93.0 + 0.5 * k as f64).collect();
    let ds = sweep(&drives);
    let rep = identify(&model, &ds, &Settings::default());
    assert!(
        !matches!(rep, Err(IdentError::ToneNearNoResonance { .. })),
        "{:?}",
        rep.err()
    );
    let rep = rep.expect("identified");
    let f = rep.modes["q1"].f_hz.value;
    assert!((f - F0).abs() < 0.01, "f = {f}");

    // A tone beyond near_rel of the sweep's own resonance (97 Hz) is refused, naming it.
    let mut far = drives.clone();
    far.insert(0, 92.0);
    let e = identify(&model, &sweep(&far), &Settings::default()).expect_err("far");
    assert!(
        matches!(e, IdentError::ToneNearNoResonance { drive_hz, .. } if drive_hz == 92.0),
        "{e}"
    );
    // A sweep in the resonance's wing (rising to its last step, 93 to 95 Hz) has no peak of
    // its own: its tones are judged against the nominal resonance, and refused.
    let wing: Vec<f64> = (0..5).map(|k| 93.0 + 0.5 * k as f64).collect();
    let e = identify(&model, &sweep(&wing), &Settings::default()).expect_err("wing");
    assert!(matches!(e, IdentError::ToneNearNoResonance { .. }), "{e}");
}

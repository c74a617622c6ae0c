//! A tiny two-mode model and closed-form data for the problem's unit tests.
//!
//! Model: modes `a` (1 kHz, Q 100) and `b` (3 kHz, Q 200) with a Duffing term `beta` and a
//! dispersive coupling `g`. The data are the *linear* response `q = G V / (ω² − Ω² + iΩγ)` at
//! every drive tone (zero at the sidebands), i.e. the exact steady state of the model with
//! `beta = g = 0`, seen at one point with shapes `a: 0.5`, `b: 0.8`. Every equation then holds
//! exactly at the truth, which the tests check to rounding.

use harmonid_data::{Dataset, Manifest, Measurement, MeasurementSpec, Point};
use harmonid_model::Model;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

pub(super) const MODEL: &str =
    "mode a at 1 kHz\nmode b at 3 kHz\nparam beta, g\npotential: beta/4*a^4 + g/2*a^2*b^2\n";
/// True f (Hz) and Q per mode.
pub(super) const F_HZ: [f64; 2] = [1000.0, 3000.0];
pub(super) const Q: [f64; 2] = [100.0, 200.0];
/// True actuator gain per mode (N/kg per drive unit), the same in every measurement.
pub(super) const GAIN: [Complex64; 2] = [Complex64::new(3.0, 1.0), Complex64::new(-2.0, 4.0)];
/// Mode shapes at the single point.
pub(super) const SHAPE: [f64; 2] = [0.5, 0.8];

pub(super) fn model() -> Model {
    harmonid_model::parse_str(MODEL, "tiny.hb").expect("tiny model")
}

/// Linear response of mode `n` at `hz` to a unit force.
pub(super) fn response(n: usize, hz: f64) -> Complex64 {
    let w = 2.0 * PI * F_HZ[n];
    let om = 2.0 * PI * hz;
    Complex64::new(1.0, 0.0) / Complex64::new(w * w - om * om, om * w / Q[n])
}

/// One measurement: name, drives (Hz, mode, level), measured frequencies (Hz).
pub(super) type Design = (&'static str, Vec<(f64, usize, f64)>, Vec<f64>);

/// The measurements: one per mode, and the pair when `with_pair`.
pub(super) fn designs(with_pair: bool) -> Vec<Design> {
    let mut d = vec![
        (
            "single_a",
            vec![(995.0, 0, 1.0), (1005.0, 0, 1.0)],
            vec![985.0, 995.0, 1005.0, 1015.0],
        ),
        (
            "single_b",
            vec![(2990.0, 1, 1.0), (3010.0, 1, 1.0)],
            vec![2970.0, 2990.0, 3010.0, 3030.0],
        ),
    ];
    if with_pair {
        d.push((
            "pair_ab",
            vec![(995.0, 0, 1.0), (1005.0, 0, 1.0), (3005.0, 1, 0.5)],
            vec![985.0, 995.0, 1005.0, 1015.0, 2995.0, 3005.0, 3015.0],
        ));
    }
    d
}

/// The dataset: `shots` shots with Gaussian noise `sigma` (m per quadrature, seeded).
pub(super) fn dataset(with_pair: bool, shots: usize, sigma: f64, seed: u64) -> Dataset {
    let mut manifest = Manifest::new("tiny");
    manifest.points.push(Point {
        name: "p0".into(),
        shape: [("a".to_string(), SHAPE[0]), ("b".to_string(), SHAPE[1])]
            .into_iter()
            .collect(),
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, 1.0).expect("normal");
    let mut measurements = Vec::new();
    for (name, drives, freqs) in designs(with_pair) {
        let spec = MeasurementSpec {
            name: name.to_string(),
            file: None,
            drives_hz: drives.iter().map(|d| d.0).collect(),
            drive_levels_v: Some(drives.iter().map(|d| d.2).collect()),
            drive_phases_rad: Some(vec![0.0; drives.len()]),
            pumps_hz: Vec::new(),
            pump_levels: None,
            pump_phases_rad: None,
            bandwidth_hz: None,
            sweep: None,
        };
        let mut m = Measurement::zeros(spec, freqs.clone(), vec![0], shots);
        for s in 0..shots {
            for (r, &f) in freqs.iter().enumerate() {
                let mut x = Complex64::new(0.0, 0.0);
                for &(hz, n, level) in &drives {
                    if hz == f {
                        x += SHAPE[n] * GAIN[n] * level * response(n, f);
                    }
                }
                let noise = Complex64::new(normal.sample(&mut rng), normal.sample(&mut rng));
                *m.amplitude_mut(s, r, 0) = x + noise * sigma;
            }
        }
        measurements.push(m);
    }
    manifest.measurements = measurements.iter().map(|m| m.spec.clone()).collect();
    Dataset {
        dir: "tiny".into(),
        manifest,
        measurements,
        truth: None,
        notes: Vec::new(),
    }
}

/// True value of every unknown of `prob` (gains the same in every measurement; beta = g = 0).
pub(super) fn truth(prob: &super::Problem) -> Vec<f64> {
    use super::Unknown;
    prob.table
        .unknowns()
        .iter()
        .map(|u| match *u {
            Unknown::OmegaSq(n) => (2.0 * PI * F_HZ[n]).powi(2),
            Unknown::Gamma(n) => 2.0 * PI * F_HZ[n] / Q[n],
            Unknown::Param(_) => 0.0,
            Unknown::Gain { mode, quad, .. } => {
                if quad == 0 {
                    GAIN[mode].re
                } else {
                    GAIN[mode].im
                }
            }
            Unknown::Background { .. } => 0.0,
            Unknown::Force { meas, tone, quad } => {
                let (_, n, level) = designs(true)[meas].1[tone];
                let f = GAIN[n] * level;
                if quad == 0 {
                    f.re
                } else {
                    f.im
                }
            }
        })
        .collect()
}

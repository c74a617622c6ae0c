//! Bad input of the output-error estimator (issue 9): a harmonic balance that fails during the
//! refinement from every start falls back to the pooled linear estimate, with a warning naming
//! the measurement, and nothing is written with NaN.
//!
//! The failure is genuine, not mocked: a mode with a fixed quadratic force `a q²` (potential
//! `a/3 q³`) has no periodic steady state once its amplitude `A` exceeds the escape amplitude,
//! where the static offset `x₀` of `ω²x₀ + a(x₀² + A²/2) = 0` stops being real:
//! `A > ω²/(√2 a)` (7.1 nm here). A dataset whose lines are 30 nm is beyond it, so the
//! harmonic balance finds no steady state from the data, nor by the drive ramp from rest, at
//! any of the refinement's starts (the only model parameter is fixed, so the starts with the
//! parameters at zero are the same one). The same data scaled to 5 nm are below it and get
//! the `ml` estimate: the fallback is caused by the amplitude, nothing else.

use harmonid_data::{Dataset, Manifest, Measurement, MeasurementSpec};
use harmonid_ident::{identify, Report, Settings};
use harmonid_sim::NoiseGen;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// `ω² = (2π · 1 MHz)²`, `a = 3.95e21 /(m s²)`: escape amplitude `ω²/(√2 a)` = 7.1 nm.
const MODEL: &str = "mode q1 at 1 MHz\nparam a = 3.95e21\npotential: a/3*q1^3\n";

/// One measurement "strong_q1": two tones two linewidths either side of `f0`, the lines at the
/// tones with amplitude `amp` (m) and the phase of a linear resonance of quality `q`, and two
/// sidebands at 5 % of it; ten shots with 0.1 % noise.
fn dataset(f0: f64, q: f64, amp: f64) -> Dataset {
    let df = 2.0 * f0 / q;
    let lines = vec![f0 - 3.0 * df, f0 - df, f0 + df, f0 + 3.0 * df];
    let spec = MeasurementSpec {
        name: "strong_q1".into(),
        file: None,
        drives_hz: vec![f0 - df, f0 + df],
        drive_levels_v: Some(vec![1.0, 1.0]),
        drive_phases_rad: Some(vec![0.0, 0.0]),
        pumps_hz: Vec::new(),
        pump_levels: None,
        pump_phases_rad: None,
        bandwidth_hz: None,
        sweep: None,
    };
    let shots = 10;
    let mut m = Measurement::zeros(spec, lines.clone(), vec![], shots);
    let w0 = TAU * f0;
    let mut noise = NoiseGen::new(7);
    for s in 0..shots {
        for (k, &f) in lines.iter().enumerate() {
            let w = TAU * f;
            let chi = 1.0 / Complex64::new(w0 * w0 - w * w, w * w0 / q);
            let size = if k == 1 || k == 2 { amp } else { 0.05 * amp };
            *m.amplitude_mut(s, k, 0) = chi / chi.norm() * size + noise.complex(amp * 1e-3);
        }
    }
    Dataset::from_parts("strong", Manifest::new("beyond escape"), vec![m], None).expect("dataset")
}

/// Every value of the report finite (f, Q, parameters) and no NaN in its JSON.
fn assert_finite(rep: &Report) {
    for (name, m) in &rep.modes {
        assert!(
            m.f_hz.value.is_finite() && m.q.value.is_finite(),
            "{name}: {m:?}"
        );
        assert!(
            m.f_hz.stderr.is_finite() && m.q.stderr.is_finite(),
            "{name}: {m:?}"
        );
    }
    for (name, e) in &rep.parameters {
        assert!(e.value.is_finite() && e.stderr.is_finite(), "{name}: {e:?}");
    }
    let json = rep.to_json();
    assert!(!json.contains("NaN") && !json.contains("null"), "{json}");
    let back = Report::from_json(&json).expect("the result reads back");
    assert_eq!(back.estimator, rep.estimator);
}

#[test]
fn a_harmonic_balance_failing_from_every_start_falls_back_to_the_linear_estimate() {
    let model = harmonid_model::parse_str(MODEL, "quadratic.hb").expect("model");
    let rep = identify(&model, &dataset(1e6, 1e4, 3e-8), &Settings::default()).expect("identify");
    assert_eq!(rep.estimator, "linear", "{:?}", rep.warnings);
    let w = rep
        .warnings
        .iter()
        .find(|w| w.contains("harmonic balance failed"))
        .unwrap_or_else(|| panic!("no warning about the harmonic balance: {:?}", rep.warnings));
    assert!(
        w.contains("\"strong_q1\"") && w.contains("no steady state") && w.contains("linear"),
        "{w}"
    );
    assert_finite(&rep);
    // The result says which unknowns the output-error fit could not fit, why, and what helps.
    let [u] = &rep.unfit[..] else {
        panic!("one unfit group: {:?}", rep.unfit)
    };
    assert_eq!(u.why, harmonid_data::result::UnfitWhy::NoOutputError);
    assert_eq!(u.unknowns, ["f_hz:q1", "Q:q1"]);
    assert!(
        u.detail.contains("no steady state") && u.advice.contains("at a lower drive"),
        "{u:?}"
    );
    // The linear estimate is the one reported: f near the data's resonance.
    let f = rep.modes["q1"].f_hz.value;
    assert!((f / 1e6 - 1.0).abs() < 1e-4, "f = {f}");
    // No Cramér–Rao bound without a forward model.
    assert!(rep.modes["q1"].f_hz.crlb.is_none());

    // Control: below the escape amplitude the same data get the ml estimate.
    let rep = identify(&model, &dataset(1e6, 1e4, 5e-9), &Settings::default()).expect("identify");
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    assert!(
        !rep.warnings
            .iter()
            .any(|w| w.contains("harmonic balance failed")),
        "{:?}",
        rep.warnings
    );
}

//! Cramér–Rao bounds: the forward model's Jacobian against finite differences, and the main
//! physics check, the bounds of the public noisy nanostring dataset against an independent
//! computation.

use harmonid_data::Dataset;
use harmonid_ident::{crlb, Noise};
use harmonid_ident::{ForceModel, ForwardModel, ForwardSettings, Unknown};
use harmonid_sim::{ModeValues, ModelValues};
use num_complex::Complex64;
use std::path::PathBuf;

const MODEL: &str = "
    mode q1 at 207.58 kHz
    mode q2 at 415.84 kHz
    param beta1, beta2, g12
    potential: beta1/4*q1^4 + beta2/4*q2^4 + g12/2*q1^2*q2^2
";

/// The public noisy dataset: the in-repo copy when present, else `../shared` (skipped when
/// neither exists).
fn noisy_dataset() -> Option<Dataset> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    for p in [
        root.join("../../tests/data/nanostring_ls50_2mode_noisy"),
        root.join("../../../shared/data/nanostring_ls50_2mode_noisy"),
    ] {
        if p.exists() {
            return Some(Dataset::load(&p).expect("load the noisy dataset"));
        }
    }
    eprintln!("skipped: nanostring_ls50_2mode_noisy not found in tests/data nor ../shared/data");
    None
}

/// The truth of the dataset as values and forces (`forces[mi][mode][tone]`).
fn truth(ds: &Dataset) -> (ModelValues, Vec<Vec<Vec<Complex64>>>) {
    let t = ds.truth.as_ref().expect("truth.toml");
    let mut v = ModelValues::default();
    for (name, m) in &t.modes {
        v.modes.insert(
            name.clone(),
            ModeValues {
                f_hz: Some(m.f_hz),
                q: Some(m.q),
            },
        );
    }
    v.parameters.insert("beta1".into(), t.eom["q1"]["q1^3"]);
    v.parameters.insert("beta2".into(), t.eom["q2"]["q2^3"]);
    v.parameters.insert("g12".into(), t.eom["q1"]["q1*q2^2"]);
    let forces = ds
        .measurements
        .iter()
        .map(|m| {
            ["q1", "q2"]
                .iter()
                .map(|mode| {
                    let tones = m.spec.drives_hz.len();
                    match t.forces.get(&m.spec.name).and_then(|f| f.get(*mode)) {
                        Some(tf) => (0..tones)
                            .map(|d| Complex64::from_polar(tf.amplitude[d], tf.phase_rad[d]))
                            .collect(),
                        None => vec![Complex64::new(0.0, 0.0); tones],
                    }
                })
                .collect()
        })
        .collect();
    (v, forces)
}

/// The forward model's Jacobian (every column) against central differences of its
/// predictions; returns the worst error relative to each column's largest entry.
fn check_jacobian(model_text: &str, force_model: ForceModel) -> f64 {
    let Some(ds) = noisy_dataset() else {
        return 0.0;
    };
    let model = harmonid_model::parse_str(model_text, "nanostring.hb").expect("model");
    let mut fwd =
        ForwardModel::new(&model, &ds, force_model, &ForwardSettings::default()).expect("forward");
    let (values, forces) = truth(&ds);
    let theta = fwd.theta_from(&values, &forces).expect("theta");
    let (no, nk) = (fwd.n_observations(), fwd.unknowns().len());
    let mut x = vec![Complex64::new(0.0, 0.0); no];
    let mut jac = vec![Complex64::new(0.0, 0.0); no * nk];
    fwd.evaluate(&theta, &mut x, Some(&mut jac))
        .expect("evaluate");
    // The prediction at the truth is the noise-free data: the shot mean is within noise.
    let m = &ds.measurements[2];
    let r = m.freq_index(207572.5).expect("drive line");
    let mean: Complex64 = (0..m.n_shots)
        .map(|s| m.amplitude(s, r, 0))
        .sum::<Complex64>()
        / m.n_shots as f64;
    let o = fwd.observations_of(2).start + r;
    assert!((mean - x[o]).norm() < 1e-10, "{mean} vs {}", x[o]);
    let mut worst: f64 = 0.0;
    for k in 0..nk {
        let col: Vec<Complex64> = (0..no).map(|o| jac[o * nk + k]).collect();
        let dmax = col.iter().map(|z| z.norm()).fold(0.0, f64::max);
        if dmax == 0.0 {
            continue;
        }
        let h = (0..no)
            .filter(|&o| col[o].norm() > 1e-3 * dmax)
            .map(|o| 1e-4 * x[o].norm() / col[o].norm())
            .fold(f64::INFINITY, f64::min);
        let mut eval = |d: f64| {
            let mut t = theta.clone();
            t[k] += d;
            let mut y = vec![Complex64::new(0.0, 0.0); no];
            fwd.evaluate(&t, &mut y, None).expect("evaluate");
            y
        };
        let (xp, xm) = (eval(h), eval(-h));
        let err = (0..no)
            .map(|o| ((xp[o] - xm[o]) / (2.0 * h) - col[o]).norm())
            .fold(0.0, f64::max)
            / dmax;
        println!("{}: relative error {err:.2e}", fwd.label(k));
        worst = worst.max(err);
    }
    worst
}

#[test]
fn forward_jacobian_matches_finite_differences() {
    let worst = check_jacobian(MODEL, ForceModel::GainPerMeasurement);
    assert!(worst < 1e-6, "worst {worst:e}");
    // Q1 fixed while f1 is identified (γ1 = √ω1²/Q1 moves with ω1²), free forces.
    let fixed_q = MODEL.replace("207.58 kHz", "207.58 kHz, Q = 116232");
    let worst = check_jacobian(&fixed_q, ForceModel::Free);
    assert!(worst < 1e-6, "worst {worst:e}");
}

#[test]
fn public_noisy_dataset_bounds_match_the_independent_computation() {
    let Some(ds) = noisy_dataset() else {
        return;
    };
    let model = harmonid_model::parse_str(MODEL, "nanostring.hb").expect("model");
    let mut fwd = ForwardModel::new(
        &model,
        &ds,
        ForceModel::GainPerMeasurement,
        &ForwardSettings::default(),
    )
    .expect("forward model");
    assert_eq!(
        fwd.unknowns()
            .iter()
            .filter(|u| matches!(u, Unknown::Gain { .. }))
            .count(),
        8,
        "one complex gain per mode and measurement"
    );
    let (values, forces) = truth(&ds);
    let theta = fwd.theta_from(&values, &forces).expect("theta");
    let b = crlb(&mut fwd, &theta, &Noise::Uniform(1e-10), 1).expect("bounds");
    let want = [
        ("f_hz:q1", 3.3e-6),
        ("Q:q1", 0.087),
        ("beta1", 0.39),
        ("f_hz:q2", 3.9e-6),
        ("Q:q2", 0.63),
        ("beta2", 2.0),
        ("g12", 0.21),
    ];
    println!("condition {:.2e}", b.condition);
    let mut bad = Vec::new();
    for (name, rel) in want {
        let got = b.get(name).expect(name).rel;
        println!(
            "{name}: {got:.3e} (independent {rel:.2e}, ratio {:.3})",
            got / rel
        );
        if (got / rel - 1.0).abs() > 0.1 {
            bad.push(name);
        }
    }
    assert!(b.unidentifiable.is_empty(), "{:?}", b.unidentifiable);
    assert!(bad.is_empty(), "outside 10 %: {bad:?}");
    // N shots: bounds shrink as 1/√N.
    let b20 = crlb(&mut fwd, &theta, &Noise::Uniform(1e-10), 20).expect("bounds");
    let r = b20.get("g12").expect("g12").rel / b.get("g12").expect("g12").rel;
    assert!((r - 20f64.sqrt().recip()).abs() < 1e-9, "{r}");
}

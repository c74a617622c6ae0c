//! Reads the shared datasets of `../shared/data` when they exist (skipped otherwise).

use harmonid_data::Dataset;
use harmonid_ident::{identify, ForceModel, Settings};
use std::path::PathBuf;

fn shared(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} not found", p.display());
        None
    }
}

#[test]
fn reads_the_shared_nanostring_datasets() {
    let Some(dir) = shared("nanostring_ls50_2mode_noisy") else {
        return;
    };
    let ds = Dataset::load(&dir).expect("load noisy dataset");
    assert_eq!(ds.measurements.len(), 3);
    let m = ds.measurement("couple_q1_q2").expect("couple");
    assert_eq!(m.n_shots, 50);
    assert_eq!(m.freqs_hz.len(), 19);
    assert_eq!(m.points, vec![0]);
    let t = ds.truth.as_ref().expect("truth");
    assert_eq!(t.modes["q1"].q, 116232.0);
    assert_eq!(t.eom["q2"]["q2^3"], 3.7e23);
    assert_eq!(t.noise.as_ref().and_then(|n| n.shots), Some(50));
    let Some(dir) = shared("nanostring_ls50_2mode") else {
        return;
    };
    let ds = Dataset::load(&dir).expect("load noise-free dataset");
    let m = ds.measurement("single_q1").expect("single_q1");
    assert_eq!(m.n_shots, 1);
    assert_eq!(m.freqs_hz.len(), 10);
    assert_eq!(m.freqs_hz[0], 207492.5);
    assert!((m.amplitude(0, 0, 0).re - 6.523944823886086e-17).abs() < 1e-30);
}

#[test]
fn quick_look() {
    let model = harmonid_model::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/nanostring_2mode/model.hb"),
    )
    .expect("model");
    for name in ["nanostring_ls50_2mode", "nanostring_ls50_2mode_noisy"] {
        let Some(dir) = shared(name) else {
            return;
        };
        let ds = Dataset::load(&dir).expect("load");
        for fm in [ForceModel::Auto, ForceModel::Free] {
            let settings = Settings {
                force_model: fm,
                ..Settings::default()
            };
            let r = identify(&model, &ds, &settings).expect("identify");
            eprintln!("{name} {fm:?}\n{}", r.summary(ds.truth.as_ref()));
        }
    }
}

//! Harmonic balance against the independent dataset `nanostring_ls50_2mode` (the copy in
//! `tests/data`): every complex amplitude above 1 % of the largest must agree to 1e-3 relative.
//! The first row of the README's accuracy table.

use harmonid::sim::{self, Excitation, HbSettings, ModelValues, NumericModel};
use num_complex::Complex64;
use std::path::{Path, PathBuf};

fn dataset_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/nanostring_ls50_2mode")
}

struct Meas {
    name: String,
    drives: Vec<f64>,
    rows: Vec<(f64, Complex64)>,
}

fn load(dir: &Path) -> (NumericModel, ModelValues, toml::Value, Vec<Meas>, Vec<f64>) {
    let truth_txt = std::fs::read_to_string(dir.join("truth.toml")).expect("truth.toml");
    let truth: toml::Value = toml::from_str(&truth_txt).expect("truth parses");
    let mut values = ModelValues::default();
    for (k, v) in truth["modes"].as_table().expect("modes") {
        values.modes.insert(
            k.clone(),
            sim::ModeValues {
                f_hz: v["f_hz"].as_float(),
                q: v["Q"].as_float(),
            },
        );
    }
    for (k, v) in truth["eom"].as_table().expect("eom") {
        let m = v
            .as_table()
            .expect("eom table")
            .iter()
            .map(|(a, b)| (a.clone(), b.as_float().expect("float")))
            .collect();
        values.eom.insert(k.clone(), m);
    }
    let names: Vec<String> = vec!["q1".into(), "q2".into()];
    let model = NumericModel::from_values(&names, &values).expect("model");
    let manifest: toml::Value =
        toml::from_str(&std::fs::read_to_string(dir.join("dataset.toml")).expect("manifest"))
            .expect("parses");
    let shape_t = manifest["point"][0]["shape"].as_table().expect("shape");
    let shape: Vec<f64> = names
        .iter()
        .map(|n| shape_t[n].as_float().expect("float"))
        .collect();
    let mut meas = Vec::new();
    for m in manifest["measurement"].as_array().expect("measurements") {
        let name = m["name"].as_str().expect("name").to_string();
        let drives: Vec<f64> = m["drives_hz"]
            .as_array()
            .expect("drives")
            .iter()
            .map(|x| x.as_float().expect("f"))
            .collect();
        let csv =
            std::fs::read_to_string(dir.join(m["file"].as_str().expect("file"))).expect("csv");
        let rows = csv
            .lines()
            .skip(1)
            .map(|l| {
                let c: Vec<f64> = l.split(',').map(|x| x.parse().expect("number")).collect();
                (c[1], Complex64::new(c[2], c[3]))
            })
            .collect();
        meas.push(Meas { name, drives, rows });
    }
    (model, values, truth, meas, shape)
}

fn excitation(truth: &toml::Value, m: &Meas, n_modes: &[&str]) -> Excitation {
    let force = n_modes
        .iter()
        .map(|mode| match truth["forces"][&m.name].get(*mode) {
            Some(t) => {
                let a = t["amplitude"].as_array().expect("amplitude");
                let p = t["phase_rad"].as_array().expect("phase");
                a.iter()
                    .zip(p)
                    .map(|(a, p)| {
                        Complex64::from_polar(a.as_float().expect("f"), p.as_float().expect("f"))
                    })
                    .collect()
            }
            None => vec![Complex64::new(0.0, 0.0); m.drives.len()],
        })
        .collect();
    Excitation {
        pumps: Vec::new(),
        tones_hz: m.drives.clone(),
        force,
    }
}

#[test]
fn hb_reproduces_the_independent_dataset() {
    let (model, _values, truth, meas, shape) = load(&dataset_dir());
    for m in &meas {
        let drive = excitation(&truth, m, &["q1", "q2"]);
        let mut s = HbSettings::default();
        s.lattice.extra_hz = m.rows.iter().map(|r| r.0).collect();
        let st = sim::steady_state(&model, &drive, &s).expect("solve");
        assert!(
            st.converged(),
            "{}: {:?} residual {}",
            m.name,
            st.status,
            st.residual
        );
        let biggest = m.rows.iter().map(|r| r.1.norm()).fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for &(f, want) in &m.rows {
            let got = st.at_point(&shape, f);
            if want.norm() >= 0.01 * biggest {
                let rel = (got - want).norm() / want.norm();
                worst = worst.max(rel);
                assert!(
                    rel <= 1e-3,
                    "{} at {f} Hz: {got} vs {want} (rel {rel:.2e})",
                    m.name
                );
            }
        }
        eprintln!(
            "{}: lattice {} lines, {} ramp steps, residual {:.1e}, worst rel. error {worst:.2e}",
            m.name,
            st.lattice_hz.len(),
            st.ramp_steps,
            st.residual
        );
    }
}

//! `harmonid check` through the real binary: golden readable, LaTeX and JSON outputs of every
//! example, and the "done when" facts of issue 2 asserted on the JSON.

use serde_json::Value;
use std::process::Command;

const EXAMPLES: &[&str] = &[
    "nanostring_2mode",
    "nanostring_5mode",
    "three_wave",
    "cubic_3mode",
    "membrane_4mode",
];

fn check(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("check")
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("NO_COLOR", "1")
        .output()
        .expect("the harmonid binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json_of(example: &str) -> Value {
    let path = format!("examples/{example}/model.hb");
    let (ok, stdout, stderr) = check(&[&path, "--json"]);
    assert!(ok, "{stderr}");
    serde_json::from_str(&stdout).expect("valid JSON")
}

#[test]
fn golden_outputs_of_every_example() {
    for ex in EXAMPLES {
        let path = format!("examples/{ex}/model.hb");
        for (flag, suffix) in [
            (None, "text"),
            (Some("--latex"), "latex"),
            (Some("--json"), "json"),
        ] {
            let mut args = vec![path.as_str()];
            args.extend(flag);
            let (ok, stdout, stderr) = check(&args);
            assert!(ok, "{ex} {suffix}: {stderr}");
            assert!(
                stderr.is_empty(),
                "{ex} {suffix}: unexpected stderr {stderr}"
            );
            insta::assert_snapshot!(format!("check_{ex}_{suffix}"), stdout);
        }
    }
}

#[test]
fn nanostring_5mode_has_15_unknowns_and_unit_factors() {
    let j = json_of("nanostring_5mode");
    let modes = j["modes"].as_array().expect("modes list");
    assert_eq!(modes.len(), 5);
    let params = j["parameters"].as_object().expect("parameters");
    assert_eq!(params.len(), 15);
    assert!(params.values().all(|p| p["kind"] == "unknown"));
    let eom = j["eom"].as_object().expect("eom");
    for i in 1..=5usize {
        let eq = eom[&format!("q{i}")].as_object().expect("equation");
        let mut expected = vec![(format!("q{i}^3"), format!("beta{i}"))];
        for k in (1..=5).filter(|&k| k != i) {
            let (a, b) = (i.min(k), i.max(k));
            // Monomial name: factors in declaration order, q_i to the first power, q_k squared.
            let mono = if i < k {
                format!("q{i}*q{k}^2")
            } else {
                format!("q{k}^2*q{i}")
            };
            expected.push((mono, format!("g{a}{b}")));
        }
        assert_eq!(eq.len(), expected.len(), "q{i}: {eq:?}");
        for (mono, param) in expected {
            let coeff = eq[&mono]
                .as_object()
                .unwrap_or_else(|| panic!("q{i} lacks {mono}"));
            assert_eq!(coeff.len(), 1, "q{i} {mono}: {coeff:?}");
            assert_eq!(coeff[&param], 1.0, "q{i} {mono}");
        }
    }
}

#[test]
fn three_wave_terms_follow_from_the_potential() {
    let j = json_of("three_wave");
    let eom = &j["eom"];
    assert_eq!(eom["q1"]["q2*q3"]["kappa"], 1.0);
    assert_eq!(eom["q2"]["q1*q3"]["kappa"], 1.0);
    assert_eq!(eom["q3"]["q1*q2"]["kappa"], 1.0);
    for i in 1..=3 {
        assert_eq!(
            eom[format!("q{i}")][format!("q{i}^3")][format!("beta{i}")],
            1.0
        );
        assert_eq!(eom[format!("q{i}")].as_object().map(|o| o.len()), Some(2));
    }
    // The process is resonant: f3 = f1 + f2 in the example's nominal frequencies.
    let f: Vec<f64> = j["modes"]
        .as_array()
        .expect("modes")
        .iter()
        .map(|m| m["nominal_hz"].as_f64().expect("nominal frequency"))
        .collect();
    assert_eq!(f[0] + f[1], f[2]);
}

#[test]
fn cubic_3mode_spreads_mu_with_exact_factors() {
    let j = json_of("cubic_3mode");
    let eom = &j["eom"];
    assert_eq!(eom["q1"]["q1*q2*q3"]["mu"], 1.0);
    assert_eq!(eom["q2"]["q1^2*q3"]["mu"], 0.5);
    assert_eq!(eom["q3"]["q1^2*q2"]["mu"], 0.5);
    assert_eq!(j["modes"][0]["Q"], 2e4);
    assert_eq!(j["modes"][1]["Q"], Value::Null);
}

#[test]
fn nanostring_2mode_matches_the_shared_dataset_names() {
    let j = json_of("nanostring_2mode");
    let eom = &j["eom"];
    // The monomials and parameter names of tests/data/nanostring_ls50_2mode/truth.toml.
    assert_eq!(eom["q1"]["q1^3"]["beta1"], 1.0);
    assert_eq!(eom["q1"]["q1*q2^2"]["g12"], 1.0);
    assert_eq!(eom["q2"]["q1^2*q2"]["g12"], 1.0);
    assert_eq!(eom["q2"]["q2^3"]["beta2"], 1.0);
    assert_eq!(j["modes"][0]["nominal_hz"], 207580.0);
    assert_eq!(j["modes"][1]["nominal_hz"], 415840.0);
}

#[test]
fn every_truth_monomial_of_the_independent_datasets_is_in_the_2mode_model() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let entries = std::fs::read_dir(&dir).expect("tests/data");
    let j = json_of("nanostring_2mode");
    let mut checked = 0;
    for e in entries.filter_map(Result::ok) {
        let Ok(truth) = std::fs::read_to_string(e.path().join("truth.toml")) else {
            continue;
        };
        if !e.file_name().to_string_lossy().contains("2mode") {
            continue;
        }
        // Lines like `"q1*q2^2" = 8.57e+22` under [eom.qN].
        let mut mode = String::new();
        for line in truth.lines() {
            let line = line.trim();
            if let Some(m) = line.strip_prefix("[eom.").and_then(|l| l.strip_suffix(']')) {
                mode = m.to_string();
            } else if line.starts_with('[') {
                mode.clear();
            } else if !mode.is_empty() && line.starts_with('"') {
                let mono = line.split('"').nth(1).unwrap_or("");
                assert!(
                    j["eom"][&mode][mono].is_object(),
                    "{}: {mode} {mono} is not a term of the model",
                    e.path().display()
                );
                checked += 1;
            }
        }
    }
    eprintln!("checked {checked} truth monomials");
    assert_eq!(checked, 8, "4 monomials in each of the two datasets");
}

#[test]
fn non_affine_models_are_printed_but_flagged() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("softening.hb");
    std::fs::write(&path, "mode q1 at 1 MHz\nparam g\npotential: g^2/4*q1^4\n").expect("write");
    let p = path.to_str().expect("UTF-8 path");
    let (ok, stdout, _) = check(&[p]);
    assert!(ok, "legal for simulation, so check succeeds");
    assert!(
        stdout.contains("q1'' + (w1/Q1) q1' + w1^2 q1 + g^2 q1^3 = F1(t)"),
        "{stdout}"
    );
    assert!(stdout.contains("identification: NOT possible"), "{stdout}");
    assert!(
        stdout.contains("the coefficient of q1^3 in the equation of q1 is g^2"),
        "{stdout}"
    );
    let (ok, stdout, stderr) = check(&[p, "--json"]);
    assert!(ok);
    let j: Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(j["identifiable"], false);
    assert_eq!(j["eom"]["q1"]["q1^3"]["g^2"], 1.0);
    assert!(stderr.contains("cannot be identified"), "{stderr}");
}

#[test]
fn broken_model_fails_with_a_located_message() {
    let (ok, _, stderr) = check(&["tests/fixtures/broken/unknown_name.hb"]);
    assert!(!ok);
    assert!(stderr.contains("unknown name `beta`"), "{stderr}");
    assert!(stderr.contains("unknown_name.hb:3:12"), "{stderr}");
    let (ok, _, stderr) = check(&["examples/nanostring_2mode/model.hb", "--json", "--latex"]);
    assert!(!ok, "--json and --latex exclude each other: {stderr}");
}

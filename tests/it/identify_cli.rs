//! `harmonid identify` end to end: a simulated dataset written to disk, the result JSON and the
//! per-shot CSV; bad inputs give clear errors naming the file (and row) and never leave a
//! result file behind.

use harmonid_testgen as gen;

use gen::{nanostring_2mode_plan, simulate};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn model_path() -> PathBuf {
    root().join("examples/nanostring_2mode/model.hb")
}

/// The nanostring drive plan, simulated with `shots` noisy shots, written into `dir`.
fn write_dataset(dir: &Path, shots: usize, sigma: f64) {
    let model = harmonid_model::load(&model_path()).expect("model");
    let (v, d) = nanostring_2mode_plan();
    let ds = simulate(&model, &v, &d, &[0.309, 0.588], sigma, shots, 11);
    ds.write(dir).expect("write dataset");
}

fn identify(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("identify")
        .args(args)
        .output()
        .expect("run harmonid");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn writes_result_json_and_per_shot_csv() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let ds = tmp.path().join("ds");
    write_dataset(&ds, 6, 2e-13);
    let out = tmp.path().join("result.json");
    let shots = tmp.path().join("shots.csv");
    let (ok, stdout, stderr) = identify(&[
        model_path().to_str().expect("utf8"),
        ds.to_str().expect("utf8"),
        "--out",
        out.to_str().expect("utf8"),
        "--per-shot",
        shots.to_str().expect("utf8"),
    ]);
    assert!(ok, "stderr: {stderr}");
    assert!(
        stdout.contains("f_q1 [Hz]") && stdout.contains("stage 2"),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).expect("result")).expect("json");
    assert_eq!(json["format"], "harmonid-result/1");
    let f1 = json["modes"]["q1"]["f_hz"]["value"].as_f64().expect("f1");
    assert!((f1 / 207582.0 - 1.0).abs() < 1e-7, "{f1}");
    let q1 = json["modes"]["q1"]["Q"]["value"].as_f64().expect("Q1");
    assert!((q1 / 116232.0 - 1.0).abs() < 0.05, "{q1}");
    let g = json["parameters"]["g12"]["value"].as_f64().expect("g12");
    assert!((g / 8.57e22 - 1.0).abs() < 0.05, "{g}");
    assert!(json["parameters"]["g12"]["std"].as_f64().expect("std") > 0.0);
    let b = json["eom"]["q2"]["q1^2*q2"].as_f64().expect("eom");
    assert!((b / 8.57e22 - 1.0).abs() < 0.05, "{b}");
    let forces = &json["forces"]["couple_q1_q2"];
    assert_eq!(forces["q1"].as_array().map(Vec::len), Some(2));
    let amp = forces["q2"][0]["amplitude"].as_f64().expect("force");
    assert!((amp / 1.81 - 1.0).abs() < 0.05, "{amp}");
    let csv = std::fs::read_to_string(&shots).expect("csv");
    assert_eq!(csv.lines().count(), 7);
    assert!(csv.starts_with("shot,f_hz:q1,Q:q1,f_hz:q2,Q:q2,beta1,beta2,g12,outlier"));
    // --joint and --free-forces run too.
    let (ok, stdout, stderr) = identify(&[
        model_path().to_str().expect("utf8"),
        ds.to_str().expect("utf8"),
        "--joint",
        "--free-forces",
    ]);
    assert!(ok, "stderr: {stderr}");
    assert!(stdout.contains("stage 0"), "{stdout}");
}

/// Runs identify on a broken copy of a valid dataset; expects failure naming `needles` and no
/// result file.
fn expect_failure(edit: impl FnOnce(&Path), needles: &[&str]) {
    let tmp = tempfile::tempdir().expect("tempdir");
    let ds = tmp.path().join("ds");
    write_dataset(&ds, 2, 0.0);
    edit(&ds);
    let out = tmp.path().join("result.json");
    let (ok, _, stderr) = identify(&[
        model_path().to_str().expect("utf8"),
        ds.to_str().expect("utf8"),
        "--out",
        out.to_str().expect("utf8"),
    ]);
    assert!(!ok, "should fail: expected {needles:?}");
    // miette wraps long messages: compare with line breaks and gutters removed.
    let stderr = stderr
        .replace(['│', '×'], " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    for n in needles {
        assert!(stderr.contains(n), "expected {n:?} in:\n{stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.exists(), "no result file may be written on failure");
}

fn edit_file(path: &Path, f: impl FnOnce(String) -> String) {
    let text = std::fs::read_to_string(path).expect("read");
    std::fs::write(path, f(text)).expect("write");
}

#[test]
fn bad_inputs_are_clear_errors() {
    // NaN in a value: file and row.
    expect_failure(
        |d| {
            edit_file(&d.join("single_q1.csv"), |t| {
                let mut lines: Vec<String> = t.lines().map(str::to_string).collect();
                let mut f: Vec<String> = lines[3].split(',').map(str::to_string).collect();
                f[3] = "NaN".into();
                lines[3] = f.join(",");
                lines.join("\n") + "\n"
            })
        },
        &["single_q1.csv", "row 4", "not finite"],
    );
    // Missing column.
    expect_failure(
        |d| edit_file(&d.join("single_q2.csv"), |t| t.replacen(",im", ",imag", 1)),
        &["single_q2.csv", "missing column \"im\""],
    );
    // A shot with a different frequency set.
    expect_failure(
        |d| {
            edit_file(&d.join("couple_q1_q2.csv"), |t| {
                let mut lines: Vec<&str> = t.lines().collect();
                lines.pop();
                lines.join("\n") + "\n"
            })
        },
        &["couple_q1_q2.csv", "shot 1"],
    );
    // A drive frequency that is not measured.
    expect_failure(
        |d| {
            edit_file(&d.join("dataset.toml"), |t| {
                t.replacen("207572.5", "207573.5", 1)
            })
        },
        &[
            "drive frequency 207573.5",
            "not among its measured frequencies",
        ],
    );
    // A mode the model does not declare.
    expect_failure(
        |d| {
            edit_file(&d.join("dataset.toml"), |t| {
                t.replace("q2 = 415", "q7 = 415")
            })
        },
        &["dataset.toml", "\"q7\" is not declared by the model"],
    );
    // Tones near no resonance.
    expect_failure(
        |d| {
            edit_file(&d.join("dataset.toml"), |t| {
                t.replace("q2 = 415", "q2 = 300000.0 # was 415")
            })
        },
        &["near no resonance", "415831.5"],
    );
    // Too few measured frequencies for the unknowns.
    expect_failure(
        |d| {
            edit_file(&d.join("single_q1.csv"), |t| {
                t.lines()
                    .filter(|l| {
                        l.starts_with("shot")
                            || l.contains(",207572.5,")
                            || l.contains(",207592.5,")
                    })
                    .collect::<Vec<_>>()
                    .join("\n")
                    + "\n"
            })
        },
        &["single_q1", "real equations", "5 unknowns"],
    );
}

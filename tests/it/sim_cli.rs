//! `harmonid simulate` and `harmonid sweep` end to end: the nanostring example model, a values
//! file and a measurement plan (the three measurements of `nanostring_ls50_2mode`).

use harmonid::data::Dataset;
use std::process::Command;

const VALUES: &str = r#"
[modes.q1]
f_hz = 207582.0
Q = 116232.0

[modes.q2]
f_hz = 415842.0
Q = 599173.0

[parameters]
beta1 = 2.68e22
beta2 = 3.70e23
g12 = 8.57e22
"#;

const PLAN: &str = r#"
description = "nanostring, three measurements of the two-mode identification"
displacement_unit = "m"

[[point]]
name = "p0"
shape = { q1 = 0.3090169943749474, q2 = 0.5877852522924731 }

[[measurement]]
name = "single_q1"
drives_hz = [207572.5, 207592.5]
force = { q1 = [3.5, 3.5] }
measure_hz = [207492.5, 207512.5, 207532.5, 207552.5, 207572.5, 207592.5, 207612.5, 207632.5, 207652.5, 207672.5]

[[measurement]]
name = "single_q2"
drives_hz = [415831.5, 415851.5]
force = { q2 = [1.81, 1.81] }
measure_hz = [415751.5, 415771.5, 415791.5, 415811.5, 415831.5, 415851.5, 415871.5, 415891.5, 415911.5, 415931.5]

[[measurement]]
name = "couple_q1_q2"
drives_hz = [207572.5, 207592.5, 415841.5]
force = { q1 = [3.5, 3.5, 0.0], q2 = [0.0, 0.0, 1.81] }
measure_hz = [207492.5, 207512.5, 207532.5, 207552.5, 207572.5, 207592.5, 207612.5, 207632.5, 207652.5, 207672.5, 415761.5, 415781.5, 415801.5, 415821.5, 415841.5, 415861.5, 415881.5, 415901.5, 415921.5]
"#;

fn model_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_2mode/model.hb")
}

#[test]
fn simulate_writes_a_dataset_matching_the_reference() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("values.toml"), VALUES).expect("write");
    std::fs::write(dir.path().join("plan.toml"), PLAN).expect("write");
    let out = dir.path().join("ds");
    let st = simulate_in(dir.path(), &["--check-stability"]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(st.status.success(), "{err}");
    // The three measurements of the shared dataset are stable states (its README).
    for name in ["single_q1", "single_q2", "couple_q1_q2"] {
        assert!(err.contains(&format!("{name}: stable")), "{err}");
    }
    assert!(!err.contains("UNSTABLE"), "{err}");
    let ds = Dataset::load(&out).expect("the written dataset loads");
    assert_eq!(ds.measurements.len(), 3);
    let truth = ds.truth.as_ref().expect("truth.toml");
    assert_eq!(truth.eom["q1"]["q1*q2^2"], 8.57e22);
    assert_eq!(
        truth.forces["couple_q1_q2"]["q2"].amplitude,
        vec![0.0, 0.0, 1.81]
    );
    // Against the independent generator's dataset (the copy in tests/data).
    let shared =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/nanostring_ls50_2mode");
    let reference = Dataset::load(&shared).expect("reference loads");
    for m in &reference.measurements {
        let ours = ds.measurement(&m.spec.name).expect("same measurement");
        let biggest = m.data.iter().map(|z| z.norm()).fold(0.0, f64::max);
        for (f, &hz) in m.freqs_hz.iter().enumerate() {
            let want = m.amplitude(0, f, 0);
            let got = ours.amplitude(0, ours.freq_index(hz).expect("frequency"), 0);
            if want.norm() > 0.01 * biggest {
                assert!(
                    (got - want).norm() < 1e-3 * want.norm(),
                    "{} {hz}: {got} vs {want}",
                    m.spec.name
                );
            }
        }
    }
}

#[test]
fn simulate_refuses_missing_values() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("values.toml"),
        "[parameters]\nbeta1 = 1.0\n",
    )
    .expect("write");
    std::fs::write(dir.path().join("plan.toml"), PLAN).expect("write");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["simulate"])
        .arg(model_path())
        .arg("--values")
        .arg(dir.path().join("values.toml"))
        .arg("--plan")
        .arg(dir.path().join("plan.toml"))
        .arg("--out")
        .arg(dir.path().join("ds"))
        .output()
        .expect("runs");
    assert!(!st.status.success());
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("f_hz of mode q1"), "{err}");
    assert!(!dir.path().join("ds").exists());
}

#[test]
fn unstable_three_tone_state_is_refused_unless_allowed() {
    // The shared dataset's README: with 4.5 N/kg per tone on mode 1 (and 1.81 N/kg on mode 2) the
    // three-tone steady state loses stability, the time-domain run drifting away from it about
    // ×3.8 per 2 s (growth rate ln 3.8 / 2 s ≈ 0.67 /s). Slow-flow Hill's method must agree, and
    // simulate refuses to write it unless asked to.
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("values.toml"), VALUES).expect("write");
    let plan = PLAN.replace("q1 = [3.5, 3.5, 0.0]", "q1 = [4.5, 4.5, 0.0]");
    std::fs::write(dir.path().join("plan.toml"), plan).expect("write");
    let st = simulate_in(dir.path(), &[]);
    let err = String::from_utf8_lossy(&st.stderr).replace(['│', '\n'], " ");
    assert!(!st.status.success(), "{err}");
    assert!(!dir.path().join("ds").exists(), "nothing written");
    assert!(
        err.contains("couple_q1_q2: the steady state is unstable"),
        "{err}"
    );
    assert!(err.contains("--allow-unstable"), "{err}");
    let rate: f64 = err
        .split("grow")
        .nth(1)
        .and_then(|s| s.split_whitespace().nth(1))
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("growth rate in {err}"));
    let want = 3.8f64.ln() / 2.0;
    assert!(
        (rate - want).abs() < 0.2 * want,
        "growth {rate} /s vs ≈{want} /s"
    );
    let st = simulate_in(dir.path(), &["--allow-unstable"]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(st.status.success(), "{err}");
    assert!(err.contains("single_q1: stable"), "{err}");
    assert!(err.contains("couple_q1_q2: UNSTABLE"), "{err}");
    assert!(
        err.contains("warning: couple_q1_q2: the steady state is unstable"),
        "{err}"
    );
    assert!(Dataset::load(dir.path().join("ds")).is_ok());
}

#[test]
fn simulate_reads_values_from_an_identification_result() {
    // identify → result.json → simulate --values result.json: the written truth holds the
    // result's values, read through the typed result file.
    let dir = tempfile::tempdir().expect("tempdir");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let result = dir.path().join("result.json");
    let data = root.join("examples/nanostring_2mode/data");
    harmonid_ok(&[
        "identify".as_ref(),
        model_path().as_os_str(),
        data.as_os_str(),
        "--out".as_ref(),
        result.as_os_str(),
    ]);
    let report = harmonid::ident::Report::from_json(
        &std::fs::read_to_string(&result).expect("result written"),
    )
    .expect("typed result");
    std::fs::write(dir.path().join("plan.toml"), PLAN).expect("write");
    let out = dir.path().join("ds");
    let plan = dir.path().join("plan.toml");
    harmonid_ok(&[
        "simulate".as_ref(),
        model_path().as_os_str(),
        "--values".as_ref(),
        result.as_os_str(),
        "--plan".as_ref(),
        plan.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let truth = Dataset::load(&out).expect("loads").truth.expect("truth");
    assert_eq!(truth.modes["q2"].f_hz, report.modes["q2"].f_hz.value);
    assert_eq!(truth.modes["q1"].q, report.modes["q1"].q.value);
    assert_eq!(
        truth.eom["q1"]["q1*q2^2"], report.parameters["g12"].value,
        "g12 from the result"
    );
    assert_eq!(truth.eom["q2"]["q2^3"], report.parameters["beta2"].value);
}

/// Runs `harmonid ARGS` and asserts it succeeds.
fn harmonid_ok(args: &[&std::ffi::OsStr]) {
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .output()
        .expect("runs");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
}

/// Runs `harmonid simulate` on `dir`'s values.toml and plan.toml into `dir/ds`, plus `extra`.
fn simulate_in(dir: &std::path::Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .env("NO_COLOR", "1")
        .arg("simulate")
        .arg(model_path())
        .arg("--values")
        .arg(dir.join("values.toml"))
        .arg("--plan")
        .arg(dir.join("plan.toml"))
        .arg("--out")
        .arg(dir.join("ds"))
        .args(extra)
        .output()
        .expect("runs")
}

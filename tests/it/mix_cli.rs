//! End-to-end checks of `harmonid mix` on the two-mode nanostring example (the issue's
//! "done when": Table S1 of the method's paper).

use serde_json::Value;
use std::path::Path;
use std::process::Command;

const MODEL: &str = "examples/nanostring_2mode/model.hb";

fn mix(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("mix")
        .args(args)
        .output()
        .expect("the harmonid binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(args: &[&str]) -> Value {
    let (ok, stdout, stderr) = mix(args);
    assert!(ok, "harmonid mix failed: {stderr}");
    serde_json::from_str(&stdout).expect("valid JSON")
}

/// Frequencies (Hz) of the lines of `monomial` in the equation of `eq` near `mode`.
fn near(v: &Value, eq: &str, monomial: &str, mode: &str) -> Vec<f64> {
    let term = v["terms"]
        .as_array()
        .expect("terms")
        .iter()
        .find(|t| t["equation"] == eq && t["monomial"] == monomial)
        .unwrap_or_else(|| panic!("no term {monomial} in the equation of {eq}"));
    term["lines"]
        .as_array()
        .expect("lines")
        .iter()
        .filter(|l| l["near"] == mode)
        .map(|l| l["freq_hz"].as_f64().expect("number"))
        .collect()
}

const W1: f64 = 207582.0;
const W2: f64 = 415842.0;
const D: f64 = 10.0;

fn offsets(hz: &[f64], centre: f64) -> Vec<i64> {
    hz.iter()
        .map(|f| ((f - centre) / D).round() as i64)
        .collect()
}

#[test]
fn table_s1_from_the_command_line() {
    let q1 = format!("q1:{},{}", W1 - D, W1 + D);
    let q2 = format!("q2:{W2}");
    let v = json(&[MODEL, "--drives", &q1, "--drives", &q2, "--json"]);
    // Near ω2: q1²·q2 at ω2 and ω2 ± 2δ; nothing of q1·q2² there.
    assert_eq!(
        offsets(&near(&v, "q2", "q1^2*q2", "q2"), W2),
        vec![-2, 0, 2]
    );
    assert!(near(&v, "q1", "q1*q2^2", "q2").is_empty());
    // Near ω1: q1·q2² at ω1 ± δ; nothing of q1²·q2 there.
    assert_eq!(offsets(&near(&v, "q1", "q1*q2^2", "q1"), W1), vec![-1, 1]);
    assert!(near(&v, "q2", "q1^2*q2", "q1").is_empty());
    // Exact coefficients and combinations as the issue specifies.
    let term = v["terms"]
        .as_array()
        .expect("terms")
        .iter()
        .find(|t| t["monomial"] == "q1^3")
        .expect("q1^3");
    let line = term["lines"]
        .as_array()
        .expect("lines")
        .iter()
        .find(|l| l["combination"] == serde_json::json!([1, 0, 0]))
        .expect("line at f1");
    assert_eq!(line["coefficient"], "3/4*X1^3 + 3/2*X1*X2^2");
    assert_eq!(line["near"], "q1");
    assert_eq!(line["freq_hz"], W1 - D);

    // With q1's own sidebands (ω1 ± 3δ, ± 5δ) the further lines of Table S1 appear.
    let v = json(&[
        MODEL,
        "--drives",
        &q1,
        "--drives",
        &q2,
        "--sidebands",
        "5",
        "--json",
    ]);
    assert_eq!(
        offsets(&near(&v, "q1", "q1*q2^2", "q1"), W1),
        vec![-5, -3, -1, 1, 3, 5]
    );
    let n2 = offsets(&near(&v, "q2", "q1^2*q2", "q2"), W2);
    assert!(n2.contains(&4) && n2.contains(&-4) && n2.contains(&0));
    assert!(near(&v, "q1", "q1*q2^2", "q2").is_empty());
    assert!(near(&v, "q2", "q1^2*q2", "q1").is_empty());
}

#[test]
fn text_markdown_and_latex_render() {
    let base = [
        MODEL,
        "--drives",
        "q1:207572,207592",
        "--drives",
        "q2:415842",
    ];
    let (ok, text, _) = mix(&base);
    assert!(ok);
    assert!(text.contains("Ω1 + Ω3 − Ω2"), "{text}");
    assert!(!text.contains("f1 + f3"), "{text}");
    assert!(text.contains("3/4*X1^3 + 3/2*X1*X2^2"));
    let (ok, md, _) = mix(&[&base[..], &["--markdown"]].concat());
    assert!(
        ok && md.contains("| near q1 (207580 Hz) | Ω1 | 207572.000 | `3/4*X1^3 + 3/2*X1*X2^2` |"),
        "{md}"
    );
    let (ok, tex, _) = mix(&[&base[..], &["--latex"]].concat());
    assert!(
        ok && tex.contains("\\frac{3}{4} X_{1}^{3} + \\frac{3}{2} X_{1} X_{2}^{2}"),
        "{tex}"
    );
    // A narrow window moves everything off resonance.
    let v = json(&[&base[..], &["--window", "1", "--json"]].concat());
    assert!(near(&v, "q1", "q1^3", "q1")
        .iter()
        .all(|f| (f - 207580.0).abs() <= 1.0));
}

#[test]
fn tones_from_a_dataset_measurement() {
    let dir = tempfile::tempdir().expect("tempdir");
    let manifest = r#"format = "harmonid-dataset/1"
[nominal_hz]
q1 = 207582.0
q2 = 415842.0

[[measurement]]
name = "couple"
drives_hz = [207572.0, 207592.0, 415842.0]
"#;
    std::fs::write(dir.path().join("dataset.toml"), manifest).expect("write");
    let d = dir.path().to_str().expect("utf-8 path");
    let v = json(&[MODEL, "--dataset", d, "--measurement", "couple", "--json"]);
    assert_eq!(
        offsets(&near(&v, "q2", "q1^2*q2", "q2"), W2),
        vec![-2, 0, 2]
    );
    assert_eq!(v["nominal_hz"]["q1"], 207582.0);
    let (ok, _, err) = mix(&[MODEL, "--dataset", d, "--measurement", "nope"]);
    assert!(
        !ok && err.contains("no [[measurement]] named `nope`"),
        "{err}"
    );
}

#[test]
fn tones_from_the_independent_dataset() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/nanostring_ls50_2mode");
    let d = dir.to_str().expect("utf-8 path");
    let v = json(&[
        MODEL,
        "--dataset",
        d,
        "--measurement",
        "couple_q1_q2",
        "--json",
    ]);
    assert_eq!(near(&v, "q2", "q1^2*q2", "q2").len(), 3);
}

#[test]
fn bad_input_gives_clear_errors() {
    for (args, want) in [
        (vec!["--drives", "q3:1000"], "`q3`, which is not declared"),
        (vec!["--drives", "q1:0"], "must be a finite number > 0 Hz"),
        (vec!["--drives", "q1:5,5"], "coincide"),
        (vec!["--drives", "q1"], "cannot read --drives"),
        (vec!["--drives", "q1:1e3,x"], "`x` is not a frequency"),
        (vec![], "no tones given"),
        (vec!["--drives", "q1:1,2", "--window=-1"], "window"),
        (vec!["--drives", "q1:1,2", "--sidebands", "99"], "too high"),
    ] {
        let (ok, _, err) = mix(&[&[MODEL][..], &args].concat());
        assert!(!ok, "{args:?} should fail");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let many: Vec<String> = (1..=70).map(|i| (1000 * i).to_string()).collect();
    let arg = format!("q1:{}", many.join(","));
    let (ok, _, err) = mix(&[MODEL, "--drives", &arg]);
    assert!(!ok && err.contains("at most 64 are supported"), "{err}");
}

/// Three-wave mixing (`U = κ q1 q2 q3`, f3 ≈ f1 + f2) with tones on q1 and q2 only: q3 has no
/// tone but responds at Ω2 − Ω1 (Z1) and Ω1 + Ω2 (Z2, its resonance); κ·q2·q3 in the equation of
/// q1 then puts `½X2·Z1 + ½X2·Z2` at Ω1 (`q2·q3 = X2 cos Ω2t · (Z1 cos(Ω2 − Ω1)t + Z2 cos(Ω1 +
/// Ω2)t)`), marked second order via q3; q3's own forcing κ·q1·q2 is first order.
#[test]
fn a_mode_without_tones_responds_through_the_coupling() {
    let model = "examples/three_wave/model.hb";
    let args = [model, "--drives", "q1:1000100", "--drives", "q2:1599960"];
    let v = json(&[&args[..], &["--json"]].concat());
    let z: Vec<(String, f64, String, String)> = v["components"]
        .as_array()
        .expect("components")
        .iter()
        .filter(|c| c["kind"] == "response")
        .map(|c| {
            (
                c["symbol"].as_str().expect("symbol").to_string(),
                c["freq_hz"].as_f64().expect("hz"),
                c["mode"].as_str().expect("mode").to_string(),
                c["name"].as_str().expect("name").to_string(),
            )
        })
        .collect();
    assert_eq!(
        z,
        vec![
            ("Z1".into(), 599860.0, "q3".into(), "Ω2 − Ω1".into()),
            ("Z2".into(), 2600060.0, "q3".into(), "Ω1 + Ω2".into()),
        ]
    );
    let term = |eq: &str, mono: &str| -> Vec<Value> {
        v["terms"]
            .as_array()
            .expect("terms")
            .iter()
            .find(|t| t["equation"] == eq && t["monomial"] == mono)
            .unwrap_or_else(|| panic!("{mono} in the equation of {eq}"))["lines"]
            .as_array()
            .expect("lines")
            .clone()
    };
    let q2q3 = term("q1", "q2*q3");
    let line = q2q3
        .iter()
        .find(|l| l["freq_hz"] == 1000100.0)
        .expect("a line at Ω1");
    assert_eq!(line["coefficient"], "1/2*X2*Z1 + 1/2*X2*Z2");
    assert_eq!(line["near"], "q1");
    assert_eq!(line["name"], "Ω1");
    assert_eq!(line["label"], "f1");
    assert_eq!(line["second_order"], true);
    assert_eq!(line["via"], serde_json::json!(["q3"]));
    // The forcing of q3 (κ·q1·q2 in its equation) is first order; its sum line sits at q3's
    // resonance.
    let q1q2 = term("q3", "q1*q2");
    assert!(q1q2
        .iter()
        .all(|l| l["second_order"] == false && l["via"] == serde_json::json!([])));
    assert!(q1q2
        .iter()
        .any(|l| l["freq_hz"] == 2600060.0 && l["near"] == "q3"));
    let (ok, text, err) = mix(&args);
    assert!(ok, "{err}");
    insta::assert_snapshot!("mix_three_wave_text", text);
}

/// The two-mode nanostring with a tone on q1 only: q2 is forced only parametrically (q1²·q2,
/// q2³ hold q2), so it stays at rest and its terms say so.
#[test]
fn a_mode_forced_only_parametrically_stays_at_rest() {
    let (ok, text, err) = mix(&[MODEL, "--drives", "q1:207572,207592"]);
    assert!(ok, "{err}");
    assert!(
        text.contains(
            "no lines (q2 at rest: no tone, and no term of its equation without it is forced)"
        ),
        "{text}"
    );
    assert!(!text.contains("second order"), "{text}");
}

#[test]
fn velocity_terms_list_their_lines_with_i_and_the_frequencies() {
    // eta1 q1^2 d(q1) under one tone: the lines of q1^3 (Ω1 and 3·Ω1), each i·(1/4 X1^3 ω(X1)):
    // q1^2 q1' = -ω X^3 cos^2 sin = -(ω X^3/4)(sin θ + sin 3θ), a complex amplitude i·ω X^3/4.
    let model = "examples/damped_2mode/model.hb";
    let v = json(&[model, "--drives", "q1:999990", "--json"]);
    let term = v["terms"]
        .as_array()
        .expect("terms")
        .iter()
        .find(|t| t["monomial"] == "q1^2*d(q1)")
        .expect("the damping term");
    assert_eq!(term["velocity_factors"], 1);
    let coefficients: Vec<&str> = term["lines"]
        .as_array()
        .expect("lines")
        .iter()
        .map(|l| l["coefficient"].as_str().expect("text"))
        .collect();
    assert_eq!(coefficients, ["i·(1/4*X1^3*ω(X1))", "i·(1/4*X1^3*ω(X1))"]);
    // The velocity coupling eta12 q2^2 d(q1) with q2 driven too: q1's tone and its
    // intermodulation with twice q2's.
    let v = json(&[
        model,
        "--drives",
        "q1:999990",
        "--drives",
        "q2:1600000",
        "--json",
    ]);
    let lines = near(&v, "q1", "q2^2*d(q1)", "q1");
    assert_eq!(lines, [999990.0]);
    let (ok, text, err) = mix(&[model, "--drives", "q1:999990"]);
    assert!(ok, "{err}");
    assert!(
        text.contains("ω(X) = 2π × the frequency of component X"),
        "{text}"
    );
    let (ok, latex, err) = mix(&[model, "--drives", "q1:999990", "--latex"]);
    assert!(ok, "{err}");
    assert!(
        latex.contains("\\dot{q}_{1}")
            && latex.contains("i\\left(")
            && latex.contains("\\omega_{X_{1}}"),
        "{latex}"
    );
}

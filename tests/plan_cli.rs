//! `harmonid plan --plot`: the figure of a scored plan (the two-mode example's) and its checks.

use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn plan(args: &[&str]) -> (bool, String, String) {
    let ex = root().join("examples/nanostring_2mode");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("plan")
        .arg(ex.join("model.hb"))
        .arg("--values")
        .arg(ex.join("values.toml"))
        .args(["--noise", "0.05nm", "--shots", "20"])
        .args(args)
        .output()
        .expect("runs");
    (
        st.status.success(),
        String::from_utf8_lossy(&st.stdout).into_owned(),
        String::from_utf8_lossy(&st.stderr).into_owned(),
    )
}

#[test]
fn evaluated_plan_is_drawn() {
    let tmp = tempfile::tempdir().expect("tmp");
    let svg = tmp.path().join("plan.svg");
    let png = tmp.path().join("plan.png");
    let example = root().join("examples/nanostring_2mode/plan.toml");
    for out in [&svg, &png] {
        let (ok, stdout, stderr) = plan(&[
            "--evaluate",
            example.to_str().expect("utf8"),
            "--plot",
            out.to_str().expect("utf8"),
        ]);
        assert!(ok, "{stdout}{stderr}");
        assert!(stderr.contains("wrote"), "{stderr}");
    }
    let text = std::fs::read_to_string(&svg).expect("svg written");
    // Three measurements: 10 + 10 + 19 predicted lines, each a dot with its combination; the
    // tones f1, f2 (and f3) as markers; every mode's response curve in the panels near it.
    assert_eq!(text.matches("<circle").count(), 39 + 3, "dots (and legend)");
    let structure = harmonid_plot::svg_structure_without_ticks(&text);
    for label in [
        "single_q1",
        "couple_q1_q2",
        "2f1−f2",
        "f1+f3−f2",
        "q1",
        "q2",
    ] {
        assert!(
            structure.lines().any(|l| l == label),
            "{label} missing:\n{structure}"
        );
    }
    insta::assert_snapshot!("plan_evaluate_structure", structure);
    assert_eq!(&std::fs::read(&png).expect("png")[1..4], b"PNG");
}

#[test]
fn plot_format_and_path_are_checked_first() {
    let example = root().join("examples/nanostring_2mode/plan.toml");
    let ex = example.to_str().expect("utf8");
    let (ok, _, stderr) = plan(&["--evaluate", ex, "--plot", "plan.pdf"]);
    assert!(!ok && stderr.contains("unknown figure format"), "{stderr}");
    // The folder must exist (checked before the plan is scored).
    let missing = root().join("no-such-folder/plan.svg");
    let (ok, _, stderr) = plan(&["--evaluate", ex, "--plot", missing.to_str().expect("utf8")]);
    assert!(!ok && stderr.contains("does not exist"), "{stderr}");
}

/// `plan --values truth.toml` (only `[eom]` coefficients) scores a plan exactly as the values
/// file with the same parameters does: the parameters are solved from the coefficients.
#[test]
fn a_truth_file_is_a_guess() {
    let ex = root().join("examples/nanostring_2mode");
    let truth = root().join("tests/data/nanostring_ls50_2mode/truth.toml");
    let example = ex.join("plan.toml");
    let score = |values: &PathBuf| {
        let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("plan")
            .arg(ex.join("model.hb"))
            .arg("--values")
            .arg(values)
            .args(["--noise", "0.05nm", "--shots", "20", "--evaluate"])
            .arg(&example)
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&st.stderr).into_owned();
        assert!(st.status.success(), "{err}");
        (String::from_utf8_lossy(&st.stdout).into_owned(), err)
    };
    let (from_truth, note) = score(&truth);
    let (from_values, _) = score(&ex.join("values.toml"));
    assert_eq!(from_truth, from_values);
    assert!(
        note.contains("parameters from its 4 [eom] coefficients")
            && note.contains("beta1 = 2.680000e22")
            && !note.contains("warning"),
        "{note}"
    );
}

//! `harmonid plan --plot`: the figure of a scored plan (the two-mode example's) and its checks.

use crate::guess_support;

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

/// A guess with uncertainties: the range is stated (given and default spreads), the plan is
/// written with its bounds at the guess and over devices drawn from the range (table and
/// `--bounds` JSON); `--nominal` designs at the guess alone.
#[test]
fn a_guess_with_uncertainties_is_planned_over_its_range() {
    let tmp = tempfile::tempdir().expect("tmp");
    let guess = tmp.path().join("guess.toml");
    std::fs::write(
        &guess,
        "[modes.q1]\nf_hz = { value = 207582.3, abs_hz = 0.5 }\nQ = { value = 8.5e4, rel = 0.4 }\n\
         [modes.q2]\nf_hz = { value = 415841.7, abs_hz = 0.5 }\nQ = 4.5e5\n\
         [parameters]\nbeta1 = 2.0e22\nbeta2 = { value = 3.0e23, factor = 3 }\ng12 = 8.57e22\n",
    )
    .expect("write");
    let ex = root().join("examples/nanostring_2mode");
    let run = |extra: &[&str]| {
        let out = tmp.path().join("plan.toml");
        let bounds = tmp.path().join("bounds.json");
        let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("plan")
            .arg(ex.join("model.hb"))
            .arg("--values")
            .arg(&guess)
            .args([
                "--noise",
                "0.05nm",
                "--shots",
                "20",
                "--max-measurements",
                "3",
            ])
            .arg("--out")
            .arg(&out)
            .arg("--bounds")
            .arg(&bounds)
            .args(extra)
            .output()
            .expect("runs");
        let stdout = String::from_utf8_lossy(&st.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&st.stderr).into_owned();
        assert!(st.status.success(), "{stdout}{stderr}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&bounds).expect("bounds")).expect("json");
        (stdout, stderr, json)
    };
    let (stdout, stderr, json) = run(&["--draws", "6"]);
    for want in [
        "f_hz:q1 = 2.075823e5 ± 5.0000e-1 (given)",
        "Q:q2 = 4.500000e5 ± 30 % (default: ± 30 %)",
        "beta2 = 3.000000e23 ×/÷ 3 (given)",
        "beta1 = 2.000000e22 ×/÷ 2 (default: ×/÷ 2)",
    ] {
        assert!(stderr.contains(want), "{want}: {stderr}");
    }
    assert!(
        stdout.contains("median") && stdout.contains("worst"),
        "{stdout}"
    );
    assert!(
        stdout.contains("over 6 devices drawn from the range, 6 of them"),
        "{stdout}"
    );
    let over = &json["over_range"];
    assert_eq!(over["draws"], 6);
    assert_eq!(over["failures"].as_array().map(Vec::len), Some(0));
    let worst = over["worst"]["parameters"]["beta2"]
        .as_f64()
        .expect("worst beta2");
    let at_guess = json["parameters"]["beta2"].as_f64().expect("beta2");
    assert!(
        worst
            >= over["median"]["parameters"]["beta2"]
                .as_f64()
                .expect("median")
    );
    assert!(worst.is_finite() && at_guess.is_finite());
    // Over the range every measurement is a drive ladder, and the plan's time counts its levels.
    let written = || std::fs::read_to_string(tmp.path().join("plan.toml")).expect("plan");
    let plan = harmonid::experiment::Plan::from_toml(&written(), "plan.toml").expect("plan");
    assert!(plan
        .measurements
        .iter()
        .all(|m| m.levels == [0.5, 0.75, 1.0]));
    assert!(
        stderr.contains("(3 measurements, 9 with their ladders' levels;"),
        "{stderr}"
    );
    // No draws: no median or worst column (nothing to take them over), and it says so.
    let (stdout, _, _) = run(&["--draws", "0"]);
    assert!(
        !stdout.contains("worst") && !stdout.contains("NaN"),
        "{stdout}"
    );
    assert!(
        stdout.contains("no device drawn from the range: --draws 0"),
        "{stdout}"
    );
    let (stdout, stderr, json) = run(&["--nominal"]);
    assert!(
        !stdout.contains("worst") && !stderr.contains("range"),
        "{stdout}{stderr}"
    );
    assert!(json.get("over_range").is_none());
    let plan = harmonid::experiment::Plan::from_toml(&written(), "plan.toml").expect("plan");
    assert!(
        plan.measurements.iter().all(|m| m.levels.is_empty()),
        "no ladder at the guess alone"
    );
}

/// A malformed uncertainty: the file, the line and what to write; nothing written.
#[test]
fn a_malformed_uncertainty_is_refused_with_its_line() {
    let tmp = tempfile::tempdir().expect("tmp");
    let guess = tmp.path().join("guess.toml");
    let out = tmp.path().join("plan.toml");
    let ex = root().join("examples/nanostring_2mode");
    let values = std::fs::read_to_string(ex.join("values.toml")).expect("values");
    // The values file with `from` replaced by `to`, planned: the error message.
    let refused = |from: &str, to: &str| -> String {
        let text = values.replace(from, to);
        assert_ne!(text, values);
        std::fs::write(&guess, &text).expect("write");
        let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("plan")
            .arg(ex.join("model.hb"))
            .arg("--values")
            .arg(&guess)
            .args(["--noise", "0.05nm", "--shots", "20", "--out"])
            .arg(&out)
            .output()
            .expect("runs");
        assert!(!st.status.success());
        assert!(!out.exists());
        String::from_utf8_lossy(&st.stderr).into_owned()
    };
    for (bad, want) in [
        ("beta2 = { value = 3.7e23, rel = 2 }", "[0, 1)"),
        (
            "beta2 = { value = 3.7e23, fator = 2 }",
            "unknown key `fator`",
        ),
    ] {
        let stderr = refused("beta2 = 3.70e23", bad);
        assert!(
            stderr.contains(want) && stderr.contains("guess.toml") && stderr.contains("line 13"),
            "{stderr}"
        );
    }
    // A spread that reaches a zero quality factor names the quantity and what to do.
    let stderr = refused("Q = 599173.0", "Q = { value = 599173.0, abs = 6e5 }");
    assert!(
        stderr.contains("Q:q2") && stderr.contains("narrow"),
        "{stderr}"
    );
}

/// The lab loop on the command line: a plan from a rough guess (default ranges: weak drives),
/// simulated on the device and identified, then `plan --after` the result: the range is
/// narrowed by the estimates and the next plan drives every mode harder.
#[test]
fn plan_after_a_result_narrows_the_range_and_drives_harder() {
    let tmp = tempfile::tempdir().expect("tmp");
    let ex = root().join("examples/nanostring_2mode");
    let guess = tmp.path().join("guess.toml");
    std::fs::write(&guess, guess_support::TWO_MODE_GUESS).expect("write");
    let harmonid = |args: &[&std::ffi::OsStr]| -> String {
        let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .args(args)
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&st.stderr).into_owned();
        assert!(
            st.status.success(),
            "{args:?}: {}{stderr}",
            String::from_utf8_lossy(&st.stdout)
        );
        stderr
    };
    let p = |name: &str| tmp.path().join(name).into_os_string();
    let model = ex.join("model.hb").into_os_string();
    let os = |s: &str| std::ffi::OsString::from(s);
    let plan_args = |out: &str| {
        vec![
            os("plan"),
            model.clone(),
            os("--values"),
            guess.clone().into_os_string(),
            os("--noise"),
            os("0.05nm"),
            os("--shots"),
            os("20"),
            os("--max-measurements"),
            os("3"),
            os("--point"),
            os("q1=0.309,q2=0.588"),
            os("--draws"),
            os("0"),
            os("--out"),
            p(out),
        ]
    };
    let run = |v: Vec<std::ffi::OsString>| {
        let r: Vec<&std::ffi::OsStr> = v.iter().map(|s| s.as_os_str()).collect();
        harmonid(&r)
    };
    run(plan_args("p0.toml"));
    run(vec![
        os("simulate"),
        model.clone(),
        os("--values"),
        ex.join("values.toml").into_os_string(),
        os("--plan"),
        p("p0.toml"),
        os("--out"),
        p("d0"),
    ]);
    run(vec![
        os("identify"),
        model.clone(),
        p("d0"),
        os("--out"),
        p("r0.json"),
    ]);
    let mut after = plan_args("p1.toml");
    after.extend([os("--after"), p("r0.json")]);
    let stderr = run(after);
    assert!(
        stderr.contains("1 result(s)") && stderr.contains("narrowed by the results"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("linewidths keeps every drive weak"),
        "{stderr}"
    );
    let force = |name: &str, m: &str| -> f64 {
        let text = std::fs::read_to_string(tmp.path().join(name)).expect("plan");
        let plan = harmonid_experiment::Plan::from_toml(&text, name).expect("plan");
        plan.measurements
            .iter()
            .find(|x| x.name == m)
            .and_then(|x| x.force.values().flatten().copied().reduce(f64::max))
            .expect("force")
    };
    for m in ["single_q1", "single_q2"] {
        let (before, after) = (force("p0.toml", m), force("p1.toml", m));
        assert!(
            after > 2.0 * before,
            "{m}: {before} N/kg, then {after} N/kg"
        );
    }
}

/// Instrument settings that cannot be used: volts without a gain, a malformed gain, a grid
/// coarser than a resonance; each names what to give, nothing is written.
#[test]
fn instrument_settings_that_cannot_be_used_are_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("plan.toml");
    for (args, want) in [
        (
            &["--max-voltage", "1"][..],
            "none for q1, q2 (give --gain q1=",
        ),
        (
            &["--gain", "q1=0.8", "--max-voltage", "1"][..],
            "none for q2",
        ),
        (&["--gain", "q1=-2"][..], "--gain q1=-2: expected MODE=GAIN"),
        (
            &["--gain", "q7=2", "--gain", "q1=1", "--gain", "q2=1"][..],
            "a gain for q7",
        ),
        (&["--grid-hz", "2"][..], "coarser than 2 linewidths of q2"),
        (
            &["--ladder", "0.5,0.4,1"][..],
            "the drive ladder must be rising fractions of the forces, each in (0, 1], at most 16 (got [0.5, 0.4, 1.0])",
        ),
        (&["--ladder", "0.5,2"][..], "(got [0.5, 2.0])"),
    ] {
        let mut all = args.to_vec();
        all.extend(["--out", out.to_str().expect("utf8")]);
        let (ok, stdout, stderr) = plan(&all);
        // miette wraps long messages: compare the words.
        let words: Vec<&str> = stderr.split_whitespace().filter(|w| *w != "│").collect();
        assert!(
            !ok && words.join(" ").contains(want),
            "{args:?}: {stdout}{stderr}"
        );
        assert!(!out.exists(), "{args:?}");
    }
}

/// `--noise` takes σ in metres or with a length unit, and refuses what is not a positive length
/// (this was a unit test of the binary's own parser; the binary has no unit tests now).
#[test]
fn noise_units() {
    let example = root().join("examples/nanostring_2mode");
    let evaluate = |noise: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("plan")
            .arg(example.join("model.hb"))
            .arg("--values")
            .arg(example.join("values.toml"))
            .arg(format!("--noise={noise}"))
            .args(["--shots", "20", "--nominal", "--evaluate"])
            .arg(example.join("plan.toml"))
            .output()
            .expect("runs");
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        (
            out.status.success(),
            text,
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (ok, nm, err) = evaluate("0.05nm");
    assert!(ok, "{err}");
    let (ok, pm, err) = evaluate("50 pm");
    assert!(ok, "{err}");
    assert_eq!(nm, pm, "0.05nm and 50 pm are the same σ");
    let (ok, metres, err) = evaluate("1e-10");
    assert!(ok, "{err}");
    assert_ne!(metres, nm, "1e-10 m is twice the σ: other bounds");
    let (ok, _, err) = evaluate("-1nm");
    assert!(!ok && err.contains("not a length"), "{err}");
    let (ok, _, err) = evaluate("0nm");
    assert!(!ok && err.contains("expected a positive σ"), "{err}");
    let (ok, _, err) = evaluate("1 furlong");
    assert!(!ok && err.contains("unknown unit `furlong`"), "{err}");
}

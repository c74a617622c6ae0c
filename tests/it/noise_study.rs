//! `harmonid noise-study` end to end on a small configuration of the default two-mode study:
//! at the lowest noise the estimates match the truth tightly, and the spread grows in
//! proportion to the noise RMS (the identification is linear in the data for small noise).

use std::collections::BTreeMap;
use std::process::Command;

/// `(level, quantity) -> (truth, mean, std, n)` from the CSV (level as `{:.2e}`).
fn read_table(path: &std::path::Path) -> BTreeMap<(String, String), (f64, f64, f64, usize)> {
    let text = std::fs::read_to_string(path).expect("the CSV is written");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).expect(name);
    let (lv, q, t, m, s, n) = (
        col("level"),
        col("quantity"),
        col("truth"),
        col("mean"),
        col("std"),
        col("n"),
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |i: usize| f[i].parse::<f64>().expect("number");
            (
                (format!("{:.2e}", num(lv)), f[q].to_string()),
                (num(t), num(m), num(s), f[n].parse().expect("count")),
            )
        })
        .collect()
}

#[test]
fn noise_study_small_configuration() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("study.csv");
    let model =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_2mode/model.hb");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("noise-study")
        .arg(&model)
        .args([
            "--levels-nm",
            "1e-3,1e-2",
            "--realisations",
            "16",
            "--quiet",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&st.stdout);
    assert!(
        st.status.success(),
        "{}{}",
        stdout,
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(stdout.contains("| beta1 |"), "{stdout}");
    assert!(dir.path().join("study.md").exists());
    let t = read_table(&out);
    let get = |lv: &str, q: &str| t[&(lv.to_string(), q.to_string())];
    for q in ["f_hz(q1)", "f_hz(q2)", "beta1", "beta2", "g12"] {
        let (truth, mean, std, n) = get("1.00e-12", q);
        assert_eq!(n, 16, "{q}");
        // Tight at the lowest noise: mean within 1e-4 and 3σ within 1e-3 of the truth.
        assert!(
            (mean - truth).abs() < 1e-4 * truth,
            "{q}: {mean} vs {truth}"
        );
        assert!(3.0 * std < 1e-3 * truth, "{q}: 3σ = {}", 3.0 * std);
        // Ten times the noise: ten times the spread (within sampling error of 16 draws).
        let (_, _, std10, _) = get("1.00e-11", q);
        let ratio = std10 / std;
        assert!((5.0..20.0).contains(&ratio), "{q}: spread ratio {ratio}");
    }
    // The study's own truth column is the paper's Table S2.
    assert_eq!(get("1.00e-12", "beta1").0, 2.68e22);
    assert_eq!(get("1.00e-12", "g12").0, 8.57e22);
}

#[test]
fn noise_study_refuses_bad_options() {
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["noise-study", "--realisations", "1", "--quiet"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs");
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("at least 2"));
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["noise-study", "--levels-nm=-1", "--quiet"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs");
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("not a noise RMS"));
}

fn noise_study(args: &[&str], cwd: &std::path::Path) -> (bool, String, String) {
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("noise-study")
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs");
    (
        st.status.success(),
        String::from_utf8_lossy(&st.stdout).into_owned(),
        // miette wraps long messages: one line, single spaces.
        String::from_utf8_lossy(&st.stderr)
            .replace('│', " ")
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" "),
    )
}

#[test]
fn noise_study_runs_from_any_folder_and_asd_equals_its_sigma() {
    // The built-in model, values and plan need no repository: run from an empty folder. An
    // amplitude spectral density S through the default lock-in (0.2 s window, boxcar ENBW
    // 1/(2T) = 2.5 Hz) is σ = S·√(2·2.5) = S·√5 per quadrature: the same seeded study.
    let dir = tempfile::tempdir().expect("tempdir");
    let asd = 1e-13;
    let sigma = asd * 5f64.sqrt();
    let (a_csv, s_csv) = (dir.path().join("a.csv"), dir.path().join("s.csv"));
    let common = ["--realisations", "4", "--quiet", "--out"];
    let (ok, out, err) = noise_study(
        &[
            &["--asd", &asd.to_string()],
            &common[..],
            &[a_csv.to_str().expect("utf8")],
        ]
        .concat(),
        dir.path(),
    );
    assert!(ok, "{out}{err}");
    assert!(out.contains("ENBW 2.500 Hz"), "{out}");
    let (ok, out, err) = noise_study(
        &[
            &["--sigma", &format!("{}pm", sigma * 1e12)],
            &common[..],
            &[s_csv.to_str().expect("utf8")],
        ]
        .concat(),
        dir.path(),
    );
    assert!(ok, "{out}{err}");
    let (a, s) = (read_table(&a_csv), read_table(&s_csv));
    assert_eq!(a.len(), s.len());
    for ((_, q), (truth, mean, std, n)) in &a {
        let (_, (t2, m2, s2, n2)) = s
            .iter()
            .find(|((_, q2), _)| q2 == q)
            .expect("same quantity");
        assert_eq!((truth, n), (t2, n2), "{q}");
        assert!(
            (mean - m2).abs() <= 1e-9 * mean.abs() && (std - s2).abs() <= 1e-6 * std,
            "{q}: {mean} ± {std} vs {m2} ± {s2}"
        );
    }
}

#[test]
fn noise_study_refuses_unbounded_or_meaningless_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (args, says) in [
        (
            &["--sample-rate-hz", "1", "--levels-nm", "1"][..],
            "faster than twice",
        ),
        (&["--realisations", "100000000"][..], "at most 10000"),
        (&["--sigma=-1e-12"][..], "not a noise level"),
        (
            &["--sigma", "1e-12", "--time-domain"][..],
            "cannot be used with",
        ),
        (&["--window-s", "nan"][..], "positive time"),
    ] {
        let (ok, out, err) = noise_study(&[args, &["--quiet"][..]].concat(), dir.path());
        assert!(!ok, "{args:?} accepted: {out}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

#[test]
fn noise_study_plot() {
    // Two low noise levels, three realisations: every estimate lies inside its panel, so the
    // count of dots is fixed (7 quantities × 2 levels × 3 realisations, and the legend's).
    let dir = tempfile::tempdir().expect("tempdir");
    let svg = dir.path().join("study.svg");
    let png = dir.path().join("study.png");
    for plot in [&svg, &png] {
        let (ok, out, err) = noise_study(
            &[
                "--sigma",
                "1e-15,1e-14",
                "--realisations",
                "3",
                "--quiet",
                "--plot",
                plot.to_str().expect("utf8"),
            ],
            dir.path(),
        );
        assert!(ok, "{out}{err}");
        assert!(out.contains("wrote"), "{out}");
    }
    let text = std::fs::read_to_string(&svg).expect("svg written");
    assert_eq!(text.matches("<circle").count(), 7 * 2 * 3 + 1);
    insta::assert_snapshot!(
        "noise_study_plot_structure",
        harmonid_plot::svg_structure_without_ticks(&text)
    );
    assert_eq!(&std::fs::read(&png).expect("png written")[1..4], b"PNG");
    // A figure format is checked before the study runs.
    let (ok, _, err) = noise_study(&["--quiet", "--plot", "study.pdf"], dir.path());
    assert!(!ok && err.contains("unknown figure format"), "{err}");
}

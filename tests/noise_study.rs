//! `harmonid noise-study` end to end on a small configuration of the default two-mode study:
//! at the lowest noise the estimates match the truth tightly, and the spread grows in
//! proportion to the noise RMS (the identification is linear in the data for small noise).

use std::collections::BTreeMap;
use std::process::Command;

/// `(level_nm, quantity) -> (truth, mean, std, n)` from the CSV.
fn read_table(path: &std::path::Path) -> BTreeMap<(String, String), (f64, f64, f64, usize)> {
    let text = std::fs::read_to_string(path).expect("the CSV is written");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).expect(name);
    let (lv, q, t, m, s, n) = (
        col("noise_rms_nm"),
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
                (format!("{:e}", num(lv)), f[q].to_string()),
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
        let (truth, mean, std, n) = get("1e-3", q);
        assert_eq!(n, 16, "{q}");
        // Tight at the lowest noise: mean within 1e-4 and 3σ within 1e-3 of the truth.
        assert!(
            (mean - truth).abs() < 1e-4 * truth,
            "{q}: {mean} vs {truth}"
        );
        assert!(3.0 * std < 1e-3 * truth, "{q}: 3σ = {}", 3.0 * std);
        // Ten times the noise: ten times the spread (within sampling error of 16 draws).
        let (_, _, std10, _) = get("1e-2", q);
        let ratio = std10 / std;
        assert!((5.0..20.0).contains(&ratio), "{q}: spread ratio {ratio}");
    }
    // The study's own truth column is the paper's Table S2.
    assert_eq!(get("1e-3", "beta1").0, 2.68e22);
    assert_eq!(get("1e-3", "g12").0, 8.57e22);
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

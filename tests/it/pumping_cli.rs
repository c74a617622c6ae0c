//! Parametric pumping on the command line (issue 20, item 6): `sweep --pump` steps the tone up
//! and down with the pump on, against the closed forms; `simulate` notes a pump-sustained
//! oscillation; what does not take a pump says so and writes nothing.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const MODEL: &str = "mode q1 at 1 kHz\nparam beta1, lambda\n\
                     potential: beta1/4*q1^4\neom q1 += lambda*pump*q1\n";
const VALUES: &str = "[modes.q1]\nf_hz = 1000.0\nQ = 1000.0\n\
                      [parameters]\nbeta1 = 1e12\nlambda = 1.0\n";

fn files(dir: &Path) -> (PathBuf, PathBuf) {
    let m = dir.join("pumped.hb");
    let v = dir.join("values.toml");
    std::fs::write(&m, MODEL).expect("model");
    std::fs::write(&v, VALUES).expect("values");
    (m, v)
}

fn harmonid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .output()
        .expect("runs")
}

/// The parametric threshold λ|P| = 2ω²/Q with λ = 1.
fn threshold() -> f64 {
    2.0 * (TAU * 1000.0f64).powi(2) / 1000.0
}

/// Rows of a CSV as maps from column name to value (`direction` kept as text).
fn rows(csv: &str) -> Vec<std::collections::HashMap<String, String>> {
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    lines
        .map(|l| {
            head.iter()
                .map(|h| h.to_string())
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

fn num(r: &std::collections::HashMap<String, String>, k: &str) -> f64 {
    r[k].parse().unwrap_or_else(|_| panic!("{k}: {}", r[k]))
}

#[test]
fn a_pumped_sweep_follows_the_closed_forms() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (m, v) = files(dir.path());
    let (m, v) = (m.to_str().expect("utf-8"), v.to_str().expect("utf-8"));
    // Below threshold, a weak tone (a linear resonator: no Duffing shift to speak of): at
    // f = f_p/2 the degenerate amplifier, iωγX + (λP/2)X̄ = F.
    let ratio = 0.5;
    let pump = format!("2000:{}", ratio * threshold());
    let out = harmonid(&[
        "sweep", m, "--values", v, "--from", "990", "--to", "1010", "--force", "q1=0.01", "--pump",
        &pump, "--points", "201",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let below = rows(&String::from_utf8_lossy(&out.stdout));
    assert_eq!(below.len(), 402);
    let at = below
        .iter()
        .find(|r| r["direction"] == "up" && (num(r, "f_hz") - 1000.0).abs() < 1e-6)
        .expect("a step at 1000 Hz");
    let wg = (TAU * 1000.0f64).powi(2) / 1000.0;
    let h = 0.5 * ratio * threshold();
    // [h, −ωγ; ωγ, −h][a; b] = [F; 0].
    let det = -h * h + wg * wg;
    let (a, b) = (-h * 0.01 / det, -wg * 0.01 / det);
    let want = a.hypot(b);
    let got = num(at, "q1_f_abs");
    assert!(
        (got / want - 1.0).abs() < 1e-4,
        "|X| {got:e}, closed form {want:e}"
    );
    assert!(below
        .iter()
        .all(|r| r["stable"] == "1" && r["converged"] == "1"));
    // Above threshold, far from f_p/2: the pump sustains the parametron at f_p/2 with
    // a² = (4/3β)·√((λP/2)² − (ω²/Q)²), whatever the weak tone does.
    let ratio = 1.5;
    let pump = format!("2000:{}", ratio * threshold());
    let out = harmonid(&[
        "sweep", m, "--values", v, "--from", "990", "--to", "992", "--force", "q1=0.01", "--pump",
        &pump, "--points", "21",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let h = 0.5 * ratio * threshold();
    let want = (4.0 / 3e12 * (h * h - wg * wg).sqrt()).sqrt();
    for r in rows(&String::from_utf8_lossy(&out.stdout)) {
        let got = num(&r, "q1_half1_abs");
        assert!(
            (got / want - 1.0).abs() < 1e-3,
            "{}: {got:e} vs {want:e}",
            r["f_hz"]
        );
        assert_eq!(r["stable"], "1");
    }
}

#[test]
fn what_takes_no_pump_says_so_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (m, v) = files(dir.path());
    let (m, v) = (m.to_str().expect("utf-8"), v.to_str().expect("utf-8"));
    let csv = dir.path().join("out.csv");
    let csv_s = csv.to_str().expect("utf-8");
    let base = ["sweep", m, "--values", v, "--from", "990", "--to", "1010"];
    for (extra, words) in [
        (
            vec!["--force", "q1=1"],
            vec!["pump terms", "q1*pump", "step by step"],
        ),
        (
            vec!["--force", "q1=1", "--pump", "2000"],
            vec!["--pump 2000", "HZ:LEVEL"],
        ),
        (
            vec!["--force", "q1=1", "--pump", "2000:1e4", "--two-tone", "2"],
            vec!["--two-tone and --pump"],
        ),
    ] {
        let mut args: Vec<&str> = base.to_vec();
        args.extend(extra);
        args.extend(["--out", csv_s]);
        let out = harmonid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        for w in words {
            assert!(err.contains(w), "{w}: {err}");
        }
        assert!(!csv.exists());
    }
    // A pump on a model without pump terms would act on nothing.
    let plain = dir.path().join("plain.hb");
    std::fs::write(
        &plain,
        "mode q1 at 1 kHz\nparam beta1, lambda\npotential: beta1/4*q1^4 + lambda*q1^2\n",
    )
    .expect("model");
    let out = harmonid(&[
        "sweep",
        plain.to_str().expect("utf-8"),
        "--values",
        v,
        "--from",
        "990",
        "--to",
        "1010",
        "--force",
        "q1=1",
        "--pump",
        "2000:1e4",
        "--out",
        csv_s,
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no pump terms"),
        "{err}"
    );
    assert!(!csv.exists());
    let plan = dir.path().join("plan.toml");
    let out = harmonid(&[
        "plan",
        m,
        "--values",
        v,
        "--noise",
        "1e-10",
        "--out",
        plan.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("harmonid::plan::pump"),
        "{err}"
    );
    assert!(!plan.exists());
    let out = harmonid(&["mix", m, "--drives", "q1:1001"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("pump terms"), "{err}");
}

#[test]
fn a_linear_resonator_above_threshold_is_named_a_parametric_instability() {
    // Without the Duffing term nothing limits the parametron: no bounded state, nothing written.
    let dir = tempfile::tempdir().expect("tempdir");
    let m = dir.path().join("linear.hb");
    std::fs::write(
        &m,
        "mode q1 at 1 kHz\nparam lambda\neom q1 += lambda*pump*q1\n",
    )
    .expect("model");
    let v = dir.path().join("values.toml");
    std::fs::write(
        &v,
        "[modes.q1]\nf_hz = 1000.0\nQ = 1000.0\n[parameters]\nlambda = 1.0\n",
    )
    .expect("values");
    let plan = dir.path().join("plan.toml");
    std::fs::write(
        &plan,
        format!(
            "description = \"above\"\ndisplacement_unit = \"m\"\n[[point]]\nname = \"p\"\n\
             shape = {{ q1 = 1.0 }}\n[noise]\nsigma_per_quadrature = 1e-12\nshots = 2\n\
             [[measurement]]\nname = \"above\"\ndrives_hz = [1001.0]\nforce = {{ q1 = [1.0] }}\n\
             pumps_hz = [2000.0]\npump_levels = [{}]\npump_phases_rad = [0.0]\n",
            1.5 * threshold()
        ),
    )
    .expect("plan");
    let out = dir.path().join("out");
    let run = harmonid(&[
        "simulate",
        m.to_str().expect("utf-8"),
        "--values",
        v.to_str().expect("utf-8"),
        "--plan",
        plan.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(err.contains("harmonid::parametric_instability"), "{err}");
    assert!(!out.exists());
}

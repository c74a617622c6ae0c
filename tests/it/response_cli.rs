//! `harmonid response` (issue 38, item 4) and the Hopf column of `harmonid sweep` (item 3):
//! about rest the response and the noise spectrum are the Lorentzians; a driven state has its
//! idler at `2f_d − f_p`; bad input is refused before any work; a driven van der Pol–Duffing
//! sweep names its Hopf points.

use std::path::Path;
use std::process::{Command, Output};

const DUFFING: &str =
    "mode q1 at 1 kHz\nmode q2 at 1.5 kHz\nparam alpha\npotential: alpha/4*q1^4\n";
const VALUES: &str = "[modes.q1]\nf_hz = 1000.0\nQ = 1000.0\n[modes.q2]\nf_hz = 1500.0\nQ = 200.0\n[parameters]\nalpha = 4e15\n";

fn run(dir: &Path, args: &[&str]) -> Output {
    std::fs::write(dir.join("m.hb"), DUFFING).expect("model");
    std::fs::write(dir.join("v.toml"), VALUES).expect("values");
    Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("response")
        .arg(dir.join("m.hb"))
        .arg("--values")
        .arg(dir.join("v.toml"))
        .args(args)
        .output()
        .expect("runs")
}

fn rows(out: &Output) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = String::from_utf8_lossy(&out.stdout);
    let mut lines = text.lines();
    let head = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect();
    (head, rows)
}

#[test]
fn at_rest_the_response_and_noise_are_lorentzians() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = run(
        tmp.path(),
        &[
            "--probe", "q2", "--from", "1400", "--to", "1600", "--points", "21",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(
        tmp.path(),
        &[
            "--probe",
            "q2",
            "--from",
            "1400",
            "--to",
            "1600",
            "--points",
            "21",
            "--probe-force",
            "2",
            "--noise-psd",
            "1e-6",
        ],
    );
    let (head, rows) = rows(&out);
    assert_eq!(
        head,
        [
            "f_probe_hz",
            "q1_signal_abs_m",
            "q1_signal_phase_rad",
            "q2_signal_abs_m",
            "q2_signal_phase_rad",
            "q1_noise_psd_m2_per_hz",
            "q2_noise_psd_m2_per_hz"
        ]
    );
    let (w, g) = (
        std::f64::consts::TAU * 1500.0,
        std::f64::consts::TAU * 1500.0 / 200.0,
    );
    for r in rows {
        let o = std::f64::consts::TAU * r[0];
        let l2 = (w * w - o * o).powi(2) + (o * g).powi(2);
        assert!((r[3] - 2.0 / l2.sqrt()).abs() < 1e-9 * r[3], "{r:?}");
        assert_eq!(r[1], 0.0);
        assert!((r[6] - 1e-6 / l2).abs() < 1e-9 * r[6], "{r:?}");
    }
}

#[test]
fn a_driven_state_has_its_idler() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = run(
        tmp.path(),
        &[
            "--drives", "q1:1008", "--force", "q1=3", "--probe", "q1", "--from", "1000", "--to",
            "1004", "--points", "5",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (head, rows) = rows(&out);
    assert_eq!(head[1], "f_idler_hz");
    for r in &rows {
        assert!((r[1] - (2016.0 - r[0])).abs() < 1e-6, "{r:?}");
        // The idler of q1 is a real fraction of its signal.
        assert!(r[4] > 0.01 * r[2], "{r:?}");
    }
}

#[test]
fn bad_input_is_refused_saying_why() {
    let tmp = tempfile::tempdir().expect("tmp");
    for (args, says) in [
        (
            &["--probe", "q3", "--from", "1", "--to", "2"][..],
            "not a mode",
        ),
        (
            &["--probe", "q1", "--from", "2", "--to", "1"][..],
            "not below --to",
        ),
        (
            &["--probe", "q1", "--from", "1", "--to", "2", "--points", "1"][..],
            "between 2 and",
        ),
        (
            &[
                "--probe", "q1", "--from", "1", "--to", "2", "--points", "10000000",
            ][..],
            "between 2 and",
        ),
        (
            &["--probe", "q1", "--from", "NaN", "--to", "2"][..],
            "finite positive",
        ),
        (
            &[
                "--probe", "q1", "--from", "1", "--to", "2", "--force", "q1=1",
            ][..],
            "without --drives",
        ),
        (
            &[
                "--probe", "q1", "--from", "1", "--to", "2", "--drives", "q1:1000",
            ][..],
            "no --force",
        ),
        (
            &[
                "--probe",
                "q1",
                "--from",
                "1",
                "--to",
                "2",
                "--noise-psd=-1",
            ][..],
            "--noise-psd",
        ),
    ] {
        let out = run(tmp.path(), args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn a_van_der_pol_duffing_sweep_names_its_hopf_points() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path();
    std::fs::write(
        d.join("vdp.hb"),
        "mode q1 at 1 kHz\nparam mu, alpha, eta\npotential: alpha/4*q1^4\neom q1 += mu*d(q1) + eta*q1^2*d(q1)\n",
    )
    .expect("model");
    std::fs::write(
        d.join("vdp.toml"),
        "[modes.q1]\nf_hz = 1000.0\nQ = 1e4\n[parameters]\nmu = -1.2566370614359172\nalpha = 1.0527578027828646e16\neta = 1.2566370614359172e12\n",
    )
    .expect("values");
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("sweep")
        .arg(d.join("vdp.hb"))
        .arg("--values")
        .arg(d.join("vdp.toml"))
        .args([
            "--from",
            "998",
            "--to",
            "1002",
            "--force",
            "q1=0.02368705",
            "--points",
            "400",
        ])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("Hopf point at").count(), 2, "{err}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.lines().next().expect("header").ends_with(",hopf_hz"));
    let hopf: Vec<f64> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.rsplit(',').next().and_then(|v| v.parse().ok()))
        .collect();
    // The closed form of the averaged equations (crates/sim/tests/it/hopf.rs).
    assert_eq!(hopf.len(), 2, "{hopf:?}");
    assert!(
        (hopf[0] - 999.80102).abs() < 1e-3 && (hopf[1] - 1000.39888).abs() < 1e-3,
        "{hopf:?}"
    );
}

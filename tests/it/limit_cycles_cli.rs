//! `harmonid sweep --limit-cycles` (issue 38, item 3) on the driven van der Pol–Duffing
//! example: a limit-cycle branch from each of the two Hopf points, outward, with the
//! self-oscillation quenched by the drive as two-frequency averaging says (`a² = a_free² − 2b²`).

use std::path::PathBuf;
use std::process::Command;

#[test]
fn sweep_writes_a_limit_cycle_branch_from_each_hopf_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (csv, plot) = (dir.path().join("lc.csv"), dir.path().join("lc.svg"));
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["sweep", "examples/vdp_duffing/model.hb", "--values"])
        .args([
            "examples/vdp_duffing/values.toml",
            "--from",
            "980",
            "--to",
            "1020",
        ])
        .args(["--force", "q1=0.446", "--points", "400", "--limit-cycles"])
        .arg(&csv)
        .arg("--plot")
        .arg(&plot)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")))
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(
        err.matches("limit-cycle branch from the Hopf point")
            .count(),
        2,
        "{err}"
    );
    assert!(plot.exists());
    let text = std::fs::read_to_string(&csv).expect("csv");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("hopf,f_hz,f2_hz,offset_hz,q1_f2_abs,q1_f_abs,q1_2f-f2_abs,stable,growth_per_s")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let num = |r: &[&str], i: usize| r[i].parse::<f64>().expect("number");
    for hopf in ["1", "2"] {
        let branch: Vec<&Vec<&str>> = rows.iter().filter(|r| r[0] == hopf).collect();
        assert!(branch.len() > 20, "{hopf}: {} rows", branch.len());
        let last = branch.last().expect("rows");
        // The self-oscillation stays near the resonance (Duffing-shifted by 0.05 Hz at 1 um)
        // while the drive moves away; the last point (20 Hz off) is stable.
        let (f, f2, a, b) = (num(last, 1), num(last, 2), num(last, 4), num(last, 5));
        assert!((f2 - 1000.05).abs() < 0.01, "{f2}");
        assert!((f - 1000.0).abs() > 19.0, "{f}");
        assert_eq!(last[7], "1");
        let want = (1e-12 - 2.0 * b * b).sqrt();
        assert!(
            (a - want).abs() < 3e-3 * 1e-6,
            "a {a:e}, averaging {want:e}"
        );
    }
}

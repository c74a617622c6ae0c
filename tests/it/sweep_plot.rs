//! `harmonid sweep --plot`: the response curve of the two-mode example followed downwards, with
//! its backbone over the whole curve and the jumps named by the sweep that makes them.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `harmonid sweep MODEL --values VALUES ARGS --out c.csv --plot c.svg` in a temporary
/// folder, asserts it succeeds, and gives its stderr and the SVG.
fn sweep_plot(model: &Path, values: &Path, args: &[&str]) -> (String, String) {
    let tmp = tempfile::tempdir().expect("tmp");
    let svg = tmp.path().join("c.svg");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("sweep")
        .arg(model)
        .arg("--values")
        .arg(values)
        .args(args)
        .arg("--out")
        .arg(tmp.path().join("c.csv"))
        .arg("--plot")
        .arg(&svg)
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&st.stderr).into_owned();
    assert!(st.status.success(), "{stderr}");
    (stderr, std::fs::read_to_string(&svg).expect("svg"))
}

#[test]
fn downward_sweep_plot() {
    let ex = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_2mode");
    let (stderr, text) = sweep_plot(
        &ex.join("model.hb"),
        &ex.join("values.toml"),
        &[
            "--from", "207700", "--to", "207500", "--force", "q1=3.5", "--points", "800",
        ],
    );
    // Followed downwards, the up-sweep still jumps at the upper fold (207652 Hz) and the
    // down-sweep at the lower one (207589 Hz).
    let up = stderr
        .split("up-sweep jumps at [")
        .nth(1)
        .and_then(|s| s.split(']').next())
        .and_then(|s| s.parse::<f64>().ok())
        .expect("one up-sweep jump");
    assert!((up - 207_652.08).abs() < 0.1, "{stderr}");
    let structure = harmonid_plot::svg_structure_without_ticks(&text);
    for label in [
        "backbone",
        "jump up-sweep",
        "jump down-sweep",
        "response of q1 to one tone",
    ] {
        assert!(
            structure.lines().any(|l| l == label),
            "{label}:\n{structure}"
        );
    }
    insta::assert_snapshot!("sweep_down_plot_structure", structure);
}

/// A model with a non-smooth term has no backbone (harmonid_sim::backbone refuses abs, sign
/// and tanh): the figure says so, where it said "backbone found only up to 0 m".
#[test]
fn a_nonsmooth_model_has_no_backbone_and_says_so() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (model, values) = (tmp.path().join("m.hb"), tmp.path().join("v.toml"));
    std::fs::write(
        &model,
        "mode q1 at 10 kHz\nparam kappa1\neom q1 += kappa1*abs(q1)*q1\n",
    )
    .expect("model");
    std::fs::write(
        &values,
        "[modes.q1]\nf_hz = 1.0e4\nQ = 2000\n[parameters]\nkappa1 = -3e9\n",
    )
    .expect("values");
    let (_, text) = sweep_plot(
        &model,
        &values,
        &[
            "--from", "9980", "--to", "10010", "--force", "q1=0.05", "--points", "60",
        ],
    );
    assert!(
        text.contains(
            "response of q1 to one tone (no backbone: computed for polynomial terms only)"
        ),
        "{}",
        harmonid_plot::svg_structure_without_ticks(&text)
    );
    assert!(!text.contains("found only up to"));
}

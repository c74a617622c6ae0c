//! A long lock-in record: 100 000 shots of one strongly driven Duffing mode, its ten lines out
//! to the ninth-order sidebands. The pooled mean is so precise (1.6e-13 m) that a harmonic
//! balance truncated at the starting order shows as misfit; the forward model must widen its
//! lattice until the truncation is below the noise. The per-shot fits are capped while the
//! estimate uses every shot.

use harmonid::data::Dataset;
use harmonid::ident::{identify, Settings, MAX_SHOT_FITS};
use std::process::Command;

const MODEL: &str = "mode q1 at 207.58 kHz\nparam beta1\npotential: beta1/4*q1^4\n";
const VALUES: &str = "[modes.q1]\nf_hz = 207582.0\nQ = 115000.0\n[parameters]\nbeta1 = 3.6e23\n";
const PLAN: &str = r#"description = "a long record"
displacement_unit = "m"
[noise]
sigma_per_quadrature = 5e-11
shots = 100000
[[measurement]]
name = "single_q1"
drives_hz = [207572.5, 207592.5]
force = { q1 = [3.5, 3.5] }
measure_hz = [207492.5, 207512.5, 207532.5, 207552.5, 207572.5, 207592.5, 207612.5, 207632.5, 207652.5, 207672.5]
"#;

#[test]
fn a_long_record_fits_with_a_widened_lattice_and_capped_per_shot_fits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |name: &str| dir.path().join(name);
    std::fs::write(p("m.hb"), MODEL).expect("model");
    std::fs::write(p("v.toml"), VALUES).expect("values");
    std::fs::write(p("p.toml"), PLAN).expect("plan");
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["simulate", "m.hb", "--values", "v.toml", "--plan", "p.toml"])
        .args(["--out", "ds", "--seed", "1"])
        .current_dir(dir.path())
        .output()
        .expect("run simulate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ds = Dataset::load(p("ds")).expect("dataset");
    let model = harmonid::model::parse_str(MODEL, "m.hb").expect("model");
    let r = identify(&model, &ds, &Settings::default()).expect("identify");
    assert_eq!(r.shots, 100_000);
    assert_eq!(r.shots_fitted, Some(MAX_SHOT_FITS));
    assert!(r.outlier_shots.iter().all(|&s| s < 100_000));
    assert!(
        r.notes
            .iter()
            .any(|n| n.contains("harmonic balance widened")),
        "{:?}",
        r.notes
    );
    let g = r.goodness_of_fit.as_ref().expect("goodness of fit");
    assert_eq!(g.fits, Some(true), "chi2/dof {}", g.chi2_per_dof);
    assert!(g.stderr_inflation < 1.5, "{}", g.stderr_inflation);
    // Every value within 4 standard errors of the truth, and the error bars at the bound.
    let m = &r.modes["q1"];
    let b = &r.parameters["beta1"];
    for (e, truth) in [(&m.f_hz, 207582.0), (&m.q, 115000.0), (b, 3.6e23)] {
        assert!((e.value - truth).abs() < 4.0 * e.stderr, "{e:?} vs {truth}");
        let crlb = e.crlb.expect("crlb");
        assert!(e.stderr <= 1.2 * crlb, "{} vs bound {crlb}", e.stderr);
    }
}

//! `harmonid simulate --time-domain --noise-rms-nm`: white noise added to every sample and
//! demodulated gives each quadrature of each amplitude the std `rms·sqrt(2/N)` (N samples per
//! lock-in window), scattered across shots around the noise-free amplitude.

use harmonid::data::Dataset;
use std::process::Command;

const MODEL: &str = "mode q at 1 kHz\nparam beta\npotential: beta/4*q^4\n";
const VALUES: &str = "[modes.q]\nf_hz = 1000.0\nQ = 50.0\n[parameters]\nbeta = 1e16\n";
const PLAN: &str = r#"
displacement_unit = "nm"
[noise]
shots = 60
[[measurement]]
name = "tone"
drives_hz = [1000.0]
force = { q = [1.0] }
measure_hz = [1000.0, 3000.0]
"#;

#[test]
fn time_domain_sample_noise_has_the_lockin_spread() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (f, t) in [("m.hb", MODEL), ("v.toml", VALUES), ("p.toml", PLAN)] {
        std::fs::write(dir.path().join(f), t).expect("write");
    }
    let rms_nm = 5.0;
    let run = |noise: f64, out: &str| {
        let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("simulate")
            .arg(dir.path().join("m.hb"))
            .arg("--values")
            .arg(dir.path().join("v.toml"))
            .arg("--plan")
            .arg(dir.path().join("p.toml"))
            .arg("--out")
            .arg(dir.path().join(out))
            .arg("--time-domain")
            .arg(format!("--noise-rms-nm={noise}"))
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&st.stderr).to_string();
        assert!(st.status.success(), "{err}");
        err
    };
    let err = run(rms_nm, "noisy");
    let samples: f64 = err
        .split("steps, ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("sample count in {err}"));
    run(0.0, "clean");
    let noisy = Dataset::load(dir.path().join("noisy")).expect("loads");
    let clean = Dataset::load(dir.path().join("clean")).expect("loads");
    let (mn, mc) = (&noisy.measurements[0], &clean.measurements[0]);
    // Dataset::load returns metres.
    let want = rms_nm * 1e-9 * (2.0 / samples).sqrt();
    for f in 0..2 {
        let z0 = mc.amplitude(0, f, 0);
        // Clean shots are all equal.
        assert_eq!(mc.amplitude(59, f, 0), z0);
        let n = mn.n_shots;
        assert_eq!(n, 60);
        let (mut s2, mut mean) = (0.0, num_complex::Complex64::new(0.0, 0.0));
        for s in 0..n {
            let d = mn.amplitude(s, f, 0) - z0;
            mean += d;
            s2 += d.re * d.re + d.im * d.im;
        }
        let std = (s2 / (2.0 * n as f64)).sqrt();
        assert!(
            (std / want - 1.0).abs() < 0.25,
            "freq {f}: per-quadrature std {std} m vs rms·sqrt(2/N) = {want} m"
        );
        // Centred on the noise-free amplitude.
        assert!((mean / n as f64).norm() < 4.0 * want / (n as f64).sqrt());
    }
}

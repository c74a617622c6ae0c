//! Nonlinear damping identified like any other coefficient (issue 20): a Duffing resonator
//! with `η q² q̇`, two drive levels (the damping shows in how the response grows with the
//! drive), simulated by harmonic balance with noise, identified by the default estimator.

use harmonid_ident::{identify, Settings};
use harmonid_testgen::{self as gen, Design, DAMPED_DUFFING as MODEL};

#[test]
fn nonlinear_damping_is_identified_within_its_error_bar() {
    let model = harmonid_model::parse_str(MODEL, "damped.hb").expect("model");
    // 10 nm shifts the resonance by about a linewidth (beta) and adds 0.4 linewidth of damping
    // (eta a^2 / 4 = 0.4 gamma).
    let (f, q) = (1.0e6, 2.0e4);
    let w = std::f64::consts::TAU * f;
    let v = gen::damped_duffing_values(0.4 * 4.0 * (w / q) / 1e-16);
    assert_eq!((v.f_hz[0], v.q[0]), (f, q));
    let lw = f / q;
    let pair = |name: &str, force: f64| Design {
        name: name.into(),
        tones: vec![(f - 2.0 * lw, 0, force), (f + 2.0 * lw, 0, force)],
        observe: Vec::new(),
    };
    // Linear peak response F Q / w^2: 2.5 nm and 10 nm.
    let unit = 1e-9 * w * w / q;
    let designs = [pair("low", 2.5 * unit), pair("high", 10.0 * unit)];
    let ds = gen::simulate(&model, &v, &designs, &[1.0], 1e-12, 10, 7);
    let rep = identify(&model, &ds, &Settings::default()).expect("identify");
    assert_eq!(rep.estimator, "ml");
    let g = rep.goodness_of_fit.as_ref().expect("a verdict");
    assert!(g.fits == Some(true), "{:?}", g.p_value);
    for (name, truth) in [("beta1", v.params["beta1"]), ("eta1", v.params["eta1"])] {
        let e = &rep.parameters[name];
        let dev = (e.value - truth) / e.stderr;
        println!(
            "{name}: {:.6e} ± {:.2e} (truth {truth:.6e}, {dev:+.2} stderr)",
            e.value, e.stderr
        );
        assert!(
            e.stderr < 0.05 * truth.abs(),
            "{name} poorly determined: {e:?}"
        );
        assert!(dev.abs() < 4.0, "{name}: {dev} stderr off");
    }
    // The result names the term the way the data format does.
    assert!(
        rep.eom["q1"].contains_key("q1^2*d(q1)"),
        "{:?}",
        rep.eom["q1"]
    );
}

#[test]
fn a_stepped_sweep_at_four_levels_identifies_the_damping() {
    // The shape of a lock-in's stepped sine: one tone and one line per step, 40 steps over ±5
    // linewidths at each of four levels, one actuator gain for the whole sweep.
    let model = harmonid_model::parse_str(MODEL, "damped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let ds = gen::simulate(&model, &v, &d, &[1.0], 1e-12, 10, 3);
    let settings = Settings {
        force_model: harmonid_ident::ForceModel::GainPerMode,
        ..Settings::default()
    };
    let rep = identify(&model, &ds, &settings).expect("identify");
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    for (name, truth) in ["beta1", "eta1"].map(|n| (n, v.params[n])) {
        let e = &rep.parameters[name];
        let dev = (e.value - truth) / e.stderr;
        println!(
            "{name}: {:.6e} ± {:.2e} ({dev:+.2} stderr)",
            e.value, e.stderr
        );
        assert!(e.stderr < 0.05 * truth, "{name}: {e:?}");
        assert!(dev.abs() < 4.0, "{name}: {dev} stderr off");
    }
}

#[test]
fn a_self_excited_mode_is_named_as_such_and_nothing_is_written() {
    // Van der Pol: -mu d(q1) outweighs w/Q, so q1 oscillates without a drive.
    let dir = tempfile::tempdir().expect("tempdir");
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        p
    };
    let model = write(
        "vdp.hb",
        "mode q1 at 1 kHz\nparam mu, nu\neom q1 += -mu*d(q1) + nu*q1^2*d(q1)\n",
    );
    let values = write(
        "vdp.toml",
        "[modes.q1]\nf_hz = 1000.0\nQ = 100.0\n[parameters]\nmu = 100.0\nnu = 1e8\n",
    );
    let plan = write(
        "plan.toml",
        "description = \"vdp\"\ndisplacement_unit = \"m\"\n[[point]]\nname = \"p\"\nshape = { q1 = 1.0 }\n\
         [noise]\nsigma_per_quadrature = 1e-12\nshots = 1\n[[measurement]]\nname = \"m\"\n\
         drives_hz = [1010.0]\nforce = { q1 = [1.0] }\nmeasure_hz = [1010.0]\n",
    );
    let out = dir.path().join("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(["simulate"])
        .arg(&model)
        .arg("--values")
        .arg(&values)
        .arg("--plan")
        .arg(&plan)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        err.contains("self_excited") && err.contains("q1 is self-excited"),
        "{err}"
    );
    // w/Q = 2 pi 1000 / 100 = 62.8 1/s against mu = 100: net -37.2 1/s; undriven, the limit
    // cycle 2 sqrt(37.17/1e8) = 1.219e-3 m (van der Pol, weakly nonlinear), its frequency lower
    // by about (net/w)^2/16.
    assert!(err.contains("-3.717e1"), "{err}");
    // (miette folds the message: the words are checked one by one)
    for words in ["stable", "limit cycle of 1.219e-3 m", "9.999978e2 Hz"] {
        assert!(err.contains(words), "{words}: {err}");
    }
    assert!(!out.exists(), "nothing written");
}

#[test]
fn plans_for_a_damped_model_stop_where_the_damping_saturates_the_response() {
    // Nonlinear damping removes the fold that bounds the designer's search for the strongest
    // drive; the search is capped where the own velocity terms add a few linewidths.
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("plan.toml");
    let root = env!("CARGO_MANIFEST_DIR");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .current_dir(root)
        .args([
            "plan",
            "examples/damped_2mode/model.hb",
            "--values",
            "examples/damped_2mode/values.toml",
            "--noise",
            "2pm",
            "--shots",
            "20",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(out.exists(), "the plan is written");
    for name in ["eta1", "eta12", "beta1", "beta2", "g12"] {
        let line = text
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("{name} in {text}"));
        // quantity, value, bound, relative (at the guess), then median and worst over the range.
        let rel: f64 = line
            .split_whitespace()
            .nth(3)
            .and_then(|x| x.parse().ok())
            .expect("relative bound");
        assert!(rel < 0.05, "{name}: relative bound {rel}");
    }
}

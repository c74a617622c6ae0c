//! Parametric pumping (issue 20, item 6): a pump at twice the resonance modulates the
//! stiffness, `λ·pump(t)·q1`. Simulated with noise through the dataset format (`pumps_hz`,
//! `pump_levels`, `pump_phases_rad`) and identified by the default estimator: λ is an
//! ordinary unknown.

use harmonid_experiment::{Plan, Settings as SimSettings};
use harmonid_ident::{identify, Settings};
use harmonid_sim::{ModeValues, ModelValues};

const MODEL: &str = "mode q1 at 100 kHz\nparam beta1, lambda\n\
                     potential: beta1/4*q1^4\neom q1 += lambda*pump*q1\n";

const F: f64 = 1.0e5;
const Q: f64 = 1.0e4;

fn values(beta: f64, lambda: f64) -> ModelValues {
    let mut v = ModelValues::default();
    v.modes.insert(
        "q1".into(),
        ModeValues {
            f_hz: Some(F),
            q: Some(Q),
        },
    );
    v.parameters.insert("beta1".into(), beta);
    v.parameters.insert("lambda".into(), lambda);
    v
}

/// Two tones 2 linewidths either side of the resonance at two drive levels, each with the pump
/// at 2f (level `pump` V) and without it (level 0: the pump switched off).
fn plan(force: f64, pump: f64, sigma: f64, shots: usize) -> Plan {
    let lw = F / Q;
    let mut text = format!(
        "description = \"pumped Duffing\"\ndisplacement_unit = \"m\"\n\
         [[point]]\nname = \"p\"\nshape = {{ q1 = 1.0 }}\n\
         [noise]\nsigma_per_quadrature = {sigma:e}\nshots = {shots}\n"
    );
    for (name, level, p) in [
        ("low_off", 1.0, 0.0),
        ("low_pumped", 1.0, pump),
        ("high_off", 3.0, 0.0),
        ("high_pumped", 3.0, pump),
    ] {
        let f = force * level;
        text.push_str(&format!(
            "[[measurement]]\nname = \"{name}\"\ndrives_hz = [{:.3}, {:.3}]\n\
             force = {{ q1 = [{f:e}, {f:e}] }}\ndrive_levels_v = [{level}, {level}]\n\
             drive_phases_rad = [0.0, 0.0]\npumps_hz = [{:.3}]\npump_levels = [{p}]\n\
             pump_phases_rad = [0.4]\n",
            F - 2.0 * lw,
            F + 2.0 * lw,
            2.0 * F
        ));
    }
    Plan::from_toml(&text, "plan.toml").expect("plan")
}

#[test]
fn the_pump_coefficient_is_identified_within_its_error_bar() {
    let model = harmonid_model::parse_str(MODEL, "pumped.hb").expect("model");
    let w = std::f64::consts::TAU * F;
    // A pump of 1 V at 60 % of the parametric threshold (λ|P| = 2ω²/Q), and a Duffing shift
    // of about a linewidth at 10 nm.
    let lambda = 0.6 * 2.0 * w * w / Q;
    let beta = 4.0 / 3.0 * (w * w / Q) / 1e-16;
    let v = values(beta, lambda);
    // Linear peak response F Q / ω² of 3 nm at the lower level.
    let force = 3e-9 * w * w / Q;
    let sim = plan(force, 1.0, 1e-12, 10)
        .simulate(&model, &v, &SimSettings::default())
        .expect("simulates");
    let ds = sim.dataset;
    assert_eq!(ds.measurements[1].spec.pumps_hz, vec![2.0 * F]);
    let rep = identify(&model, &ds, &Settings::default()).expect("identify");
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    for (name, truth) in [("beta1", beta), ("lambda", lambda)] {
        let e = &rep.parameters[name];
        let dev = (e.value - truth) / e.stderr;
        println!(
            "{name}: {:.6e} ± {:.2e} (truth {truth:.6e}, {dev:+.2} stderr)",
            e.value, e.stderr
        );
        assert!(e.stderr < 0.02 * truth.abs(), "{name}: {e:?}");
        assert!(dev.abs() < 4.0, "{name}: {dev} stderr off");
    }
    assert!(rep.eom["q1"].contains_key("q1*pump"), "{:?}", rep.eom["q1"]);
}

#[test]
fn a_dataset_without_a_pump_is_refused_by_name() {
    let model = harmonid_model::parse_str(MODEL, "pumped.hb").expect("model");
    let plain = harmonid_model::parse_str(
        "mode q1 at 100 kHz\nparam beta1\npotential: beta1/4*q1^4\n",
        "plain.hb",
    )
    .expect("model");
    let w = std::f64::consts::TAU * F;
    let mut v = values(4.0 / 3.0 * (w * w / Q) / 1e-16, 0.0);
    v.parameters.remove("lambda");
    let mut p = plan(3e-9 * w * w / Q, 0.0, 1e-12, 3);
    for m in &mut p.measurements {
        m.pumps_hz.clear();
        m.pump_levels = None;
        m.pump_phases_rad = None;
    }
    let ds = p
        .simulate(&plain, &v, &SimSettings::default())
        .expect("simulates")
        .dataset;
    let e = identify(&model, &ds, &Settings::default()).expect_err("no pump");
    let text = e.to_string();
    assert!(
        text.contains("low_off") && text.contains("no pump") && text.contains("q1*pump"),
        "{text}"
    );
}

#[test]
fn error_bars_of_the_pump_coefficient_cover_the_truth_as_often_as_they_say() {
    // 200 noise realisations of the design above: the truth within 1 and 2 stderr as often as
    // a Gaussian says (68 ± 8 %, 95 ± 4 %), and the scatter of the estimates at the error bar.
    let model = harmonid_model::parse_str(MODEL, "pumped.hb").expect("model");
    let w = std::f64::consts::TAU * F;
    let lambda = 0.6 * 2.0 * w * w / Q;
    let beta = 4.0 / 3.0 * (w * w / Q) / 1e-16;
    let v = values(beta, lambda);
    let p = plan(3e-9 * w * w / Q, 1.0, 1e-12, 10);
    let runs = 200;
    let mut within = [[0usize; 2]; 2];
    let mut est = [Vec::new(), Vec::new()];
    let mut stderr = [Vec::new(), Vec::new()];
    for seed in 0..runs {
        let settings = SimSettings {
            seed: 1000 + seed as u64,
            ..SimSettings::default()
        };
        let ds = p
            .simulate(&model, &v, &settings)
            .expect("simulates")
            .dataset;
        let rep = identify(&model, &ds, &Settings::default()).expect("identify");
        for (k, (name, truth)) in [("beta1", beta), ("lambda", lambda)].iter().enumerate() {
            let e = &rep.parameters[*name];
            let dev = ((e.value - truth) / e.stderr).abs();
            within[k][0] += usize::from(dev <= 1.0);
            within[k][1] += usize::from(dev <= 2.0);
            est[k].push(e.value);
            stderr[k].push(e.stderr);
        }
    }
    for (k, name) in ["beta1", "lambda"].iter().enumerate() {
        let n = runs as f64;
        let mean = est[k].iter().sum::<f64>() / n;
        let scatter = (est[k].iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let mut s = stderr[k].clone();
        s.sort_by(f64::total_cmp);
        let median_stderr = s[s.len() / 2];
        let (c1, c2) = (
            100.0 * within[k][0] as f64 / n,
            100.0 * within[k][1] as f64 / n,
        );
        println!(
            "{name}: within 1 stderr {c1:.1} %, within 2 {c2:.1} %, scatter / median stderr {:.3}",
            scatter / median_stderr
        );
        assert!(
            (60.0..=76.0).contains(&c1),
            "{name}: {c1} % within 1 stderr"
        );
        assert!(
            (91.0..=99.0).contains(&c2),
            "{name}: {c2} % within 2 stderr"
        );
        assert!(
            scatter / median_stderr < 1.2,
            "{name}: scatter {scatter:e}, stderr {median_stderr:e}"
        );
    }
}

//! The truncation check runs by default (issue 11: at order 9 a four-mode model's harmonic
//! balance differed from the time domain by 2.4e-4 of the largest line, reported only on
//! request). Started too low, the order is raised until the measured lines change by less than
//! 1e-6 of the largest, and the lines then agree with a much wider lattice; when the largest
//! order allowed is not enough, the simulation is refused unless the user asks for the state.

use harmonid_experiment::{values_from_toml, Plan, Settings, Truncation};

const MODEL: &str = include_str!("../../../../examples/nanostring_2mode/model.hb");
const VALUES: &str = include_str!("../../../../examples/nanostring_2mode/values.toml");
const PLAN: &str = r#"
[[measurement]]
name = "couple_q1_q2"
drives_hz = [207572.5, 207592.5, 415841.5]
force = { q1 = [3.5, 3.5, 0.0], q2 = [0.0, 0.0, 1.81] }
"#;

fn run(order: usize, truncation: Truncation) -> Result<harmonid_experiment::Simulation, String> {
    let model = harmonid_model::parse_str(MODEL, "model.hb").expect("model");
    let values = values_from_toml(VALUES, "values.toml").expect("values");
    let plan = Plan::from_toml(PLAN, "plan.toml").expect("plan");
    let settings = Settings {
        order,
        truncation,
        ..Settings::noise_free()
    };
    plan.simulate(&model, &values, &settings)
        .map_err(|e| e.to_string())
}

#[test]
fn a_low_order_is_raised_until_the_lines_settle() {
    let sim = run(3, Truncation::default()).expect("simulates");
    let r = &sim.reports[0];
    assert!(r.order > 3, "order stayed at {}", r.order);
    let change = r.truncation_change.expect("checked");
    assert!(change < 1e-6, "change {change:e} at order {}", r.order);
    // The lines agree with those of a far wider lattice (order 21, no check) to about the
    // tolerance.
    let wide = run(21, Truncation::off()).expect("simulates");
    let (a, b) = (&sim.dataset.measurements[0], &wide.dataset.measurements[0]);
    let largest = b.data.iter().map(|x| x.norm()).fold(0.0, f64::max);
    for (k, &f) in a.freqs_hz.iter().enumerate() {
        let j = b
            .freqs_hz
            .iter()
            .position(|&g| (g - f).abs() < 1e-6)
            .unwrap_or_else(|| panic!("{f} Hz missing at order 21"));
        let d = (a.data[k] - b.data[j]).norm() / largest;
        assert!(d < 5e-6, "{f} Hz differs by {d:e} of the largest line");
    }
}

#[test]
fn a_state_that_does_not_settle_is_refused_unless_asked_for() {
    let strict = Truncation {
        max_order: 3,
        ..Truncation::default()
    };
    let e = run(3, strict.clone()).expect_err("order 3 is not enough");
    assert!(e.contains("couple_q1_q2") && e.contains("order"), "{e}");
    let lenient = Truncation {
        required: false,
        ..strict
    };
    let sim = run(3, lenient).expect("written on request");
    assert!(
        sim.reports[0]
            .notes
            .iter()
            .any(|n| n.contains("still changes the measured lines")),
        "{:?}",
        sim.reports[0].notes
    );
}

/// The plan's noise sets a floor: a change of the lines below a tenth of the noise of the mean
/// over its shots (`0.1 σ/√shots`) cannot move the fit, so the order-3 state that the strict
/// tolerance refuses passes under a large noise, and is refused under a small one; the
/// refusal's tolerance is the floor's when it is the larger.
#[test]
fn the_plans_noise_sets_the_truncation_floor() {
    let at_order_3 = Truncation {
        max_order: 3,
        ..Truncation::default()
    };
    let with_noise = |sigma: &str| -> Result<harmonid_experiment::Simulation, String> {
        let model = harmonid_model::parse_str(MODEL, "model.hb").expect("model");
        let values = values_from_toml(VALUES, "values.toml").expect("values");
        let plan = Plan::from_toml(
            &format!("[noise]\nsigma_per_quadrature = {sigma}\nshots = 4\n{PLAN}"),
            "plan.toml",
        )
        .expect("plan");
        let settings = Settings {
            order: 3,
            truncation: at_order_3.clone(),
            ..Settings::noise_free()
        };
        plan.simulate(&model, &values, &settings)
            .map_err(|e| e.to_string())
    };
    // The change at order 3, relative to the largest line (about 1e-8 m).
    let lenient = Truncation {
        required: false,
        ..at_order_3.clone()
    };
    let change = run(3, lenient).expect("written on request").reports[0]
        .truncation_change
        .expect("checked");
    assert!(change > 1e-6, "order 3 already settles: {change:e}");
    let sim = with_noise("1e-6").expect("far below the noise: passes");
    assert_eq!(sim.reports[0].order, 3);
    let e = with_noise("1e-14").expect_err("above a tiny noise: refused");
    assert!(e.contains("tolerance 1e-6"), "{e}");
}

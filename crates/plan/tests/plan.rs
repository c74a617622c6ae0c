//! The planner on the two-mode nanostring: the paper's plan scored, and (ignored, slow) a
//! designed plan.

use harmonid_experiment::Plan;
use harmonid_plan::{design, evaluate, DesignSettings};
use std::path::PathBuf;

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/nanostring_2mode")
        .join(name)
}

fn model_values() -> (harmonid_model::Model, harmonid_sim::ModelValues) {
    let model = harmonid_model::load(&example("model.hb")).expect("model");
    let values = harmonid_experiment::read_values(&example("values.toml")).expect("values");
    (model, values)
}

#[test]
fn the_papers_plan_scores_as_the_single_shot_bounds_scale() {
    let (model, values) = model_values();
    let text = std::fs::read_to_string(example("plan.toml")).expect("plan");
    let plan = Plan::from_toml(&text, "plan.toml").expect("plan parses");
    let ev = evaluate(&model, &values, &plan, 5e-11, 20).expect("evaluate");
    assert!(ev.findings.is_empty(), "{:?}", ev.findings);
    // The public dataset's bounds (1 shot, 0.1 nm; crates/ident/tests/crlb.rs) scaled by
    // 0.5/√20: the gains profiled out per measurement equal the full inverse.
    let k = 0.5 / 20f64.sqrt();
    for (name, rel1) in [
        ("f_hz:q1", 3.256e-6),
        ("Q:q1", 0.08737),
        ("beta2", 2.002),
        ("g12", 0.2075),
    ] {
        let got = ev.bounds.get(name).expect(name).rel;
        assert!(
            (got / (rel1 * k) - 1.0).abs() < 0.01,
            "{name}: {got:e} vs {:e}",
            rel1 * k
        );
    }
    let json = ev.to_json();
    assert!(json["modes"]["q2"]["Q"].as_f64().is_some_and(|x| x > 0.0));
    assert!(json["parameters"]["beta2"]
        .as_f64()
        .is_some_and(|x| x > 0.1));
}

#[test]
fn a_plan_that_never_couples_the_modes_names_g12() {
    let (model, values) = model_values();
    let text = std::fs::read_to_string(example("plan.toml")).expect("plan");
    let mut plan = Plan::from_toml(&text, "plan.toml").expect("plan parses");
    plan.measurements.truncate(2);
    let ev = evaluate(&model, &values, &plan, 5e-11, 20).expect("evaluate");
    assert_eq!(ev.findings.len(), 1, "{:?}", ev.findings);
    assert_eq!(ev.findings[0].unknown, "g12");
    assert!(ev.findings[0].suggestion.contains("q1, q2"));
}

#[test]
fn a_budget_too_small_is_refused() {
    let (model, values) = model_values();
    let s = DesignSettings {
        max_measurements: Some(2),
        ..DesignSettings::default()
    };
    let e = design(&model, &values, &s).expect_err("3 measurements needed");
    assert!(e.to_string().contains("3 measurements are needed"), "{e}");
}

/// Slow (minutes on a loaded machine): the designed plan at 0.05 nm, 20 shots, ≤ 3
/// measurements beats the paper's by more than 2× in its worst bound (measured: β2 0.034 vs
/// 0.224).
#[test]
#[ignore]
fn the_designed_plan_beats_the_papers_twice() {
    let (model, values) = model_values();
    let s = DesignSettings {
        max_measurements: Some(3),
        points: vec![harmonid_ident::Point {
            name: "p0".into(),
            shape: [
                ("q1".to_string(), 0.3090169943749474),
                ("q2".to_string(), 0.5877852522924731),
            ]
            .into(),
        }],
        ..DesignSettings::default()
    };
    let (_, ev) = design(&model, &values, &s).expect("design");
    let worst = ev.bounds.worst().expect("bounds").rel;
    assert!(worst < 0.5 * 0.2238, "worst {worst}");
}

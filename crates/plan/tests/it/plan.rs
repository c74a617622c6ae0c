//! The planner on the nanostrings: the paper's two-mode plan scored, designed plans that beat
//! it, the three-tone coupled measurement against two pairs, and the shipped five-mode plan.

use harmonid_experiment::{Plan, PlanMeasurement, Settings};
use harmonid_plan::{design, evaluate, DesignSettings};
use std::path::PathBuf;

fn example_of(dir: &str, name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(dir)
        .join(name)
}

fn example(name: &str) -> PathBuf {
    example_of("nanostring_2mode", name)
}

fn model_values_of(dir: &str) -> (harmonid_model::Model, harmonid_sim::ModelValues) {
    let model = harmonid_model::load(&example_of(dir, "model.hb")).expect("model");
    let values = harmonid_experiment::read_values(&example_of(dir, "values.toml")).expect("values");
    (model, values)
}

fn model_values() -> (harmonid_model::Model, harmonid_sim::ModelValues) {
    model_values_of("nanostring_2mode")
}

#[test]
fn the_papers_plan_scores_as_the_single_shot_bounds_scale() {
    let (model, values) = model_values();
    let text = std::fs::read_to_string(example("plan.toml")).expect("plan");
    let plan = Plan::from_toml(&text, "plan.toml").expect("plan parses");
    let ev = evaluate(&model, &values, &plan, 5e-11, 20).expect("evaluate");
    assert!(ev.findings.is_empty(), "{:?}", ev.findings);
    // The public dataset's bounds (1 shot, 0.1 nm; crates/ident/tests/it/crlb.rs) scaled by
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

fn two_mode_settings() -> DesignSettings {
    DesignSettings {
        max_measurements: Some(3),
        points: vec![harmonid_data::Point {
            name: "p0".into(),
            shape: [
                ("q1".to_string(), 0.3090169943749474),
                ("q2".to_string(), 0.5877852522924731),
            ]
            .into(),
        }],
        ..DesignSettings::default()
    }
}

/// The designed plan at 0.05 nm, 20 shots, ≤ 3 measurements beats the paper's by more than 2×
/// in its worst bound (measured: β2 0.027 vs 0.224), and scoring it gives the design's bounds.
#[test]
fn the_designed_plan_beats_the_papers_twice() {
    let (model, values) = model_values();
    let (plan, ev) = design(&model, &values, &two_mode_settings()).expect("design");
    let worst = ev.bounds.worst().expect("bounds").rel;
    assert!(worst < 0.5 * 0.2238, "worst {worst}");
    let again = evaluate(&model, &values, &plan, 5e-11, 20).expect("evaluate");
    for b in &ev.bounds.quantities {
        let got = again.bounds.get(&b.name).expect("same quantities").rel;
        assert!(
            (got / b.rel - 1.0).abs() < 1e-6,
            "{}: {got} vs {}",
            b.name,
            b.rel
        );
    }
}

/// Forces of `pm` (per tone, over modes) times `scale`.
fn scaled(pm: &PlanMeasurement, scale: f64) -> PlanMeasurement {
    let mut pm = pm.clone();
    for v in pm.force.values_mut() {
        v.iter_mut().for_each(|f| *f *= scale);
    }
    pm.drive_levels_v = pm
        .drive_levels_v
        .map(|l| l.iter().map(|f| f * scale).collect());
    pm
}

/// The coupled measurement of the two-mode design is the paper's kind (a pair on one mode,
/// one tone on the other): its g12 bound is within 20 % of (here: better than) the one of both
/// stage-1 pairs together, on a lattice less than half as large.
#[test]
fn the_three_tone_coupled_measurement_matches_two_pairs_on_a_smaller_lattice() {
    let (model, values) = model_values();
    let (plan, ev) = design(&model, &values, &two_mode_settings()).expect("design");
    let couple = &plan.measurements[2];
    assert_eq!(couple.drives_hz.len(), 3, "{couple:?}");
    // Both stage-1 pairs together, scaled down until the drive ramp meets no fold.
    let mut four = PlanMeasurement {
        name: "couple_q1_q2".into(),
        measure_hz: None,
        ..plan.measurements[0].clone()
    };
    let q2 = &plan.measurements[1];
    four.drives_hz.extend(&q2.drives_hz);
    four.force.insert("q1".into(), {
        let mut v = plan.measurements[0].force["q1"].clone();
        v.extend([0.0, 0.0]);
        v
    });
    four.force.insert("q2".into(), {
        let mut v = vec![0.0, 0.0];
        v.extend(&q2.force["q2"]);
        v
    });
    four.drive_levels_v = Some(
        (0..4)
            .map(|d| four.force["q1"][d] + four.force["q2"][d])
            .collect(),
    );
    four.drive_phases_rad = Some(vec![0.0; 4]);
    let mut with_four = plan.clone();
    let mut g12_four = None;
    for k in 0..8 {
        with_four.measurements[2] = scaled(&four, 0.7f64.powi(k));
        if let Ok(e) = evaluate(&model, &values, &with_four, 5e-11, 20) {
            g12_four = Some(e.bounds.get("g12").expect("g12").rel);
            break;
        }
    }
    let g12_four = g12_four.expect("two pairs at some level");
    let g12_three = ev.bounds.get("g12").expect("g12").rel;
    assert!(
        g12_three < 1.2 * g12_four,
        "3 tones {g12_three}, 4 tones {g12_four}"
    );
    let lines = |pm: &PlanMeasurement| {
        let p = Plan {
            measurements: vec![pm.clone()],
            ..plan.clone()
        };
        let sim = p
            .simulate(&model, &values, &Settings::default())
            .expect("simulates");
        sim.reports[0].lattice_lines
    };
    let (l3, l4) = (lines(couple), lines(&with_four.measurements[2]));
    assert!(2 * l3 < l4, "lattices: 3 tones {l3}, 4 tones {l4}");
}

/// The shipped five-mode plan (0.1 nm, 30 shots, one point) is what the planner designs, determines every
/// parameter to better than 10 %, and `simulate --plan` (default settings, truncation check)
/// accepts it on lattices of at most a few hundred lines.
#[test]
fn the_shipped_five_mode_plan_is_designed_cheap_and_determines_everything() {
    let (model, values) = model_values_of("nanostring_5mode");
    let text = std::fs::read_to_string(example_of("nanostring_5mode", "plan.toml")).expect("plan");
    let shipped = Plan::from_toml(&text, "plan.toml").expect("plan parses");
    // Measured at a tenth of the string: shapes sin(nπ/10), as written by `--point`.
    let shape = [
        0.309_016_994_374_947_45,
        0.587_785_252_292_473_1,
        0.809_016_994_374_947_5,
        0.951_056_516_295_153_5,
        1.0,
    ]
    .iter()
    .enumerate()
    .map(|(n, &s)| (format!("q{}", n + 1), s))
    .collect();
    let s = DesignSettings {
        sigma_m: 1e-10,
        shots: 30,
        points: vec![harmonid_data::Point {
            name: "p0".into(),
            shape,
        }],
        ..DesignSettings::default()
    };
    let (plan, ev) = design(&model, &values, &s).expect("design");
    assert_eq!(plan.measurements, shipped.measurements);
    assert_eq!(plan.noise, shipped.noise);
    assert_eq!(plan.points, shipped.points);
    assert!(ev.findings.is_empty(), "{:?}", ev.findings);
    for b in &ev.bounds.quantities {
        assert!(b.rel < 0.1, "{}: {}", b.name, b.rel);
    }
    let sim = shipped
        .simulate(&model, &values, &Settings::default())
        .expect("simulate --plan accepts it");
    assert_eq!(sim.reports.len(), 15);
    for r in &sim.reports {
        assert!(
            r.lattice_lines <= 200,
            "{}: {} lines",
            r.name,
            r.lattice_lines
        );
        if r.name.starts_with("couple") {
            assert!(r.measured <= 32);
        }
    }
}

#[test]
fn a_spent_time_budget_keeps_the_first_feasible_candidates_and_says_so() {
    // A budget of zero: every measurement keeps its first feasible candidate; the plan is
    // complete, determines every unknown, and names each measurement the budget cut short.
    let (model, values) = model_values();
    let s = DesignSettings {
        time_budget_s: Some(0.0),
        ..two_mode_settings()
    };
    let (plan, ev) = design(&model, &values, &s).expect("design");
    let (full, full_ev) = design(&model, &values, &two_mode_settings()).expect("design");
    assert_eq!(plan.measurements.len(), full.measurements.len());
    assert!(ev.findings.is_empty());
    assert!(full_ev.notes.is_empty(), "{:?}", full_ev.notes);
    let cut: Vec<&String> = ev
        .notes
        .iter()
        .filter(|n| n.contains("time budget"))
        .collect();
    assert!(!cut.is_empty(), "{:?}", ev.notes);
    for q in &ev.bounds.quantities {
        assert!(q.rel.is_finite(), "{}: {}", q.name, q.rel);
    }
}

/// Whether every measurement of `plan` reaches its level on the device `values` without a jump
/// and stable: the names of those that do not, with why.
fn failures_on(
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    plan: &Plan,
) -> Vec<String> {
    let settings = Settings {
        check_stability: true,
        stop_at_fold: true,
        ..Settings::noise_free()
    };
    let mut out = Vec::new();
    for pm in &plan.measurements {
        let one = Plan {
            measurements: vec![pm.clone()],
            ..plan.clone()
        };
        match one.simulate(model, values, &settings) {
            Ok(sim) if sim.reports[0].drive_jumps.is_empty() => {}
            Ok(sim) => out.push(format!(
                "{}: jumps at {:?}",
                pm.name, sim.reports[0].drive_jumps
            )),
            Err(e) => out.push(format!("{}: {e}", pm.name)),
        }
    }
    out
}

/// Issue 23's case on the two-mode nanostring: planned from a guess with Q2 = 4.5e5 (the device
/// has 6.0e5), Q1 = 8.5e4 (1.16e5), β1 and β2 20–25 % low, both frequencies 0.3 Hz off, the plan
/// designed at the guess alone fails on the device, the one designed over the guess's range
/// (frequencies ± 0.5 Hz, Q ± 40 %, parameters ×/÷ 2: the device is inside) does not, and its
/// report over devices drawn from the range names no failure.
#[test]
fn a_plan_over_the_guess_range_survives_the_device_a_plan_at_the_guess_does_not() {
    let (model, truth) = model_values();
    let guess = harmonid_experiment::values_from_toml(
        "[modes.q1]\nf_hz = 207582.3\nQ = 8.5e4\n[modes.q2]\nf_hz = 415841.7\nQ = 4.5e5\n\
         [parameters]\nbeta1 = 2.0e22\nbeta2 = 3.0e23\ng12 = 8.57e22\n",
        "guess.toml",
    )
    .expect("guess");
    let spread: std::collections::BTreeMap<String, harmonid_experiment::Spread> = [
        ("f_hz:q1", harmonid_experiment::Spread::Abs(0.5)),
        ("f_hz:q2", harmonid_experiment::Spread::Abs(0.5)),
        ("Q:q1", harmonid_experiment::Spread::Rel(0.4)),
        ("Q:q2", harmonid_experiment::Spread::Rel(0.4)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let range = harmonid_plan::GuessRange::new(&model, &guess, &spread).expect("range");
    // The device is inside the range.
    for e in range.entries() {
        let (lo, hi) = e.ends();
        let t = match e.name.split_once(':') {
            Some(("f_hz", m)) => truth.modes[m].f_hz.expect("f"),
            Some(("Q", m)) => truth.modes[m].q.expect("Q"),
            _ => truth.parameters[&e.name],
        };
        assert!(lo <= t && t <= hi, "{}: {t} outside {lo}..{hi}", e.name);
    }
    let (at_guess, _) = design(&model, &guess, &two_mode_settings()).expect("design at the guess");
    let failed = failures_on(&model, &truth, &at_guess);
    assert!(
        !failed.is_empty(),
        "the plan at the guess survives the device"
    );
    let s = DesignSettings {
        range: Some(range),
        draws: 20,
        ..two_mode_settings()
    };
    let (robust, ev) = design(&model, &guess, &s).expect("design over the range");
    let failed = failures_on(&model, &truth, &robust);
    assert!(failed.is_empty(), "{failed:?}");
    let r = ev.robustness.as_ref().expect("reported over the range");
    assert_eq!(r.draws, 20);
    assert!(r.failures.is_empty(), "{:?}", r.failures);
    for b in &ev.bounds.quantities {
        let worst = r.worst[&b.name];
        assert!(
            worst.is_finite() && worst >= r.median[&b.name],
            "{}",
            b.name
        );
    }
    println!("at the guess: {failed:?}\n{}", ev.table());
}

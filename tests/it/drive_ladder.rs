//! Drive ladders (a measurement recorded at several rising drive levels): a level without a
//! stable steady state on the device costs that level and not the measurement, and the
//! dataset keeps the ladder as a `direction = "level"` sweep.

use harmonid::data::{Dataset, Direction};
use harmonid::experiment::{values_from_toml, Plan, Settings};
use harmonid::model::Model;
use std::path::Path;

fn example(file: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples/nanostring_2mode")
        .join(file);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The paper's plan with its coupled measurement driven at 4.5 N/kg on q1 (1.8 V at the
/// example's gain of 2.5 N/kg/V), where the coupled state is unstable (growth 0.76 /s), as a
/// ladder `levels`.
fn strong_plan(levels: &str) -> Plan {
    let text = example("plan.toml")
        .replace(
            "name = \"couple_q1_q2\"",
            &format!("name = \"couple_q1_q2\"\nlevels = {levels}"),
        )
        .replace(
            "force = { q1 = [3.5, 3.5, 0.0], q2 = [0.0, 0.0, 1.81] }",
            "force = { q1 = [4.5, 4.5, 0.0], q2 = [0.0, 0.0, 1.81] }",
        )
        .replace(
            "drive_levels_v = [1.4, 1.4, 1.0647058823529412]",
            "drive_levels_v = [1.8, 1.8, 1.0647058823529412]",
        );
    Plan::from_toml(&text, "plan.toml").expect("plan")
}

fn model() -> (Model, harmonid::sim::ModelValues) {
    let model = harmonid::model::parse_str(&example("model.hb"), "model.hb").expect("model");
    let values = values_from_toml(&example("values.toml"), "values.toml").expect("values");
    (model, values)
}

#[test]
fn a_ladder_loses_its_unstable_top_level_and_identifies_from_the_others() {
    let (model, values) = model();
    let settings = Settings::default();
    let single = strong_plan("[]");
    let e = single
        .simulate(&model, &values, &settings)
        .expect_err("the full drive is unstable")
        .to_string();
    assert!(
        e.contains("couple_q1_q2: the steady state is unstable"),
        "{e}"
    );

    let sim = strong_plan("[0.4, 0.7, 1.0]")
        .simulate(&model, &values, &settings)
        .expect("the ladder simulates");
    assert_eq!(sim.lost_levels.len(), 1, "{:?}", sim.lost_levels);
    let lost = &sim.lost_levels[0];
    assert_eq!((lost.measurement.as_str(), lost.level), ("couple_q1_q2", 2));
    assert!(lost.why.contains("unstable"), "{}", lost.why);
    let names: Vec<&str> = sim
        .dataset
        .measurements
        .iter()
        .map(|m| m.spec.name.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "single_q1",
            "single_q2",
            "couple_q1_q2[0]",
            "couple_q1_q2[1]"
        ]
    );
    // The kept levels carry their scaled drive levels.
    let levels = |k: usize| sim.dataset.measurements[2 + k].spec.drive_levels_v.clone();
    assert!((levels(0).expect("levels")[0] - 0.4 * 1.8).abs() < 1e-12);
    assert!((levels(1).expect("levels")[0] - 0.7 * 1.8).abs() < 1e-12);
    let truth = sim.dataset.truth.as_ref().expect("truth");
    let f = truth.forces["couple_q1_q2[1]"]["q1"].amplitude[0];
    assert!((f - 0.7 * 4.5).abs() < 1e-12, "{f}");

    let dir = tempfile::tempdir().expect("tempdir");
    sim.dataset.write(dir.path().join("ds")).expect("write");
    let back = Dataset::load(dir.path().join("ds")).expect("read back");
    assert_eq!(back.manifest.sweeps.len(), 1);
    assert_eq!(back.manifest.sweeps[0].direction, Direction::Level);
    assert_eq!(back.measurements, sim.dataset.measurements);

    let rep = harmonid::ident::identify(&model, &back, &harmonid::ident::Settings::default())
        .expect("identify");
    for (name, truth) in [("beta1", 2.68e22), ("beta2", 3.7e23), ("g12", 8.57e22)] {
        let e = &rep.parameters[name];
        assert!(
            (e.value - truth).abs() <= 4.0 * e.stderr && e.stderr < 0.1 * truth,
            "{name}: {} ± {} against {truth}",
            e.value,
            e.stderr
        );
    }
}

#[test]
fn a_ladder_without_any_stable_level_is_refused_with_the_first_loss() {
    let (model, values) = model();
    let e = strong_plan("[0.98, 1.0]")
        .simulate(&model, &values, &Settings::default())
        .expect_err("no level is stable")
        .to_string();
    assert!(
        e.contains("couple_q1_q2[0]: the steady state is unstable"),
        "{e}"
    );
}

#[test]
fn broken_ladders_are_refused_with_the_key() {
    for (levels, says) in [
        (
            "[0.5, 0.5]",
            "level 1 (0.5) does not rise above level 0 (0.5)",
        ),
        (
            "[0.5, 1.2]",
            "1.2 is not allowed: expected a fraction of the forces in (0, 1]",
        ),
        ("[0.0, 1.0]", "0 is not allowed"),
    ] {
        let text = example("plan.toml").replace(
            "name = \"single_q1\"",
            &format!("name = \"single_q1\"\nlevels = {levels}"),
        );
        let e = Plan::from_toml(&text, "plan.toml")
            .expect_err(levels)
            .to_string();
        assert!(e.contains(says), "{levels}: {e}");
        assert!(e.contains("levels"), "{levels}: {e}");
    }
}

/// The paper's plan with `single_q1` as the ladder `[0.4, 0.7, 1.0]` of its forces times
/// `scale` (its drive levels, which the dataset records, stay the plan's).
fn laddered_single(scale: f64) -> Plan {
    let mut plan = Plan::from_toml(&example("plan.toml"), "plan.toml").expect("plan");
    let pm = &mut plan.measurements[0];
    assert_eq!(pm.name, "single_q1");
    pm.levels = vec![0.4, 0.7, 1.0];
    for f in pm.force.values_mut() {
        f.iter_mut().for_each(|x| *x *= scale);
    }
    plan
}

/// A level whose record does not belong to the drive its ladder gives it (here recorded at 1.2
/// times that drive, as a response that jumped or drifted would not be the state of its
/// level) is left out, said, and the others identify the device; on 20 clean datasets no level
/// is left out (the check's family-wise false alarm is 1 %).
#[test]
fn a_level_off_its_ladders_branch_is_left_out_and_said() {
    let (model, values) = model();
    let settings = |seed| Settings {
        seed,
        ..Settings::default()
    };
    let ident = harmonid::ident::Settings::default();
    for seed in 0..20 {
        let clean = laddered_single(1.0)
            .simulate(&model, &values, &settings(seed))
            .expect("clean");
        let rep = harmonid::ident::identify(&model, &clean.dataset, &ident).expect("identify");
        assert!(
            rep.excluded_levels.is_empty(),
            "seed {seed}: {:?}",
            rep.excluded_levels
        );
    }
    let mut ds = laddered_single(1.0)
        .simulate(&model, &values, &settings(1))
        .expect("clean")
        .dataset;
    let pushed = laddered_single(1.2)
        .simulate(&model, &values, &settings(1))
        .expect("pushed")
        .dataset;
    let i = ds
        .measurements
        .iter()
        .position(|m| m.spec.name == "single_q1[2]")
        .expect("level 2");
    ds.measurements[i].data = pushed.measurements[i].data.clone();
    let rep = harmonid::ident::identify(&model, &ds, &ident).expect("identify");
    let names: Vec<&str> = rep
        .excluded_levels
        .iter()
        .map(|e| e.measurement.as_str())
        .collect();
    assert_eq!(names, ["single_q1[2]"]);
    assert!(
        rep.warnings.iter().any(|w| w.starts_with(
            "single_q1[2]: left out of the fit: it does not fit the branch the other levels of its drive ladder single_q1 define"
        )),
        "{:?}",
        rep.warnings
    );
    // Every level off (each at another multiple of its drive): no single level explains it,
    // and nothing is left out.
    let mut all_off = ds.clone();
    for (k, scale) in [(0, 1.3), (1, 0.8)] {
        let other = laddered_single(scale)
            .simulate(&model, &values, &settings(1))
            .expect("other")
            .dataset;
        let j = i - 2 + k;
        all_off.measurements[j].data = other.measurements[j].data.clone();
    }
    let none = harmonid::ident::identify(&model, &all_off, &ident).expect("identify");
    assert!(
        none.excluded_levels.is_empty(),
        "{:?}",
        none.excluded_levels
    );
    assert!(
        none.notes
            .iter()
            .any(|n| n.contains("drive ladder single_q1: its levels do not fit, and leaving out any one of them does not make the others fit")),
        "{:?}",
        none.notes
    );
    let fit = rep.goodness_of_fit.as_ref().expect("goodness");
    assert!(fit.measurements.iter().all(|m| m.name != "single_q1[2]"));
    for (name, truth) in [("beta1", 2.68e22), ("beta2", 3.7e23), ("g12", 8.57e22)] {
        let e = &rep.parameters[name];
        assert!(
            (e.value - truth).abs() <= 4.0 * e.stderr,
            "{name}: {} ± {} against {truth}",
            e.value,
            e.stderr
        );
    }
}

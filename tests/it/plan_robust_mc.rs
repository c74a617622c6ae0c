//! Issue 23's promise checked by Monte Carlo: a plan designed from an uncertain guess (not the
//! truth) over the guess's range, then run on devices drawn from that range with noise and
//! identified, determines every unknown within 4 standard errors in at least 95 % of the
//! devices.
//!
//! The two-mode nanostring runs in CI (20 devices, a few seconds); it prints its table with
//!
//!     cargo test --release --test it -- plan_robust_mc:: --nocapture

use crate::guess_support;

use guess_support::{point, two_mode_settings, TWO_MODE_GUESS};
use harmonid_experiment::{values_from_toml, Plan, Settings, Spread};
use harmonid_ident::{identify, Report};
use harmonid_model::Model;
use harmonid_plan::{design, DesignSettings, GuessRange, DEFAULT_LADDER};
use harmonid_sim::ModelValues;
use std::collections::BTreeMap;

/// One quantity's estimate and standard error in a result.
fn estimate(r: &Report, name: &str) -> Option<(f64, f64)> {
    let e = if let Some(m) = name.strip_prefix("f_hz:") {
        &r.modes.get(m)?.f_hz
    } else if let Some(m) = name.strip_prefix("Q:") {
        &r.modes.get(m)?.q
    } else {
        r.parameters.get(name)?
    };
    Some((e.value, e.stderr))
}

/// A device's true value of quantity `name`.
fn truth_of(v: &ModelValues, name: &str) -> f64 {
    match name.split_once(':') {
        Some(("f_hz", m)) => v.modes[m].f_hz.expect("f"),
        Some(("Q", m)) => v.modes[m].q.expect("Q"),
        _ => v.parameters[name],
    }
}

/// Per device of `devices`: the plan simulated on it with noise (seed = its index; levels of
/// drive ladders without a stable state left out, as a lab would) and identified; returns, per
/// device, the quantities that missed (|estimate − truth| > 4 stderr, or no estimate) or why
/// the device failed, and the quantities left undetermined (relative stderr above
/// `harmonid_ident::MAX_REL_STDERR`).
fn run(
    model: &Model,
    plan: &Plan,
    range: &GuessRange,
    devices: &[ModelValues],
) -> Vec<(Vec<String>, Vec<String>)> {
    let mut out = Vec::new();
    for (k, truth) in devices.iter().enumerate() {
        let settings = Settings {
            seed: k as u64,
            ..Settings::default()
        };
        let sim = match plan.simulate(model, truth, &settings) {
            Ok(s) => s,
            Err(e) => {
                let why = format!("device {k}: the plan does not simulate: {e}");
                out.push((vec![why], Vec::new()));
                continue;
            }
        };
        // A level that jumped onto another stable state is data like any other (the same
        // equations hold there); a level with no stable state is not in the dataset. Both are
        // said, and the identification is the judge.
        for r in sim.reports.iter().filter(|r| !r.drive_jumps.is_empty()) {
            println!("device {k}: {} jumped and landed on a stable state", r.name);
        }
        for l in &sim.lost_levels {
            println!("device {k}: {} level {} lost", l.measurement, l.level);
        }
        let rep =
            identify(model, &sim.dataset, &harmonid_ident::Settings::default()).expect("identify");
        let missed = range
            .entries()
            .iter()
            .filter_map(|e| {
                let t = truth_of(truth, &e.name);
                match estimate(&rep, &e.name) {
                    Some((v, s)) if s.is_finite() && s > 0.0 && (v - t).abs() <= 4.0 * s => None,
                    Some((v, s)) => Some(format!(
                        "device {k}: {} = {v:.4e} ± {s:.2e}, truth {t:.4e} ({:.1} stderr)",
                        e.name,
                        (v - t).abs() / s
                    )),
                    None => Some(format!("device {k}: {} not estimated", e.name)),
                }
            })
            .collect();
        let undetermined = range
            .entries()
            .iter()
            .filter(|e| {
                estimate(&rep, &e.name).is_none_or(|(v, s)| {
                    !(s.is_finite() && s <= harmonid_ident::MAX_REL_STDERR * v.abs())
                })
            })
            .map(|e| e.name.clone())
            .collect();
        out.push((missed, undetermined));
    }
    out
}

/// The guess of the two-mode nanostring's tests: off the device (Q1 and Q2 25 % low, β1 and β2
/// 20–25 % low, frequencies 0.3 Hz off, as after a low-drive sweep), with frequencies
/// ± 0.5 Hz, Q ± 40 % and parameters ×/÷ 2 (default).
fn two_mode_guess() -> (Model, ModelValues, GuessRange) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_2mode");
    let model = harmonid_model::load(&root.join("model.hb")).expect("model");
    let guess = values_from_toml(TWO_MODE_GUESS, "guess.toml").expect("guess");
    let spread: BTreeMap<String, Spread> = [
        ("f_hz:q1", Spread::Abs(0.5)),
        ("f_hz:q2", Spread::Abs(0.5)),
        ("Q:q1", Spread::Rel(0.4)),
        ("Q:q2", Spread::Rel(0.4)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let range = GuessRange::new(&model, &guess, &spread).expect("range");
    (model, guess, range)
}

/// The design over `range` as `harmonid plan` makes it by default: with its drive ladder.
fn over(range: &GuessRange) -> DesignSettings {
    DesignSettings {
        range: Some(range.clone()),
        ladder: DEFAULT_LADDER.to_vec(),
        ..two_mode_settings()
    }
}

/// Designs from the guess with `s`, runs the plan on 20 devices drawn from the range (another
/// seed than the design's report) and asserts that at most one misses an unknown by more than
/// 4 stderr (the error bars hold on devices the plan was not designed at); prints how often
/// each unknown stays undetermined; returns the plan.
fn designed_and_run(label: &str, s: &DesignSettings) -> Plan {
    let (model, guess, range) = two_mode_guess();
    let (plan, ev) = design(&model, &guess, s).expect("design");
    println!("{label}\n{}", ev.table());
    let devices = range.draws(20, 1);
    let outcome = run(&model, &plan, &range, &devices);
    let bad: Vec<&Vec<String>> = outcome
        .iter()
        .map(|o| &o.0)
        .filter(|m| !m.is_empty())
        .collect();
    for m in &bad {
        println!("{m:?}");
    }
    let mut undetermined: BTreeMap<&str, usize> = BTreeMap::new();
    for o in &outcome {
        for q in &o.1 {
            *undetermined.entry(q.as_str()).or_default() += 1;
        }
    }
    println!(
        "{label}: {} of {} devices with every unknown within 4 stderr; undetermined (relative \
         stderr > {}): {undetermined:?}",
        outcome.len() - bad.len(),
        outcome.len(),
        harmonid_ident::MAX_REL_STDERR
    );
    assert!(bad.len() <= 1, "{label}: {bad:?}");
    plan
}

#[test]
fn a_plan_over_an_uncertain_guess_determines_every_unknown_on_the_devices_of_its_range() {
    let (_, _, range) = two_mode_guess();
    designed_and_run("two-mode nanostring", &over(&range));
}

/// Issue 23's instrument units: a 1 Hz grid (every tone, so every line, an integer multiple),
/// actuator gains of 0.8 and 0.3 N/kg per V and at most 0.3 V per tone (the cap binds on q1:
/// 0.24 N/kg where the range allows 0.34); the plan's levels are volts, and its error bars hold
/// on the devices of the range as the plan's in N/kg do (measured: 20 of 20; the capped drive
/// leaves β1 and β2 undetermined on most devices, which the table says before the lab does).
#[test]
fn a_plan_in_volts_on_an_instrument_grid_determines_every_unknown_on_the_devices_of_its_range() {
    let (_, _, range) = two_mode_guess();
    let s = DesignSettings {
        grid_hz: 1.0,
        gains: [("q1".to_string(), 0.8), ("q2".to_string(), 0.3)].into(),
        max_voltage: Some(0.3),
        ..over(&range)
    };
    let plan = designed_and_run("two-mode nanostring in volts on a 1 Hz grid", &s);
    let top = plan
        .measurements
        .iter()
        .flat_map(|pm| pm.drive_levels_v.iter().flatten().copied())
        .fold(0.0, f64::max);
    assert_eq!(top, 0.3, "the voltage cap binds");
    for pm in &plan.measurements {
        let levels = pm.drive_levels_v.as_ref().expect("levels");
        for (d, &hz) in pm.drives_hz.iter().enumerate() {
            assert_eq!(hz, hz.round(), "{}: tone {hz} off the 1 Hz grid", pm.name);
            assert!(
                levels[d] > 0.0 && levels[d] <= 0.3,
                "{}: {} V",
                pm.name,
                levels[d]
            );
            for (mode, gain) in [("q1", 0.8), ("q2", 0.3)] {
                if let Some(f) = pm.force.get(mode).map(|f| f[d]).filter(|&f| f != 0.0) {
                    assert!(
                        (f - gain * levels[d]).abs() <= 1e-12 * f,
                        "{}: {f} N/kg",
                        pm.name
                    );
                }
            }
        }
        for hz in pm.measure_hz.as_ref().expect("lines") {
            assert_eq!(*hz, hz.round(), "{}: line {hz} off the grid", pm.name);
        }
    }
}

/// Laser spot at L/10: mode shapes sin(nπ/10) (the nanostring examples' point).
const NANOSTRING_SHAPE: [f64; 5] = [0.309, 0.588, 0.809, 0.951, 1.0];

/// One example planned from a guess off its values (each frequency a quarter linewidth high,
/// every Q and parameter 20 % low) with frequencies ± half a linewidth (as after a low-drive
/// sweep), Q ± 30 % and parameters ×/÷ 2 (the defaults), then run on 20 devices drawn from the
/// range: the share of devices with every unknown within 4 stderr, the undetermined counts and
/// the design's CPU time.
fn example_case(example: &str, shape: &[f64], sigma_m: f64, shots: usize) -> (usize, usize) {
    // The examples, and the models written for this check (tests/fixtures/plan_models).
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = [
        repo.join("examples"),
        repo.join("tests/fixtures/plan_models"),
    ]
    .into_iter()
    .map(|d| d.join(example))
    .find(|d| d.is_dir())
    .unwrap_or_else(|| panic!("no example or plan model {example}"));
    let model = harmonid_model::load(&root.join("model.hb")).expect("model");
    let truth = harmonid_experiment::read_values(&root.join("values.toml")).expect("values");
    let mut guess = truth.clone();
    let mut spread = BTreeMap::new();
    for (name, m) in &mut guess.modes {
        let (f, q) = (m.f_hz.expect("f"), m.q.expect("Q"));
        m.f_hz = Some(f + 0.25 * f / q);
        m.q = Some(0.8 * q);
        spread.insert(format!("f_hz:{name}"), Spread::Abs(0.5 * f / q));
    }
    for v in guess.parameters.values_mut() {
        *v *= 0.8;
    }
    let range = GuessRange::new(&model, &guess, &spread).expect("range");
    let s = DesignSettings {
        sigma_m,
        shots,
        points: point(shape),
        range: Some(range.clone()),
        ladder: DEFAULT_LADDER.to_vec(),
        ..DesignSettings::default()
    };
    let t0 = std::time::Instant::now();
    let (plan, ev) = design(&model, range.guess(), &s).expect("design");
    let seconds = t0.elapsed().as_secs_f64();
    println!("{example}\n{}", ev.table());
    for n in &ev.notes {
        println!("note: {n}");
    }
    let outcome = run(&model, &plan, &range, &range.draws(20, 1));
    let good = outcome.iter().filter(|o| o.0.is_empty()).count();
    let determined = outcome
        .iter()
        .filter(|o| o.0.is_empty() && o.1.is_empty())
        .count();
    for o in outcome.iter().filter(|o| !o.0.is_empty()) {
        println!("{:?}", o.0);
    }
    let mut undetermined: BTreeMap<&str, usize> = BTreeMap::new();
    for o in &outcome {
        for q in &o.1 {
            *undetermined.entry(q.as_str()).or_default() += 1;
        }
    }
    println!(
        "{example}: design {seconds:.1} s wall, {} measurements; every unknown within 4 stderr on \
         {good} of 20 devices, and determined too on {determined}; undetermined: {undetermined:?}",
        plan.measurements.len()
    );
    (good, determined)
}

/// The examples and the two models of `tests/fixtures/plan_models` planned from guesses off
/// their values, each run on 20 devices of its range (minutes; the numbers of
/// docs/planning.md). Issue 23's acceptance check: at least 19 of 20 each.
///
///     cargo test --release --test it -- plan_robust_mc:: --ignored --nocapture
#[test]
#[ignore = "minutes: the examples over their guesses' ranges"]
fn the_examples_planned_from_guesses_off_their_values() {
    let cases: [(&str, &[f64], f64, usize); 8] = [
        ("nanostring_2mode", &NANOSTRING_SHAPE[..2], 5e-11, 20),
        ("internal_1to2", &[], 5e-11, 20),
        ("internal_1to3", &[], 5e-11, 20),
        ("three_wave", &[0.5, 0.5, 0.5], 5e-11, 20),
        ("cubic_3mode", &[0.5, 0.5, 0.5], 5e-11, 20),
        ("damped_2mode", &[], 2e-12, 20),
        ("membrane_4mode", &[], 5e-11, 20),
        ("nanostring_5mode", &NANOSTRING_SHAPE, 1e-10, 30),
    ];
    // HARMONID_EXAMPLES=cubic_3mode,three_wave runs those alone.
    let only = std::env::var("HARMONID_EXAMPLES").ok();
    let mut calibrated = Vec::new();
    for (example, shape, sigma, shots) in cases {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|e| e == example))
        {
            continue;
        }
        let (good, _) = example_case(example, shape, sigma, shots);
        calibrated.push((example, good));
    }
    for (example, good) in calibrated {
        assert!(good >= 19, "{example}: {good} of 20");
    }
}

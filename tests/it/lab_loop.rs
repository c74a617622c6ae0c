//! Issue 37's lab loop, three rounds, with the rounds pooled: plan from a guess off the device
//! (frequencies a fraction of a linewidth off, Q and parameters 20–50 % off, the default
//! spreads) → measure (simulated on the true device with noise) → pool every round so far
//! (`Dataset::merge`, what `harmonid merge` runs) → identify → plan `--after` that result.
//! After three rounds every unknown is within 3 standard errors of the truth, and the next
//! plan's bounds on the device are each within 2× of those of a plan designed from the truth.
//!
//! Runs on the cubic three-mode and (ignored in CI, for time) the three-wave examples. The plans score no drawn devices
//! (`draws: 0`: the corners of the range still decide feasibility), which keeps the loop at a
//! few seconds; the command-line loop is the same (docs/planning.md, "The lab loop").
//!
//!     cargo test --release --test it -- lab_loop:: --nocapture

use crate::guess_support::worst_ratio;
use harmonid::data::Dataset;
use harmonid_experiment::{guess_from_reports, values_from_toml, Guess, Settings};
use harmonid_ident::identify;
use harmonid_ident::Report;
use harmonid_model::Model;
use harmonid_plan::{design, evaluate, DesignSettings, GuessRange};
use harmonid_sim::ModelValues;
use std::path::Path;

const CUBIC_GUESS: &str = "[modes.q1]\nf_hz = 1.00001e6\nQ = 2.0e4\n\
    [modes.q2]\nf_hz = 0.799985e6\nQ = 1.2e4\n\
    [modes.q3]\nf_hz = 1.20002e6\nQ = 3.0e4\n\
    [parameters]\nbeta1 = 2.0e25\nbeta2 = 3.0e25\nbeta3 = 2.2e25\n\
    g12 = 1.0e25\ng13 = 2.8e25\ng23 = 1.2e25\nmu = 1.5e25\n";

const THREE_WAVE_GUESS: &str = "[modes.q1]\nf_hz = 1.00001e6\nQ = 1.6e4\n\
    [modes.q2]\nf_hz = 1.59998e6\nQ = 3.0e4\n\
    [modes.q3]\nf_hz = 2.60002e6\nQ = 2.4e4\n\
    [parameters]\nkappa = 1.4e17\nbeta1 = 3.5e25\nbeta2 = 4.0e25\nbeta3 = 1.6e26\n";

/// 0.05 nm per quadrature, 10 shots, no drawn devices, no ladder (`plan --nominal`'s).
fn settings() -> DesignSettings {
    DesignSettings {
        sigma_m: 5e-11,
        shots: 10,
        draws: 0,
        ..DesignSettings::default()
    }
}

/// The plan designed for the guess's range narrowed by `latest` (the result of every round so
/// far), and that range.
fn plan_after(
    model: &Model,
    guess: &Guess,
    latest: Option<&Report>,
) -> (harmonid_experiment::Plan, GuessRange) {
    let range = GuessRange::new(model, &guess.values, &guess.spread)
        .and_then(|r| {
            r.narrowed(
                model,
                &guess_from_reports(latest.map_or(&[], std::slice::from_ref)),
            )
        })
        .expect("range");
    // As `harmonid plan` does over a range: each measurement on the default drive ladder.
    let s = DesignSettings {
        range: Some(range.clone()),
        ladder: harmonid_plan::default_ladder(true),
        ..settings()
    };
    let (plan, _) = design(model, range.guess(), &s).expect("design");
    (plan, range)
}

/// Every identified unknown's distance from the truth in standard errors, the largest first.
fn deviations(report: &Report, truth: &ModelValues) -> Vec<(f64, String)> {
    let mut v = Vec::new();
    for (name, e) in &report.parameters {
        let t = truth.parameters[name];
        v.push(((e.value - t).abs() / e.stderr, name.clone()));
    }
    for (name, r) in &report.modes {
        let t = &truth.modes[name];
        for (what, e, t) in [("f", &r.f_hz, t.f_hz), ("Q", &r.q, t.q)] {
            if let (true, Some(t)) = (e.stderr > 0.0, t) {
                v.push(((e.value - t).abs() / e.stderr, format!("{what}:{name}")));
            }
        }
    }
    v.sort_by(|a, b| b.0.total_cmp(&a.0));
    v
}

/// Runs three rounds on `example` from `guess_toml`; returns the final worst deviation (in
/// standard errors) and the worst bound ratio of the next plan.
fn three_rounds(example: &str, guess_toml: &str) -> (f64, f64) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(example);
    let model = harmonid_model::load(&root.join("model.hb")).expect("model");
    let truth = harmonid_experiment::read_values(&root.join("values.toml")).expect("truth");
    let guess = Guess {
        values: values_from_toml(guess_toml, "guess.toml").expect("guess"),
        spread: Default::default(),
    };
    let (reference_plan, _) = design(&model, &truth, &settings()).expect("the plan from the truth");
    let reference = evaluate(&model, &truth, &reference_plan, 5e-11, 10).expect("evaluate");
    let tmp = tempfile::tempdir().expect("tempdir");
    let mut rounds: Vec<Dataset> = Vec::new();
    let mut latest: Option<Report> = None;
    for round in 0..3u64 {
        let (plan, _) = plan_after(&model, &guess, latest.as_ref());
        let sim = plan
            .simulate(
                &model,
                &truth,
                &Settings {
                    seed: round,
                    ..Settings::default()
                },
            )
            .expect("the plan runs on the device");
        let dir = tmp.path().join(format!("round{round}"));
        sim.dataset.write(&dir).expect("write the round");
        rounds.push(Dataset::load(&dir).expect("read the round"));
        let pooled = Dataset::merge(&rounds).expect("the rounds merge");
        assert_eq!(
            pooled.measurements.len(),
            rounds.iter().map(|d| d.measurements.len()).sum::<usize>()
        );
        let report =
            identify(&model, &pooled, &harmonid_ident::Settings::default()).expect("identify");
        let worst = deviations(&report, &truth);
        println!(
            "{example} round {round}: worst {:.2} stderr ({})",
            worst[0].0, worst[0].1
        );
        latest = Some(report);
    }
    let worst = deviations(latest.as_ref().expect("three rounds"), &truth)[0].clone();
    let (next, _) = plan_after(&model, &guess, latest.as_ref());
    let on_device = evaluate(&model, &truth, &next, 5e-11, 10).expect("evaluate");
    let (ratio, name) = worst_ratio(&on_device, &reference);
    println!(
        "{example}: after three rounds, worst bound {ratio:.2}× the truth-designed plan's ({name})"
    );
    (worst.0, ratio)
}

#[test]
fn three_pooled_rounds_identify_the_cubic_three_mode_device() {
    let (dev, ratio) = three_rounds("cubic_3mode", CUBIC_GUESS);
    assert!(dev <= 3.0, "an unknown {dev:.2} stderr from the truth");
    assert!(
        ratio <= 2.0,
        "a bound {ratio:.2}× the truth-designed plan's"
    );
}

/// Ignored in CI (32 s alone on the 2-core VM, 2026-11-28; CI stood at 840 of its 900 s): the
/// loop is the cubic device's test's, and the three-wave device's plan and identification are
/// checked in `roundtrip`, `discover` and the plan Monte Carlo tests. Run it with
/// `cargo test --release --test it -- lab_loop::three_pooled_rounds_identify_the_three_wave_device --ignored`.
#[test]
#[ignore = "32 s, beyond CI's budget: run with --ignored"]
fn three_pooled_rounds_identify_the_three_wave_device() {
    let (dev, ratio) = three_rounds("three_wave", THREE_WAVE_GUESS);
    assert!(dev <= 3.0, "an unknown {dev:.2} stderr from the truth");
    assert!(
        ratio <= 2.0,
        "a bound {ratio:.2}× the truth-designed plan's"
    );
}

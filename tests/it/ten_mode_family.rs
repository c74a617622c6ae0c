//! Issue 40: the output-error fit converges wherever the data determine the model, judged on
//! families of devices, not on the one example.
//!
//! - `uniform_q_ten_mode_string_converges` (CI): the ten-mode string with every Q = 1.3·10⁵
//!   (`harmonid_testgen::ten_mode_uniform_q`), planned by `harmonid plan --nominal --noise
//!   0.1nm --shots 30` (the plan is committed: `tests/it/data/ten_mode_uniform_q_plan.toml`),
//!   simulated with 0.1 nm of noise and identified. Before the staged start its fit stopped
//!   unconverged (χ²/dof 4.5 to 320 where a correct model gives 1.04, gains of q6 and q7 at
//!   half their value standing in for wrong frequencies).
//! - `ten_mode_family_study` (ignored, 98 s on 2026-11-27, 5 min before the forward model
//!   solved only the modes each drive reaches): 20 strings drawn around the example's
//!   values (`harmonid_testgen::ten_mode_family`: each Q, β and g ×/÷ 2), each planned
//!   `--nominal` in-process, simulated and identified; at least 19 must converge, fit to their
//!   noise and put every determined quantity within 4 standard errors. Each identification's
//!   time is printed, not asserted (the goal, under 10 s each, is judged by the table and the
//!   benches `identify/many_modes/*` in `benches/ident.rs`). Run with
//!   `cargo test --release --test it -- ten_mode_family::ten_mode_family_study --ignored --nocapture`.
//! - `twenty_mode_string` (ignored: tens of seconds, beyond CI's budget): the twenty-mode
//!   string (20 + 190 unknown parameters, `harmonid_testgen::string_model(20)`) from its
//!   committed nominal plan (`tests/it/data/string_20mode_plan.toml`, 210 measurements),
//!   identified within 4 stderr (the goal: under 60 s). Met at every noise seed tried since
//!   the staged start leaves out of its combination a group whose refinement over the shared
//!   unknowns ended far from the other groups (2026-11-28 04:10 UTC, 2-core VM shared, load
//!   1.9-3.6, 550-560 MB peak with the simulation; χ²/dof expected 1.036, spread 0.016):
//!   seed 11 (`TWENTY_MODE_SEED=11`) 11.7 s, χ²/dof 1.036, 250 of 250 determined, worst 2.84
//!   stderr (g9_12), where it failed before (36 s, 1.52, f of q11 44 stderr off: two pair
//!   groups put q11's damping near zero and the combination followed); seed 20 24.0 s, 1.072,
//!   3.23 (g2_16); seed 7 11.0 s, 1.043, 3.04; seed 3 11.7 s, 1.027, 2.98; seeds 1, 2, 4, 5
//!   13-16 s, 1.029-1.040, worst 2.60-3.61; seeds 6, 8, 9, 10, 12 10.8-19.2 s,
//!   1.014-1.048, worst 2.53-3.36: 13 of 13 pass. The history is in
//!   `examples/nanostring_20mode/README.md`. Run with
//!   `cargo test --release --test it -- ten_mode_family::twenty_mode_string --ignored --nocapture`.

use harmonid::experiment::Plan;
use harmonid::ident::{identify, Report, Settings};
use harmonid::model::Model;
use harmonid_testgen as gen;
use std::path::Path;
use std::time::Instant;

/// How an identification came out against the truth.
struct Verdict {
    converged_and_fits: bool,
    chi2_per_dof: f64,
    expected: f64,
    /// The largest |estimate − truth|/stderr over the determined quantities, and which.
    worst: (f64, String),
    /// Determined quantities (f, Q, parameters) of all.
    determined: (usize, usize),
}

fn judge(model: &Model, rep: &Report, v: &gen::Values) -> Verdict {
    let g = rep.goodness_of_fit.as_ref().expect("verdict");
    let mut worst = (0.0, String::new());
    let mut determined = (0, 0);
    let mut check = |name: String, value: f64, stderr: f64, identifiable: bool, truth: f64| {
        determined.1 += 1;
        if !identifiable {
            return;
        }
        determined.0 += 1;
        let dev = ((value - truth) / stderr).abs();
        if dev.is_nan() || dev > worst.0 {
            worst = (dev, name);
        }
    };
    for (n, m) in model.modes.iter().enumerate() {
        let r = &rep.modes[&m.name];
        let f = &r.f_hz;
        check(
            format!("f of {}", m.name),
            f.value,
            f.stderr,
            f.identifiable,
            v.f_hz[n],
        );
        let q = &r.q;
        check(
            format!("Q of {}", m.name),
            q.value,
            q.stderr,
            q.identifiable,
            v.q[n],
        );
    }
    for (name, e) in &rep.parameters {
        check(
            name.clone(),
            e.value,
            e.stderr,
            e.identifiable,
            v.params[name],
        );
    }
    Verdict {
        converged_and_fits: rep.estimator == "ml" && g.converged && g.fits == Some(true),
        chi2_per_dof: g.chi2_per_dof,
        expected: g.expected_chi2_per_dof,
        worst,
        determined,
    }
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn ten_mode_model() -> Model {
    harmonid::model::load(&root().join("examples/nanostring_10mode/model.hb")).expect("model")
}

fn read_plan(name: &str) -> Plan {
    let path = root().join("tests/it/data").join(name);
    let text = std::fs::read_to_string(&path).expect("plan");
    Plan::from_toml(&text, &path.display().to_string()).expect("plan parses")
}

/// Simulates `plan` at `v` with 30 shots of 0.1 nm, identifies it and judges the result.
fn round_trip(model: &Model, plan: &Plan, v: &gen::Values, seed: u64) -> (Verdict, f64) {
    let clean = gen::simulate_plan(model, plan, v, 30);
    let ds = gen::add_noise(&clean, 1e-10, seed);
    let started = Instant::now();
    let rep = identify(model, &ds, &Settings::default()).expect("identify");
    let secs = started.elapsed().as_secs_f64();
    for w in rep.warnings.iter().chain(&rep.notes).take(6) {
        println!("  {w}");
    }
    (judge(model, &rep, v), secs)
}

/// Prints `verdict` and checks it: converged and fits, every quantity determined, every
/// unknown within 4 standard errors.
fn check_verdict(what: &str, verdict: &Verdict, secs: f64) {
    println!(
        "{what} in {secs:.1} s: χ²/dof {:.3} (expected {:.3}), {} of {} determined, worst {:.2} stderr ({})",
        verdict.chi2_per_dof,
        verdict.expected,
        verdict.determined.0,
        verdict.determined.1,
        verdict.worst.0,
        verdict.worst.1
    );
    assert!(
        verdict.converged_and_fits,
        "χ²/dof {}",
        verdict.chi2_per_dof
    );
    assert_eq!(verdict.determined.0, verdict.determined.1);
    assert!(
        verdict.worst.0 < 4.0,
        "{} is {:.2} stderr off",
        verdict.worst.1,
        verdict.worst.0
    );
}

#[test]
fn uniform_q_ten_mode_string_converges() {
    let model = ten_mode_model();
    let v = gen::ten_mode_uniform_q();
    let (verdict, secs) = round_trip(&model, &read_plan("ten_mode_uniform_q_plan.toml"), &v, 11);
    check_verdict("identified", &verdict, secs);
}

/// The `--nominal` design of `harmonid plan --noise 0.1nm --shots 30` at `v`.
fn nominal_plan(model: &Model, v: &gen::Values) -> Plan {
    let settings = harmonid_plan::DesignSettings {
        sigma_m: 1e-10,
        shots: 30,
        time_budget_s: Some(120.0),
        ladder: harmonid_plan::default_ladder(false),
        ..harmonid_plan::DesignSettings::default()
    };
    harmonid_plan::design(model, &gen::model_values(model, v), &settings)
        .expect("nominal plan")
        .0
}

#[test]
#[ignore = "20 designs and identifications, about 2 min: run with --ignored --nocapture"]
fn ten_mode_family_study() {
    let model = ten_mode_model();
    let mut good = 0;
    let mut slowest: f64 = 0.0;
    println!("seed  plan_s  ident_s  chi2/dof  expected  converged+fits  determined  worst_stderr (quantity)");
    for seed in 1..=20u64 {
        let v = gen::ten_mode_family(seed);
        let started = Instant::now();
        let plan = nominal_plan(&model, &v);
        let plan_s = started.elapsed().as_secs_f64();
        let (verdict, secs) = round_trip(&model, &plan, &v, 100 + seed);
        let ok = verdict.converged_and_fits
            && verdict.determined.0 == verdict.determined.1
            && verdict.worst.0 < 4.0;
        good += usize::from(ok);
        slowest = slowest.max(secs);
        println!(
            "{seed:4}  {plan_s:6.1}  {secs:7.1}  {:8.3}  {:8.3}  {:>14}  {:>4} of {:<3}  {:.2} ({}){}",
            verdict.chi2_per_dof,
            verdict.expected,
            verdict.converged_and_fits,
            verdict.determined.0,
            verdict.determined.1,
            verdict.worst.0,
            verdict.worst.1,
            if ok { "" } else { "  FAILED" }
        );
    }
    println!("{good} of 20 converge within 4 stderr; slowest identification {slowest:.1} s");
    assert!(good >= 19, "{good} of 20");
}

#[test]
#[ignore = "the twenty-mode string, 15-30 s: run with --ignored --nocapture"]
fn twenty_mode_string() {
    let (model, v) = gen::string_model(20);
    // The noise seed: 20 unless TWENTY_MODE_SEED says another (7 and 3 also measured).
    let seed = std::env::var("TWENTY_MODE_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let (verdict, secs) = round_trip(&model, &read_plan("string_20mode_plan.toml"), &v, seed);
    check_verdict("twenty modes identified", &verdict, secs);
}

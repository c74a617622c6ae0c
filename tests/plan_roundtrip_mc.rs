//! The planner's promise checked by Monte Carlo (issue 10): plan → simulate with noise →
//! identify determines every parameter, and the actual scatter of the estimates matches the
//! Cramér–Rao bound the planner predicted for the plan.
//!
//! The short version runs in CI (two-mode nanostring and three-wave example, 16 seeds each, a
//! few seconds); the long one (`--ignored`, 100 seeds per model, one test per model) prints the
//! table of `docs/planning.md`:
//!
//!     cargo test --release --test plan_roundtrip_mc -- --ignored --nocapture --test-threads 1

mod plan_mc_support;

use plan_mc_support::{
    cpu_seconds, misses, point, prepare, run, settings, table, Case, Prepared, Source,
};

/// Laser spot at L/10 from the support: mode shapes sin(nπ/10) of modes 1 and 2 (the point of
/// the two-mode example's plan).
const NANOSTRING_SHAPE: [f64; 2] = [0.309_016_994_374_947_45, 0.587_785_252_292_473_1];

fn two_mode() -> Case {
    Case {
        example: "nanostring_2mode",
        points: point(&NANOSTRING_SHAPE),
        sigma_m: 5e-11,
        shots: 20,
        source: Source::Design,
    }
}

/// A three-mode example designed at 0.05 nm, 20 shots, one point of shape 0.5 for every mode.
fn three_mode(example: &'static str) -> Case {
    Case {
        example,
        points: point(&[0.5, 0.5, 0.5]),
        sigma_m: 5e-11,
        shots: 20,
        source: Source::Design,
    }
}

/// The committed five-mode plan (designed by `harmonid plan` at 0.1 nm, 30 shots; it measures
/// the modal amplitudes: no point).
fn five_mode() -> Case {
    Case {
        example: "nanostring_5mode",
        points: Vec::new(),
        sigma_m: 1e-10,
        shots: 30,
        source: Source::File("plan.toml"),
    }
}

fn label(p: &Prepared, seeds: u64) -> String {
    format!(
        "{}: {} measurements, {:.2} nm, {} shots, {seeds} seeds",
        p.example,
        p.plan.measurements.len(),
        p.plan.sigma_m() * 1e9,
        p.plan.noise.shots
    )
}

/// The bounds `design` returns are those `evaluate` gives for the plan it wrote.
fn design_bounds_are_the_plans(p: &Prepared) {
    let d = p.design_eval.as_ref().expect("a designed case");
    assert_eq!(d.bounds.quantities.len(), p.eval.bounds.quantities.len());
    for (a, b) in d.bounds.quantities.iter().zip(&p.eval.bounds.quantities) {
        assert_eq!(a.name, b.name);
        assert!(
            (a.std / b.std - 1.0).abs() < 1e-3,
            "{}: {}: design {:e}, evaluate {:e}",
            p.example,
            a.name,
            a.std,
            b.std
        );
    }
}

/// Short version for CI: 16 seeds of each designed model (two-mode nanostring, three-wave,
/// cubic; about a second each). First, solving once and adding the noise per seed must give the
/// very dataset `simulate --plan --seed` does. Then loose targets that a defect still fails (a
/// bound off by 2×, σ or shots not those of the plan): each quantity's scatter/bound within
/// 0.5–1.9 (with 15 degrees of freedom a correct bound leaves that range with probability
/// below 0.2 %), their RMS over the model within 0.75–1.33, every quantity determined in every
/// realisation.
#[test]
fn plan_roundtrip_short() {
    let n = 16;
    for (case, seed0) in [
        (two_mode(), 100),
        (three_mode("three_wave"), 200),
        (three_mode("cubic_3mode"), 300),
    ] {
        let p = prepare(&case);
        design_bounds_are_the_plans(&p);
        let sim = p
            .plan
            .simulate(&p.model, &p.values, &settings(seed0, true))
            .expect("simulates");
        assert!(p.noisy(seed0) == sim.dataset, "{}: seed {seed0}", p.example);
        assert!(p.noisy(seed0) != p.noisy(seed0 + 1));
        let rows = table(&run(&p, seed0, n), &label(&p, n));
        let mut ms = 0.0;
        for r in &rows {
            assert_eq!(
                r.undetermined, 0,
                "{}: {} not determined",
                p.example, r.name
            );
            assert!(
                (0.5..=1.9).contains(&r.scatter_over_bound),
                "{}: {}: scatter/bound {:.3}",
                p.example,
                r.name,
                r.scatter_over_bound
            );
            ms += r.scatter_over_bound.powi(2) / rows.len() as f64;
        }
        assert!(
            (0.75..=1.33).contains(&ms.sqrt()),
            "{}: RMS scatter/bound {:.3}",
            p.example,
            ms.sqrt()
        );
    }
}

/// Runs one case of the long Monte Carlo: 100 seeds, every quantity determined in every
/// realisation, scatter within 20 % of the planner's bound. 100 seeds, not 50: a correct bound
/// leaves 1 ± 0.2 with probability 4.7 % at 50 seeds (the sampling error of a standard
/// deviation is `1/√(2(n−1))`, 10 %), so a model of ten quantities would fail by chance one run
/// in three; at 100 seeds (7 %) the probability is 0.5 % per quantity.
/// `HARMONID_MC_SEEDS` overrides the number of seeds (a quicker look; at least 50 for the
/// issue's check).
fn long_case(case: Case, seed0: u64) {
    let n = std::env::var("HARMONID_MC_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100);
    let c0 = cpu_seconds();
    let p = prepare(&case);
    let c1 = cpu_seconds();
    if p.design_eval.is_some() {
        design_bounds_are_the_plans(&p);
    }
    let s = run(&p, seed0, n);
    let c2 = cpu_seconds();
    let l = label(&p, n);
    let rows = table(&s, &l);
    println!(
        "CPU: plan and noise-free simulation {:.1} s, {n} identifications {:.1} s",
        c1 - c0,
        c2 - c1
    );
    let m = misses(&rows, &l, 0.2);
    assert!(m.is_empty(), "missed targets:\n{}", m.join("\n"));
}

#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_two_mode() {
    long_case(two_mode(), 10_000);
}

#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_three_wave() {
    long_case(three_mode("three_wave"), 20_000);
}

#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_cubic_3mode() {
    long_case(three_mode("cubic_3mode"), 30_000);
}

#[test]
#[ignore = "long Monte Carlo (tens of minutes); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_five_mode() {
    long_case(five_mode(), 40_000);
}

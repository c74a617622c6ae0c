//! The planner's promise checked by Monte Carlo (issue 10): plan → simulate with noise →
//! identify determines every parameter, and the actual scatter of the estimates matches the
//! Cramér–Rao bound the planner predicted for the plan.
//!
//! The short version runs in CI (the two-mode nanostring, three-wave and cubic designs, 16 seeds
//! each, a few seconds); the long one (`--ignored`, one test per model: 100 seeds, 400 for the
//! five-mode nanostring) prints the tables of `docs/planning.md`:
//!
//!     cargo test --release --test it -- plan_roundtrip_mc:: --ignored --nocapture --test-threads 1

use crate::plan_mc_support;

use plan_mc_support::{
    cpu_seconds, misses, point, prepare, run, settings, table, Case, Prepared, Source,
};

/// Laser spot at L/10 from the support: mode shapes sin(nπ/10) (the point of the nanostring
/// examples' plans).
const NANOSTRING_SHAPE: [f64; 5] = [
    0.309_016_994_374_947_45,
    0.587_785_252_292_473_1,
    0.809_016_994_374_947_5,
    0.951_056_516_295_153_5,
    1.0,
];

fn two_mode() -> Case {
    Case {
        example: "nanostring_2mode",
        points: point(&NANOSTRING_SHAPE[..2]),
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

/// The committed five-mode plan (designed by `harmonid plan` at 0.1 nm, 30 shots, at the point
/// of shapes sin(nπ/10)).
fn five_mode() -> Case {
    Case {
        example: "nanostring_5mode",
        points: point(&NANOSTRING_SHAPE),
        sigma_m: 1e-10,
        shots: 30,
        source: Source::File("plan.toml"),
    }
}

/// The committed plan of the planning guide's worked example (designed by `harmonid plan` at
/// 0.05 nm, 20 shots, modal amplitudes).
fn membrane_4mode() -> Case {
    Case {
        example: "membrane_4mode",
        points: Vec::new(),
        sigma_m: 5e-11,
        shots: 20,
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

/// Runs one case of the long Monte Carlo: `n` seeds, every quantity determined in every
/// realisation, scatter within 20 % of the planner's bound. At least 100 seeds, not 50: a
/// correct bound leaves 1 ± 0.2 with probability 4.7 % at 50 seeds (the sampling error of a
/// standard deviation is `1/√(2(n−1))`, 10 %), so a model of ten quantities would fail by chance
/// one run in three; at 100 seeds (7 %) the probability is 0.5 % per quantity.
/// `HARMONID_MC_SEEDS` overrides `n` (a quicker look, or a closer one).
fn long_case(case: Case, seed0: u64, n: u64) {
    let n = std::env::var("HARMONID_MC_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(n);
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
#[ignore = "long Monte Carlo (seconds); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_two_mode() {
    long_case(two_mode(), 10_000, 100);
}

#[test]
#[ignore = "long Monte Carlo (seconds); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_three_wave() {
    long_case(three_mode("three_wave"), 20_000, 100);
}

#[test]
#[ignore = "long Monte Carlo (seconds); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_cubic_3mode() {
    long_case(three_mode("cubic_3mode"), 30_000, 100);
}

#[test]
#[ignore = "long Monte Carlo (about 5 min CPU); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_five_mode() {
    // 400 seeds: 25 quantities, some with a scatter 5–10 % above the bound (Q of q4, g34),
    // where 100 seeds cannot tell 1.1 from 1.2 (seeds 40000–40099 alone put g34 at 1.25 and
    // Q4 at 1.20; all 400 at 1.071 and 1.111, the sampling error then 3.5 %).
    long_case(five_mode(), 40_000, 400);
}

#[test]
#[ignore = "long Monte Carlo (about 2 min CPU); run with --ignored --nocapture --test-threads 1"]
fn plan_roundtrip_long_membrane_4mode() {
    long_case(membrane_4mode(), 50_000, 100);
}

//! The planner's round trip as a Monte Carlo (issue 10): a plan (designed by
//! `harmonid_plan::design`, or a committed one scored by `harmonid_plan::evaluate`), simulated
//! noise-free once by the experiment layer, then per seed the plan's noise added and the data
//! identified; the scatter of the estimates is compared with the planner's Cramér–Rao bound.
//!
//! The noise of a realisation is exactly what `harmonid simulate --plan --seed S` adds: one
//! [`NoiseGen`] seeded with `S`, independent per-quadrature Gaussian noise of the plan's σ on
//! every amplitude of every shot, measurement after measurement ([`add_noise`]); the harmonic
//! balance is deterministic, so its state does not depend on the seed and is solved once.
//! `noisy_equals_simulate` in `tests/it/plan_roundtrip_mc.rs` checks the two are the same dataset.

use harmonid_data::{Dataset, Point, TruthNoise};
use harmonid_experiment::{add_noise, read_values, Plan, Settings};
use harmonid_ident::{identify, Estimate, Report};
use harmonid_model::Model;
use harmonid_plan::{design, evaluate, DesignSettings, Evaluation};
use harmonid_sim::{ModelValues, NoiseGen};
use std::path::PathBuf;

/// Where a case's plan comes from.
pub enum Source {
    /// Designed by `harmonid_plan::design` at the case's noise, shots and points.
    Design,
    /// The plan file in the example's folder (its own noise, shots and points).
    File(&'static str),
}

/// One model of the round trip.
pub struct Case {
    /// The example's folder under `examples/` (`model.hb`, `values.toml`).
    pub example: &'static str,
    /// Measurement points (mode shapes); empty: modal amplitudes.
    pub points: Vec<Point>,
    /// Per-quadrature noise, m.
    pub sigma_m: f64,
    /// Shots per measurement.
    pub shots: usize,
    /// The plan.
    pub source: Source,
}

/// The settings of `harmonid simulate --plan --seed seed`, with or without the noise.
pub fn settings(seed: u64, noise: bool) -> Settings {
    Settings {
        seed,
        noise,
        ..Settings::default()
    }
}

/// A case made ready: the plan, the planner's bounds for it, and its noise-free dataset.
pub struct Prepared {
    /// The example's folder name.
    pub example: &'static str,
    pub model: Model,
    /// The true values (the guess the planner designs with).
    pub values: ModelValues,
    pub plan: Plan,
    /// The planner's bounds of the plan (`evaluate` of the plan at the true values).
    pub eval: Evaluation,
    /// The bounds `design` returned with the plan (designed cases).
    pub design_eval: Option<Evaluation>,
    /// Every measurement simulated as `harmonid simulate --plan` does, without noise.
    pub clean: Dataset,
}

fn example(dir: &str, file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(dir)
        .join(file)
}

pub use crate::guess_support::point;

/// Designs (or reads) the plan, scores it and simulates it without noise.
pub fn prepare(case: &Case) -> Prepared {
    let model = harmonid_model::load(&example(case.example, "model.hb")).expect("model");
    let values = read_values(&example(case.example, "values.toml")).expect("values");
    let (plan, design_eval) = match case.source {
        Source::Design => {
            let s = DesignSettings {
                sigma_m: case.sigma_m,
                shots: case.shots,
                points: case.points.clone(),
                ..DesignSettings::default()
            };
            let (plan, ev) = design(&model, &values, &s).expect("design");
            (plan, Some(ev))
        }
        Source::File(name) => {
            let text = std::fs::read_to_string(example(case.example, name)).expect("plan file");
            (Plan::from_toml(&text, name).expect("plan parses"), None)
        }
    };
    // The simulation must add the noise the bounds were computed for.
    assert_eq!(plan.sigma_m(), case.sigma_m, "{}: plan σ", case.example);
    assert_eq!(plan.noise.shots, case.shots, "{}: plan shots", case.example);
    assert_eq!(plan.points, case.points, "{}: plan points", case.example);
    let eval =
        evaluate(&model, &values, &plan, plan.sigma_m(), plan.noise.shots).expect("evaluate");
    let sim = plan
        .simulate(&model, &values, &settings(0, false))
        .expect("the plan simulates");
    for r in &sim.reports {
        for note in &r.notes {
            println!("{}: {}: {note}", case.example, r.name);
        }
    }
    let clean = sim.dataset;
    Prepared {
        example: case.example,
        model,
        values,
        plan,
        eval,
        design_eval,
        clean,
    }
}

impl Prepared {
    /// The dataset `harmonid simulate --plan --seed seed` writes: the noise-free amplitudes
    /// plus the plan's noise drawn from one generator seeded with `seed`.
    pub fn noisy(&self, seed: u64) -> Dataset {
        let mut ds = self.clean.clone();
        let mut gen = NoiseGen::new(seed);
        for m in &mut ds.measurements {
            add_noise(m, self.plan.sigma_m(), &mut gen);
        }
        if let Some(t) = ds.truth.as_mut() {
            t.noise = Some(TruthNoise {
                sigma_per_quadrature: self.plan.noise.sigma_per_quadrature,
                shots: Some(self.plan.noise.shots),
            });
        }
        ds
    }
}

/// One quantity over the realisations.
pub struct Samples {
    /// `f_hz:q1`, `Q:q1`, or the parameter's name.
    pub name: String,
    /// The true value.
    pub truth: f64,
    /// The planner's one-sigma bound (absolute).
    pub bound: f64,
    pub values: Vec<f64>,
    pub stderrs: Vec<f64>,
    /// The seed of each realisation.
    pub seeds: Vec<u64>,
    /// Realisations in which identify did not determine it (not identifiable, or relative
    /// stderr above `MAX_REL_STDERR`).
    pub undetermined: usize,
}

fn get<'a>(r: &'a Report, name: &str) -> Option<&'a Estimate> {
    if let Some(m) = name.strip_prefix("f_hz:") {
        r.modes.get(m).map(|x| &x.f_hz)
    } else if let Some(m) = name.strip_prefix("Q:") {
        r.modes.get(m).map(|x| &x.q)
    } else {
        r.parameters.get(name)
    }
}

/// Every quantity identify estimates (non-zero stderr), by name.
fn estimated(r: &Report) -> Vec<String> {
    let mut out = Vec::new();
    for (m, x) in &r.modes {
        if x.f_hz.stderr > 0.0 {
            out.push(format!("f_hz:{m}"));
        }
        if x.q.stderr > 0.0 {
            out.push(format!("Q:{m}"));
        }
    }
    for (p, x) in &r.parameters {
        if x.stderr > 0.0 {
            out.push(p.clone());
        }
    }
    out
}

/// Identifies the plan's data for seeds `seed0 .. seed0 + n` with the default settings
/// (output-error maximum likelihood).
pub fn run(p: &Prepared, seed0: u64, n: u64) -> Vec<Samples> {
    let mut out: Vec<Samples> = p
        .eval
        .bounds
        .quantities
        .iter()
        .map(|b| Samples {
            name: b.name.clone(),
            truth: b.value,
            bound: b.std,
            values: Vec::new(),
            stderrs: Vec::new(),
            seeds: Vec::new(),
            undetermined: 0,
        })
        .collect();
    for seed in seed0..seed0 + n {
        let ds = p.noisy(seed);
        let rep = identify(&p.model, &ds, &harmonid_ident::Settings::default()).expect("identify");
        assert_eq!(rep.estimator, "ml", "{}: {:?}", p.example, rep.warnings);
        for name in estimated(&rep) {
            assert!(
                out.iter().any(|s| s.name == name),
                "{}: identify estimates {name}, the planner gives no bound for it",
                p.example
            );
        }
        for s in &mut out {
            let e = get(&rep, &s.name).unwrap_or_else(|| panic!("{}: no {}", p.example, s.name));
            let rel = e.stderr / e.value.abs();
            if !e.identifiable || rel.is_nan() || rel > harmonid_ident::MAX_REL_STDERR {
                s.undetermined += 1;
            }
            s.values.push(e.value);
            s.stderrs.push(e.stderr);
            s.seeds.push(seed);
        }
    }
    out
}

/// The summary of one quantity.
pub struct Row {
    pub name: String,
    /// Planner's bound, relative.
    pub bound_rel: f64,
    /// Actual scatter (sample std of the estimates) over the planner's bound.
    pub scatter_over_bound: f64,
    /// Robust scatter (interquartile range / 1.349, the std of a normal distribution) over the
    /// planner's bound: near `scatter_over_bound` unless a few realisations are far out.
    pub robust_over_bound: f64,
    /// (mean − truth) / scatter.
    pub bias_over_scatter: f64,
    /// The largest |estimate − truth| / stderr over the realisations, and its seed.
    pub worst: (f64, u64),
    /// Share of realisations with the truth within ±1 and ±2 reported stderr.
    pub in1: f64,
    pub in2: f64,
    pub undetermined: usize,
}

/// Summarises `samples` and prints the table under `label`.
pub fn table(samples: &[Samples], label: &str) -> Vec<Row> {
    println!("\n{label}");
    println!(
        "{:<10} {:>10} {:>11} {:>11} {:>11} {:>8} {:>8} {:>7} {:>6} {:>6} {:>5} {:>13}",
        "quantity",
        "bound rel",
        "bound",
        "mean stderr",
        "scatter",
        "sc/bnd",
        "rob/bnd",
        "bias/sc",
        "in ±1",
        "in ±2",
        "undet",
        "worst z, seed"
    );
    let mut rows = Vec::new();
    for s in samples {
        let n = s.values.len() as f64;
        let mean = s.values.iter().sum::<f64>() / n;
        let scatter = (s.values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let mse = s.stderrs.iter().sum::<f64>() / n;
        let within = |k: f64| {
            s.values
                .iter()
                .zip(&s.stderrs)
                .filter(|(x, e)| (*x - s.truth).abs() <= k * *e)
                .count() as f64
                / n
        };
        let mut sorted = s.values.clone();
        sorted.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            let x = q * (sorted.len() - 1) as f64;
            let (i, t) = (x.floor() as usize, x.fract());
            sorted[i] + t * (sorted[(i + 1).min(sorted.len() - 1)] - sorted[i])
        };
        let robust = (quantile(0.75) - quantile(0.25)) / 1.349;
        let worst = s
            .values
            .iter()
            .zip(&s.stderrs)
            .zip(&s.seeds)
            .map(|((x, e), &seed)| ((x - s.truth).abs() / e, seed))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
        let row = Row {
            name: s.name.clone(),
            bound_rel: s.bound / s.truth.abs(),
            scatter_over_bound: scatter / s.bound,
            robust_over_bound: robust / s.bound,
            worst,
            bias_over_scatter: (mean - s.truth) / scatter,
            in1: within(1.0),
            in2: within(2.0),
            undetermined: s.undetermined,
        };
        println!(
            "{:<10} {:>10.3e} {:>11.3e} {:>11.3e} {:>11.3e} {:>8.3} {:>8.3} {:>+7.2} {:>5.0}% {:>5.0}% {:>5} {:>5.1} {:>7}",
            row.name,
            row.bound_rel,
            s.bound,
            mse,
            scatter,
            row.scatter_over_bound,
            row.robust_over_bound,
            row.bias_over_scatter,
            100.0 * row.in1,
            100.0 * row.in2,
            row.undetermined,
            row.worst.0,
            row.worst.1
        );
        rows.push(row);
    }
    rows
}

/// The quantities that miss: undetermined in any realisation, or scatter/bound outside
/// `1 ± tol`.
pub fn misses(rows: &[Row], label: &str, tol: f64) -> Vec<String> {
    rows.iter()
        .filter_map(|r| {
            let mut why = Vec::new();
            if r.undetermined > 0 {
                why.push(format!("not determined in {} realisations", r.undetermined));
            }
            if r.scatter_over_bound.is_nan() || (r.scatter_over_bound - 1.0).abs() > tol {
                why.push(format!(
                    "scatter/bound {:.3} (outside 1 ± {tol})",
                    r.scatter_over_bound
                ));
            }
            (!why.is_empty()).then(|| format!("{label}: {}: {}", r.name, why.join(", ")))
        })
        .collect()
}

/// CPU seconds of this process so far (user + system; Linux `/proc`, else 0).
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command name (which ends with the last ')'): utime is the 12th, stime
    // the 13th, in clock ticks of 1/100 s.
    let rest = stat.rsplit_once(')').map_or("", |x| x.1);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    f.iter().sum::<f64>() / 100.0
}

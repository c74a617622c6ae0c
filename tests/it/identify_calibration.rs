//! Monte-Carlo calibration of the reported uncertainties (issue 9): simulate → identify over
//! seeded noise realisations; the truth must fall inside ±1 stderr in ~68 % and ±2 stderr in
//! ~95 % of the realisations, the mean bias must be small against the stderr, and the actual
//! scatter must be close to harmonid's own Cramér–Rao bound.
//!
//! The short version runs in CI; the long one (`--ignored`, ≥ 100 realisations per case) prints
//! the table the issue asks for. The noise-free steady states are simulated once per design and
//! each realisation adds its own seeded noise ([`gen::add_noise`]); every noise level has its
//! own seeds (with shared seeds the realisations at the three levels are the same draws scaled,
//! and a chance deviation repeats at every level).

use harmonid_testgen as gen;

use gen::{add_noise, nanostring_2mode_plan, simulate_clean, Design, Values};
use harmonid_ident::{identify, Estimate, Report, Settings};
use std::path::PathBuf;

fn model(path: &str) -> harmonid_model::Model {
    harmonid_model::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)).expect("model")
}

/// Per quantity: (name, truth, estimates, stderrs, crlbs).
type Samples = Vec<(String, f64, Vec<f64>, Vec<f64>, Vec<f64>)>;

fn truths(v: &Values, names: &[String]) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for (n, name) in names.iter().enumerate() {
        out.push((format!("f_hz:{name}"), v.f_hz[n]));
        out.push((format!("Q:{name}"), v.q[n]));
    }
    for (p, x) in &v.params {
        out.push((p.clone(), *x));
    }
    out
}

fn get<'a>(r: &'a Report, name: &str) -> &'a Estimate {
    if let Some(m) = name.strip_prefix("f_hz:") {
        &r.modes[m].f_hz
    } else if let Some(m) = name.strip_prefix("Q:") {
        &r.modes[m].q
    } else {
        &r.parameters[name]
    }
}

/// Identifies `realisations` noisy copies of `clean` (seeded noise `sigma`, m per quadrature).
fn run(
    model: &harmonid_model::Model,
    v: &Values,
    clean: &harmonid_data::Dataset,
    sigma: f64,
    realisations: u64,
    seed0: u64,
) -> Samples {
    let names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
    let t = truths(v, &names);
    let mut out: Samples = t
        .iter()
        .map(|(n, x)| (n.clone(), *x, Vec::new(), Vec::new(), Vec::new()))
        .collect();
    for r in 0..realisations {
        let ds = add_noise(clean, sigma, seed0 + r);
        let rep = identify(model, &ds, &Settings::default()).expect("identify");
        assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
        for q in out.iter_mut() {
            let e = get(&rep, &q.0);
            assert!(
                e.value.is_finite() && e.stderr.is_finite(),
                "{}: {e:?}",
                q.0
            );
            q.2.push(e.value);
            q.3.push(e.stderr);
            q.4.push(e.crlb.unwrap_or(f64::NAN));
        }
    }
    out
}

/// (name, bias/stderr, within 1 stderr, within 2, scatter/crlb, median relative stderr) per
/// quantity.
fn table(samples: &Samples, label: &str) -> Vec<(String, f64, f64, f64, f64, f64)> {
    println!("\n{label}");
    println!(
        "{:<12} {:>12} {:>9} {:>9} {:>14} {:>12} {:>14}",
        "quantity", "bias/stderr", "in ±1", "in ±2", "scatter/crlb", "rel. stderr", "stderr spread"
    );
    let mut rows = Vec::new();
    for (name, truth, est, se, crlb) in samples {
        let n = est.len() as f64;
        let mean = est.iter().sum::<f64>() / n;
        let scatter = (est.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let mse = se.iter().sum::<f64>() / n;
        if mse == 0.0 {
            println!("{name:<12} fixed by the model");
            continue;
        }
        let mcrlb = crlb.iter().sum::<f64>() / n;
        let z: Vec<f64> = est.iter().zip(se).map(|(x, s)| (x - truth) / s).collect();
        let in1 = z.iter().filter(|z| z.abs() <= 1.0).count() as f64 / n;
        let in2 = z.iter().filter(|z| z.abs() <= 2.0).count() as f64 / n;
        let bias = (mean - truth) / mse;
        let ratio = scatter / mcrlb;
        let mut rel: Vec<f64> = se.iter().map(|s| s / truth.abs()).collect();
        rel.sort_by(f64::total_cmp);
        let rel = rel[rel.len() / 2];
        // Relative spread of the stderr over the realisations (the bound is evaluated at each
        // estimate, and the noise of each line estimated from its shots).
        let spread = (se.iter().map(|s| (s - mse).powi(2)).sum::<f64>() / (n - 1.0)).sqrt() / mse;
        println!(
            "{name:<12} {bias:>+12.3} {:>8.1}% {:>8.1}% {ratio:>14.3} {rel:>12.2e} {spread:>14.3}",
            100.0 * in1,
            100.0 * in2
        );
        rows.push((name.clone(), bias, in1, in2, ratio, rel));
    }
    rows
}

#[test]
fn two_mode_nanostring_stderrs_cover_the_truth() {
    let m = model("examples/nanostring_2mode/model.hb");
    let (v, d) = nanostring_2mode_plan();
    let clean = simulate_clean(&m, &v, &d, &[0.309, 0.588], 10);
    let s = run(&m, &v, &clean, 5e-11, 24, 1000);
    let rows = table(
        &s,
        "two-mode nanostring, 0.05 nm, 10 shots, 24 realisations",
    );
    for (name, bias, in1, in2, _, _) in rows {
        // 24 realisations: loose versions of the long test's targets.
        assert!(bias.abs() < 0.6, "{name}: bias {bias:.2} stderr");
        assert!(
            (0.4..=0.92).contains(&in1),
            "{name}: {in1:.2} within ±1 stderr"
        );
        assert!(in2 >= 0.8, "{name}: {in2:.2} within ±2 stderr");
    }
}

/// Realisations per case of the long calibration: `HARMONID_CALIB_N`, default 1000 (400 for
/// the five-mode string, 1.2 s each). The tolerances (68 ± 8 %, 95 ± 4 %) are 1.7 and
/// 1.8 binomial standard errors at its minimum of 100 realisations: an exact estimator would
/// then miss about one cell in seven of the 75 (quantity, noise level) cells by chance. At 400
/// they are 3.4 and 3.7 standard errors, at 1000 5.4 and 5.8, and a miss means something.
fn long_realisations(default: u64) -> u64 {
    std::env::var("HARMONID_CALIB_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// Runs one case of the long calibration and adds every missed target to `failures`.
fn long_case(
    model_path: &str,
    (v, clean): &(Values, harmonid_data::Dataset),
    sigma: f64,
    n: u64,
    seed0: u64,
    failures: &mut Vec<String>,
) {
    let m = model(model_path);
    let t0 = std::time::Instant::now();
    let s = run(&m, v, clean, sigma, n, seed0);
    let label = format!(
        "{model_path}, {:.3} nm, {} shots, {n} realisations ({:.0} s)",
        sigma * 1e9,
        clean.measurements[0].n_shots,
        t0.elapsed().as_secs_f64()
    );
    for (name, bias, in1, in2, ratio, rel) in table(&s, &label) {
        // A quantity the plan does not determine (harmonid reports it NOT DETERMINED, relative
        // stderr above 0.3) would be listed but not held to the targets; the plans here
        // determine every quantity, so it counts as a miss.
        if rel > harmonid_ident::MAX_REL_STDERR {
            failures.push(format!(
                "{label}: {name} not determined by the plan (median relative stderr {rel:.2})"
            ));
            continue;
        }
        if bias.abs() >= 0.3
            || !(0.60..=0.76).contains(&in1)
            || !(0.91..=0.99).contains(&in2)
            || ratio > 1.2
        {
            failures.push(format!(
                "{label}: {name}: bias {bias:.2}, ±1 {in1:.2}, ±2 {in2:.2}, scatter/crlb {ratio:.2}"
            ));
        }
    }
}

/// The long calibration: the four models at 0.01, 0.05 and 0.1 nm (the damped one at 1, 2 and
/// 5 pm), each noise level with its own seeds.
/// `HARMONID_CALIB_ONLY=two_mode|five_mode|three_wave|cubic|damped` runs one model.
#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture"]
fn calibration_long() {
    let only = std::env::var("HARMONID_CALIB_ONLY").ok();
    let want = |k: &str| only.as_deref().is_none_or(|o| o == k);
    let mut failures = Vec::new();
    let hand = |path: &str, (v, d): (Values, Vec<Design>), shape: &[f64], shots| {
        let clean = simulate_clean(&model(path), &v, &d, shape, shots);
        (v, clean)
    };
    // The five-mode string: the hand-made fold-scaled plan (30 shots), or with
    // `HARMONID_CALIB_FIVE=designed` the designed `examples/nanostring_5mode/plan.toml`. The
    // designed plan drives closer to the folds: at the pooled linear estimate the harmonic
    // balance of "couple_q1_q2" often has no steady state, and the fit from the fall-back
    // start can end in another minimum (f1 off by 0.4 Hz on noise-free data); not yet
    // calibrated (docs/identification.md).
    let five = |path: &str| {
        if std::env::var("HARMONID_CALIB_FIVE").is_ok_and(|x| x == "designed") {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_5mode");
            gen::simulate_plan_file(&model(path), &dir, 30)
        } else {
            hand(
                path,
                gen::nanostring_5mode_fold_plan(),
                &gen::NANOSTRING_SHAPE,
                30,
            )
        }
    };
    type Prepare<'a> = Box<dyn Fn(&str) -> (Values, harmonid_data::Dataset) + 'a>;
    // The noise levels of every case but the damped one, whose damping shows as a few per cent
    // of the response: at 0.05 nm its plan leaves beta2 and eta1 undetermined.
    const LEVELS: [f64; 3] = [1e-11, 5e-11, 1e-10];
    const QUIET: [f64; 3] = [1e-12, 2e-12, 5e-12];
    let cases: Vec<(&str, &str, Prepare, u64, u64)> = vec![
        (
            "two_mode",
            "examples/nanostring_2mode/model.hb",
            Box::new(|p: &str| hand(p, gen::nanostring_2mode_fold_plan(), &[0.309, 0.588], 20)),
            1000,
            5000,
        ),
        (
            "five_mode",
            "examples/nanostring_5mode/model.hb",
            Box::new(five),
            400,
            9000,
        ),
        (
            "three_wave",
            "examples/three_wave/model.hb",
            Box::new(|p: &str| hand(p, gen::three_wave_plan(), &[0.5; 3], 20)),
            1000,
            13000,
        ),
        (
            "cubic",
            "examples/cubic_3mode/model.hb",
            Box::new(|p: &str| hand(p, gen::cubic_3mode_plan(), &[0.5; 3], 20)),
            1000,
            17000,
        ),
        (
            "damped",
            "examples/damped_2mode/model.hb",
            Box::new(|p: &str| hand(p, gen::damped_2mode_plan(), &[0.5, 0.5], 20)),
            1000,
            21000,
        ),
    ];
    for (key, path, prepare, n, seed0) in &cases {
        if !want(key) {
            continue;
        }
        let case = prepare(path);
        let levels = if *key == "damped" { QUIET } else { LEVELS };
        for (i, sigma) in levels.into_iter().enumerate() {
            let seed = seed0 + 100_000 * i as u64;
            let n = long_realisations(*n);
            long_case(path, &case, sigma, n, seed, &mut failures);
        }
    }
    assert!(
        failures.is_empty(),
        "missed targets:\n{}",
        failures.join("\n")
    );
}

/// The short version of the three-mode cases for CI: 16 realisations at 0.05 nm each of the
/// three-wave and cubic examples (about a second); loose versions of the long test's targets.
#[test]
fn three_mode_stderrs_cover_the_truth() {
    for (path, (v, d), seed0) in [
        ("examples/three_wave/model.hb", gen::three_wave_plan(), 300),
        (
            "examples/cubic_3mode/model.hb",
            gen::cubic_3mode_plan(),
            400,
        ),
    ] {
        let m = model(path);
        let clean = simulate_clean(&m, &v, &d, &[0.5, 0.5, 0.5], 20);
        let s = run(&m, &v, &clean, 5e-11, 16, seed0);
        short_targets(table(
            &s,
            &format!("{path}, 0.05 nm, 20 shots, 16 realisations"),
        ));
    }
}

/// Relative Cramér–Rao bounds of every quantity of the five-mode string at its truth, 0.1 nm
/// and 30 shots, for a plan.
fn five_mode_bounds((v, d): &(Values, Vec<Design>)) -> Vec<(String, f64)> {
    let m = model("examples/nanostring_5mode/model.hb");
    let names: Vec<String> = m.modes.iter().map(|x| x.name.clone()).collect();
    let clean = simulate_clean(&m, v, d, &gen::NANOSTRING_SHAPE, 1);
    let mut fwd = harmonid_ident::ForwardModel::new(
        &m,
        &clean,
        harmonid_ident::ForceModel::GainPerMeasurement,
        &harmonid_ident::ForwardSettings::default(),
    )
    .expect("forward model");
    let theta = fwd
        .theta_from(
            &gen::model_values(&m, v),
            &gen::truth_forces(&clean, &names),
        )
        .expect("truth");
    fwd.start_from_data(&clean);
    let b = harmonid_ident::crlb(&mut fwd, &theta, &harmonid_ident::Noise::Uniform(1e-10), 30)
        .expect("bounds");
    assert!(b.unidentifiable.is_empty(), "{:?}", b.unidentifiable);
    b.quantities
        .iter()
        .map(|q| (q.name.clone(), q.rel))
        .collect()
}

/// The five-mode calibration needs a plan that determines every parameter at every noise
/// level: with 3.5 N/kg on every mode, β4, β5 and the couplings among q3–q5 are known to
/// 30 % or worse at 0.1 nm (β5 not even in sign), their estimates are clipped at `g ≥ 0` or wander
/// into the nonlinear range of the model, and f5, which they shift, scattered 1.36× its
/// bound at 0.1 nm (1.48× for an unbounded fit with the true noise). The fold-scaled plan
/// determines every quantity to 15 % or better.
#[test]
fn five_mode_fold_plan_determines_every_parameter() {
    let weak = five_mode_bounds(&gen::nanostring_5mode_plan());
    let loose: Vec<&str> = weak
        .iter()
        .filter(|(_, r)| *r > harmonid_ident::MAX_REL_STDERR)
        .map(|(n, _)| n.as_str())
        .collect();
    for p in ["beta4", "beta5", "g34", "g35", "g45"] {
        assert!(loose.contains(&p), "{p}: {weak:?}");
    }
    for (name, rel) in five_mode_bounds(&gen::nanostring_5mode_fold_plan()) {
        assert!(rel < 0.15, "{name}: relative bound {rel:.3}");
    }
}

/// The short version of the nonlinear-damping case for CI (issue 20): 16 realisations at
/// 2 pm of `examples/damped_2mode` (nonlinear damping and a velocity coupling); loose
/// versions of the long test's targets.
#[test]
fn nonlinear_damping_stderrs_cover_the_truth() {
    let path = "examples/damped_2mode/model.hb";
    let m = model(path);
    let (v, d) = gen::damped_2mode_plan();
    let clean = simulate_clean(&m, &v, &d, &[0.5, 0.5], 20);
    // The damping shows as a few per cent of the response at 10 nm: 2 pm of noise determines
    // every unknown to about 10 % (at 50 pm the plan leaves beta2 and eta1 undetermined).
    let s = run(&m, &v, &clean, 2e-12, 16, 500);
    short_targets(table(
        &s,
        &format!("{path}, 0.002 nm, 20 shots, 16 realisations"),
    ));
}

/// The short versions' loose targets (16 realisations): every quantity determined by the plan,
/// |bias| < 0.8 stderr, ±1 stderr in 35–97 %, ±2 stderr in at least 75 %.
fn short_targets(rows: Vec<(String, f64, f64, f64, f64, f64)>) {
    for (name, bias, in1, in2, _, rel) in rows {
        assert!(
            rel <= harmonid_ident::MAX_REL_STDERR,
            "{name}: the plan determines it ({rel:.2})"
        );
        assert!(bias.abs() < 0.8, "{name}: bias {bias:.2} stderr");
        assert!(
            (0.35..=0.97).contains(&in1),
            "{name}: {in1:.2} within ±1 stderr"
        );
        assert!(in2 >= 0.75, "{name}: {in2:.2} within ±2 stderr");
    }
}

//! The goodness-of-fit verdict (issue 22) on data from a correct model: its p-value must be
//! uniform and "does not fit" (p < 1e-3) must be as rare as it says. simulate → identify over
//! seeded noise realisations; the short version runs in CI, the long one (`--ignored`,
//! `HARMONID_GOF_N` realisations per case, default 1000) prints the table of the closing note.
//! And on data the model cannot describe (a Duffing term left out) the verdict is "does not
//! fit", naming the measurement.

use harmonid_testgen as gen;

use gen::{add_noise, nanostring_2mode_plan, simulate, simulate_clean, Design, Values};
use harmonid_data::Dataset;
use harmonid_ident::{identify, Settings, P_DOES_NOT_FIT};
use std::path::PathBuf;

fn model(path: &str) -> harmonid_model::Model {
    harmonid_model::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)).expect("model")
}

/// The p-values of `n` noisy copies of `clean` (noise `sigma`, m per quadrature).
fn p_values(
    m: &harmonid_model::Model,
    clean: &Dataset,
    sigma: f64,
    n: u64,
    seed0: u64,
) -> Vec<f64> {
    use rayon::prelude::*;
    (0..n)
        .into_par_iter()
        .map(|r| {
            let ds = add_noise(clean, sigma, seed0 + r);
            let rep = identify(m, &ds, &Settings::default()).expect("identify");
            let g = rep.goodness_of_fit.expect("the ml estimate is judged");
            assert!(g.converged, "seed {}: {:?}", seed0 + r, rep.notes);
            g.p_value.expect("noise from the shot scatter")
        })
        .collect()
}

/// Kolmogorov–Smirnov distance of `p` from the uniform distribution.
fn ks_uniform(p: &mut [f64]) -> f64 {
    p.sort_by(f64::total_cmp);
    let n = p.len() as f64;
    p.iter()
        .enumerate()
        .map(|(i, &x)| (x - i as f64 / n).abs().max(((i + 1) as f64 / n - x).abs()))
        .fold(0.0, f64::max)
}

/// (false alarms at P_DOES_NOT_FIT, KS distance, fraction below 0.05) of `p`.
fn summary(p: &mut [f64]) -> (usize, f64, f64) {
    let alarms = p.iter().filter(|&&x| x < P_DOES_NOT_FIT).count();
    let below = p.iter().filter(|&&x| x < 0.05).count() as f64 / p.len() as f64;
    (alarms, ks_uniform(p), below)
}

#[test]
fn a_correct_model_fits_at_the_nominal_rate() {
    let m = model("examples/nanostring_2mode/model.hb");
    let (v, d) = nanostring_2mode_plan();
    let clean = simulate_clean(&m, &v, &d, &[0.309, 0.588], 10);
    let mut p = p_values(&m, &clean, 5e-11, 60, 5000);
    let (alarms, ks, below) = summary(&mut p);
    eprintln!("two-mode, 0.05 nm, 10 shots, 60 realisations: {alarms} alarms, KS {ks:.3}, p<0.05 in {:.1} %", 100.0 * below);
    // 60 draws: the 1 % KS critical value is 0.21; p < 0.05 in at most 12 (binomial 99.9 %).
    assert_eq!(alarms, 0, "a correct model said not to fit");
    assert!(ks < 0.21, "p-values not uniform: KS distance {ks:.3}");
    assert!(below <= 0.2, "p < 0.05 in {:.0} %", 100.0 * below);
}

#[test]
fn a_model_without_the_duffing_term_does_not_fit() {
    // The data have β₁ = 2.68e22 (the example's); the model has no Duffing term on q1.
    let truth = model("examples/nanostring_2mode/model.hb");
    let (v, d) = nanostring_2mode_plan();
    let ds = simulate(&truth, &v, &d, &[0.309, 0.588], 5e-11, 10, 77);
    let wrong = harmonid_model::parse_str(
        "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta2, g12\n\
         potential: beta2/4*q2^4\npotential: g12/2*q1^2*q2^2\n",
        "no_beta1.hb",
    )
    .expect("model without beta1");
    let rep = identify(&wrong, &ds, &Settings::default()).expect("identify");
    let g = rep.goodness_of_fit.as_ref().expect("judged");
    assert_eq!(g.fits, Some(false), "{g:?}");
    assert!(g.p_value.expect("p") < 1e-6);
    assert!(
        rep.warnings[0].starts_with("THE MODEL DOES NOT FIT THE DATA"),
        "{:?}",
        rep.warnings
    );
    // The measurement that drives mode 1 hard is the worst.
    assert!(
        rep.warnings[0].contains("Worst: \"single_q1\""),
        "{}",
        rep.warnings[0]
    );
    let summary = rep.summary(None);
    assert!(
        summary.starts_with("THE MODEL DOES NOT FIT THE DATA"),
        "{summary}"
    );
    // Model-limited error bars are inflated, and said so.
    assert!(
        g.stderr_inflation > 2.0 && summary.contains("model-limited"),
        "{summary}"
    );
}

fn long_n() -> u64 {
    std::env::var("HARMONID_GOF_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000)
}

/// A long-study case: model path, values and designs, mode shape at the point, shots.
type Case = (&'static str, (Values, Vec<Design>), Vec<f64>, usize);

/// The long version: the two-mode and five-mode nanostrings, the three-wave and cubic
/// examples, each at 0.01 and 0.1 nm. Prints the table; fails when a case false-alarms in more
/// than 0.3 % or its KS distance exceeds the 1 % critical value.
#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture"]
fn goodness_of_fit_long() {
    let n = long_n();
    let mut cases: Vec<Case> = vec![
        (
            "examples/nanostring_2mode/model.hb",
            nanostring_2mode_plan(),
            vec![0.309, 0.588],
            10,
        ),
        (
            "examples/nanostring_5mode/model.hb",
            gen::nanostring_5mode_fold_plan(),
            gen::NANOSTRING_SHAPE.to_vec(),
            20,
        ),
    ];
    cases.push((
        "examples/three_wave/model.hb",
        gen::three_wave_plan(),
        vec![0.5; 3],
        20,
    ));
    cases.push((
        "examples/cubic_3mode/model.hb",
        gen::cubic_3mode_plan(),
        vec![0.5; 3],
        20,
    ));
    let mut failures = Vec::new();
    eprintln!("| model | noise | shots | realisations | p < 1e-3 | KS distance (1 % critical) | p < 0.05 |");
    eprintln!("|---|---|---|---|---|---|---|");
    for (ci, (path, (v, d), shape, shots)) in cases.iter().enumerate() {
        let m = model(path);
        let clean = simulate_clean(&m, v, d, shape, *shots);
        for (li, sigma) in [1e-11, 1e-10].into_iter().enumerate() {
            let seed0 = 100_000 * (1 + ci as u64) + 10_000 * li as u64;
            let mut p = p_values(&m, &clean, sigma, n, seed0);
            let (alarms, ks, below) = summary(&mut p);
            let crit = 1.63 / (n as f64).sqrt();
            eprintln!(
                "| {path} | {:.2} nm | {shots} | {n} | {alarms} ({:.2} %) | {ks:.3} ({crit:.3}) | {:.1} % |",
                sigma * 1e9,
                100.0 * alarms as f64 / n as f64,
                100.0 * below
            );
            if alarms as f64 > 0.003 * n as f64 || ks > crit {
                failures.push(format!("{path} at {sigma:e}: {alarms} alarms, KS {ks:.3}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// `identify --holdout` (issue 22, item 2): a correct model predicts a held-out measurement
/// to about its noise; one without q1's Duffing term misses it by far more; bad holdouts are
/// refused with the names; a quantity the rest leaves undetermined is warned about.
#[test]
fn held_out_measurements_are_predicted_by_a_correct_model_only() {
    use harmonid_ident::{identify_with_holdout, IdentError};
    let truth = model("examples/nanostring_2mode/model.hb");
    let (v, d) = gen::nanostring_2mode_fold_plan();
    let ds = simulate(&truth, &v, &d, &[0.309, 0.588], 1e-11, 20, 91);
    let held = vec!["single_q1".to_string()];
    let rep = identify_with_holdout(&truth, &ds, &held, &Settings::default()).expect("holdout");
    assert_eq!(rep.holdout.len(), 1);
    let h = &rep.holdout[0];
    assert_eq!(h.measurement, "single_q1");
    let rms = h.rms_sigma.expect("noise from the shots");
    // Above 1: the prediction carries the estimate's own uncertainty besides the noise.
    assert!((0.5..3.0).contains(&rms), "correct model: {rms} sigmas");
    // The fit itself saw no single_q1.
    let g = rep.goodness_of_fit.as_ref().expect("judged");
    assert!(g.measurements.iter().all(|m| m.name != "single_q1"));
    assert!(rep.summary(None).contains("held out \"single_q1\""));
    // A model that cannot describe q1's nonlinearity, fitted on the coupled measurement
    // (where q1's nonlinearity is mixed with the coupling), predicts single_q1 badly.
    let without = harmonid_model::parse_str(
        "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta2, g12\n\
         potential: beta2/4*q2^4\npotential: g12/2*q1^2*q2^2\n",
        "no_beta1.hb",
    )
    .expect("model");
    let bad = identify_with_holdout(&without, &ds, &held, &Settings::default()).expect("holdout");
    let bad_rms = bad.holdout[0].rms_sigma.expect("noise");
    eprintln!("held-out single_q1: correct model {rms:.3} sigmas ({:.3} %), without beta1 {bad_rms:.3} sigmas ({:.3} %)", 100.0 * h.relative_rms, 100.0 * bad.holdout[0].relative_rms);
    assert!(
        bad_rms > 5.0 * rms,
        "wrong model predicts to {bad_rms} sigmas, right one {rms}"
    );
    // Bad input: an unknown name, every measurement.
    let e = identify_with_holdout(&truth, &ds, &["nope".to_string()], &Settings::default())
        .expect_err("unknown measurement");
    assert!(
        matches!(e, IdentError::Holdout(_))
            && e.to_string().contains("no measurement or sweep \"nope\""),
        "{e}"
    );
    let all: Vec<String> = ds
        .measurements
        .iter()
        .map(|m| m.spec.name.clone())
        .collect();
    let e = identify_with_holdout(&truth, &ds, &all, &Settings::default()).expect_err("all");
    assert!(e.to_string().contains("every measurement"), "{e}");
    // A name given twice is one measurement held out, not two.
    let twice = vec!["single_q1".to_string(); 3];
    let rep = identify_with_holdout(&truth, &ds, &twice, &Settings::default()).expect("twice");
    assert_eq!(rep.holdout.len(), 1);
    // Without the coupled measurement g12 has no value at all: refused, naming it.
    let coupled = vec!["couple_q1_q2".to_string()];
    let e = identify_with_holdout(&truth, &ds, &coupled, &Settings::default()).expect_err("g12");
    assert!(e.to_string().contains("do not determine g12"), "{e}");
    // Without single_q2, beta2 has a value but is not determined (relative stderr 0.49): the
    // prediction is made from it, a warning names it, and the misfit shows it mattered.
    let q2 = vec!["single_q2".to_string()];
    let rep = identify_with_holdout(&truth, &ds, &q2, &Settings::default()).expect("predicted");
    assert!(
        rep.warnings
            .iter()
            .any(|w| w
                .contains("--holdout single_q2: the other measurements do not determine beta2")),
        "{:?}",
        rep.warnings
    );
    let rms = rep.holdout[0].rms_sigma.expect("noise from the shots");
    assert!(
        rms > 10.0,
        "undetermined beta2 predicts single_q2 to {rms} sigmas"
    );
}

/// A `Q` the model fixes is reported as the model's value exactly, also when `f` is identified
/// by the output-error fit (before: `√ω²_ml / γ_linear`, about 1e-7 off).
#[test]
fn a_fixed_q_is_reported_exactly() {
    let m = model("examples/cubic_3mode/model.hb");
    let (v, d) = gen::cubic_3mode_plan();
    let clean = simulate_clean(&m, &v, &d, &[0.5, 0.5, 0.5], 20);
    let rep = identify(&m, &add_noise(&clean, 5e-11, 3), &Settings::default()).expect("identify");
    assert_eq!(rep.estimator, "ml");
    assert_eq!(rep.modes["q1"].q.value, 2e4, "{:?}", rep.modes["q1"].q);
}

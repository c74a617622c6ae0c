//! An error floor fitted with the model (`identify --error-floor`) keeps its promise: on a
//! stepped sweep whose steps carry an error their own samples do not see (each step's mean
//! off by a Gaussian error of its own, ten times the shot noise of the mean, as drift between
//! steps does), the shot noise alone misses the data, while with the floor the truth is
//! within 1 / 2 standard errors as often as it should be and the floor found is the one put
//! in. Without such an error, the floor found is small and the estimates those of the shot
//! noise alone.

use harmonid::data::Dataset;
use harmonid::ident::{identify, ForceModel, Settings};
use harmonid_testgen as gen;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const SHOTS: usize = 10;
/// Shot noise per quadrature of one sample, m.
const SIGMA_SHOT: f64 = 3e-12;
/// The steps' own error per quadrature, m: ten times the shot noise of a step's mean.
const SIGMA_STEP: f64 = 10.0 * SIGMA_SHOT / 3.162_277_660_168_379_5;

fn setup() -> (harmonid::model::Model, gen::Values, Dataset) {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let clean = gen::simulate_clean(&model, &v, &d, &[1.0], SHOTS);
    (model, v, clean)
}

/// `clean` with shot noise on every sample and an error of its own on every step's lines
/// (the same for all its shots).
fn noisy(clean: &Dataset, step_sigma: f64, seed: u64) -> Dataset {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let shot = Normal::new(0.0, SIGMA_SHOT).expect("normal");
    let step = Normal::new(0.0, step_sigma.max(f64::MIN_POSITIVE)).expect("normal");
    let mut ds = clean.clone();
    for m in &mut ds.measurements {
        let per = m.freqs_hz.len() * m.points.len();
        let offsets: Vec<Complex64> = (0..per)
            .map(|_| Complex64::new(step.sample(&mut rng), step.sample(&mut rng)))
            .collect();
        for (i, x) in m.data.iter_mut().enumerate() {
            *x += offsets[i % per] + Complex64::new(shot.sample(&mut rng), shot.sample(&mut rng));
        }
    }
    ds
}

fn settings(error_floor: bool) -> Settings {
    Settings {
        force_model: ForceModel::GainPerMode,
        error_floor,
        jackknife: false,
        ..Settings::default()
    }
}

/// Per quantity (f, Q, beta1, eta1): the fraction of `runs` realisations with the truth
/// within 1 and 2 standard errors, and the median floor found over the floor put in.
fn coverage(runs: u64) -> ([(f64, f64); 4], f64) {
    let (model, v, clean) = setup();
    let truth = [v.f_hz[0], v.q[0], v.params["beta1"], v.params["eta1"]];
    let mut hits = [(0usize, 0usize); 4];
    let mut floors = Vec::new();
    for seed in 0..runs {
        let ds = noisy(&clean, SIGMA_STEP, seed);
        let rep = identify(&model, &ds, &settings(true)).expect("identify");
        assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
        let g = rep.goodness_of_fit.as_ref().expect("verdict");
        assert_eq!(
            (g.p_value, g.fits),
            (None, None),
            "a fitted floor is not judged"
        );
        floors.push(g.error_floor.expect("a floor") / SIGMA_STEP);
        let est = [
            &rep.modes["q1"].f_hz,
            &rep.modes["q1"].q,
            &rep.parameters["beta1"],
            &rep.parameters["eta1"],
        ];
        for ((h, e), t) in hits.iter_mut().zip(est).zip(truth) {
            let dev = ((e.value - t) / e.stderr).abs();
            h.0 += usize::from(dev <= 1.0);
            h.1 += usize::from(dev <= 2.0);
        }
    }
    floors.sort_by(f64::total_cmp);
    let n = runs as f64;
    (
        hits.map(|(a, b)| (a as f64 / n, b as f64 / n)),
        floors[floors.len() / 2],
    )
}

#[test]
fn the_floor_is_found_and_its_error_bars_cover_the_truth() {
    let (cover, floor) = coverage(24);
    println!(
        "coverage (±1, ±2 stderr) of f, Q, beta1, eta1: {cover:?}; median floor / true {floor:.3}"
    );
    assert!(
        (0.85..1.15).contains(&floor),
        "floor found / put in: {floor}"
    );
    for (in1, in2) in cover {
        assert!((0.4..=0.95).contains(&in1), "{cover:?}");
        assert!(in2 >= 0.8, "{cover:?}");
    }
}

/// The long calibration: 400 realisations (about a minute).
#[test]
#[ignore]
fn the_floor_is_calibrated_over_many_realisations() {
    let (cover, floor) = coverage(400);
    println!(
        "coverage (±1, ±2 stderr) of f, Q, beta1, eta1: {cover:?}; median floor / true {floor:.3}"
    );
    assert!(
        (0.95..1.05).contains(&floor),
        "floor found / put in: {floor}"
    );
    for (in1, in2) in cover {
        assert!((0.60..=0.76).contains(&in1), "{cover:?}");
        assert!((0.91..=0.99).contains(&in2), "{cover:?}");
    }
}

#[test]
fn shot_noise_alone_misses_such_data_and_a_floor_changes_little_without_them() {
    let (model, v, clean) = setup();
    // With the steps' own errors the shot noise alone does not fit.
    let ds = noisy(&clean, SIGMA_STEP, 1);
    let rep = identify(&model, &ds, &settings(false)).expect("identify");
    let g = rep.goodness_of_fit.as_ref().expect("verdict");
    assert_eq!(g.fits, Some(false), "{}", g.one_line());
    assert!(g.error_floor.is_none());
    // Without them the floor found is below the shot noise of a mean, and the estimates
    // move by a fraction of their error bars.
    let ds = noisy(&clean, 0.0, 2);
    let plain = identify(&model, &ds, &settings(false)).expect("identify");
    let floored = identify(&model, &ds, &settings(true)).expect("identify");
    let floor = floored
        .goodness_of_fit
        .as_ref()
        .and_then(|g| g.error_floor)
        .expect("a floor");
    assert!(
        floor < SIGMA_SHOT / 3.0,
        "floor {floor:e} on data without step errors"
    );
    for name in ["beta1", "eta1"] {
        let (a, b) = (&plain.parameters[name], &floored.parameters[name]);
        assert!(
            (a.value - b.value).abs() < 0.3 * a.stderr,
            "{name}: {} vs {} (stderr {})",
            a.value,
            b.value,
            a.stderr
        );
        assert!((b.value - v.params[name]).abs() < 4.0 * b.stderr);
    }
}

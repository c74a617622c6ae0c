//! Criterion benches for harmonid-ident: identification of the five-mode nanostring from 15
//! measurements (5 two-tone, 10 three-tone), per shot.
//!
//! `fit_1shot`: all 15 fits of one shot (products, regressors, equilibrated SVD solves).
//! `fit_20shots`: 20 shots with row weights from shot scatter (three passes), reported per
//! shot through criterion's throughput.
//! `identify_ml_30shots`: the whole default identification of 30 shots at 0.1 nm (per-shot
//! fits, pooling, pooled linear fit, output-error ML by harmonic balance, Fisher stderrs,
//! jackknife, drift check).
//! `stepped_sweep_160steps`: a stepped-sine sweep as a lock-in records it (issue 20): one
//! Duffing mode with nonlinear damping, 40 single-tone steps at each of 4 drive levels, each
//! step a measurement of one line, 10 shots, one actuator gain for the whole sweep; the whole
//! default identification.
//! `hysteretic_1152steps`, `hysteretic_10008steps`: a lab's stepped-sine frequency response
//! (issue 35): a softening Duffing mode with nonlinear damping, 12 drive levels each swept up
//! and down through its folds (48 or 417 steps a sweep, 5 samples a step, 0.02 nm), the whole
//! identification with the error floor, one gain for the dataset.
//! `ten_mode_uniform_q`, `ten_mode_example`, `twenty_mode_string` (issue 40): the ten-mode
//! string with every Q = 1.3e5 (`harmonid_testgen::ten_mode_uniform_q`), the ten-mode example
//! itself (`examples/nanostring_10mode` and its plan) and the twenty-mode string (20 + 190
//! unknown parameters, `harmonid_testgen::string_model(20)`), each from its committed
//! `harmonid plan --nominal --noise 0.1nm --shots 30` plan (`tests/it/data/`), 30 shots at
//! 0.1 nm; the whole default identification. `HARMONID_BENCH_SKIP_20=1` leaves the twenty-mode
//! one out (a sample is about 30 s: 28.5 s on the 2-core VM at load 3.5).
//! `long_record_1m_rows`: one Duffing mode driven by two tones (the nanostring's `single_q1`),
//! 125 000 shots of its 8 lines at 0.05 nm, 1 million rows, as a long lock-in record gives;
//! the whole default identification.
#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use harmonid_ident::{identify, ForceModel, Problem, Settings};
use std::hint::black_box;
use std::path::PathBuf;

use harmonid_testgen as gen;

fn bench_identify(c: &mut Criterion) {
    let model = harmonid_model::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_5mode/model.hb"),
    )
    .expect("example model");
    let (v, d) = gen::nanostring_5mode_plan();
    let settings = Settings::default();
    let mut group = c.benchmark_group("identify/nanostring_5mode_15meas");
    for shots in [1usize, 20] {
        let ds = gen::simulate(&model, &v, &d, &gen::NANOSTRING_SHAPE, 1e-12, shots, 5);
        let prob = Problem::new(&model, &ds, &settings).expect("problem");
        group.throughput(Throughput::Elements(shots as u64));
        group.bench_function(format!("fit_{shots}shots"), |b| {
            b.iter(|| black_box(prob.fit(black_box(&ds)).expect("fit")))
        });
        if shots == 1 {
            group.bench_function("setup", |b| {
                b.iter(|| black_box(Problem::new(&model, &ds, &settings).expect("problem")))
            });
        }
    }
    let ds = gen::simulate(&model, &v, &d, &gen::NANOSTRING_SHAPE, 1e-10, 30, 7);
    group.sample_size(10);
    group.throughput(Throughput::Elements(1));
    group.bench_function("identify_ml_30shots", |b| {
        b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
    });
    group.finish();
}

fn bench_stepped_sweep(c: &mut Criterion) {
    let model = harmonid_model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let ds = gen::simulate(&model, &v, &d, &[1.0], 1e-12, 10, 3);
    let settings = Settings {
        force_model: ForceModel::GainPerMode,
        ..Settings::default()
    };
    let mut group = c.benchmark_group("identify/stepped_sweep");
    group.sample_size(10);
    group.bench_function("stepped_sweep_160steps", |b| {
        b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
    });
    group.finish();
}

fn bench_hysteretic_sweeps(c: &mut Criterion) {
    let model = harmonid_model::parse_str(gen::DAMPED_DUFFING, "softening.hb").expect("model");
    let settings = Settings {
        force_model: ForceModel::GainPerMode,
        error_floor: true,
        ..Settings::default()
    };
    let mut group = c.benchmark_group("identify/stepped_sweep");
    group.sample_size(10);
    for steps in [48usize, 417] {
        let (v, sweeps) = gen::hysteretic_sweeps(12, steps);
        let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps, &[1.0], 5);
        let ds = gen::add_noise(&clean, 2e-11, 3);
        group.bench_function(format!("hysteretic_{}steps", 24 * steps), |b| {
            b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
        });
    }
    group.finish();
}

fn bench_long_record(c: &mut Criterion) {
    let model = harmonid_model::parse_str(
        "mode q1 at 207.58 kHz\nparam beta1\npotential: beta1/4*q1^4\n",
        "duffing.hb",
    )
    .expect("model");
    let (mut v, d) = gen::nanostring_2mode_plan();
    v.f_hz.truncate(1);
    v.q.truncate(1);
    v.params.retain(|k, _| k == "beta1");
    // More shots than a simulation plan takes: the clean state repeated, then the noise.
    let mut clean = gen::simulate_clean(&model, &v, &d[..1], &[1.0], 1);
    for m in &mut clean.measurements {
        m.data = m.data.repeat(125_000);
        m.n_shots = 125_000;
    }
    let ds = gen::add_noise(&clean, 5e-11, 11);
    let rows: usize = ds.measurements.iter().map(|m| m.data.len()).sum();
    assert!(rows >= 900_000, "{rows} rows");
    let settings = Settings::default();
    let mut group = c.benchmark_group("identify/long_record");
    group.sample_size(10);
    group.bench_function("long_record_1m_rows", |b| {
        b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
    });
    group.finish();
}

/// The committed nominal plan `tests/it/data/{name}`.
fn committed_plan(name: &str) -> harmonid_experiment::Plan {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/it/data")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("plan");
    harmonid_experiment::Plan::from_toml(&text, &path.display().to_string()).expect("plan parses")
}

fn bench_many_modes(c: &mut Criterion) {
    let settings = Settings::default();
    let mut group = c.benchmark_group("identify/many_modes");
    group.sample_size(10);
    let model = harmonid_model::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_10mode/model.hb"),
    )
    .expect("example model");
    let v = gen::ten_mode_uniform_q();
    let clean = gen::simulate_plan(
        &model,
        &committed_plan("ten_mode_uniform_q_plan.toml"),
        &v,
        30,
    );
    let ds = gen::add_noise(&clean, 1e-10, 11);
    group.bench_function("ten_mode_uniform_q", |b| {
        b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
    });
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_10mode");
    let (_, clean) = gen::simulate_plan_file(&model, &dir, 30);
    let ds = gen::add_noise(&clean, 1e-10, 11);
    group.bench_function("ten_mode_example", |b| {
        b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
    });
    if std::env::var_os("HARMONID_BENCH_SKIP_20").is_none() {
        let (model, v) = gen::string_model(20);
        let clean = gen::simulate_plan(&model, &committed_plan("string_20mode_plan.toml"), &v, 30);
        let ds = gen::add_noise(&clean, 1e-10, 20);
        group.bench_function("twenty_mode_string", |b| {
            b.iter(|| black_box(identify(&model, black_box(&ds), &settings).expect("identify")))
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    bench_identify,
    bench_stepped_sweep,
    bench_hysteretic_sweeps,
    bench_long_record,
    bench_many_modes
);
criterion_main!(benches);

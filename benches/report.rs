//! Criterion bench for harmonid-report: the report of the five-mode nanostring (15
//! measurements, 30 shots at 5 pm, the round-trip tests' plan) from an identification already
//! made, so that it measures what the report itself adds (15 harmonic-balance reconstructions,
//! the figures as SVG, the page) and, separately, writing the folder (every figure as SVG and
//! PNG). The identification is the ident bench's (`identify_ml_30shots`).
#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid_ident::{identify, Estimator, Settings};
use harmonid_report::{build, Source};
use std::hint::black_box;
use std::path::PathBuf;

use harmonid_testgen as gen;

fn bench_report(c: &mut Criterion) {
    let model_path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_5mode/model.hb");
    let model = harmonid_model::load(&model_path).expect("example model");
    let (v, d) = gen::nanostring_5mode_plan();
    let ds = gen::simulate(&model, &v, &d, &gen::NANOSTRING_SHAPE, 5e-12, 30, 5);
    // The rendering does not depend on the estimator: the fast one keeps the set-up short.
    let settings = Settings {
        estimator: Estimator::Linear,
        ..Settings::default()
    };
    let rep = identify(&model, &ds, &settings).expect("identify");
    let source = || Source::Result(PathBuf::from("result.json"), Box::new(rep.clone()));
    let mut group = c.benchmark_group("report/nanostring_5mode_15meas_30shots");
    group.sample_size(10);
    group.bench_function("build", |b| {
        b.iter(|| black_box(build(&model_path, &model, &ds, source()).expect("build")))
    });
    let page = build(&model_path, &model, &ds, source()).expect("build");
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("report");
    group.bench_function("write", |b| {
        b.iter(|| page.write(black_box(&out), &[]).expect("write"))
    });
    group.finish();
}

criterion_group!(benches, bench_report);
criterion_main!(benches);

//! Criterion benches for harmonid-plan: designing the plans of the nanostring examples.
//!
//! `design/nanostring_2mode`: the worked example of docs/planning.md (0.05 nm, 20 shots, ≤ 3
//! measurements, one point). `design/nanostring_5mode`: the shipped
//! `examples/nanostring_5mode/plan.toml` (0.1 nm, 30 shots, one point, 15 measurements).
//! Few samples: one five-mode design takes seconds.
//!
//! `design_range/nanostring_10mode`: the ten-mode example's own command, `harmonid plan
//! examples/nanostring_10mode/model.hb --values … --noise 0.1nm --shots 30`: designed over the
//! guess's default range (f ± 2 linewidths, Q ± 30 %, ×/÷ 2), the default ladder, 10 draws, the
//! command line's 120 s budget, which bounds the whole design (issue 40, item 4). About 54 s per
//! design on the 2-core VM (2026-11-28, the measurements of a stage designed side by side): ten
//! samples take ten minutes; run it alone (`cargo bench --bench plan -- design_range`).
#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid_plan::{default_ladder, design, DesignSettings, GuessRange};
use std::hint::black_box;
use std::path::PathBuf;

/// Mode shapes at a tenth of the string, `sin(nπ/10)`.
const SHAPE: [f64; 5] = [
    0.309_016_994_374_947_45,
    0.587_785_252_292_473_1,
    0.809_016_994_374_947_5,
    0.951_056_516_295_153_5,
    1.0,
];

fn bench_design(c: &mut Criterion) {
    let mut group = c.benchmark_group("design");
    group.sample_size(10);
    for (example, modes, sigma_m, shots, max) in [
        ("nanostring_2mode", 2, 5e-11, 20, Some(3)),
        ("nanostring_5mode", 5, 1e-10, 30, None),
    ] {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("examples")
            .join(example);
        let model = harmonid_model::load(&dir.join("model.hb")).expect("example model");
        let values =
            harmonid_experiment::read_values(&dir.join("values.toml")).expect("example values");
        let s = DesignSettings {
            sigma_m,
            shots,
            max_measurements: max,
            points: vec![harmonid_data::Point {
                name: "p0".into(),
                shape: (0..modes)
                    .map(|n| (format!("q{}", n + 1), SHAPE[n]))
                    .collect(),
            }],
            ..DesignSettings::default()
        };
        group.bench_function(example, |b| {
            b.iter(|| black_box(design(&model, &values, &s).expect("design")))
        });
    }
    group.finish();
}

fn bench_design_range(c: &mut Criterion) {
    let mut group = c.benchmark_group("design_range");
    group.sample_size(10);
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_10mode");
    let model = harmonid_model::load(&dir.join("model.hb")).expect("example model");
    let values =
        harmonid_experiment::read_values(&dir.join("values.toml")).expect("example values");
    let range = GuessRange::new(&model, &values, &Default::default()).expect("range");
    let s = DesignSettings {
        sigma_m: 1e-10,
        shots: 30,
        time_budget_s: Some(120.0),
        ladder: default_ladder(true),
        range: Some(range),
        ..DesignSettings::default()
    };
    group.bench_function("nanostring_10mode", |b| {
        b.iter(|| black_box(design(&model, &values, &s).expect("design")))
    });
    group.finish();
}

criterion_group!(benches, bench_design, bench_design_range);
criterion_main!(benches);

//! Criterion benches for harmonid-plan: designing the plans of the nanostring examples.
//!
//! `design/nanostring_2mode`: the worked example of docs/planning.md (0.05 nm, 20 shots, ≤ 3
//! measurements, one point). `design/nanostring_5mode`: the shipped
//! `examples/nanostring_5mode/plan.toml` (0.1 nm, 30 shots, one point, 15 measurements).
//! Few samples: one five-mode design takes seconds.
#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid_plan::{design, DesignSettings};
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

criterion_group!(benches, bench_design);
criterion_main!(benches);

//! The parametron's phase diagram (Duffing + `lambda*pump*q1`, no drive), 100 × 100 over the
//! pump frequency and level: HarmonicBalance.jl's benchmark takes 0.73–1.03 s for it.

#![allow(missing_docs)] // criterion_group! generates undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid_explore::{phase_diagram, Axis, AxisRange, PhaseSettings, Problem};
use harmonid_sim::{Excitation, ModelValues, PumpTone};
use num_complex::Complex64;
use std::hint::black_box;

fn parametron(c: &mut Criterion) {
    let model = harmonid_model::parse_str(
        "mode q1, f = 1 kHz, Q = 1000\nparam beta, lambda\neom q1 += beta*q1^3 + lambda*pump*q1\n",
        "parametron.hb",
    )
    .expect("parses");
    let mut values = ModelValues::default();
    values.parameters.insert("beta".into(), 1e12);
    values.parameters.insert("lambda".into(), 1.0);
    let drive = Excitation {
        tones_hz: vec![],
        force: vec![vec![]],
        pumps: vec![PumpTone {
            hz: 2000.0,
            amplitude: Complex64::new(1e5, 0.0),
        }],
    };
    let p = Problem {
        model: &model,
        values: &values,
        drive: &drive,
    };
    let x = AxisRange {
        axis: Axis::PumpHz,
        from: 1990.0,
        to: 2010.0,
        n: 100,
    };
    let y = AxisRange {
        axis: Axis::PumpLevel,
        from: 1e3,
        to: 4e5,
        n: 100,
    };
    let mut g = c.benchmark_group("phase_diagram");
    g.sample_size(20);
    g.bench_function("parametron_100x100", |b| {
        b.iter(|| {
            black_box(phase_diagram(&p, &x, &y, &PhaseSettings::default(), &|_| {}).expect("runs"))
        })
    });
    g.finish();
}

criterion_group!(benches, parametron);
criterion_main!(benches);

//! Criterion benches for harmonid-sim: (a) one three-tone steady state of the two-mode
//! nanostring model, (b) a 2000-point Duffing sweep through folds, (c) the time-domain lock-in
//! simulation of one measurement (single_q1 of nanostring_ls50_2mode, from the HB state).

#![allow(missing_docs)] // criterion_group! generates undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid_sim::{
    self as sim, Excitation, HbSettings, HbSolver, NumericModel, Start, SweepSettings, TdSettings,
    Term,
};
use num_complex::Complex64;
use std::hint::black_box;

fn nanostring() -> NumericModel {
    let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
    NumericModel::new(
        vec!["q1".into(), "q2".into()],
        vec![207582.0, 415842.0],
        vec![116232.0, 599173.0],
        vec![
            t(0, 2.68e22, vec![(0, 3)]),
            t(0, 8.57e22, vec![(0, 1), (1, 2)]),
            t(1, 8.57e22, vec![(0, 2), (1, 1)]),
            t(1, 3.70e23, vec![(1, 3)]),
        ],
    )
    .expect("model")
}

fn c(x: f64) -> Complex64 {
    Complex64::new(x, 0.0)
}

fn steady_state(cr: &mut Criterion) {
    let model = nanostring();
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![207572.5, 207592.5, 415841.5],
        force: vec![vec![c(3.5), c(3.5), c(0.0)], vec![c(0.0), c(0.0), c(1.81)]],
    };
    let settings = HbSettings::default();
    let mut solver = HbSolver::new(&model, &drive, &settings.lattice).expect("solver");
    let mut g = cr.benchmark_group("hb_three_tone");
    g.bench_function("setup+ramp", |b| {
        b.iter(|| black_box(sim::steady_state(&model, &drive, &settings).expect("solve")))
    });
    g.bench_function("ramp (solver reused)", |b| {
        b.iter(|| black_box(solver.solve(&settings)))
    });
    let direct = HbSettings {
        ramp: false,
        ..settings.clone()
    };
    g.bench_function("no ramp (solver reused)", |b| {
        b.iter(|| black_box(solver.solve(&direct)))
    });
    g.finish();
}

fn duffing_sweep(cr: &mut Criterion) {
    let model = NumericModel::new(
        vec!["q".into()],
        vec![1000.0],
        vec![200.0],
        vec![Term {
            eq: 0,
            coef: 1e14,
            factors: vec![(0, 3)],
        }],
    )
    .expect("model");
    let s = SweepSettings {
        f_start_hz: 990.0,
        f_stop_hz: 1030.0,
        points: 2000,
        ..Default::default()
    };
    let mut g = cr.benchmark_group("sweep");
    g.bench_function("duffing_2000_points", |b| {
        b.iter(|| black_box(sim::sweep(&model, &[c(20.0)], &s).expect("sweep")))
    });
    g.finish();
}

fn time_domain(cr: &mut Criterion) {
    let model = nanostring();
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![207572.5, 207592.5],
        force: vec![vec![c(3.5), c(3.5)], vec![c(0.0), c(0.0)]],
    };
    let measure: Vec<f64> = (0..10).map(|k| 207492.5 + 20.0 * k as f64).collect();
    let mut hs = HbSettings::default();
    hs.lattice.extra_hz = measure.clone();
    let st = sim::steady_state(&model, &drive, &hs).expect("hb");
    let (q, v) = st.state_at(0.0);
    let start = Start::State { q, v };
    let shapes = vec![vec![0.3090169943749474, 0.5877852522924731]];
    let mut g = cr.benchmark_group("time_domain");
    g.sample_size(10);
    g.bench_function("single_q1_from_hb", |b| {
        b.iter(|| {
            black_box(
                sim::simulate_lockin(
                    &model,
                    &drive,
                    &measure,
                    &shapes,
                    &start,
                    &TdSettings::default(),
                )
                .expect("td"),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, steady_state, duffing_sweep, time_domain);
criterion_main!(benches);

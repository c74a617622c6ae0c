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

/// The non-smooth terms (issue 36). One harmonic-balance solve (reused solver, no ramp) of a
/// 10 kHz, Q 1000 resonator driven near resonance with `abs(q1)*q1` and `abs(d(q1))*d(q1)` (512
/// samples of one period, spectral Jacobian) and with Coulomb friction `sign(d(q1))` (4096
/// samples, Jacobian by central differences); and one torus column as the identification builds
/// it: `abs(q)*q` from two input lines on the 128 × 128 torus of 9996.3 + 10001.7 Hz, projected
/// on four lines (synthesis, evaluation, projection by `GridSampler`).
fn nonsmooth(cr: &mut Criterion) {
    use harmonid::model::NonSmooth;
    use harmonid::poly::VarId;
    let numeric = |eom: &str, params: &[(&str, f64)]| {
        let src =
            format!("mode q1, f = 10 kHz, Q = 1000\nparam kappa1, drag1, mu1\neom q1 += {eom}\n");
        let m = harmonid::model::parse_str(&src, "bench.hb").expect("model");
        let mut v = sim::ModelValues::default();
        for (k, x) in ["kappa1", "drag1", "mu1"]
            .iter()
            .map(|k| (k, 0.0))
            .chain(params.iter().map(|(k, x)| (k, *x)))
        {
            v.parameters.insert((*k).to_string(), x);
        }
        NumericModel::from_model(&m, &v).expect("numeric model")
    };
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![10_005.0],
        force: vec![vec![c(4.0)]],
    };
    let settings = HbSettings {
        ramp: false,
        ..HbSettings::default()
    };
    let mut g = cr.benchmark_group("nonsmooth");
    for (name, eom, params) in [
        (
            "hb_solve_abs",
            "kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)",
            &[("kappa1", 3e13), ("drag1", 7e2)][..],
        ),
        ("hb_solve_coulomb", "mu1*sign(d(q1))", &[("mu1", 1.0)][..]),
    ] {
        let model = numeric(eom, params);
        let mut solver = HbSolver::new(&model, &drive, &settings.lattice).expect("solver");
        g.bench_function(name, |b| b.iter(|| black_box(solver.solve(&settings))));
    }
    let tones = [9996.3, 10001.7];
    let lines = [
        2.0 * tones[0] - tones[1],
        tones[0],
        tones[1],
        2.0 * tones[1] - tones[0],
    ];
    let grid = sim::Grid::choose(&tones, &lines).expect("a torus");
    let sampler = sim::GridSampler::new(&grid);
    let nt = sampler.samples();
    let (mut xs, mut f) = (vec![0.0; nt], vec![0.0; nt]);
    let abs_q = [(NonSmooth::Abs(VarId(0)), 1)];
    g.bench_function("torus_column_128x128", |b| {
        b.iter(|| {
            xs.fill(0.0);
            f.fill(0.0);
            sampler.add_line(1, Complex64::from_polar(1.0, 0.4), &mut xs, None);
            sampler.add_line(2, Complex64::from_polar(0.45, -0.7), &mut xs, None);
            sampler.add_term(1.0, &[(0, 1)], &abs_q, &xs, &mut f);
            black_box(
                (0..lines.len())
                    .map(|r| sampler.coefficient(r, &f))
                    .collect::<Vec<_>>(),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, steady_state, duffing_sweep, time_domain, nonsmooth);
criterion_main!(benches);

//! Criterion benches for harmonid-spectral: the numeric product of measured spectra and the
//! symbolic mixing table.
#![allow(missing_docs)] // criterion_group! generates undocumented items
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use harmonid_poly::PowerProduct;
use harmonid_spectral::{mixing_table, monomial_amplitudes, ProductPlan, ToneAssignment, Window};
use num_complex::Complex64;
use std::hint::black_box;

/// R measured frequencies: the two modes of the nanostring with R/2 sidebands each, δ = 10 Hz.
fn measured(r: usize) -> Vec<f64> {
    let half = r / 2;
    let mut f = Vec::with_capacity(r);
    for (centre, n) in [(207582.0, half), (415842.0, r - half)] {
        for j in 0..n {
            // Odd multiples of δ around the resonance: ±δ, ±3δ, ...
            let k = (j / 2) as f64 * 2.0 + 1.0;
            let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
            f.push(centre + sign * 10.0 * k);
        }
    }
    f
}

fn products(c: &mut Criterion) {
    let mut group = c.benchmark_group("products");
    for r in [8usize, 16, 32] {
        let f = measured(r);
        let plan = ProductPlan::new(&f, &f, 3).expect("plan");
        let mut scratch = plan.scratch();
        let q1: Vec<Complex64> = (0..r)
            .map(|i| Complex64::from_polar(1e-7, i as f64))
            .collect();
        let q2: Vec<Complex64> = (0..r)
            .map(|i| Complex64::from_polar(2e-8, 0.3 * i as f64))
            .collect();
        let m = PowerProduct::from_exponents(&[1, 2]);
        let mut out = vec![Complex64::new(0.0, 0.0); r];
        group.bench_with_input(BenchmarkId::new("q1*q2^2", format!("R={r}")), &r, |b, _| {
            b.iter(|| {
                monomial_amplitudes(&plan, &m, &[&q1, &q2], &mut out, &mut scratch);
                black_box(&out);
            })
        });
        let m3 = PowerProduct::from_exponents(&[3]);
        group.bench_with_input(BenchmarkId::new("q1^3", format!("R={r}")), &r, |b, _| {
            b.iter(|| {
                monomial_amplitudes(&plan, &m3, &[&q1, &q2], &mut out, &mut scratch);
                black_box(&out);
            })
        });
        group.bench_with_input(BenchmarkId::new("plan", format!("R={r}")), &r, |b, _| {
            b.iter(|| black_box(ProductPlan::new(&f, &f, 3).expect("plan")))
        });
    }
    group.finish();
}

/// Bench name, tones per mode, exponents of (q1, q2).
type SymbolicCase = (&'static str, Vec<(String, Vec<f64>)>, [u32; 2]);

fn symbolic(c: &mut Criterion) {
    let mut group = c.benchmark_group("mixing_table");
    let nominal = [Some(207582.0), Some(415842.0)];
    let cases: [SymbolicCase; 2] = [
        (
            "q1^3 (4 tones on q1)",
            vec![("q1".into(), vec![207562.0, 207572.0, 207592.0, 207602.0])],
            [3, 0],
        ),
        (
            "q1*q2^2 (2+2 tones)",
            vec![
                ("q1".into(), vec![207572.0, 207592.0]),
                ("q2".into(), vec![415832.0, 415852.0]),
            ],
            [1, 2],
        ),
    ];
    for (name, drives, exps) in cases {
        let a = ToneAssignment::from_drives(&["q1", "q2"], &drives).expect("tones");
        let m = PowerProduct::from_exponents(&exps);
        group.bench_function(name, |b| {
            b.iter(|| black_box(mixing_table(&m, &a, &nominal, Window::default()).expect("small")))
        });
    }
    group.finish();
}

criterion_group!(benches, products, symbolic);
criterion_main!(benches);

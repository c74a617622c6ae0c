//! Criterion bench of `harmonid import`: a long LabOne demodulator record, 1 million samples
//! (100 steps of 10 000) in one `;`-separated CSV of 70 MB, read, conventions applied, steps cut,
//! settling dropped, made a dataset (not written).
#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn

use criterion::{criterion_group, criterion_main, Criterion};
use harmonid::data::import::{zi_csv, Amplitude, Conventions, Quadrature, Response, Settle};
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;

fn bench_zi_csv(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("dev1_demods_0_sample_00000.csv");
    let mut s = String::from("chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1\n");
    let mut tick: u64 = 1000;
    for k in 0..100 {
        let f = 100.0 + 0.01 * k as f64;
        for j in 0..10_000 {
            tick += 6000;
            let x = 1e-3 + 1e-9 * j as f64;
            let _ = writeln!(s, "0;{tick};{x:.8e};{:.8e};{f:.10};0.1;0;0;0;0", -2.0 * x);
        }
    }
    std::fs::write(&path, s).expect("write");
    let conv = Conventions {
        amplitude: Amplitude::Rms,
        quadrature: Quadrature::XPlusIY,
        response: Response::Displacement,
        metres_per_unit: None,
        displacement_unit: "V".into(),
        phase_unit: None,
        frequency_scale: None,
    };
    let settle = Settle {
        settle_s: Some(1e-3),
        settle_samples: None,
    };
    let opts = zi_csv::Options {
        clockbase_hz: 60e6,
        drive_level: None,
        drive_phase_rad: None,
    };
    let mut group = c.benchmark_group("import");
    group.sample_size(10);
    group.bench_function("zi_csv_1m_samples", |b| {
        b.iter(|| {
            black_box(
                zi_csv::import(
                    std::slice::from_ref(&path),
                    &conv,
                    settle,
                    &opts,
                    Path::new("out"),
                )
                .expect("import"),
            )
        })
    });
    group.finish();
}

criterion_group!(benches, bench_zi_csv);
criterion_main!(benches);

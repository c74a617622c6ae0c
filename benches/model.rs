//! Criterion benches for harmonid-model: the equations of a full quartic N-mode potential
//! (every degree-4 monomial in N modes with its own parameter; C(N+3, 4) terms, 123 410 for
//! N = 40), written with index families:
//!
//! ```text
//! for i in 1..N: mode q[i]
//! for i<=j<=k<=l in 1..N {
//!     param c[i,j,k,l]
//!     potential: c[i,j,k,l] * q[i]*q[j]*q[k]*q[l]
//! }
//! ```
//!
//! - `model/lower/N`: the whole pipeline from source text (parse, expand, resolve, lower,
//!   differentiate) to a `Model`;
//! - `model/derive/N`: the derivative step alone, `∂U/∂q_n` for every mode from the lowered `U`.
#![allow(missing_docs)] // criterion_group! generates undocumented items
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use harmonid::model::{equations_from_potential, parse_str};
use std::hint::black_box;

fn full_quartic_source(n: usize) -> String {
    format!(
        "for i in 1..{n}: mode q[i]\n\
         for i<=j<=k<=l in 1..{n} {{\n\
         \x20   param c[i,j,k,l]\n\
         \x20   potential: c[i,j,k,l] * q[i]*q[j]*q[k]*q[l]\n\
         }}\n"
    )
}

fn full_quartic(c: &mut Criterion) {
    let mut group = c.benchmark_group("model");
    group.sample_size(10);
    for n in [5usize, 10, 20, 40] {
        let src = full_quartic_source(n);
        let model = match parse_str(&src, "full_quartic.hb") {
            Ok(m) => m,
            Err(e) => panic!("{}", e.render_plain(100)),
        };
        assert_eq!(model.potential.len(), binomial(n + 3, 4));
        group.bench_with_input(BenchmarkId::new("lower", n), &src, |b, src| {
            b.iter(|| black_box(parse_str(black_box(src), "full_quartic.hb").is_ok()))
        });
        group.bench_with_input(BenchmarkId::new("derive", n), &model, |b, m| {
            b.iter(|| {
                black_box(equations_from_potential(black_box(&m.potential), n).map(|e| e.len()))
            })
        });
    }
    group.finish();
}

fn binomial(n: usize, k: usize) -> usize {
    (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
}

criterion_group!(benches, full_quartic);
criterion_main!(benches);

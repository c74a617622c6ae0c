//! The rejection of disturbed shots by Monte Carlo (`#[ignore]`d, about a minute): how often a
//! clean dataset of the sizes users have (2 to 50 shots a step, 10 to 2000 steps) loses any
//! shot (the documented family-wise rate is at most 1 %), and how often a shot `D` σ off is
//! caught. Run with
//!
//! ```text
//! cargo test --release -p harmonid-ident --test it -- disturbed_shots_mc --ignored --nocapture
//! ```
//!
//! Measured: docs/identification.md, "Pooling".

use harmonid_ident::disturbed_shots;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// `n` clean shots on `lines` lines, circular Gaussian noise of 1 per quadrature, means of
/// different sizes per line.
fn step(rng: &mut rand_chacha::ChaCha8Rng, n: usize, lines: usize) -> Vec<Vec<Complex64>> {
    let d = Normal::new(0.0, 1.0).expect("normal");
    (0..n)
        .map(|_| {
            (0..lines)
                .map(|o| {
                    Complex64::new(10.0 * o as f64, -3.0)
                        + Complex64::new(d.sample(rng), d.sample(rng))
                })
                .collect()
        })
        .collect()
}

fn rejected(s: &[Vec<Complex64>], family: usize) -> Vec<usize> {
    let refs: Vec<&[Complex64]> = s.iter().map(Vec::as_slice).collect();
    disturbed_shots(&refs, family)
}

#[test]
#[ignore = "Monte Carlo, about a minute: see the module documentation"]
fn family_wise_false_alarms_and_power() {
    let t0 = std::time::Instant::now();
    println!("clean datasets that lose any shot (family = every shot of the dataset):");
    for (n, lines) in [(2, 1), (3, 1), (4, 1), (4, 3), (10, 1), (10, 3), (50, 1)] {
        for steps in [10, 480, 2000] {
            let sets = if n * steps >= 20_000 { 300 } else { 1000 };
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64((n * 1000 + steps) as u64);
            let family = n * steps;
            let any = (0..sets)
                .filter(|_| {
                    (0..steps).any(|_| !rejected(&step(&mut rng, n, lines), family).is_empty())
                })
                .count();
            let p = any as f64 / sets as f64;
            println!(
                "  {n:>2} shots, {lines} line(s), {steps:>4} steps: {any}/{sets} = {:.4} ± {:.4}",
                p,
                (p * (1.0 - p) / sets as f64).sqrt()
            );
            assert!(p < 0.01 + 3.0 * (0.01 * 0.99 / sets as f64).sqrt(), "{p}");
        }
    }
    println!("a shot displaced by D σ (σ per quadrature, |Δx| = D σ), one line, 480-step sweep:");
    for n in [4, 10, 30] {
        let family = 480 * n;
        for dev in [5.0, 10.0, 20.0, 50.0, 100.0] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7 + n as u64);
            let trials = 2000;
            let caught = (0..trials)
                .filter(|_| {
                    let mut s = step(&mut rng, n, 1);
                    s[1][0] += Complex64::new(dev, dev) / 2_f64.sqrt();
                    rejected(&s, family) == vec![1]
                })
                .count();
            println!(
                "  {n:>2} shots, {dev:>5} σ: caught alone in {:.3}",
                caught as f64 / trials as f64
            );
        }
    }
    println!("{:.1} s", t0.elapsed().as_secs_f64());
}

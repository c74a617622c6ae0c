//! Property test: the exact product against a brute-force time-domain DFT.
//!
//! Inputs are integer multiples `k_r·Δ` of a base frequency, so every signal is periodic with
//! period `1/Δ`; the factors are synthesised on `N` samples of that period, multiplied, and the
//! product's amplitudes read off with a direct DFT. `N` exceeds twice the highest product
//! frequency, so there is no aliasing and the DFT is exact up to rounding.

use harmonid_spectral::ProductPlan;
use num_complex::Complex64;
use proptest::prelude::*;
use std::f64::consts::PI;

const N: usize = 512;
const MAX_K: usize = 40;

fn dft_product(
    input: &[f64],
    output: &[f64],
    factors: &[Vec<Complex64>],
    base: f64,
) -> Vec<Complex64> {
    let period = 1.0 / base;
    let mut p = vec![1.0f64; N];
    for x in factors {
        for (n, pn) in p.iter_mut().enumerate() {
            let t = period * n as f64 / N as f64;
            let v: f64 = input
                .iter()
                .zip(x)
                .map(|(&f, &a)| (a * Complex64::from_polar(1.0, 2.0 * PI * f * t)).re)
                .sum();
            *pn *= v;
        }
    }
    output
        .iter()
        .map(|&f| {
            // Integer bin index of f on the period grid.
            let bin = (f / base).round() as usize;
            let mut acc = Complex64::new(0.0, 0.0);
            for (n, &pn) in p.iter().enumerate() {
                let phase = -2.0 * PI * ((bin * n) % N) as f64 / N as f64;
                acc += pn * Complex64::from_polar(1.0, phase);
            }
            acc / N as f64 * if bin == 0 { 1.0 } else { 2.0 }
        })
        .collect()
}

/// Input multiples, output multiples, factor amplitudes (re, im), base frequency.
type Case = (Vec<usize>, Vec<usize>, Vec<Vec<(f64, f64)>>, f64);

fn case() -> impl Strategy<Value = Case> {
    (
        proptest::sample::subsequence((1..=MAX_K).collect::<Vec<_>>(), 1..=6),
        0usize..=4,
        prop_oneof![Just(1.0), Just(7.25), Just(1037.5)],
    )
        .prop_flat_map(|(input, k, base)| {
            let r = input.len();
            let outputs = proptest::collection::vec(0usize..=(k.max(1) * MAX_K), 1..12);
            let factors = proptest::collection::vec(
                proptest::collection::vec((-2.0f64..2.0, -2.0f64..2.0), r..=r),
                k..=k,
            );
            (Just(input), outputs, factors, Just(base))
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn product_matches_time_domain_dft((input, outputs, factors, base) in case()) {
        let input_hz: Vec<f64> = input.iter().map(|&k| k as f64 * base).collect();
        let output_hz: Vec<f64> = outputs.iter().map(|&k| k as f64 * base).collect();
        let xs: Vec<Vec<Complex64>> = factors
            .iter()
            .map(|f| f.iter().map(|&(a, b)| Complex64::new(a, b)).collect())
            .collect();
        let plan = ProductPlan::new(&input_hz, &output_hz, 4).expect("valid plan");
        let mut scratch = plan.scratch();
        let refs: Vec<&[Complex64]> = xs.iter().map(|v| v.as_slice()).collect();
        let mut out = vec![Complex64::new(0.0, 0.0); output_hz.len()];
        plan.eval(&refs, &mut out, &mut scratch);
        let want = dft_product(&input_hz, &output_hz, &xs, base);
        // Relative to the signal's size: Π_k Σ_r |X_kr| bounds every amplitude of the product.
        let scale: f64 = xs.iter().map(|x| x.iter().map(|z| z.norm()).sum::<f64>()).product();
        for (o, (a, b)) in out.iter().zip(&want).enumerate() {
            prop_assert!(
                (a - b).norm() <= 1e-12 * scale.max(1e-300),
                "output {} ({} Hz): plan {} vs DFT {} (scale {})", o, output_hz[o], a, b, scale
            );
        }
    }
}

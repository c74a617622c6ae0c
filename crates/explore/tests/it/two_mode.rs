//! Two Duffing modes with a dispersive coupling, driven on both by one tone: `states` lists
//! every state a brute-force Newton search from random starts finds, and no fewer.

use super::models::two_mode;
use harmonid_explore::{states, SingleHarmonic, StatesSettings, Tone};
use harmonid_sim::{Excitation, NumericModel};
use num_complex::Complex64;
use rand::{Rng, SeedableRng};

/// Above both resonances, hard enough for five states (two stable).
const TONE_HZ: f64 = 1014.0;
const FORCES: [f64; 2] = [80.0, 64.0];

fn drive() -> Excitation {
    Excitation::new(
        vec![TONE_HZ],
        FORCES
            .iter()
            .map(|&f| vec![Complex64::new(f, 0.0)])
            .collect(),
    )
}

/// Real Newton on the single-harmonic equations from `starts` random points in the box
/// `|u|, |v| ≤ box_size` (scaled unknowns); the distinct converged solutions, physical (m).
fn brute_force(m: &NumericModel, starts: usize, box_size: f64) -> Vec<Vec<Complex64>> {
    let tone = Tone {
        hz: TONE_HZ,
        force: FORCES.iter().map(|&f| Complex64::new(f, 0.0)).collect(),
        pump: Complex64::new(0.0, 0.0),
    };
    let sh = SingleHarmonic::new(m).expect("expands");
    let scale = sh.natural_scale(m, &tone);
    let (sys, _) = sh.system(m, &tone, scale, true).expect("system");
    let n = sys.n;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut pw = sys.scratch();
    let mut found: Vec<Vec<Complex64>> = Vec::new();
    let z = Complex64::new(0.0, 0.0);
    for _ in 0..starts {
        let mut x: Vec<Complex64> = (0..n)
            .map(|_| Complex64::new(rng.random_range(-box_size..box_size), 0.0))
            .collect();
        let (mut f, mut j) = (vec![z; n], vec![z; n * n]);
        let mut ok = false;
        for _ in 0..60 {
            sys.eval(&x, &mut f, &mut j, &mut pw);
            // Real Gaussian elimination on J dx = −f.
            let mut a: Vec<f64> = j.iter().map(|v| v.re).collect();
            let mut b: Vec<f64> = f.iter().map(|v| -v.re).collect();
            if !gauss(&mut a, &mut b, n) {
                break;
            }
            let step: f64 = b.iter().map(|v| v * v).sum::<f64>().sqrt();
            // Damped: at most a tenth of the box per step.
            let damp = (0.1 * box_size / step).min(1.0);
            for k in 0..n {
                x[k].re += damp * b[k];
            }
            let size = 1.0 + x.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
            if step < 1e-12 * size {
                ok = true;
                break;
            }
        }
        if ok {
            let phys: Vec<Complex64> = (0..n / 2)
                .map(|k| Complex64::new(x[2 * k].re, x[2 * k + 1].re) * scale)
                .collect();
            let size: f64 = phys.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
            if !found.iter().any(|y| {
                y.iter()
                    .zip(&phys)
                    .map(|(a, b)| (a - b).norm_sqr())
                    .sum::<f64>()
                    .sqrt()
                    <= 1e-7 * size
            }) {
                found.push(phys);
            }
        }
    }
    found
}

fn gauss(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs()))
            .unwrap_or(k);
        if a[p * n + k] == 0.0 {
            return false;
        }
        for c in 0..n {
            a.swap(k * n + c, p * n + c);
        }
        b.swap(k, p);
        for i in k + 1..n {
            let m = a[i * n + k] / a[k * n + k];
            for c in k..n {
                a[i * n + c] -= m * a[k * n + c];
            }
            b[i] -= m * b[k];
        }
    }
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|c| a[k * n + c] * b[c]).sum();
        b[k] = (b[k] - s) / a[k * n + k];
    }
    true
}

fn check(starts: usize) {
    let (_, _, m) = two_mode();
    let s = states(
        &m,
        &drive(),
        &StatesSettings {
            lattice: false,
            ..StatesSettings::default()
        },
    )
    .expect("solves");
    let listed: Vec<&Vec<Complex64>> = s.states.iter().map(|x| &x.amplitudes).collect();
    let largest = listed
        .iter()
        .flat_map(|v| v.iter())
        .map(|z| z.norm())
        .fold(0.0, f64::max);
    let sh = SingleHarmonic::new(&m).expect("expands");
    let tone = harmonid_explore::tone_of(&m, &drive()).expect("tone");
    let box_size = 2.0 * largest / sh.natural_scale(&m, &tone);
    let bf = brute_force(&m, starts, box_size);
    for b in &bf {
        let size: f64 = b.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
        assert!(
            listed.iter().any(|l| l
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).norm_sqr())
                .sum::<f64>()
                .sqrt()
                <= 1e-6 * size),
            "brute force found a state `states` misses: {b:?}"
        );
    }
    println!(
        "{} states ({} stable) from {} paths ({} finite complex); brute force from {starts} starts found {}",
        s.states.len(),
        s.states.iter().filter(|x| x.stable).count(),
        s.paths,
        s.complex_solutions,
        bf.len()
    );
    assert_eq!(s.states.len(), 5, "the test point has five states");
    assert_eq!(bf.len(), 5, "the brute force finds all five");
}

#[test]
fn states_lists_every_state_a_1000_start_newton_search_finds() {
    check(1000);
}

/// The same with 10⁴ starts (about a second in release):
/// `cargo test --release -p harmonid-explore --test it -- two_mode:: --ignored --nocapture`.
#[test]
#[ignore]
fn states_lists_every_state_a_10000_start_newton_search_finds() {
    check(10_000);
}

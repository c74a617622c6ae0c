//! Modes without a tone of their own: their response through the coupling
//! ([`ToneAssignment::add_responses`]) and the second-order lines it makes, against
//! hand-derived coefficients and a brute-force Fourier transform of the product.

use harmonid_poly::PowerProduct;
use harmonid_spectral::{mixing_table, ComponentKind, MixingTable, ToneAssignment, Window};
use std::f64::consts::TAU;

fn pp(e: &[u32]) -> PowerProduct {
    PowerProduct::from_exponents(e)
}

/// The line at `hz` (panics when absent).
fn at(t: &MixingTable, hz: f64) -> &harmonid_spectral::Line {
    t.lines
        .iter()
        .find(|l| (l.hz - hz).abs() < 1e-9)
        .unwrap_or_else(|| panic!("no line at {hz} Hz"))
}

/// Amplitude of `cos(2π f t)` (DC value at 0) of `signal(t)` over one second, sampled `n` times:
/// exact for integer frequencies below `n/2` Hz.
fn dft(signal: impl Fn(f64) -> f64, f: f64, n: usize) -> f64 {
    let s: f64 = (0..n)
        .map(|j| {
            let t = j as f64 / n as f64;
            signal(t) * (TAU * f * t).cos()
        })
        .sum();
    if f == 0.0 {
        s / n as f64
    } else {
        2.0 * s / n as f64
    }
}

/// `U = κ/2 q1² q2`: the equation of q2 holds `κ/2·q1²`, that of q1 `κ·q1·q2`. Two tones
/// `Ωa`, `Ωb` on q1, none on q2. With `q1 = Xa cos a + Xb cos b`,
/// `q1² = (Xa² + Xb²)/2 + Xa²/2 cos 2a + Xb²/2 cos 2b + Xa Xb cos(a + b) + Xa Xb cos(a − b)`:
/// q2 responds at DC, `Ωb − Ωa`, `2Ωa`, `Ωa + Ωb`, `2Ωb` (Z1..Z5 by frequency), and `q1·q2`
/// then has at `Ωa` the second-order line `Xa Z1 + ½ Xb Z2 + ½ Xa Z3 + ½ Xb Z4`.
#[test]
fn quadratic_coupling_with_two_tones_on_one_mode() {
    let (fa, fb) = (10.0, 13.0);
    let drives = vec![("q1".to_string(), vec![fa, fb])];
    let mut a = ToneAssignment::from_drives(&["q1", "q2"], &drives).expect("tones");
    let equations = vec![vec![pp(&[1, 1])], vec![pp(&[2, 0])]];
    // The forcing of q2 before it moves: the hand-derived coefficients, exactly.
    let forcing = mixing_table(&pp(&[2, 0]), &a, &[None, None], Window::default()).expect("table");
    let syms = a.symbols();
    let want = [
        (0.0, "1/2*X1^2 + 1/2*X2^2"),
        (fb - fa, "X1*X2"),
        (2.0 * fa, "1/2*X1^2"),
        (fa + fb, "X1*X2"),
        (2.0 * fb, "1/2*X2^2"),
    ];
    assert_eq!(forcing.lines.len(), want.len());
    for (hz, c) in want {
        assert_eq!(
            at(&forcing, hz).coefficient.to_string_with(&syms),
            c,
            "{hz} Hz"
        );
    }
    assert_eq!(a.add_responses(&equations).expect("responses"), 5);
    let z: Vec<(usize, f64, String)> = a
        .components()
        .iter()
        .filter(|c| c.kind == ComponentKind::Response)
        .map(|c| (c.mode, c.combination.hz(a.tones()), c.symbol.clone()))
        .collect();
    let want_z: Vec<(usize, f64, String)> = [0.0, fb - fa, 2.0 * fa, fa + fb, 2.0 * fb]
        .iter()
        .enumerate()
        .map(|(j, &hz)| (1, hz, format!("Z{}", j + 1)))
        .collect();
    assert_eq!(z, want_z);
    // Calling again adds nothing: every mode moves.
    assert_eq!(a.add_responses(&equations).expect("responses"), 0);
    let t = mixing_table(&pp(&[1, 1]), &a, &[None, None], Window::default()).expect("table");
    let syms = a.symbols();
    let line = at(&t, fa);
    assert_eq!(
        line.coefficient.to_string_with(&syms),
        "X1*Z1 + 1/2*X1*Z3 + 1/2*X2*Z2 + 1/2*X2*Z4"
    );
    assert_eq!(a.responses_in(&line.coefficient), vec![1]);
    // Every line of q1·q2 against the brute-force transform of the product.
    let amps = [0.7, -1.3, 0.4, -0.9, 1.1, 0.25, -0.6];
    let q1 = |t: f64| amps[0] * (TAU * fa * t).cos() + amps[1] * (TAU * fb * t).cos();
    let q2 = |t: f64| {
        a.components()
            .iter()
            .enumerate()
            .filter(|(_, c)| c.mode == 1)
            .map(|(i, c)| amps[i] * (TAU * c.combination.hz(a.tones()) * t).cos())
            .sum::<f64>()
    };
    let mut total = 0;
    for l in &t.lines {
        let want = dft(|t| q1(t) * q2(t), l.hz, 512);
        assert!((l.eval(&amps) - want).abs() < 1e-12, "{} Hz", l.hz);
        total += 1;
    }
    // Lines at Ωa, Ωb, |2Ωa − Ωb|, 2Ωb − Ωa, 3Ωa, 2Ωa + Ωb, Ωa + 2Ωb, 3Ωb.
    assert_eq!(total, 8);
    // No line is missing: the transform is zero everywhere else.
    for f in 0..60 {
        let f = f64::from(f);
        if t.lines.iter().all(|l| (l.hz - f).abs() > 1e-9) {
            assert!(dft(|t| q1(t) * q2(t), f, 512).abs() < 1e-12, "{f} Hz");
        }
    }
    // The forcing of q2 does not go through a response; q1's own tones are not responses.
    assert!(forcing
        .lines
        .iter()
        .all(|l| a.responses_in(&l.coefficient).is_empty()));
}

/// The three-wave example (`U = κ q1 q2 q3`, f3 ≈ f1 + f2): tones Ω1 on q1, Ω2 on q2, none on q3.
/// q3 responds at `Ω2 − Ω1` (Z1) and `Ω1 + Ω2` (Z2, at its resonance); `κ q2 q3` in the
/// equation of q1 then has the second-order line at Ω1, `q2·q3 = X2 cos Ω2t (Z1 cos(Ω2 − Ω1)t +
/// Z2 cos(Ω1 + Ω2)t)` → `½ X2 Z1 + ½ X2 Z2` at Ω1.
#[test]
fn three_wave_sum_frequency_response() {
    // The monomials of examples/three_wave/model.hb's equations (κ and the Duffing terms).
    let names = ["q1", "q2", "q3"];
    let equations = vec![
        vec![pp(&[0, 1, 1]), pp(&[3, 0, 0])],
        vec![pp(&[1, 0, 1]), pp(&[0, 3, 0])],
        vec![pp(&[1, 1, 0]), pp(&[0, 0, 3])],
    ];
    let (f1, f2) = (1.0e6 + 100.0, 1.6e6 - 40.0);
    let drives = vec![("q1".to_string(), vec![f1]), ("q2".to_string(), vec![f2])];
    let mut a = ToneAssignment::from_drives(&names, &drives).expect("tones");
    assert_eq!(a.add_responses(&equations).expect("responses"), 2);
    let z: Vec<(String, f64)> = a
        .components()
        .iter()
        .filter(|c| c.kind == ComponentKind::Response)
        .map(|c| (c.symbol.clone(), c.combination.hz(a.tones())))
        .collect();
    assert_eq!(z, vec![("Z1".into(), f2 - f1), ("Z2".into(), f1 + f2)]);
    let nominal = [Some(1.0e6), Some(1.6e6), Some(2.6e6)];
    // q3's response at Ω1 + Ω2 sits at its resonance (2.6 MHz + 60 Hz).
    let forcing = mixing_table(&pp(&[1, 1, 0]), &a, &nominal, Window::default()).expect("table");
    assert_eq!(at(&forcing, f1 + f2).near_mode(), Some(2));
    let t = mixing_table(&pp(&[0, 1, 1]), &a, &nominal, Window::default()).expect("table");
    let syms = a.symbols();
    let line = at(&t, f1);
    assert_eq!(
        line.coefficient.to_string_with(&syms),
        "1/2*X2*Z1 + 1/2*X2*Z2"
    );
    assert_eq!(line.near_mode(), Some(0));
    assert_eq!(a.responses_in(&line.coefficient), vec![2]);
    // q1·q3 in the equation of q2: the idler line at Ω2 (from (Ω1 + Ω2) − Ω1), also second order.
    let t13 = mixing_table(&pp(&[1, 0, 1]), &a, &nominal, Window::default()).expect("table");
    let idler = at(&t13, f2);
    assert_eq!(
        idler.coefficient.to_string_with(&syms),
        "1/2*X1*Z1 + 1/2*X1*Z2"
    );
    assert_eq!(idler.near_mode(), Some(1));
}

/// A mode forced only through terms that hold itself (the dispersive `q1²·q2` in the equation of
/// q2) stays at rest: no response, and the terms holding it have no lines.
#[test]
fn a_mode_forced_only_parametrically_stays_at_rest() {
    let drives = vec![("q1".to_string(), vec![100.0, 110.0])];
    let mut a = ToneAssignment::from_drives(&["q1", "q2"], &drives).expect("tones");
    let equations = vec![
        vec![pp(&[3, 0]), pp(&[1, 2])],
        vec![pp(&[0, 3]), pp(&[2, 1])],
    ];
    assert_eq!(a.add_responses(&equations).expect("responses"), 0);
    let t = mixing_table(&pp(&[2, 1]), &a, &[None, None], Window::default()).expect("table");
    assert!(t.lines.is_empty());
}

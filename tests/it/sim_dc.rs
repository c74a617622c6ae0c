//! Static offset (0 Hz line) and even-order lines of models with even-degree terms: harmonic
//! balance against the closed-form perturbation series and against the time-domain lock-in.

use harmonid::sim::{
    self, choose_lattice, linear_response, Excitation, HbSettings, LatticeSettings, NumericModel,
    Start, TdSettings, Term,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

fn term(eq: usize, coef: f64, factors: Vec<(usize, u32)>) -> Term {
    Term { eq, coef, factors }
}

/// `q'' + γq' + ω0²q + a q² = F cos(Ωt)`, f0 = 1 kHz, Q = 100.
fn quadratic(a: f64) -> NumericModel {
    NumericModel::new(
        vec!["q".into()],
        vec![1000.0],
        vec![100.0],
        vec![term(0, a, vec![(0, 2)])],
    )
    .expect("model")
}

#[test]
fn lattice_has_dc_and_even_lines_only_for_even_models() {
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![995.0, 1005.0],
        force: vec![vec![Complex64::new(1.0, 0.0); 2]],
    };
    let s = LatticeSettings::default();
    let even = choose_lattice(&quadratic(1e9), &drive, &s).expect("lattice");
    for f in [0.0, 10.0, 1990.0, 2000.0, 2010.0] {
        assert!(
            even.iter().any(|&x| (x - f).abs() < 1e-9),
            "{f} Hz missing from {even:?}"
        );
    }
    assert_eq!(even[0], 0.0);
    let duffing = NumericModel::new(
        vec!["q".into()],
        vec![1000.0],
        vec![100.0],
        vec![term(0, 1e12, vec![(0, 3)])],
    )
    .expect("model");
    let odd = choose_lattice(&duffing, &drive, &s).expect("lattice");
    assert!(odd.iter().all(|&f| f > 900.0 && f < 1100.0), "{odd:?}");
    // Odd orders only: 1000 ± 5, ± 15, ... = 995 + 10 k; never 1000 (order 2) or DC.
    assert!(odd
        .iter()
        .all(|&f| ((f - 995.0) / 10.0).fract().abs() < 1e-9));
    assert!(!odd.iter().any(|&f| (f - 1000.0).abs() < 1e-9));
    // Commensurate tones (f2 = 2 f1): 2 f1 − f2 = 0 is order 3, so a cubic model has a DC line.
    let comm = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![1000.0, 2000.0],
        force: vec![vec![Complex64::new(1.0, 0.0); 2]],
    };
    let l = choose_lattice(&duffing, &comm, &s).expect("lattice");
    assert_eq!(l[0], 0.0, "{l:?}");
}

/// Returns `(rel. error of X0, rel. error of X2)` of HB against the leading-order series
/// (with `x1` = linear response when `linear`, the HB fundamental otherwise).
fn quadratic_errors(a: f64, f: f64, force: f64, linear: bool) -> (f64, f64, f64) {
    let m = quadratic(a);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![f],
        force: vec![vec![Complex64::new(force, 0.0)]],
    };
    let st = sim::steady_state(&m, &drive, &HbSettings::default()).expect("hb");
    assert!(st.converged(), "{:?}", st.status);
    assert!(st.lattice_hz.contains(&0.0) && st.lattice_hz.contains(&(2.0 * f)));
    let (w, g) = (m.omega(0), m.gamma(0));
    let x1 = if linear {
        linear_response(w, g, f, Complex64::new(force, 0.0))
    } else {
        st.amplitude(0, f)
    };
    let o2 = 2.0 * TAU * f;
    let l2 = Complex64::new(w * w - o2 * o2, o2 * g);
    let x0 = -a * x1.norm_sqr() / (2.0 * w * w);
    let x2 = -x1 * x1 * a / (l2 * 2.0);
    let h0 = st.amplitude(0, 0.0);
    let h2 = st.amplitude(0, 2.0 * f);
    assert_eq!(h0.im, 0.0, "the static offset is real");
    let eps = a * x1.norm() / (w * w);
    (
        (h0 - x0).norm() / x0.abs(),
        (h2 - x2).norm() / x2.norm(),
        eps,
    )
}

#[test]
fn quadratic_offset_and_second_harmonic_match_closed_form() {
    // Weak nonlinearity ε = a|X1|/ω0² ≈ 1e-3 near resonance.
    let (f, force) = (1002.0, 2.0);
    let x1 = 2.0 * 100.0 / (TAU * 1000.0f64).powi(2);
    let a = 1e-3 * (TAU * 1000.0f64).powi(2) / x1;
    let (e0, e2, eps) = quadratic_errors(a, f, force, true);
    eprintln!("linear X1: eps {eps:.2e}, X0 err {e0:.2e}, X2 err {e2:.2e}");
    assert!(e0 < 0.03 && e2 < 0.03, "{e0:.2e} {e2:.2e}");
    // With the HB fundamental in the formulas the remainder is O(ε²) (the a X0², a X2², 2a X0 X2
    // terms: X0/X1 and X2/X1 are O(ε)); measured 4.5e-7 and 2.9e-7 at ε² = 8.6e-7.
    let (e0, e2, eps) = quadratic_errors(a, f, force, false);
    eprintln!("HB X1: eps {eps:.2e}, X0 err {e0:.2e}, X2 err {e2:.2e}");
    assert!(e0 < eps * eps && e2 < eps * eps, "{e0:.2e} {e2:.2e}");
    // And it is that order: halving a quarters it.
    let (h0, h2, _) = quadratic_errors(0.5 * a, f, force, false);
    assert!((h0 / e0 - 0.25).abs() < 0.02, "{h0:.3e} / {e0:.3e}");
    assert!((h2 / e2 - 0.25).abs() < 0.02, "{h2:.3e} / {e2:.3e}");
}

/// Two modes with quadratic self and coupling terms (`U ⊃ a/3 q1³ + c/2 q1² q2`) and a cubic
/// term, low Q so the time domain integrates few periods; f2 ≈ 2 f1 so the 2f lines resonate.
fn two_mode_quadratic() -> NumericModel {
    NumericModel::new(
        vec!["q1".into(), "q2".into()],
        vec![1000.0, 2010.0],
        vec![80.0, 120.0],
        vec![
            term(0, 3.0e10, vec![(0, 2)]),
            term(0, 2.0e10, vec![(0, 1), (1, 1)]),
            term(1, 1.0e10, vec![(0, 2)]),
            term(0, 1.0e13, vec![(0, 3)]),
        ],
    )
    .expect("model")
}

#[test]
fn hb_with_offset_and_time_domain_agree() {
    let model = two_mode_quadratic();
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![995.0, 1005.0],
        force: vec![
            vec![Complex64::new(20.0, 0.0), Complex64::new(0.0, 15.0)],
            vec![Complex64::new(0.0, 0.0); 2],
        ],
    };
    let measure: Vec<f64> = [0.0, 10.0]
        .into_iter()
        .chain((-2..=3).map(|k| 995.0 + 10.0 * k as f64))
        .chain((-2..=2).map(|k| 2000.0 + 10.0 * k as f64))
        .collect();
    let mut hs = HbSettings::default();
    hs.lattice.extra_hz = measure.clone();
    hs.lattice.order = 11;
    hs.lattice.harmonics = true;
    hs.lattice.window_rel = 0.05;
    let st = sim::steady_state(&model, &drive, &hs).expect("hb");
    assert!(st.converged(), "{:?}", st.status);
    let main = st.amplitude(0, 995.0).norm();
    let dc = st.amplitude(0, 0.0).re;
    // The offset and the 2f lines matter (else the test proves nothing).
    assert!(dc.abs() > 0.005 * main, "offset {dc:.3e} vs {main:.3e}");
    assert!(st.amplitude(1, 2000.0).norm() > 0.05 * main);
    let shapes = vec![vec![0.3, 0.6]];
    let (q, v) = st.state_at(0.0);
    for start in [Start::Rest, Start::State { q, v }] {
        let r = sim::simulate_lockin(
            &model,
            &drive,
            &measure,
            &shapes,
            &start,
            &TdSettings::default(),
        )
        .expect("td");
        let mut worst: f64 = 0.0;
        for n in 0..2 {
            let biggest = measure
                .iter()
                .map(|&f| st.amplitude(n, f).norm())
                .fold(0.0, f64::max);
            for (k, &f) in measure.iter().enumerate() {
                let hb = st.amplitude(n, f);
                if hb.norm() >= 0.003 * biggest {
                    let rel = (r.modal[n][k] - hb).norm() / hb.norm();
                    worst = worst.max(rel);
                    assert!(
                        rel < 1e-3,
                        "q{} at {f} Hz: td {} vs hb {hb} ({rel:.2e}), start {start:?}",
                        n + 1,
                        r.modal[n][k]
                    );
                }
            }
        }
        // The point signal too, including its offset.
        let p0 = st.at_point(&shapes[0], 0.0);
        assert!((r.points[0][0] - p0).norm() < 1e-3 * p0.norm());
        eprintln!("start {start:?}: worst {worst:.2e}, DC {dc:.3e} (main {main:.3e})");
    }
}

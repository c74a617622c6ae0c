//! Parametric pumping (issue 20, item 6): a pump tone that modulates a stiffness,
//! `q̈ + γq̇ + ω²q + λ·pump(t)·q + β q³ = F(t)`, `pump(t) = Re[P e^{i2πf_p t}]`, against closed
//! forms — the parametric instability threshold `λ|P| = 2ω²/Q` at `f_p = 2f`, the
//! phase-sensitive gain of the degenerate parametric amplifier — and against the time-domain
//! integrator.

use harmonid_sim::{
    check_stability, simulate_lockin, steady_state, Excitation, HbSettings, NumericModel, PumpTone,
    SimError, Start, TdSettings, Term,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 1000.0;
const Q: f64 = 1000.0;

/// One mode at 1 kHz: `λ pump q` (variable 2 of a one-mode model is the pump) and `β q³`.
fn pumped(lambda: f64, beta: f64) -> NumericModel {
    let mut terms = vec![Term {
        eq: 0,
        coef: lambda,
        factors: vec![(0, 1), (2, 1)],
    }];
    if beta != 0.0 {
        terms.push(Term {
            eq: 0,
            coef: beta,
            factors: vec![(0, 3)],
        });
    }
    NumericModel::new(vec!["q".into()], vec![F0], vec![Q], terms).expect("model")
}

fn excitation(f_hz: f64, force: Complex64, pump_hz: f64, pump: Complex64) -> Excitation {
    Excitation {
        tones_hz: vec![f_hz],
        force: vec![vec![force]],
        pumps: vec![PumpTone {
            hz: pump_hz,
            amplitude: pump,
        }],
    }
}

/// `λ|P|` at the threshold of a single mode pumped at `2f`, from the single-harmonic balance
/// `iωγX + (λP/2) X̄ = 0`: `λ|P| = 2ωγ = 2ω²/Q`.
fn threshold() -> f64 {
    2.0 * (TAU * F0).powi(2) / Q
}

#[test]
fn the_zero_state_loses_stability_at_the_parametric_threshold() {
    let m = pumped(1.0, 0.0);
    let settings = HbSettings::default();
    // A weak drive off the pump's half, so the lattice has both the drive's lines and f_p/2.
    let stable_at = |p: f64| {
        let drive = excitation(
            F0 + 3.0,
            Complex64::new(1e-3, 0.0),
            2.0 * F0,
            Complex64::new(p, 0.0),
        );
        let st = steady_state(&m, &drive, &settings).expect("solves");
        // At the threshold itself a linear resonator has no steady state (the Jacobian is
        // singular there); anywhere else it has one.
        if (p / threshold() - 1.0).abs() > 1e-3 {
            assert!(st.converged(), "P = {p}: {:?}", st.status);
        }
        st.converged() && check_stability(&m, &drive, &st).expect("stability").stable
    };
    let pth = threshold();
    assert!(stable_at(0.9 * pth));
    assert!(!stable_at(1.1 * pth));
    // Bisection to 1e-7.
    let (mut lo, mut hi) = (0.9 * pth, 1.13 * pth);
    while hi - lo > 1e-7 * pth {
        let mid = 0.5 * (lo + hi);
        if stable_at(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let found = 0.5 * (lo + hi);
    println!("threshold {found:.6e}, closed form {pth:.6e}");
    // The closed form is the single-harmonic one; the lines the lattice adds shift it by
    // O((λP/ω²)²) = O(1/Q²) (9e-7 here).
    assert!(
        (found / pth - 1.0).abs() < 2e-6,
        "threshold {found:e}, closed form {pth:e}"
    );
}

#[test]
fn the_degenerate_amplifier_has_the_phase_sensitive_gain_of_the_closed_form() {
    // Drive at f_p/2 = f0: iωγX + (λP/2)X̄ = F, solved as a real 2×2 system.
    let m = pumped(1.0, 0.0);
    let (w, g) = (TAU * F0, TAU * F0 / Q);
    let quarter = 0.25 * std::f64::consts::PI;
    for (ratio, phase) in [
        (0.5, quarter),
        (0.8, quarter),
        (0.8, 3.0 * quarter),
        (0.3, 1.0),
    ] {
        let p = ratio * threshold();
        let force = Complex64::from_polar(1.0, phase);
        let drive = excitation(F0, force, 2.0 * F0, Complex64::new(p, 0.0));
        let st = steady_state(&m, &drive, &HbSettings::default()).expect("solves");
        assert!(st.converged() && !st.pump_sustained);
        // X = a + ib: [(λP/2), −ωγ; ωγ, −(λP/2)] [a; b] = [Re F; Im F].
        let h = 0.5 * p;
        let det = -h * h + w * g * w * g;
        let a = (-h * force.re + w * g * force.im) / det;
        let b = (-w * g * force.re + h * force.im) / det;
        let want = Complex64::new(a, b);
        let got = st.amplitude(0, F0);
        println!("P/Pth {ratio}, phase {phase}: HB {got}, closed form {want}");
        assert!(
            (got - want).norm() < 1e-5 * want.norm(),
            "HB {got}, closed form {want}"
        );
        // Against the linear response: a pump of phase 0 amplifies a force of phase 3π/4 by
        // 1/(1 − P/Pth) and squeezes one of phase π/4 by 1/(1 + P/Pth).
        let linear = force / Complex64::new(0.0, w * g);
        let gain = got.norm() / linear.norm();
        if phase == quarter || phase == 3.0 * quarter {
            let expected = if phase == quarter {
                1.0 / (1.0 + ratio)
            } else {
                1.0 / (1.0 - ratio)
            };
            assert!(
                (gain / expected - 1.0).abs() < 1e-4,
                "gain {gain}, {expected}"
            );
        }
    }
}

#[test]
fn harmonic_balance_agrees_with_the_time_domain_under_a_pump() {
    // A Duffing mode driven 2 Hz above resonance, pumped at 2f below threshold: the idler at
    // f_p − f_d and the mixing products of both.
    // β a² ≈ ω²/Q at the signal's amplitude a: a Duffing shift of about a linewidth.
    let beta = 1e13;
    let m = pumped(1.0, beta);
    let (fd, fp) = (F0 + 1.0, 2.0 * F0);
    let force = 1e-4 * (TAU * F0).powi(2) / Q;
    let drive = excitation(
        fd,
        Complex64::new(force, 0.0),
        fp,
        Complex64::from_polar(0.6 * threshold(), 0.3),
    );
    // The pump's sum lines near 3f (f_p + each line near f) and the Duffing harmonics feed
    // back at ~1e-5 of the signal: keep them.
    let mut settings = HbSettings::default();
    settings.lattice.order = 11;
    settings.lattice.harmonics = true;
    settings.lattice.extra_hz = (-4..=4).map(|k| fp + F0 + f64::from(k)).collect();
    let st = steady_state(&m, &drive, &settings).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    assert!(check_stability(&m, &drive, &st).expect("stability").stable);
    let idler = fp - fd;
    let measure = [fd, idler, 2.0 * fd - idler, 2.0 * idler - fd];
    let (q0, v0) = st.state_at(0.0);
    let td = simulate_lockin(
        &m,
        &drive,
        &measure,
        &[vec![1.0]],
        &Start::State { q: q0, v: v0 },
        &TdSettings {
            rtol: 1e-11,
            settle_tau: Some(12.0),
            settle_tol: 1e-8,
            ..TdSettings::default()
        },
    )
    .expect("time domain runs");
    let big = st.amplitude(0, fd).norm();
    // The pump makes an idler comparable to the signal.
    println!("signal {big:e}, idler {:e}", st.amplitude(0, idler).norm());
    assert!(st.amplitude(0, idler).norm() > 0.1 * big);
    for (k, &fk) in measure.iter().enumerate() {
        let (hb, t) = (st.amplitude(0, fk), td.modal[0][k]);
        println!("{fk} Hz: HB {hb:.6e}, time domain {t:.6e}");
        assert!(
            (hb - t).norm() < 1e-6 * big,
            "{fk} Hz: HB {hb}, time domain {t}"
        );
    }
}

#[test]
fn a_pump_term_without_a_pump_is_refused_by_name() {
    let m = pumped(1.0, 0.0);
    let drive = Excitation::new(vec![F0], vec![vec![Complex64::new(1.0, 0.0)]]);
    let e = steady_state(&m, &drive, &HbSettings::default()).expect_err("no pump");
    assert!(matches!(e, SimError::NoPump { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("q*pump") && text.contains("pumps_hz"),
        "{text}"
    );
}

#[test]
fn computations_without_a_pump_refuse_a_pumped_model() {
    let m = pumped(1.0, 1e13);
    let sweep = harmonid_sim::sweep(
        &m,
        &[Complex64::new(1.0, 0.0)],
        &harmonid_sim::SweepSettings {
            f_start_hz: 990.0,
            f_stop_hz: 1010.0,
            ..harmonid_sim::SweepSettings::default()
        },
    )
    .expect_err("no pump in a single-tone sweep");
    assert!(
        matches!(sweep, SimError::PumpTerms { .. }) && sweep.to_string().contains("stepped"),
        "{sweep}"
    );
    let lc = harmonid_sim::limit_cycle(&m, 5).expect_err("no pump in a limit cycle");
    assert!(matches!(lc, SimError::PumpTerms { .. }), "{lc}");
    let bb = harmonid_sim::backbone(&m, 0, &[1e-5], 5).expect_err("no backbone");
    assert!(matches!(bb, SimError::PumpTerms { .. }), "{bb}");
}

#[test]
fn a_stepped_sweep_under_a_pump_follows_the_harmonic_balance() {
    // Each step re-solved from rest agrees with the step carried from the previous one (a
    // stable, single-valued response below threshold and below the Duffing fold).
    let m = pumped(1.0, 1e12);
    let force = 1e-5 * (TAU * F0).powi(2) / Q;
    let pump = Complex64::new(0.5 * threshold(), 0.0);
    let drives: Vec<Excitation> = (0..=40)
        .map(|k| {
            excitation(
                995.0 + 0.25 * f64::from(k),
                Complex64::new(force, 0.0),
                2.0 * F0,
                pump,
            )
        })
        .collect();
    let settings = HbSettings::default();
    let states = harmonid_sim::stepped_sweep(&m, &drives, &settings).expect("sweep");
    for (d, st) in drives.iter().zip(&states) {
        assert!(st.converged(), "{} Hz: {:?}", d.tones_hz[0], st.status);
        let fresh = steady_state(&m, d, &settings).expect("solves");
        let f = d.tones_hz[0];
        let (a, b) = (st.amplitude(0, f), fresh.amplitude(0, f));
        assert!((a - b).norm() < 1e-8 * b.norm(), "{f} Hz: {a} vs {b}");
    }
}

#[test]
fn above_threshold_the_pump_sustains_the_duffing_limited_oscillation() {
    // Single harmonic at f_p/2 = f0: iωγX + (λP/2)X̄ + (3/4)β|X|²X = 0, so the parametric
    // oscillation's amplitude is a² = (4/3β)·√((λP/2)² − (ωγ)²).
    let beta = 1e12;
    let m = pumped(1.0, beta);
    let wg = (TAU * F0).powi(2) / Q;
    for ratio in [1.5, 3.0] {
        // A drive far weaker than the oscillation, off f_p/2: the seed of an experiment.
        let drive = excitation(
            F0 + 3.0,
            Complex64::new(1e-3, 0.0),
            2.0 * F0,
            Complex64::new(ratio * threshold(), 0.0),
        );
        let st = steady_state(&m, &drive, &HbSettings::default()).expect("solves");
        assert!(st.converged(), "{:?}", st.status);
        assert!(st.pump_sustained);
        assert!(check_stability(&m, &drive, &st).expect("stability").stable);
        let h = 0.5 * ratio * threshold();
        let want = (4.0 / (3.0 * beta) * (h * h - wg * wg).sqrt()).sqrt();
        let got = st.amplitude(0, F0).norm();
        println!("P/Pth {ratio}: a = {got:.6e}, closed form {want:.6e}");
        assert!(
            (got / want - 1.0).abs() < 1e-3,
            "a = {got:e}, closed form {want:e}"
        );
    }
}

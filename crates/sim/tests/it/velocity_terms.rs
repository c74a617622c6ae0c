//! Velocity terms (nonlinear damping `η q² q̇`, issue 20) in the harmonic balance and the time
//! domain, against closed forms: the power balance of the periodic steady state, the
//! single-harmonic amplitude equation in the weakly nonlinear limit, and the time-domain
//! integrator.

use harmonid_sim::{
    simulate_lockin, steady_state, Excitation, HbSettings, NumericModel, Start, TdSettings, Term,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 1000.0;
const Q: f64 = 100.0;

/// One mode at 1 kHz, Q = 100: `q̈ + γq̇ + ω²q + β q³ + η q² q̇ = Re[F e^{iΩt}]`.
fn damped_duffing(beta: f64, eta: f64) -> NumericModel {
    let mut terms = vec![Term {
        eq: 0,
        coef: eta,
        // Variable 1 of a one-mode model is its velocity.
        factors: vec![(0, 2), (1, 1)],
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

/// Harmonic balance with the direct harmonics (3f, 5f, ...) on the lattice: far from the
/// resonance, the default window leaves them out.
fn with_harmonics() -> HbSettings {
    let mut s = HbSettings::default();
    s.lattice.harmonics = true;
    s.lattice.order = 11;
    s
}

fn drive(f_hz: f64, force: f64) -> Excitation {
    Excitation {
        pumps: Vec::new(),
        tones_hz: vec![f_hz],
        force: vec![vec![Complex64::new(force, 0.0)]],
    }
}

/// Linear peak amplitude 1 mm at resonance: F = x ω²/Q.
fn force_for_mm() -> f64 {
    1e-3 * (TAU * F0).powi(2) / Q
}

/// η that adds one linewidth of damping at 1 mm: η a²/4 = γ.
fn eta_linewidth() -> f64 {
    4.0 * TAU * F0 / Q / 1e-6
}

#[test]
fn power_in_equals_power_dissipated() {
    let beta = 2e11;
    let eta = eta_linewidth();
    let m = damped_duffing(beta, eta);
    let f = F0 * 1.004;
    let force = force_for_mm();
    let st = steady_state(&m, &drive(f, force), &with_harmonics()).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    // Average over one period of the drive (every lattice line is a harmonic of it): exact
    // for the trigonometric polynomials here with 512 samples.
    let n = 512;
    let (mut p_in, mut p_lin, mut p_nl) = (0.0, 0.0, 0.0);
    for j in 0..n {
        let t = j as f64 / (n as f64 * f);
        let (q, v) = st.state_at(t);
        let drive_force = force * (TAU * f * t).cos();
        p_in += drive_force * v[0];
        p_lin += m.gamma(0) * v[0] * v[0];
        p_nl += eta * q[0] * q[0] * v[0] * v[0];
    }
    let (p_in, p_out) = (p_in / n as f64, (p_lin + p_nl) / n as f64);
    assert!(
        (p_in - p_out).abs() < 1e-9 * p_in,
        "in {p_in:e}, out {p_out:e}"
    );
    // The nonlinear damping takes a sizable share.
    assert!(
        p_nl > 0.2 * (p_lin + p_nl),
        "{p_nl:e} of {:e}",
        p_lin + p_nl
    );
}

#[test]
fn the_fundamental_follows_the_single_harmonic_amplitude_equation() {
    // (ω² − Ω² + iΩγ + ¾β a² + iΩ η a²/4) a e^{iφ} = F, with a = |X| at the drive line: the
    // first harmonic of q² q̇ is (|X|²/4)·iΩX. On a lattice of the drive line alone the harmonic
    // balance is exactly this equation; with the direct harmonics it differs by their feedback,
    // small at this nonlinearity.
    let beta = 2e10;
    let eta = eta_linewidth();
    let m = damped_duffing(beta, eta);
    let force = force_for_mm();
    let (w, g) = (m.omega(0), m.gamma(0));
    let one_line = HbSettings::default();
    for df in [-10.0, -3.0, 0.0, 2.0, 6.0, 15.0] {
        let f = F0 + df;
        let o = TAU * f;
        let lhs = |a: f64| {
            Complex64::new(
                w * w - o * o + 0.75 * beta * a * a,
                o * g + o * eta * a * a / 4.0,
            )
        };
        let single_harmonic = |start: f64| {
            // Fixed point of a ↦ F / |L(a)| (a contraction at this nonlinearity).
            let mut a = start;
            for _ in 0..200 {
                a = force / lhs(a).norm();
            }
            force / lhs(a)
        };
        let st = steady_state(&m, &drive(f, force), &one_line).expect("solves");
        assert!(st.converged());
        assert_eq!(st.lattice_hz.len(), 1, "the drive line alone");
        let x = st.amplitude(0, f);
        let want = single_harmonic(x.norm());
        let rel = (x - want).norm() / want.norm();
        assert!(
            rel < 1e-10,
            "Δf {df} Hz: HB {x}, closed form {want}, rel {rel:e}"
        );
        let wide = steady_state(&m, &drive(f, force), &with_harmonics()).expect("solves");
        let rel = (wide.amplitude(0, f) - want).norm() / want.norm();
        assert!(
            rel < 1e-3 && rel > 1e-8,
            "Δf {df} Hz: with harmonics, rel {rel:e}"
        );
    }
}

#[test]
fn harmonic_balance_agrees_with_the_time_domain() {
    let beta = 2e11;
    let eta = eta_linewidth();
    let m = damped_duffing(beta, eta);
    let f = F0 * 1.002;
    let dr = drive(f, force_for_mm());
    let st = steady_state(&m, &dr, &with_harmonics()).expect("solves");
    assert!(st.converged());
    let (q0, v0) = st.state_at(0.0);
    let measure = [f, 3.0 * f, 5.0 * f];
    let td = simulate_lockin(
        &m,
        &dr,
        &measure,
        &[vec![1.0]],
        &Start::State { q: q0, v: v0 },
        &TdSettings {
            rtol: 1e-11,
            // The HB state starts the run; what it misses (its truncation) decays in a few
            // 2Q/ω.
            settle_tau: Some(12.0),
            settle_tol: 1e-8,
            ..TdSettings::default()
        },
    )
    .expect("time domain runs");
    let big = st.amplitude(0, f).norm();
    for (k, &fk) in measure.iter().enumerate() {
        let (hb, t) = (st.amplitude(0, fk), td.modal[0][k]);
        assert!(
            (hb - t).norm() < 1e-6 * big,
            "{fk} Hz: HB {hb}, time domain {t}"
        );
    }
    // The third harmonic is there and carries the velocity term's phase.
    assert!(st.amplitude(0, 3.0 * f).norm() > 1e-4 * big);
}

#[test]
fn the_arclength_sweep_follows_the_harmonic_balance() {
    // The single-tone sweep (alternating frequency-time, harmonics 1 and 3) and the multi-tone
    // harmonic balance on the lines f and 3f solve the same truncated problem.
    let m = damped_duffing(2e11, eta_linewidth());
    let force = force_for_mm();
    let settings = harmonid_sim::SweepSettings {
        f_start_hz: 980.0,
        f_stop_hz: 1030.0,
        points: 200,
        harmonics: 3,
        tol: 1e-12,
    };
    let r = harmonid_sim::sweep(&m, &[Complex64::new(force, 0.0)], &settings).expect("sweeps");
    assert!(r.complete);
    let mut checked = 0;
    for p in r.points.iter().step_by(10) {
        let st = steady_state(&m, &drive(p.f_hz, force), &with_harmonics()).expect("solves");
        assert!(st.converged());
        let x = st.amplitude(0, p.f_hz);
        let i1 = r
            .harmonics
            .iter()
            .position(|&h| h == 1)
            .expect("fundamental");
        let rel = (p.amplitudes[0][i1] - x).norm() / x.norm();
        assert!(
            rel < 1e-8,
            "{} Hz: sweep {}, HB {x}",
            p.f_hz,
            p.amplitudes[0][i1]
        );
        checked += 1;
    }
    assert!(checked > 5);
    // No fold: the nonlinear damping keeps the response single-valued here.
    assert!(r.folds.is_empty());
}

#[test]
fn the_backbone_of_a_damped_model_is_refused() {
    let m = damped_duffing(0.0, eta_linewidth());
    let e = harmonid_sim::backbone(&m, 0, &[1e-3], 3).expect_err("refused");
    assert!(e.to_string().contains("velocity terms"), "{e}");
}

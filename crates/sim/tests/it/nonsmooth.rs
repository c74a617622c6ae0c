//! Non-smooth terms (`abs`, `sign`, `tanh`; issue 36) in the harmonic balance (alternating
//! frequency–time on the lattice) and the time domain, against closed forms: the describing
//! functions of `κ|q|q`, `c|q̇|q̇`, Coulomb `μ sign(q̇)` and `tanh(q̇/v₀)` on a one-line
//! lattice, `|q|²q = q³` exactly on a wide lattice, and the time-domain integrator.

use harmonid_sim::{
    simulate_lockin, steady_state, Excitation, HbSettings, HbSolver, ModelValues, NumericModel,
    Observation, SensParam, Sensitivity, Start, TdSettings,
};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

const F0: f64 = 10_000.0;
const Q: f64 = 1000.0;

/// A one-mode model at 10 kHz, Q = 1000, from the model language, with `params` values.
fn model(terms: &str, params: &[(&str, f64)]) -> NumericModel {
    let names: Vec<&str> = params.iter().map(|(n, _)| *n).collect();
    let src = format!(
        "mode q1, f = 10 kHz, Q = 1000\nparam {}\neom q1 += {terms}\n",
        names.join(", ")
    );
    let m = harmonid_model::parse_str(&src, "test.hb").expect("parses");
    let mut v = ModelValues::default();
    for (n, x) in params {
        v.parameters.insert(n.to_string(), *x);
    }
    NumericModel::from_model(&m, &v).expect("numeric model")
}

fn drive(f_hz: f64, force: f64) -> Excitation {
    Excitation {
        pumps: Vec::new(),
        tones_hz: vec![f_hz],
        force: vec![vec![Complex64::new(force, 0.0)]],
    }
}

/// Linear peak amplitude 1 µm at resonance.
fn force_um() -> f64 {
    1e-6 * (TAU * F0).powi(2) / Q
}

/// Solves `X = F / L(|X|)` by fixed-point iteration from the harmonic balance's own `|X|`:
/// the single-harmonic amplitude equation `L(a) X = F`.
fn single_harmonic(force: f64, start: f64, l: impl Fn(f64) -> Complex64) -> Complex64 {
    let mut a = start;
    for _ in 0..400 {
        a = force / l(a).norm();
    }
    force / l(a)
}

#[test]
fn describing_functions_of_abs_and_quadratic_drag() {
    // Fundamental of κ|q|q at q = a cos θ: 8κa²/(3π); of c|q̇|q̇: 8c(aΩ)²/(3π) in phase with q̇.
    // Each adds about a linewidth's shift or damping at 1 µm.
    let w = TAU * F0;
    let kappa = 0.5 * w * w / Q / 1e-6 * 3.0 * PI / 8.0;
    let drag = 0.5 * (w / Q) / (w * 1e-6) * 3.0 * PI / 8.0;
    let m = model(
        "kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)",
        &[("kappa1", kappa), ("drag1", drag)],
    );
    let g = m.gamma(0);
    let force = force_um();
    let mut worst: f64 = 0.0;
    for df in [-20.0, -5.0, 0.0, 5.0, 12.0, 30.0] {
        let f = F0 + df;
        let o = TAU * f;
        let st = steady_state(&m, &drive(f, force), &HbSettings::default()).expect("solves");
        assert!(st.converged(), "{df}: {:?}", st.status);
        assert_eq!(st.lattice_hz.len(), 1, "the drive line alone");
        let x = st.amplitude(0, f);
        let want = single_harmonic(force, x.norm(), |a| {
            Complex64::new(
                w * w - o * o + 8.0 * kappa * a / (3.0 * PI),
                o * g + 8.0 * drag * a * o * o / (3.0 * PI),
            )
        });
        worst = worst.max((x - want).norm() / want.norm());
    }
    println!("abs and drag describing functions: worst relative error {worst:.2e}");
    assert!(worst < 1e-6, "worst {worst:e}");
}

#[test]
fn coulomb_friction_and_its_tanh_limits() {
    // μ sign(q̇): fundamental 4μ/π in phase with q̇, an equivalent damping 4μ/(π a Ω).
    let w = TAU * F0;
    let force = force_um();
    let mu = 0.3 * force;
    let coulomb = |o: f64, g: f64, mu: f64| {
        move |a: f64| Complex64::new(w * w - o * o, o * g + 4.0 * mu / (PI * a))
    };
    let m = model("mu1*sign(d(q1))", &[("mu1", mu)]);
    let (g, f) = (m.gamma(0), F0 + 3.0);
    let o = TAU * f;
    let st = steady_state(&m, &drive(f, force), &HbSettings::default()).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    let x = st.amplitude(0, f);
    let want = single_harmonic(force, x.norm(), coulomb(o, g, mu));
    let rel = (x - want).norm() / want.norm();
    println!("Coulomb describing function: relative error {rel:.2e}");
    assert!(rel < 1e-6, "sign: HB {x}, closed form {want}, rel {rel:e}");
    // tanh(q̇/v0) with v0 far below the velocity amplitude tends to sign.
    let v_amp = x.norm() * o;
    let m = model("mu1*tanh(d(q1)/1e-7)", &[("mu1", mu)]);
    let st = steady_state(&m, &drive(f, force), &HbSettings::default()).expect("solves");
    let rel = (st.amplitude(0, f) - x).norm() / x.norm();
    println!(
        "tanh, v0 = {:.1e} of the velocity: {rel:.2e} from sign",
        1e-7 / v_amp
    );
    assert!(rel < 1e-3, "tanh near sign: {rel:e}");
    // Far above it, a linear damping μ/v0 (cubic correction (aΩ/v0)²/4 ≈ 1e-7 here).
    // (v0 = 1e3 velocity amplitudes, coefficient g·v0: one more linewidth of damping).
    let v0 = 1e3 * v_amp;
    let m = model(&format!("mu1*tanh(d(q1)/{v0:e})"), &[("mu1", g * v0)]);
    let st = steady_state(&m, &drive(f, force), &HbSettings::default()).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    let lin = force / Complex64::new(w * w - o * o, o * 2.0 * g);
    let rel = (st.amplitude(0, f) - lin).norm() / lin.norm();
    println!("tanh, v0 = 1e3 velocities: {rel:.2e} from the linear damping");
    assert!(rel < 1e-6, "tanh near linear: {rel:e}");
}

#[test]
fn abs_squared_times_q_is_the_cubic_on_a_wide_lattice() {
    // |q|²q = q³ and |q|² = q²: the sampled terms and the exact spectral products must give
    // the same steady state, static offset and harmonics included.
    let beta = 4e20;
    let alpha = 2e13;
    let smooth = model(
        "beta1*q1^3 + alpha1*q1^2",
        &[("beta1", beta), ("alpha1", alpha)],
    );
    let rough = model(
        "beta1*abs(q1)^2*q1 + alpha1*abs(q1)^2",
        &[("beta1", beta), ("alpha1", alpha)],
    );
    // Newton at full drive from the linear response: the drive ramp (42 steps here) takes
    // 15 ms with the exact products but 11-13 s with the sampled terms (Jacobians by
    // differences), too slow for CI.
    let mut s = HbSettings {
        ramp: false,
        ..HbSettings::default()
    };
    let f = F0 * 1.001;
    s.lattice.extra_hz = (2..=5).map(|k| k as f64 * f).collect();
    let t0 = std::time::Instant::now();
    let a = steady_state(&smooth, &drive(f, force_um()), &s).expect("solves");
    let t1 = std::time::Instant::now();
    let b = steady_state(&rough, &drive(f, force_um()), &s).expect("solves");
    println!(
        "exact products {:?}, sampled {:?}, ramp steps {} / {}",
        t1 - t0,
        t1.elapsed(),
        a.ramp_steps,
        b.ramp_steps
    );
    assert!(a.converged() && b.converged());
    assert_eq!(a.lattice_hz, b.lattice_hz);
    assert!(
        a.lattice_hz.len() >= 6 && a.lattice_hz[0] == 0.0,
        "{:?}",
        a.lattice_hz
    );
    let big = a.amplitude(0, f).norm();
    let mut worst: f64 = 0.0;
    for &fr in &a.lattice_hz {
        worst = worst.max((a.amplitude(0, fr) - b.amplitude(0, fr)).norm() / big);
    }
    println!(
        "|q|^2 q vs q^3 on {} lines: worst {worst:.2e} of the fundamental",
        a.lattice_hz.len()
    );
    assert!(worst < 1e-9, "worst {worst:e}");
    assert!(
        a.amplitude(0, 0.0).norm() > 1e-4 * big,
        "an offset to compare"
    );
}

#[test]
fn harmonic_balance_agrees_with_the_time_domain() {
    let w = TAU * F0;
    let kappa = 2.0 * w * w / Q / 1e-6;
    let drag = 1.0 * (w / Q) / (w * 1e-6);
    let m = model(
        "kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)",
        &[("kappa1", kappa), ("drag1", drag)],
    );
    let f = F0 * 1.0005;
    let dr = drive(f, force_um());
    let mut s = HbSettings::default();
    s.lattice.extra_hz = (2..=9).map(|k| k as f64 * f).collect();
    let st = steady_state(&m, &dr, &s).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    let (q0, v0) = st.state_at(0.0);
    let measure = [f, 3.0 * f];
    let td = simulate_lockin(
        &m,
        &dr,
        &measure,
        &[vec![1.0]],
        &Start::State { q: q0, v: v0 },
        &TdSettings {
            rtol: 1e-11,
            settle_tau: Some(2.0),
            settle_tol: 1e-9,
            ..TdSettings::default()
        },
    )
    .expect("time domain runs");
    let big = st.amplitude(0, f).norm();
    for (k, &fk) in measure.iter().enumerate() {
        let (hb, t) = (st.amplitude(0, fk), td.modal[0][k]);
        let rel = (hb - t).norm() / big;
        println!("{fk} Hz: HB {hb:.6e}, time domain {t:.6e}, {rel:.2e} of the fundamental");
        assert!(rel < 1e-6, "{fk} Hz: HB {hb}, time domain {t}");
    }
    assert!(
        st.amplitude(0, 3.0 * f).norm() > 1e-5 * big,
        "a third harmonic"
    );
}

#[test]
fn newton_converges_with_coulomb_friction_on_harmonics() {
    // The pointwise derivative of sign is zero; the Jacobian by differences of the harmonic
    // coefficients is not, and Newton converges on a lattice with harmonics.
    let force = force_um();
    let m = model(
        "mu1*sign(d(q1)) + beta1*q1^3",
        &[("mu1", 0.2 * force), ("beta1", 1e20)],
    );
    let f = F0 * 1.0002;
    let mut s = HbSettings::default();
    s.lattice.extra_hz = vec![3.0 * f, 5.0 * f, 7.0 * f];
    let st = steady_state(&m, &drive(f, force), &s).expect("solves");
    assert!(
        st.converged(),
        "{:?}, residual {:e}",
        st.status,
        st.residual
    );
    assert!(st.residual < 1e-9, "{:e}", st.residual);
}

#[test]
fn sensitivity_to_a_nonsmooth_coefficient_matches_differences() {
    let w = TAU * F0;
    let kappa = w * w / Q / 1e-6;
    let f = F0 * 1.0003;
    let at = |k: f64| model("kappa1*abs(q1)*q1", &[("kappa1", k)]);
    let m = at(kappa);
    let dr = drive(f, force_um());
    let s = HbSettings::default();
    let mut solver = HbSolver::new(&m, &dr, &s.lattice).expect("set up");
    let st = solver.solve(&s);
    assert!(st.converged());
    let obs = [Observation {
        f_hz: f,
        shape: vec![1.0],
    }];
    let mut sens = Sensitivity::new(&solver, &[f], &[SensParam::Param(0)], &obs).expect("sens");
    let mut out = [Complex64::new(0.0, 0.0)];
    sens.compute(&mut solver, &st, &mut out).expect("computes");
    let h = 1e-5 * kappa;
    let xp = steady_state(&at(kappa + h), &dr, &s)
        .expect("solves")
        .amplitude(0, f);
    let xm = steady_state(&at(kappa - h), &dr, &s)
        .expect("solves")
        .amplitude(0, f);
    let fd = (xp - xm) / (2.0 * h);
    let rel = (out[0] - fd).norm() / fd.norm();
    println!(
        "dX/dkappa: {:.6e} vs differences {fd:.6e}, {rel:.1e}",
        out[0]
    );
    assert!(rel < 1e-5, "{} vs {fd}", out[0]);
}

#[test]
fn the_backbone_refuses_nonsmooth_terms() {
    let m = model("kappa1*abs(q1)*q1", &[("kappa1", 1e10)]);
    let err = harmonid_sim::backbone(&m, 0, &[1e-6], 3).expect_err("refused");
    let text = err.to_string();
    assert!(text.contains("abs(q1)*q1 in the equation of q1"), "{text}");
    assert!(text.contains("harmonid sweep"), "{text}");
}

#[test]
fn truth_values_name_the_nonsmooth_terms_and_read_back() {
    // `truth.toml`'s `[eom.q1]` holds every term by its monomial name; read back, the model
    // gives the same forces.
    let m = model(
        "kappa1*abs(q1)*q1 + mu1*tanh(d(q1)/0.001) + beta1*q1^3 + eta1*sign(d(q1))*q1^2",
        &[
            ("kappa1", 3.0),
            ("mu1", 5.0),
            ("beta1", 7.0),
            ("eta1", 11.0),
        ],
    );
    let map = m.eom_map(0);
    assert_eq!(map.get("abs(q1)*q1"), Some(&3.0));
    assert_eq!(map.get("tanh(d(q1)/0.001)"), Some(&5.0));
    assert_eq!(map.get("sign(d(q1))*q1^2"), Some(&11.0));
    let mut v = ModelValues::default();
    v.modes.insert(
        "q1".into(),
        harmonid_sim::ModeValues {
            f_hz: Some(F0),
            q: Some(Q),
        },
    );
    v.eom.insert("q1".into(), map);
    let back = NumericModel::from_values(&["q1".to_string()], &v).expect("reads back");
    assert_eq!(back.rough_terms().len(), 3);
    let x = [-0.7, 2e-3];
    let (mut a, mut b) = ([0.0], [0.0]);
    let mut pows = vec![0.0; m.pow_len()];
    m.forces(&x, &mut pows, &mut a);
    let mut pows = vec![0.0; back.pow_len()];
    back.forces(&x, &mut pows, &mut b);
    assert!((a[0] - b[0]).abs() < 1e-12 * a[0].abs(), "{a:?} vs {b:?}");
    let want = 3.0 * 0.7 * -0.7 + 5.0 * (2.0f64).tanh() + 7.0 * (-0.343) + 11.0 * 0.49;
    assert!(
        (a[0] - want).abs() < 1e-12 * want.abs(),
        "{} vs {want}",
        a[0]
    );
}

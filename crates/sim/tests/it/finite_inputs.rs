//! No panic on any finite input (issue 11): the public numeric entry points of `sim` given
//! arbitrary finite numbers (zeros, subnormals, ±1e308 included) return a value or an error.
//! Results are not checked here (the physics tests do that), only that nothing panics and that
//! what is returned as converged is finite.

use harmonid_sim::{
    check_stability, common_grid, linear_response, parse_monomial, steady_state, sweep, Excitation,
    HbSettings, NumericModel, SweepSettings, Term,
};
use num_complex::Complex64;
use proptest::prelude::*;

/// Any finite f64: normal, subnormal or zero, either sign.
fn finite() -> impl Strategy<Value = f64> {
    prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO
}

/// A finite f64 that is, three times in four, of a physically plausible size (so that the
/// solvers are reached, not only the checks).
fn plausible(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![1 => finite(), 3 => (lo.ln()..hi.ln()).prop_map(f64::exp)]
}

/// A one- or two-mode model with a cubic term per mode and a coupling, arbitrary numbers.
fn model() -> impl Strategy<Value = (Vec<f64>, Vec<f64>, Vec<f64>)> {
    (1usize..=2).prop_flat_map(|n| {
        (
            prop::collection::vec(plausible(1.0, 1e6), n),
            prop::collection::vec(plausible(1.0, 1e5), n),
            prop::collection::vec(prop_oneof![1 => finite(), 3 => -1e12..1e12], n + 1),
        )
    })
}

fn build(f: &[f64], q: &[f64], coef: &[f64]) -> Result<NumericModel, harmonid_sim::SimError> {
    let n = f.len();
    let names = (1..=n).map(|i| format!("q{i}")).collect();
    let mut terms: Vec<Term> = (0..n)
        .map(|m| Term {
            eq: m,
            coef: coef[m],
            factors: vec![(m, 3)],
        })
        .collect();
    if n == 2 {
        terms.push(Term {
            eq: 0,
            coef: coef[2],
            factors: vec![(0, 1), (1, 2)],
        });
        terms.push(Term {
            eq: 1,
            coef: coef[2],
            factors: vec![(0, 2), (1, 1)],
        });
    }
    NumericModel::new(names, f.to_vec(), q.to_vec(), terms)
}

/// Settings that keep each solve short: low order, few Newton iterations and ramp steps.
fn quick() -> HbSettings {
    let mut s = HbSettings::default();
    s.lattice.order = 3;
    s.max_iter = 20;
    s.max_ramp_steps = 20;
    s
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn steady_state_and_stability_never_panic(
        (f, q, coef) in model(),
        tones in prop::collection::vec(plausible(1.0, 1e6), 1..=3),
        forces in prop::collection::vec(plausible(1e-3, 1e3), 6),
    ) {
        let Ok(m) = build(&f, &q, &coef) else { return Ok(()) };
        let drive = Excitation {
 pumps: Vec::new(),
            force: (0..m.n_modes())
                .map(|n| (0..tones.len()).map(|d| Complex64::new(forces[(n * 3 + d) % 6], 0.0)).collect())
                .collect(),
            tones_hz: tones,
        };
        if drive.check(m.n_modes()).is_err() {
            return Ok(());
        }
        if let Ok(st) = steady_state(&m, &drive, &quick()) {
            if st.converged() {
                prop_assert!(st.amplitudes.iter().flatten().all(|x| x.re.is_finite() && x.im.is_finite()));
                let _ = check_stability(&m, &drive, &st);
            }
        }
    }

    #[test]
    fn sweep_never_panics(
        (f, q, coef) in model(),
        from in plausible(1.0, 1e6),
        to in plausible(1.0, 1e6),
        force in plausible(1e-3, 1e3),
        points in 0usize..40,
        harmonics in 0usize..8,
    ) {
        let Ok(m) = build(&f, &q, &coef) else { return Ok(()) };
        let settings = SweepSettings {
            f_start_hz: from,
            f_stop_hz: to,
            points,
            harmonics,
            ..SweepSettings::default()
        };
        let force: Vec<Complex64> = (0..m.n_modes()).map(|_| Complex64::new(force, 0.0)).collect();
        if let Ok(r) = sweep(&m, &force, &settings) {
            prop_assert!(r.points.iter().all(|p| p.f_hz.is_finite()));
        }
    }

    #[test]
    fn small_helpers_never_panic(
        omega in finite(), gamma in finite(), f in finite(), re in finite(), im in finite(),
        freqs in prop::collection::vec(finite(), 0..6), tol in finite(), min in finite(),
        name in "[q0-9^*a-z ]{0,12}",
    ) {
        let _ = linear_response(omega, gamma, f, Complex64::new(re, im));
        let _ = common_grid(&freqs, tol, min);
        let _ = parse_monomial(&name, &["q1".to_string(), "q2".to_string()]);
    }
}

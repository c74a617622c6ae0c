//! The bounded-restoring-force check of `NumericModel` with non-smooth position terms
//! (issue 36 notes): `abs(q)*q` counts as an odd power of degree 2, `sign(q)` and
//! `tanh(q/τ)` as degree 0, beside the polynomial own powers.

use harmonid_sim::{ModelValues, NumericModel, SimError};

/// A one-mode model at 1 kHz, Q = 100, with `eom q1 += {terms}` and `params` values.
fn build(terms: &str, params: &[(&str, f64)]) -> Result<NumericModel, SimError> {
    let names: Vec<&str> = params.iter().map(|(n, _)| *n).collect();
    let src = format!(
        "mode q1, f = 1 kHz, Q = 100\nparam {}\neom q1 += {terms}\n",
        names.join(", ")
    );
    let m = harmonid_model::parse_str(&src, "test.hb").expect("parses");
    let mut v = ModelValues::default();
    for (n, x) in params {
        v.parameters.insert(n.to_string(), *x);
    }
    NumericModel::from_model(&m, &v)
}

/// `ω²` of the 1 kHz mode, s⁻².
fn w2() -> f64 {
    (std::f64::consts::TAU * 1e3).powi(2)
}

#[test]
fn wrong_sign_abs_q_q_without_a_well_is_refused_by_name() {
    // A buckled mode (stiffness at rest −ω²) whose |q|q term pushes away: unbounded.
    let r = build(
        "k1*q1 - kappa1*abs(q1)*q1",
        &[("k1", -2.0 * w2()), ("kappa1", 1e12)],
    );
    let Err(e @ SimError::Unbounded { .. }) = r else {
        panic!("expected Unbounded, got {:?}", r.map(|_| ()));
    };
    let msg = e.to_string();
    assert!(msg.contains("along q1"), "{msg}");
    assert!(msg.contains("abs(q1)*q1"), "names the term: {msg}");
    assert!(msg.contains("degree 2"), "{msg}");
    assert!(
        msg.contains("-3.948e7"),
        "the stiffness at rest, −ω²: {msg}"
    );
}

#[test]
fn restoring_abs_q_q_bounds_a_buckled_mode() {
    // Refused before the check read non-smooth terms ("no higher power stops it").
    let r = build(
        "k1*q1 + kappa1*abs(q1)*q1",
        &[("k1", -2.0 * w2()), ("kappa1", 1e12)],
    );
    assert!(r.is_ok(), "{:?}", r.err());
}

#[test]
fn positive_cubic_dominates_a_wrong_sign_abs_q_q() {
    let r = build(
        "k1*q1 - kappa1*abs(q1)*q1 + beta1*q1^3",
        &[("k1", -2.0 * w2()), ("kappa1", 1e12), ("beta1", 1e15)],
    );
    assert!(r.is_ok(), "{:?}", r.err());
}

#[test]
fn even_terms_of_the_same_degree_add_up_per_direction() {
    // c2 q² + c|q|q: along +q the force grows as (c2 + c) q², along −q as (c2 − c) q²; it
    // is bounded exactly when c > |c2|.
    let p = |c2: f64, c: f64| [("k1", -2.0 * w2()), ("c2", c2), ("kappa1", c)];
    let terms = "k1*q1 + c2*q1^2 + kappa1*abs(q1)*q1";
    assert!(build(terms, &p(1e11, 2e11)).is_ok());
    assert!(build(terms, &p(-1e11, 2e11)).is_ok());
    let e = build(terms, &p(3e11, 2e11)).err().map(|e| e.to_string());
    let msg = e.expect("refused: q² outgrows |q|q along −q1");
    assert!(msg.contains("along −q1"), "{msg}");
    assert!(msg.contains("q1^2 + abs(q1)*q1"), "{msg}");
}

#[test]
fn a_tanh_spring_gives_a_well_at_rest_and_sign_bounds_at_zero_stiffness() {
    // c·tanh(q/τ) adds c/τ to the stiffness at rest: ω² − 2ω² + 3ω² > 0, a well.
    let tau = 1e-6;
    let r = build(
        "k1*q1 + c1*tanh(q1/1e-6)",
        &[("k1", -2.0 * w2()), ("c1", 3.0 * w2() * tau)],
    );
    assert!(r.is_ok(), "{:?}", r.err());
    // No stiffness at all but a restoring step force μ sign(q): bounded.
    let r = build("k1*q1 + mu1*sign(q1)", &[("k1", -w2()), ("mu1", 1.0)]);
    assert!(r.is_ok(), "{:?}", r.err());
    let r = build("k1*q1 - mu1*sign(q1)", &[("k1", -w2()), ("mu1", 1.0)]);
    assert!(matches!(r, Err(SimError::Unbounded { .. })));
}

#[test]
fn a_positive_stiffness_at_rest_is_a_well_as_for_softening_duffing() {
    // As a softening Duffing term, a softening |q|q term with ω² > 0 bounds the mode about
    // rest only: accepted, the sweeps stay near rest (a design choice of the check).
    assert!(build("kappa1*abs(q1)*q1", &[("kappa1", -1e15)]).is_ok());
    assert!(build("beta1*q1^3", &[("beta1", -1e15)]).is_ok());
    // Velocity factors are not position forces: they do not enter the check.
    let r = build(
        "k1*q1 + drag1*abs(d(q1))*d(q1)",
        &[("k1", -2.0 * w2()), ("drag1", 1e3)],
    );
    assert!(matches!(r, Err(SimError::Unbounded { .. })));
}

//! Unit tests of non-smooth factors in terms (issue 36): lowering, names, output, refusals.

use crate::{parse_str, Code, Model, NonSmooth};
use harmonid_poly::VarId;

fn ok(src: &str) -> Model {
    match parse_str(src, "test.hb") {
        Ok(m) => m,
        Err(e) => panic!("{}", e.render_plain(100)),
    }
}

/// The first diagnostic's code and rendered text.
fn refused(src: &str) -> (Code, String) {
    match parse_str(src, "bad.hb") {
        Ok(_) => panic!("expected an error for {src}"),
        Err(e) => (e.diagnostics()[0].code, e.render_plain(120)),
    }
}

/// `nonsmooth[n]` as `monomial -> coefficient` text.
fn rough(m: &Model, n: usize) -> Vec<(String, String)> {
    let params = m.param_names();
    m.nonsmooth[n]
        .terms()
        .map(|(mono, c)| (m.monomial_name(mono), c.to_string_with(&params)))
        .collect()
}

const BEAM: &str = "mode q1 at 10 kHz\nparam beta1, kappa1, drag1, mu1, v0 = 2e-3\n\
    eom q1 += beta1*q1^3 + kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)\n\
    eom q1 += mu1*sign(d(q1)) - mu1/2*tanh(d(q1)/1e-3) + mu1*tanh(d(q1)/v0)\n";

#[test]
fn nonsmooth_terms_lower_beside_the_polynomial_equation() {
    let m = ok(BEAM);
    assert_eq!(m.eom[0].len(), 1, "only beta1 q1^3 stays polynomial");
    assert_eq!(
        m.nonsmooth_factors,
        [
            NonSmooth::Abs(VarId(0)),
            NonSmooth::Abs(VarId(1)),
            NonSmooth::Sign(VarId(1)),
            NonSmooth::Tanh(VarId(1), 1e-3),
            NonSmooth::Tanh(VarId(1), 2e-3),
        ]
    );
    let mut terms = rough(&m, 0);
    terms.sort();
    let want = [
        ("abs(d(q1))*d(q1)", "drag1"),
        ("abs(q1)*q1", "kappa1"),
        ("sign(d(q1))", "mu1"),
        ("tanh(d(q1)/0.001)", "-1/2*mu1"),
        ("tanh(d(q1)/0.002)", "mu1"),
    ];
    let want: Vec<(String, String)> = want
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    assert_eq!(terms, want);
    assert!(m.has_nonsmooth() && m.has_velocity_terms());
    assert!(m.check_identifiable().is_ok());
    assert_eq!(m.term_count(), 6);
    // The factor's variable and the split of a monomial.
    let (mono, _) = m.nonsmooth[0].terms().next().expect("a term");
    let (poly, factors) = m.split_nonsmooth(mono);
    assert!(factors.iter().all(|&(k, e)| k < 5 && e == 1));
    assert!(poly.degree() <= 1);
    assert_eq!(m.nonsmooth_var(0), VarId(3));
}

#[test]
fn equal_factors_share_a_variable_and_terms_combine() {
    let m =
        ok("mode q1\nparam a, b\neom q1 += a*abs(q1)*q1\neom q1 += b*q1*abs(q1) - abs(q1)*(a*q1)");
    assert_eq!(m.nonsmooth_factors.len(), 1);
    assert_eq!(rough(&m, 0), [("abs(q1)*q1".to_string(), "b".to_string())]);
}

#[test]
fn text_latex_json_and_source_show_them() {
    let m = ok(BEAM);
    let text = m.equation_text(0);
    assert!(text.contains("kappa1 abs(q1) q1"), "{text}");
    assert!(text.contains("mu1 sign(d(q1))"), "{text}");
    assert!(m
        .to_text()
        .contains("non-smooth factors: abs(q1), abs(d(q1)), sign(d(q1))"));
    let latex = m.to_latex();
    assert!(latex.contains("\\left|q_{1}\\right| q_{1}"), "{latex}");
    assert!(
        latex.contains("\\operatorname{sign}(\\dot{q}_{1})"),
        "{latex}"
    );
    let json: serde_json::Value = serde_json::from_str(&m.to_json()).expect("json");
    assert_eq!(json["eom"]["q1"]["abs(q1)*q1"]["kappa1"], 1.0);
    assert_eq!(json["eom"]["q1"]["tanh(d(q1)/0.001)"]["mu1"], -0.5);
    // The written source reads back to the same equations.
    let back = ok(&m.to_source("round trip"));
    assert_eq!(rough(&back, 0).len(), 5);
    let mut a = rough(&m, 0);
    let mut b = rough(&back, 0);
    a.sort();
    b.sort();
    assert_eq!(a, b);
}

#[test]
fn misused_nonsmooth_factors_are_located_errors() {
    let head = "mode q1\nmode q2\nparam k, c = 0.5, u\n";
    let cases = [
        ("eom q1 += k*abs(q1 + q2)", "of a sum"),
        ("eom q1 += abs(k)*q1", "of a parameter"),
        ("eom q1 += k*tanh(d(q1)/0)", "tanh(x/0)"),
        ("eom q1 += k*tanh(d(q1)/(-2))", "positive"),
        ("eom q1 += k*tanh(d(q1)/u)", "fixed parameter"),
        ("eom q1 += k*abs(sign(q1))", "do not nest"),
        ("eom q1 += k*abs(-q1)", "sign outside"),
        ("eom q1 += k*abs(q1^2)", "not a product"),
        ("eom q1 += k*abs(q1, q2)", "one argument"),
        ("eom q1 += k*tanh(q2)", "`tanh(q2/1e-9)`"),
        ("eom q1 += k*tanh(d(q1))", "`tanh(d(q1))` has no scale"),
        ("eom q1 += k*tanh(q1 + q2)", "of a sum"),
        (
            "eom q1 += k*sign(q1)^2",
            "`sign(q1)^2` is 1 wherever `q1` is not zero",
        ),
        (
            "eom q1 += k*sign(d(q2))*q1*sign(d(q2))",
            "the term is its other factors alone",
        ),
        (
            "eom q1 += k*sign(d(q1))^3",
            "`sign(d(q1))^3` is `sign(d(q1))`",
        ),
        ("potential: k*abs(q1)^3", "write the force in the equation"),
        (
            "dissipation: k*abs(d(q1))*d(q1)^2",
            "eom q1 += drag1*abs(d(q1))*d(q1)",
        ),
    ];
    for (line, words) in cases {
        let (code, text) = refused(&format!("{head}{line}\n"));
        assert_eq!(code, Code::BadNonSmooth, "{line}: {text}");
        assert!(text.contains(words), "{line}: {text}");
        assert!(text.contains("bad.hb:4:"), "{line} is located: {text}");
    }
    // A fixed parameter is a valid scale; so is 1 written out (a coordinate that is a pure
    // number), and abs of sign or sign times abs is no power of sign.
    let m = ok(&format!(
        "{head}eom q1 += k*tanh(d(q1)/c) + u*tanh(q2/1) + k*sign(q1)*abs(q1)\n"
    ));
    assert_eq!(
        m.nonsmooth_factors,
        [
            NonSmooth::Tanh(VarId(2), 0.5),
            NonSmooth::Tanh(VarId(1), 1.0),
            NonSmooth::Sign(VarId(0)),
            NonSmooth::Abs(VarId(0))
        ]
    );
    // Other functions stay refused as not polynomial.
    let (code, _) = refused(&format!("{head}eom q1 += k*sin(q1)\n"));
    assert_eq!(code, Code::NotPolynomial);
}

#[test]
fn the_functions_and_their_derivatives() {
    let a = NonSmooth::Abs(VarId(0));
    let s = NonSmooth::Sign(VarId(0));
    let t = NonSmooth::Tanh(VarId(0), 0.5);
    assert_eq!((a.value(-2.0), a.derivative(-2.0)), (2.0, -1.0));
    assert_eq!(
        (s.value(-2.0), s.value(0.0), s.derivative(3.0)),
        (-1.0, 0.0, 0.0)
    );
    let h = 1e-6;
    let fd = (t.value(0.3 + h) - t.value(0.3 - h)) / (2.0 * h);
    assert!((t.derivative(0.3) - fd).abs() < 1e-8);
    assert_eq!(crate::format_scale(1e-3), "0.001");
    assert_eq!(crate::format_scale(1e-6), "1e-6");
}

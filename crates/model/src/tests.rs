//! Unit tests of the language: names, families, declarations, lowering, robustness.

use crate::{parse_str, Bounds, Code, Linear, Model, ParamKind};
use harmonid_poly::{Poly, VarId};
use proptest::prelude::*;

fn ok(src: &str) -> Model {
    match parse_str(src, "test.hb") {
        Ok(m) => m,
        Err(e) => panic!("{}", e.render_plain(100)),
    }
}

fn err_codes(src: &str) -> Vec<Code> {
    match parse_str(src, "test.hb") {
        Ok(_) => panic!("expected an error for {src}"),
        Err(e) => e.diagnostics().iter().map(|d| d.code).collect(),
    }
}

/// The equation of `mode` as `monomial -> coefficient` text.
fn eq(m: &Model, mode: &str) -> Vec<(String, String)> {
    let n = m.mode_index(mode).expect("mode exists");
    let params = m.param_names();
    m.eom[n]
        .terms()
        .map(|(mono, c)| (m.monomial_name(mono), c.to_string_with(&params)))
        .collect()
}

fn pairs(v: &[(&str, &str)]) -> Vec<(String, String)> {
    v.iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

#[test]
fn indexed_and_plain_names_are_the_same() {
    let m = ok("mode q[1]\nmode q2\nparam beta[1], g12\neom q1 += beta1*q[1]^3 + g[1,2]*q1*q[2]^2");
    assert_eq!(m.mode_names(), ["q1", "q2"]);
    assert_eq!(m.param_names(), ["beta1", "g12"]);
    assert_eq!(
        eq(&m, "q1"),
        pairs(&[("q1^3", "beta1"), ("q1*q2^2", "g12")])
    );
}

#[test]
fn families_of_ten_or_more_modes_join_indices_with_underscores() {
    let m = ok(
        "for i in 1..12: mode q[i]\nfor i<j in 1..12: param g[i,j]\n\
                for i<j in 1..12: potential: g[i,j]/2*q[i]^2*q[j]^2\n\
                eom q1 += g1_12 * q1^5",
    );
    assert_eq!(m.modes.len(), 12);
    assert_eq!(m.params.len(), 66);
    assert_eq!(m.params[0].name, "g1_2");
    assert_eq!(m.params[10].name, "g1_12");
    assert_eq!(m.params[65].name, "g11_12");
    let q1 = eq(&m, "q1");
    assert!(q1.contains(&("q1*q12^2".to_string(), "g1_12".to_string())));
    assert!(q1.contains(&("q1^5".to_string(), "g1_12".to_string())));
}

#[test]
fn family_relations_count_tuples() {
    for (head, count) in [
        ("i in 1..3", 3),
        ("i<j in 1..3", 3),
        ("i<=j in 1..3", 6),
        ("i!=j in 1..3", 6),
        ("i,j in 1..3", 9),
        ("i<j<k in 1..4", 4),
        ("i<=j<=k<=l in 1..3", 15),
    ] {
        let vars = head.split(" in ").next().unwrap_or("");
        let idx: Vec<&str> = vars
            .split(['<', '=', '!', ','])
            .filter(|s| !s.is_empty())
            .collect();
        let src = format!("mode q1\nfor {head}: param c[{}]", idx.join(","));
        assert_eq!(ok(&src).params.len(), count, "{head}");
    }
}

#[test]
fn nearest_neighbour_chain_with_index_shift_and_block() {
    let m = ok("for i in 1..4: mode q[i]\n\
                for i in 1..3 {\n  param c[i]\n  potential: c[i] * q[i] * q[i+1]\n}");
    assert_eq!(eq(&m, "q2"), pairs(&[("q1", "c1"), ("q3", "c2")]));
    assert_eq!(eq(&m, "q4"), pairs(&[("q3", "c3")]));
}

#[test]
fn declarations_with_values_bounds_and_linear_parts() {
    let m = ok(
        "mode q1 at 207.58 kHz, Q = 116232, f = 207.582 kHz\nmode q2, f = 1.5 GHz\nmodes q3, q4\n\
                param 0 < eta < 1e5, k = -2.5e3, g >= 0, h <= 1\n\
                eom q1 += eta*q1^3 + k*q2 + g*q3 + h*q4",
    );
    assert_eq!(m.modes[0].nominal_hz, Some(207_580.0));
    assert_eq!(m.modes[0].f_hz, Linear::Fixed(207_582.0));
    assert_eq!(m.modes[0].q_factor, Linear::Fixed(116_232.0));
    assert_eq!(
        m.modes[1].nominal_hz,
        Some(1.5e9),
        "f doubles as the nominal frequency"
    );
    assert_eq!(m.modes[2].f_hz, Linear::Unknown);
    assert_eq!(
        m.params[0].bounds,
        Bounds {
            lower: Some(0.0),
            upper: Some(1e5)
        }
    );
    assert_eq!(m.params[1].kind, ParamKind::Fixed(-2500.0));
    assert_eq!(
        m.params[2].bounds,
        Bounds {
            lower: Some(0.0),
            upper: None
        }
    );
    assert_eq!(
        m.params[3].bounds,
        Bounds {
            lower: None,
            upper: Some(1.0)
        }
    );
}

#[test]
fn expressions_expand_exactly() {
    let m = ok("modes q1, q2  # two modes\nparam a, b\n\
                potential: 3/4*a*(q1 + q2)^2   # a comment\n\
                  - b*q1*q2/2\n\
                eom q1 -= 0.5*a*q1 - 2.5e-1*b*q2\n\
                for i in 2..2: eom q2 += a*q2^(i+1)/i");
    // dU/dq1 = 3/2 a (q1 + q2) - b/2 q2; minus (1/2 a q1 - 1/4 b q2).
    assert_eq!(eq(&m, "q1"), pairs(&[("q1", "a"), ("q2", "3/2*a - 1/4*b")]));
    // dU/dq2 = 3/2 a (q1 + q2) - b/2 q1; plus a q2^3 / 2.
    assert_eq!(
        eq(&m, "q2"),
        pairs(&[("q1", "3/2*a - 1/2*b"), ("q2", "3/2*a"), ("q2^3", "1/2*a")])
    );
    assert_eq!(m.potential.len(), 3);
}

#[test]
fn index_variables_are_numbers_outside_brackets() {
    let m = ok("mode q1\nfor i in 1..3: param c[i]\nfor i in 1..3: potential: c[i]/(i+1)*q1^(i+1)");
    assert_eq!(
        eq(&m, "q1"),
        pairs(&[("q1", "c1"), ("q1^2", "c2"), ("q1^3", "c3")])
    );
}

#[test]
fn potential_derivative_agrees_with_poly_derivative() -> Result<(), harmonid_poly::Overflow> {
    let m = ok("modes q1, q2, q3\nparam a, b, c\n\
                potential: a*q1^3*q2 + b/3*(q1 + q2 - q3)^3 + c*q1*q2*q3 + a*b*q3^4");
    let eqs = crate::equations_from_potential(&m.potential, 3)?;
    for (n, e) in eqs.iter().enumerate() {
        assert_eq!(*e, m.potential.derivative(VarId(n as u32))?);
        assert_eq!(m.eom[n], *e);
    }
    assert!(m.check_identifiable().is_err(), "a*b is not affine");
    Ok(())
}

#[test]
fn linear_model_without_terms_is_fine() {
    let m = ok("mode q1 at 1 MHz");
    assert_eq!(m.eom, vec![Poly::zero()]);
    assert_eq!(m.equation_text(0), "q1'' + (w1/Q1) q1' + w1^2 q1 = F1(t)");
}

#[test]
fn semantic_errors_are_all_collected() {
    let codes = err_codes("mode q1\nmode q1\neom q9 += x*q1\npotential: q1^-2 + q1/q1");
    assert_eq!(
        codes,
        [
            Code::Duplicate,
            Code::UndeclaredMode,
            Code::UnknownName,
            Code::NotPolynomial,
            Code::NotPolynomial
        ]
    );
    assert_eq!(err_codes("param a"), [Code::EmptyModel]);
    assert_eq!(err_codes("mode q1\npotential: q1 q1"), [Code::Syntax]);
    assert_eq!(
        err_codes("mode q1\nparam a\npotential: (a+q1)^40*(a+q1)^40"),
        [Code::TooLarge]
    );
}

#[test]
fn latex_names() {
    assert_eq!(crate::latex_name("beta1"), "\\beta_{1}");
    assert_eq!(crate::latex_name("g1_12"), "g_{1,12}");
    assert_eq!(crate::latex_name("kappa"), "\\kappa");
    assert_eq!(crate::latex_name("b122"), "b_{122}");
    assert_eq!(crate::latex_name("eta_nl"), "\\eta_{nl}");
    assert_eq!(crate::latex_name("xy"), "\\mathrm{xy}");
}

const TOKENS: &[&str] = &[
    "mode ",
    "modes ",
    "param ",
    "eom ",
    "potential",
    ":",
    "for ",
    " in ",
    "at ",
    "q1",
    "q2",
    "q[i]",
    "g[i,j]",
    "beta",
    "i",
    "j",
    "<",
    "<=",
    ">=",
    "!=",
    ",",
    "=",
    "+=",
    "-=",
    "+",
    "-",
    "*",
    "/",
    "^",
    "(",
    ")",
    "[",
    "]",
    "{",
    "}",
    "1",
    "2",
    "0",
    "2.5",
    "1e40",
    "..",
    "kHz",
    " ",
    "\n",
    "# c\n",
    "sin",
    "é",
    "\u{0}",
];

#[test]
fn a_very_long_name_prints_without_panicking() {
    // A 65,536-character name used to panic in the name column's formatting width.
    let name = format!("q{}", "x".repeat(65_536));
    let m = ok(&format!(
        "mode {name} at 1 kHz\nparam b{}\neom {name} += b{} * {name}^3\n",
        "y".repeat(65_536),
        "y".repeat(65_536)
    ));
    let text = m.to_text();
    assert!(text.contains(&name));
}

#[test]
fn a_byte_order_mark_is_skipped() {
    let m = ok("\u{FEFF}mode q1 at 1 kHz\n");
    assert_eq!(m.mode_names(), ["q1"]);
    let m = crate::parse_bytes(b"\xEF\xBB\xBFmode q1 at 1 kHz\n", "bom.hb").expect("bom");
    assert_eq!(m.mode_names(), ["q1"]);
}

#[test]
fn bytes_that_are_not_utf8_are_located() {
    let e = crate::parse_bytes(b"mode q1\n\xFF\n", "bad.hb").expect_err("not utf-8");
    assert_eq!(e.diagnostics()[0].code, Code::NotUtf8);
    assert!(
        e.render_plain(80).contains("bad.hb:2:1"),
        "{}",
        e.render_plain(80)
    );
}

#[test]
fn many_parameters_on_one_monomial_are_summed() {
    // 490,000 parameters on one monomial was quadratic in the coefficient's length (many
    // minutes); summed as a balanced tree it is n log n. 20,000 here keep the test short.
    let n = 20_000;
    let m = ok(&format!(
        "mode q1 at 1 kHz\nfor i in 1..{n}: param c[i]\nfor i in 1..{n}: potential: c[i]/4*q1^4\n"
    ));
    let eq = m.equation_text(0);
    assert!(eq.contains("c1 + c2 + c3"), "{}", &eq[..eq.len().min(200)]);
    assert!(eq.contains(&format!("c{n}")));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// No token soup makes the parser panic; every failure carries a diagnostic.
    #[test]
    fn token_soup_never_panics(picks in prop::collection::vec(0..TOKENS.len(), 0..40)) {
        let src: String = picks.iter().map(|&i| TOKENS[i]).collect();
        if let Err(e) = parse_str(&src, "soup.hb") {
            prop_assert!(!e.diagnostics().is_empty());
            let _ = e.render_plain(80);
        }
    }

    /// Cutting and splicing the examples never panics.
    #[test]
    fn mutated_examples_never_panic(which in 0usize..4, cut in 0usize..2000, len in 0usize..40, ins in 0..TOKENS.len()) {
        let src = [
            include_str!("../../../examples/nanostring_2mode/model.hb"),
            include_str!("../../../examples/nanostring_5mode/model.hb"),
            include_str!("../../../examples/three_wave/model.hb"),
            include_str!("../../../examples/cubic_3mode/model.hb"),
        ][which];
        let mut bytes = src.as_bytes().to_vec();
        let at = cut.min(bytes.len());
        let end = (at + len).min(bytes.len());
        bytes.splice(at..end, TOKENS[ins].bytes());
        if let Ok(text) = String::from_utf8(bytes) {
            if let Err(e) = parse_str(&text, "mutated.hb") {
                let _ = e.render_plain(80);
            }
        }
    }
}

#[test]
fn velocities_are_factors_of_direct_terms() {
    let m = ok("mode q1\nmode q2\nparam eta, eta12, mu, nu\n\
                eom q1 += eta*q1^2*d(q1) + eta12*q2^2*d(q1)\n\
                eom q2 += -mu*d(q2) + nu*q2^2*d(q2)");
    assert!(m.has_velocity_terms());
    assert_eq!(m.variable_names(), ["q1", "q2", "d(q1)", "d(q2)", "pump"]);
    assert_eq!(
        eq(&m, "q1"),
        pairs(&[("q1^2*d(q1)", "eta"), ("q2^2*d(q1)", "eta12")])
    );
    assert_eq!(
        eq(&m, "q2"),
        pairs(&[("d(q2)", "-mu"), ("q2^2*d(q2)", "nu")])
    );
    assert!(
        m.equation_text(0).contains("eta q1^2 d(q1)"),
        "{}",
        m.equation_text(0)
    );
    assert!(m.to_latex().contains("\\dot{q}_{1}"), "{}", m.to_latex());
    assert!(m.to_json().contains("\"q1^2*d(q1)\""));
    // Families index velocities like positions.
    let f = ok("for i in 1..3: mode q[i]\nfor i in 1..3: param eta[i]\n\
                for i in 1..3: eom q[i] += eta[i]*q[i]^2*d(q[i])");
    assert_eq!(eq(&f, "q3"), pairs(&[("q3^2*d(q3)", "eta3")]));
    let plain = ok("mode q1\nparam b\npotential: b/4*q1^4");
    assert!(!plain.has_velocity_terms());
}

#[test]
fn a_dissipation_function_gives_its_velocity_derivatives() {
    // D = eta/4 q1^2 d(q1)^2 + c/2 d(q1)^2 d(q2)^2: dD/dv1 = eta/2 q1^2 v1 + c v1 v2^2.
    let m = ok("mode q1\nmode q2\nparam eta, c\n\
                dissipation: eta/4*q1^2*d(q1)^2 + c/2*d(q1)^2*d(q2)^2");
    assert_eq!(
        eq(&m, "q1"),
        pairs(&[("q1^2*d(q1)", "1/2*eta"), ("d(q1)*d(q2)^2", "c")])
    );
    assert_eq!(eq(&m, "q2"), pairs(&[("d(q1)^2*d(q2)", "c")]));
    assert!(!m.dissipation.is_zero());
    assert!(m.potential.is_zero());
}

#[test]
fn misused_velocities_are_located_errors() {
    let base = "mode q1\nmode q2\nparam eta\n";
    for (body, code) in [
        ("eom q1 += eta*d(eta)", Code::BadVelocity),
        ("eom q1 += eta*d(d(q1))", Code::BadVelocity),
        ("eom q1 += eta*d(q1+q2)", Code::BadVelocity),
        ("eom q1 += eta*d(q1, q2)", Code::BadVelocity),
        ("potential: eta*q1^2*d(q1)", Code::VelocityInPotential),
        ("dissipation: eta*q1^2", Code::BadVelocity),
        ("eom q1 += eta*d(q3)", Code::UnknownName),
        ("eom q1 += eta*sin(q1)", Code::NotPolynomial),
    ] {
        let src = format!("{base}{body}");
        assert_eq!(err_codes(&src), [code], "{body}");
    }
    let e = parse_str(&format!("{base}potential: eta*q1^2*d(q1)"), "t.hb")
        .expect_err("a velocity in a potential");
    let text = e.render_plain(100);
    assert!(text.contains("dissipation:"), "{text}");
    assert!(text.contains("t.hb:4"), "{text}");
}

#[test]
fn to_source_reads_back_to_the_same_model() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
    for ex in [
        "nanostring_2mode",
        "nanostring_5mode",
        "three_wave",
        "cubic_3mode",
        "damped_2mode",
        "membrane_4mode",
    ] {
        let path = format!("{root}/{ex}/model.hb");
        let src = std::fs::read_to_string(&path).expect("model");
        let m = crate::parse_str(&src, &path).expect("parses");
        let text = m.to_source("written by a test\nsecond line");
        assert!(
            text.starts_with("# written by a test\n# second line\n"),
            "{text}"
        );
        let back =
            crate::parse_str(&text, "back.hb").unwrap_or_else(|e| panic!("{ex}: {e:?}\n{text}"));
        assert_eq!(back.modes, m.modes, "{ex}");
        assert_eq!(back.params, m.params, "{ex}");
        assert_eq!(back.eom, m.eom, "{ex}:\n{text}");
    }
    // Bounds and fixed values survive.
    let m = crate::parse_str(
        "mode q1 at 1 kHz, Q = 100\nmode q2, f = 2 kHz\nparam 0 <= a <= 5, b >= -1, c = 2.5, d < 3\neom q1 += a*q1^3 + b*q1*q2^2 + c*q1^2*d(q1)\neom q2 += d*q2^3\n",
        "m.hb",
    )
    .expect("parses");
    let back = crate::parse_str(&m.to_source(""), "back.hb").expect("reads back");
    assert_eq!(
        (back.modes, back.params, back.eom),
        (m.modes, m.params, m.eom)
    );
}

#[test]
fn the_pump_is_a_built_in_factor() {
    // A modulated stiffness written directly and through a potential, and a pumped coupling.
    let m = ok("mode q1\nmode q2\nparam lambda, kappa, c\n\
                eom q1 += lambda*pump*q1\n\
                potential: kappa/2*pump*q2^2\n\
                eom q2 += c*pump*q1*d(q2)");
    assert!(m.has_pump_terms());
    assert!(m.has_velocity_terms());
    assert_eq!(m.variable_names(), ["q1", "q2", "d(q1)", "d(q2)", "pump"]);
    assert_eq!(eq(&m, "q1"), pairs(&[("q1*pump", "lambda")]));
    assert_eq!(
        m.pump_term_names(),
        [
            "q1*pump in the equation of q1",
            "q2*pump in the equation of q2",
            "q1*d(q2)*pump in the equation of q2"
        ]
    );
    assert_eq!(
        eq(&m, "q2"),
        pairs(&[("q2*pump", "kappa"), ("q1*d(q2)*pump", "c")])
    );
    assert!(m.to_latex().contains("p(t)"), "{}", m.to_latex());
    let back = crate::parse_str(&m.to_source(""), "back.hb").expect("reads back");
    assert_eq!(back.eom, m.eom);
    // A pump-free model has no pump terms, and velocities alone are not a pump.
    let plain = ok("mode q1\nparam eta\neom q1 += eta*q1^2*d(q1)");
    assert!(!plain.has_pump_terms());
    let pumped = ok("mode q1\nparam lambda\neom q1 += lambda*pump*q1");
    assert!(!pumped.has_velocity_terms());
}

#[test]
fn misused_pumps_are_located_errors() {
    let base = "mode q1\nparam lambda\n";
    for (body, code) in [
        ("param pump", Code::ReservedName),
        ("mode pump", Code::ReservedName),
        ("eom q1 += lambda*d(pump)*q1", Code::BadVelocity),
        ("eom pump += lambda*q1", Code::UndeclaredMode),
    ] {
        let src = format!("{base}{body}");
        assert_eq!(err_codes(&src), [code], "{body}");
    }
    let e = parse_str(&format!("{base}param pump"), "t.hb").expect_err("reserved");
    let text = e.render_plain(100);
    assert!(
        text.contains("built-in") && text.contains("t.hb:3"),
        "{text}"
    );
}

/// Hostile input 16: a syntax error at the end of a 1 MB line made miette panic ("Formatting
/// argument out of range"); hostile input 15: a nesting error quoted the whole 200 kB line.
#[test]
fn an_error_on_a_huge_line_is_quoted_as_a_window() {
    let long = format!(
        "mode q1 at 1 kHz\nparam b\npotential: b*q1^4{} + $\n",
        " + b*q1^4".repeat(110_000)
    );
    let e = parse_str(&long, "long.hb").expect_err("syntax error");
    assert_eq!(e.diagnostics()[0].code, Code::Syntax);
    let text = e.render_plain(100);
    assert!(text.len() < 2_000, "{} bytes", text.len());
    assert!(
        text.contains("long.hb:3:990021") && text.contains('$'),
        "{text}"
    );

    let n = 100_000;
    let deep = format!(
        "mode q1 at 1 kHz\nparam b\npotential: {}b*q1^4{}\n",
        "(".repeat(n),
        ")".repeat(n)
    );
    let e = parse_str(&deep, "deep.hb").expect_err("too deep");
    assert_eq!(e.diagnostics()[0].code, Code::TooDeep);
    let text = e.render_plain(100);
    assert!(text.len() < 2_000, "{} bytes", text.len());
    assert!(text.contains("deep.hb:3:76"), "{text}");
}

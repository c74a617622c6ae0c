//! The corpus of broken models (tests/fixtures/broken/*.hb): every file must be refused with a
//! located diagnostic, never a panic. The plain-text rendering of each is snapshotted (insta),
//! and the table below asserts on the code and the words of every message.

use harmonid::model::{load, Code, ModelErrors};
use std::path::Path;

/// (file stem, expected code of the first diagnostic, words the rendering must contain).
const EXPECTED: &[(&str, Code, &[&str])] = &[
    (
        "unknown_name",
        Code::UnknownName,
        &[
            "unknown name `beta`",
            "did you mean `beta1`",
            "unknown_name.hb:3:12",
        ],
    ),
    (
        "undeclared_mode",
        Code::UndeclaredMode,
        &[
            "equation of `q3`, which is not a declared mode",
            "q1, q2",
            "undeclared_mode.hb:4:5",
        ],
    ),
    (
        "duplicate_declaration",
        Code::Duplicate,
        &[
            "`q1` is declared twice",
            "`g12` is declared twice",
            "declared on line 1",
            "already a mode",
        ],
    ),
    (
        "negative_power",
        Code::NotPolynomial,
        &[
            "exponent -1 is negative",
            "not a polynomial",
            "negative_power.hb:3:18",
        ],
    ),
    (
        "function_call",
        Code::NotPolynomial,
        &["`sin(...)` is a function", "function_call.hb:3:16"],
    ),
    (
        "fractional_power",
        Code::NotPolynomial,
        &[
            "exponent 2.5 is not a whole number",
            "fractional_power.hb:3:19",
        ],
    ),
    (
        "division_by_mode",
        Code::NotPolynomial,
        &[
            "division by an expression that contains modes",
            "divide only by numbers",
        ],
    ),
    (
        "family_out_of_range",
        Code::FamilyRange,
        &[
            "index family runs out of range: `q6` (with i = 6)",
            "q1, q2, q3, q4, q5",
            "family_out_of_range.hb:5:28",
        ],
    ),
    (
        "family_empty_range",
        Code::FamilyRange,
        &["the range 2..1 is empty", "write `1..2`"],
    ),
    (
        "empty_model",
        Code::EmptyModel,
        &["the model declares no mode", "mode q1 at 207.58 kHz"],
    ),
    (
        "empty_file",
        Code::EmptyModel,
        &["the model declares no mode"],
    ),
    (
        "not_utf8",
        Code::NotUtf8,
        &["is not UTF-8 text", "byte 21", "not_utf8.hb:3:6"],
    ),
    (
        "missing_star",
        Code::Syntax,
        &[
            "expected",
            "found `q1`",
            "explicit `*`",
            "a new statement",
            "missing_star.hb:3:20",
        ],
    ),
    (
        "missing_unit",
        Code::Syntax,
        &[
            "frequency unit (Hz, kHz, MHz or GHz)",
            "found the end of the file",
        ],
    ),
    (
        "unfinished",
        Code::Syntax,
        &["an expression", "found the end of the file"],
    ),
    (
        "power_blowup",
        Code::TooLarge,
        &["exponent 1000 is above the limit of 64"],
    ),
    (
        "product_blowup",
        Code::TooLarge,
        &["more than the limit of 1000000"],
    ),
    (
        "huge_family",
        Code::TooLarge,
        &["index families expand to more than 2000000 statements"],
    ),
    ("overflow", Code::Overflow, &["overflowed", "128-bit"]),
    (
        "bad_bounds",
        Code::BadBound,
        &[
            "bounds of g are empty: 5 > 1",
            "both a fixed value and a bound",
        ],
    ),
    (
        "param_equation",
        Code::UndeclaredMode,
        &["`k` is a parameter, not a mode"],
    ),
    (
        "unknown_index_variable",
        Code::UnknownName,
        &["`j` is not an index variable"],
    ),
    (
        "index_variable_reused",
        Code::FamilyRange,
        &["index variable `i` is already in use"],
    ),
    ("deep_nesting", Code::TooDeep, &["nested more than 64 deep"]),
    (
        "many_errors",
        Code::Duplicate,
        &[
            "4 errors",
            "declared twice",
            "unknown name `beta2`",
            "not a declared mode",
            "`cos(...)` is a function",
        ],
    ),
    (
        "bad_quality_factor",
        Code::BadLinear,
        &[
            "quality factor `Q` is a plain number",
            "resonance frequency `f` needs a unit",
        ],
    ),
    (
        "keyword_as_name",
        Code::Syntax,
        &["expected a parameter", "found `in`", "reserved word"],
    ),
    (
        "huge_number",
        Code::BadNumber,
        &["1e60 cannot be represented exactly"],
    ),
    (
        "negative_frequency",
        Code::Syntax,
        &[
            "expected a number, found `-`",
            "must be positive",
            "negative_frequency.hb:1:12",
        ],
    ),
    (
        "non_ascii_name",
        Code::Syntax,
        &["U+00E9", "ASCII", "non_ascii_name.hb:2:8"],
    ),
    (
        "invisible_character",
        Code::Syntax,
        &[
            "the character U+00A0",
            "ASCII",
            "invisible_character.hb:2:6",
        ],
    ),
    // Non-smooth factors (issue 36): each refusal names the term and what to write instead.
    (
        "nonsmooth_sign_squared",
        Code::BadNonSmooth,
        &[
            "`sign(d(q1))^2` is 1 wherever `d(q1)` is not zero",
            "mu1*sign(d(q1))",
            "nonsmooth_sign_squared.hb:3:14",
        ],
    ),
    (
        "nonsmooth_tanh_no_scale",
        Code::BadNonSmooth,
        &[
            "`tanh(q1)` has no scale",
            "tanh(q1/1e-9)",
            "nonsmooth_tanh_no_scale.hb:3:18",
        ],
    ),
    (
        "nonsmooth_sum",
        Code::BadNonSmooth,
        &[
            "`abs(...)` of a sum",
            "nonsmooth_sum.hb:4:17",
            "`kappa1*abs(q1)*q1`",
        ],
    ),
    (
        "nonsmooth_parameter",
        Code::BadNonSmooth,
        &["`abs(...)` of a parameter", "nonsmooth_parameter.hb:3:17"],
    ),
    (
        "nonsmooth_zero_scale",
        Code::BadNonSmooth,
        &[
            "`tanh(x/0)`",
            "nonsmooth_zero_scale.hb:3:25",
            "`sign(d(q1))`",
        ],
    ),
    (
        "nonsmooth_negative_scale",
        Code::BadNonSmooth,
        &[
            "must be a positive number",
            "nonsmooth_negative_scale.hb:3:25",
        ],
    ),
    (
        "nonsmooth_nested",
        Code::BadNonSmooth,
        &["functions do not nest", "nonsmooth_nested.hb:3:19"],
    ),
    (
        // The help once read "`-`mu1*tanh(d(q1)/1e-3)``".
        "nonsmooth_negated",
        Code::BadNonSmooth,
        &[
            "of a negated mode or velocity",
            "nonsmooth_negated.hb:3:",
            "write the sign outside the function: `-mu1*tanh(d(q1)/1e-3)`",
        ],
    ),
    (
        "nonsmooth_potential",
        Code::BadNonSmooth,
        &[
            "a potential cannot hold `abs`, `sign` or `tanh`",
            "nonsmooth_potential.hb:3:",
        ],
    ),
];

fn render(e: &ModelErrors) -> String {
    e.render_plain(100)
}

#[test]
fn every_broken_model_is_refused_with_located_messages() {
    let dir = Path::new("tests/fixtures/broken");
    let mut seen = Vec::new();
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("tests/fixtures/broken exists")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "hb"))
        .collect();
    entries.sort();
    for path in entries {
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .expect("ASCII file names")
            .to_string();
        let err = match load(&path) {
            Ok(_) => panic!("{} should be refused", path.display()),
            Err(e) => e,
        };
        let text = render(&err);
        let (_, code, words) = EXPECTED
            .iter()
            .find(|(s, _, _)| *s == stem)
            .unwrap_or_else(|| panic!("add {stem} to EXPECTED in tests/it/model_broken.rs"));
        assert_eq!(err.diagnostics()[0].code, *code, "{stem}:\n{text}");
        for w in *words {
            assert!(text.contains(w), "{stem}: expected {w:?} in\n{text}");
        }
        // Every diagnostic has a help line and, except whole-file problems, a location.
        for d in err.diagnostics() {
            assert!(!d.help.is_empty(), "{stem}: no help for {}", d.message);
            assert!(!d.message.is_empty(), "{stem}: empty message");
        }
        insta::assert_snapshot!(format!("broken_{stem}"), text);
        seen.push(stem);
    }
    for (stem, _, _) in EXPECTED {
        assert!(
            seen.iter().any(|s| s == stem),
            "fixture {stem}.hb is missing"
        );
    }
}

#[test]
fn unreadable_file_is_a_diagnostic() {
    let err = load(Path::new("tests/fixtures/broken/does_not_exist.hb")).expect_err("missing file");
    assert_eq!(err.diagnostics()[0].code, Code::Io);
    let text = render(&err);
    assert!(
        text.contains("cannot read tests/fixtures/broken/does_not_exist.hb"),
        "{text}"
    );
    let err = load(Path::new("tests/fixtures")).expect_err("a folder");
    assert!(render(&err).contains("is a folder"));
}

//! `harmonid mix` on non-smooth terms (issue 36): their lines with coefficients computed
//! numerically at given amplitudes, checked against closed forms (the Fourier series of
//! |cos|cos and of the square wave) and against a brute-force time average.

use serde_json::Value;
use std::f64::consts::{PI, TAU};
use std::process::Command;

const MODEL: &str = "mode q1 at 1 kHz
param kappa1, mu1
eom q1 += kappa1*abs(q1)*q1 + mu1*sign(d(q1))
";

fn mix_json(args: &[&str]) -> Value {
    let dir = tempfile::tempdir().expect("temp dir");
    let model = dir.path().join("model.hb");
    std::fs::write(&model, MODEL).expect("write the model");
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("mix")
        .arg(&model)
        .args(args)
        .arg("--json")
        .output()
        .expect("the harmonid binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "harmonid mix failed: {stderr}");
    serde_json::from_slice(&out.stdout).expect("valid JSON")
}

/// The complex amplitude (re, im) and error estimate of `monomial`'s line at `combination`.
fn line(v: &Value, monomial: &str, combination: &[i64]) -> Option<(f64, f64, f64)> {
    let term = v["nonsmooth"]["terms"]
        .as_array()
        .expect("nonsmooth terms")
        .iter()
        .find(|t| t["monomial"] == monomial)
        .unwrap_or_else(|| panic!("no non-smooth term {monomial}"));
    term["lines"]
        .as_array()
        .expect("lines")
        .iter()
        .find_map(|l| {
            let k: Vec<i64> = l["combination"]
                .as_array()
                .expect("combination")
                .iter()
                .map(|x| x.as_i64().expect("integer"))
                .collect();
            (k == combination).then(|| {
                (
                    l["re"].as_f64().expect("re"),
                    l["im"].as_f64().expect("im"),
                    l["error"].as_f64().expect("error estimate"),
                )
            })
        })
}

#[test]
fn one_tone_matches_the_describing_functions() {
    let a = 0.3;
    let v = mix_json(&[
        "--drives",
        "q1:1000",
        "--amplitude",
        "X1=0.3",
        "--nonsmooth-order",
        "7",
    ]);
    assert_eq!(v["nonsmooth"]["numerical"], true);
    assert!(v["nonsmooth"]["method"]
        .as_str()
        .is_some_and(|m| m.contains("numerical, by sampling in time") && m.contains("|X1| = 0.3")));
    // |cos|cos = 8/(3π) cos + 8/(15π) cos 3 − 8/(105π) cos 5 + 8/(315π) cos 7 (odd harmonics only).
    let abs_q = [
        (1, 8.0 / (3.0 * PI)),
        (3, 8.0 / (15.0 * PI)),
        (5, -8.0 / (105.0 * PI)),
        (7, 8.0 / (315.0 * PI)),
    ];
    for (k, c) in abs_q {
        let (re, im, err) = line(&v, "abs(q1)*q1", &[k]).expect("odd harmonic listed");
        assert!(
            (re - a * a * c).abs() < 1e-9 && im.abs() < 1e-12,
            "{k}f: {re} {im} vs {}",
            a * a * c
        );
        assert!(err < 1e-9, "{k}f error estimate {err}");
    }
    for k in [0, 2, 4, 6] {
        assert!(line(&v, "abs(q1)*q1", &[k]).is_none(), "no even line {k}f");
    }
    // sign(q̇) = sign(−sin θ) = −(4/π)(sin θ + sin 3θ/3 + ...): C_k = i·4/(kπ), any amplitude.
    for k in [1, 3, 5, 7] {
        let (re, im, _) = line(&v, "sign(d(q1))", &[k]).expect("odd harmonic listed");
        let c = 4.0 / (f64::from(k as i32) * PI);
        assert!(
            re.abs() < 1e-12 && (im - c).abs() < 1e-6 * c,
            "{k}f: {re} {im} vs i·{c}"
        );
    }
    assert!(line(&v, "sign(d(q1))", &[2]).is_none());
}

/// `2⟨f(x(t), ẋ(t)) e^{−iΩt}⟩` over one common period of 1000 and 1013 Hz (1 s), `Ω` the
/// frequency of `k`: 2^20 steps, each step's value `segment(start, midpoint, end)` of the
/// variables `[q, q̇]` (a jump averaged with the variable linear across the step: O(step²)).
fn time_average(
    segment: impl Fn([f64; 2], [f64; 2], [f64; 2]) -> f64,
    k: [i64; 2],
    x2: f64,
) -> (f64, f64) {
    let (f1, f2) = (1000.0, 1013.0);
    let n = 1 << 20;
    let om = TAU * (k[0] as f64 * f1 + k[1] as f64 * f2);
    let at = |t: f64| {
        let (p1, p2) = (TAU * f1 * t, TAU * f2 * t);
        let q = p1.cos() + x2 * p2.cos();
        let dq = -TAU * f1 * p1.sin() - x2 * TAU * f2 * p2.sin();
        [q, dq]
    };
    let (mut re, mut im) = (0.0, 0.0);
    let mut a = at(0.0);
    for j in 0..n {
        let b = at((j + 1) as f64 / n as f64);
        let t = (j as f64 + 0.5) / n as f64;
        let y = segment(a, at(t), b);
        re += y * (om * t).cos();
        im -= y * (om * t).sin();
        a = b;
    }
    (2.0 * re / n as f64, 2.0 * im / n as f64)
}

/// |q|q at the step's midpoint (smooth enough: O(step²)).
fn abs_q_q(_: [f64; 2], m: [f64; 2], _: [f64; 2]) -> f64 {
    m[0].abs() * m[0]
}

/// The average of sign(q̇) with q̇ linear across the step: (|b| − |a|)/(b − a).
fn sign_dq(a: [f64; 2], _: [f64; 2], b: [f64; 2]) -> f64 {
    let (u, v) = (a[1], b[1]);
    if (v - u).abs() <= 1e-12 * (u.abs() + v.abs()) {
        (0.5 * (u + v)).signum()
    } else {
        (v.abs() - u.abs()) / (v - u)
    }
}

#[test]
fn two_tones_match_a_brute_force_time_average() {
    let v = mix_json(&[
        "--drives",
        "q1:1000,1013",
        "--amplitude",
        "X2=0.5",
        "--nonsmooth-order",
        "3",
    ]);
    for k in [[2, -1], [-1, 2], [1, 0], [0, 1], [2, 1], [3, 0]] {
        let (re, im, err) = line(&v, "abs(q1)*q1", &k).expect("line listed");
        let (bre, bim) = time_average(abs_q_q, k, 0.5);
        assert!(
            (re - bre).abs() < 1e-7 && (im - bim).abs() < 1e-7,
            "abs(q1)*q1 at {k:?}: {re} {im} vs {bre} {bim}"
        );
        assert!(err < 1e-7, "{err}");
        let (re, im, err) = line(&v, "sign(d(q1))", &k).expect("line listed");
        let (bre, bim) = time_average(sign_dq, k, 0.5);
        let d = (re - bre).hypot(im - bim);
        assert!(
            d < 5e-5,
            "sign(d(q1)) at {k:?}: {re} {im} vs {bre} {bim} (error estimate {err})"
        );
    }
    // The symmetric sidebands of |q|q are equal (the function is even in time).
    let lower = line(&v, "abs(q1)*q1", &[2, -1]).expect("2Ω1 − Ω2");
    let upper = line(&v, "abs(q1)*q1", &[2, 1]).expect("2Ω1 + Ω2");
    assert!((lower.0 - upper.0).abs() < 1e-9 && lower.0 > 0.1);
}

#[test]
fn bad_amplitudes_are_refused_with_the_option_named() {
    let dir = tempfile::tempdir().expect("temp dir");
    let model = dir.path().join("model.hb");
    std::fs::write(&model, MODEL).expect("write the model");
    for bad in ["X9=1", "X1", "X1=nan"] {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("mix")
            .arg(&model)
            .args(["--drives", "q1:1000", "--amplitude", bad])
            .output()
            .expect("the harmonid binary runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains("--amplitude"),
            "{bad}: {stderr}"
        );
    }
}

/// Hostile `--amplitude` and `--nonsmooth-order` values: each refused naming the option and
/// the value, exit 1, and no output file (`-o` is written only on success). 1e308 once
/// printed `NaN + i·NaN` lines and -1 printed lines "at |X1| = -1".
#[test]
fn bad_amplitudes_and_orders_are_refused_without_output() {
    let dir = tempfile::tempdir().expect("temp dir");
    let model = dir.path().join("model.hb");
    std::fs::write(
        &model,
        "mode q1 at 1 kHz\nparam kappa1\neom q1 += kappa1*abs(q1)*q1\n",
    )
    .expect("write the model");
    let out_file = dir.path().join("mix.txt");
    for (args, words) in [
        (["--amplitude", "X1=-1"], "must be positive, not -1"),
        (["--amplitude", "X1=0"], "must be positive, not 0"),
        (["--amplitude", "X1=nan"], "`nan` is not a finite number"),
        (
            ["--amplitude", "X1=1e308"],
            "the lines of abs(q1)*q1 overflow",
        ),
        (
            ["--amplitude", "X1=1e-320"],
            "is zero at --amplitude X1=1e-320",
        ),
        (
            ["--nonsmooth-order", "100000"],
            "--nonsmooth-order 100000: expected an order",
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("mix")
            .arg(&model)
            .args(["--drives", "q1:1000"])
            .args(args)
            .arg("-o")
            .arg(&out_file)
            .output()
            .expect("the harmonid binary runs");
        // One line, without miette's wrapping and its `│` margin.
        let stderr = String::from_utf8_lossy(&out.stderr)
            .split_whitespace()
            .filter(|w| *w != "│")
            .collect::<Vec<_>>()
            .join(" ");
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(words),
            "{args:?}: expected {words:?} in {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!out_file.exists(), "{args:?} wrote {}", out_file.display());
    }
}

/// A term whose lines all underflow while another's do not is named in a warning with the
/// amplitude and what to give instead, and the listing goes on: at X1 = 1e-200 the lines of
/// abs(q1)*q1 (amplitude²: 1e-400) are below the smallest double, sign(d(q1))'s
/// (amplitude⁰) are not. At the default amplitude there is no warning.
#[test]
fn a_term_whose_lines_underflow_alone_is_named_in_a_warning() {
    let dir = tempfile::tempdir().expect("temp dir");
    let model = dir.path().join("model.hb");
    std::fs::write(&model, MODEL).expect("write the model");
    let run = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .arg("mix")
            .arg(&model)
            .args(["--drives", "q1:1000"])
            .args(extra)
            .output()
            .expect("the harmonid binary runs");
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{extra:?}: {stderr}");
        (String::from_utf8_lossy(&out.stdout).into_owned(), stderr)
    };
    let (stdout, stderr) = run(&["--amplitude", "X1=1e-200"]);
    for words in [
        "warning:",
        "every line of abs(q1)*q1 (equation of q1) underflows to zero at --amplitude X1=1e-200",
        "amplitude^2",
        "--amplitude X1=1e-9",
    ] {
        assert!(stderr.contains(words), "expected {words:?} in {stderr}");
    }
    assert!(!stderr.contains("sign(d(q1)) (equation"), "{stderr}");
    assert!(stdout.contains("sign(d(q1))"), "{stdout}");
    let (_, stderr) = run(&[]);
    assert!(!stderr.contains("underflows"), "{stderr}");
}

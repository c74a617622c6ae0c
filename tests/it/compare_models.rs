//! `harmonid compare` (issue 22, item 3): on data from the two-mode nanostring's potential
//! model the potential model wins by BIC; on data whose dispersive couplings differ between the
//! two equations (not a potential) the per-equation model wins, with a likelihood-ratio p below
//! 1e-6; a model without the coupling does not fit, and the verdict says so; bad input is
//! refused with the model named.

use harmonid_testgen as gen;

use gen::{nanostring_2mode_fold_plan, simulate, Values};
use harmonid_ident::{compare, CompareError, ModelComparison, NestedTest, Settings};
use std::process::Command;

const POTENTIAL: &str = "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta1, beta2, g12\n\
    potential: beta1/4*q1^4 + beta2/4*q2^4\npotential: g12/2*q1^2*q2^2\n";
const PER_EQUATION: &str =
    "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta1, beta2, g1, g2\n\
    potential: beta1/4*q1^4 + beta2/4*q2^4\neom q1 += g1*q1*q2^2\neom q2 += g2*q1^2*q2\n";
const UNCOUPLED: &str = "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta1, beta2\n\
    potential: beta1/4*q1^4 + beta2/4*q2^4\n";

/// The likelihood-ratio test of `simpler` within `richer`.
fn nested<'c>(c: &'c ModelComparison, simpler: &str, richer: &str) -> &'c NestedTest {
    c.nested
        .iter()
        .find(|t| t.simpler == simpler && t.richer == richer)
        .unwrap_or_else(|| panic!("{simpler} within {richer}: {:?}", c.nested))
}

fn models() -> Vec<(String, harmonid_model::Model)> {
    [
        ("potential", POTENTIAL),
        ("per_equation", PER_EQUATION),
        ("uncoupled", UNCOUPLED),
    ]
    .iter()
    .map(|(n, t)| {
        (
            n.to_string(),
            harmonid_model::parse_str(t, n).expect("model"),
        )
    })
    .collect()
}

/// The fold plan's data (0.01 nm, 20 shots) from `model` with `v`.
fn data(model: &harmonid_model::Model, v: &Values, seed: u64) -> harmonid_data::Dataset {
    let (_, d) = nanostring_2mode_fold_plan();
    simulate(model, v, &d, &[0.309, 0.588], 1e-11, 20, seed)
}

#[test]
fn the_potential_wins_on_potential_data() {
    let ms = models();
    let (v, _) = nanostring_2mode_fold_plan();
    let c = compare(&ms, &data(&ms[0].1, &v, 11), &Settings::default()).expect("compare");
    eprintln!("{}", c.table());
    assert_eq!(c.models[c.best].model, "potential", "{}", c.verdict);
    assert_eq!(c.models[0].fits, Some(true));
    assert_eq!(c.models[1].unknowns, c.models[0].unknowns + 1);
    // The uncoupled model is nested in both and misses the coupling by far.
    assert_eq!(c.models[2].fits, Some(false));
    let t = nested(&c, "uncoupled", "potential");
    assert!(t.p_value < 1e-12, "{t:?}");
    // potential within per_equation: the extra freedom is not needed.
    let t = nested(&c, "potential", "per_equation");
    assert!(t.p_value > 1e-3, "{t:?}");
    assert!(c.verdict.starts_with("the data"), "{}", c.verdict);
}

#[test]
fn per_equation_couplings_win_on_non_potential_data() {
    let ms = models();
    let (mut v, _) = nanostring_2mode_fold_plan();
    let g = v.params.remove("g12").expect("g12");
    // 7 % apart, as the finite-element model of the issue.
    v.params.insert("g1".into(), g);
    v.params.insert("g2".into(), 1.07 * g);
    let c = compare(&ms, &data(&ms[1].1, &v, 12), &Settings::default()).expect("compare");
    eprintln!("{}", c.table());
    assert_eq!(c.models[c.best].model, "per_equation", "{}", c.verdict);
    assert_eq!(c.models[1].fits, Some(true));
    let t = nested(&c, "potential", "per_equation");
    assert!(t.p_value < 1e-6, "{t:?}");
    assert!(
        c.verdict.contains("very strongly support per_equation"),
        "{}",
        c.verdict
    );
}

#[test]
fn the_command_line_compares_and_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("tmp");
    let ms = models();
    let (v, _) = nanostring_2mode_fold_plan();
    data(&ms[0].1, &v, 13)
        .write(dir.path().join("data"))
        .expect("write dataset");
    for (n, t) in [("potential", POTENTIAL), ("uncoupled", UNCOUPLED)] {
        std::fs::write(dir.path().join(format!("{n}.hb")), t).expect("model file");
    }
    let bin = env!("CARGO_BIN_EXE_harmonid");
    let out = Command::new(bin)
        .current_dir(dir.path())
        .args([
            "compare",
            "data",
            "potential.hb",
            "uncoupled.hb",
            "--json",
            "--out",
            "c.json",
        ])
        .output()
        .expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json on stdout");
    assert_eq!(
        json["models"][json["best"].as_u64().expect("best") as usize]["model"],
        "potential.hb"
    );
    let written = std::fs::read_to_string(dir.path().join("c.json")).expect("written");
    assert_eq!(
        serde_json::from_str::<serde_json::Value>(&written).expect("json"),
        json
    );
    // One model: refused by the command line; a model of other modes: named, nothing written.
    let one = Command::new(bin)
        .current_dir(dir.path())
        .args(["compare", "data", "potential.hb"])
        .output()
        .expect("run");
    assert!(!one.status.success());
    std::fs::write(
        dir.path().join("other.hb"),
        "mode a at 1 kHz\nparam k\neom a += k*a^3\n",
    )
    .expect("model");
    let bad = Command::new(bin)
        .current_dir(dir.path())
        .args([
            "compare",
            "data",
            "potential.hb",
            "other.hb",
            "--out",
            "bad.json",
        ])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("other.hb"), "{err}");
    assert!(!dir.path().join("bad.json").exists());
    let too_few = compare(&ms[..1], &data(&ms[0].1, &v, 14), &Settings::default());
    assert!(matches!(too_few, Err(CompareError::TooFew { found: 1 })));
}

/// The five-mode nanostring with every dispersive coupling written per equation (20
/// parameters) instead of the potential's 10.
const FIVE_PER_EQUATION: &str = "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nmode q3 at 624.3 kHz\n\
    mode q4 at 833.2 kHz\nmode q5 at 1042.6 kHz\n\
    for i in 1..5 {\n param beta[i]\n potential: beta[i]/4 * q[i]^4\n}\n\
    for i<j in 1..5 {\n param a[i,j], b[i,j]\n eom q[i] += a[i,j] * q[i] * q[j]^2\n eom q[j] += b[i,j] * q[i]^2 * q[j]\n}\n";

/// The case: data from a five-mode model whose dispersive couplings differ by up to
/// 7 % between the two equations they appear in (not a potential), at 0.01 nm: the
/// per-equation model wins with a likelihood-ratio p < 1e-6; on data from the potential model
/// the potential model wins by BIC.
#[test]
fn five_modes_per_equation_against_the_potential() {
    let potential = harmonid_model::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("examples/nanostring_5mode/model.hb"),
    )
    .expect("example model");
    let per_eq = harmonid_model::parse_str(FIVE_PER_EQUATION, "per_equation").expect("model");
    let models = vec![
        ("potential".to_string(), potential.clone()),
        ("per_equation".to_string(), per_eq.clone()),
    ];
    let (v, d) = gen::nanostring_5mode_fold_plan();
    let shape = gen::NANOSTRING_SHAPE;
    // Potential data.
    let ds = simulate(&potential, &v, &d, &shape, 1e-11, 20, 21);
    let c = compare(&models, &ds, &Settings::default()).expect("compare");
    eprintln!("{}", c.table());
    assert_eq!(c.models[c.best].model, "potential", "{}", c.verdict);
    assert_eq!(c.models[1].unknowns, c.models[0].unknowns + 10);
    // Per-equation data: a_ij = g_ij, b_ij = g_ij · (0.93, 1 or 1.07).
    let mut w = v.clone();
    for i in 1..=5u32 {
        for j in i + 1..=5 {
            let g = w.params.remove(&format!("g{i}{j}")).expect("g");
            let factor = 1.0 + 0.07 * (f64::from((i * j) % 3) - 1.0);
            w.params.insert(format!("a{i}{j}"), g);
            w.params.insert(format!("b{i}{j}"), g * factor);
        }
    }
    let ds = simulate(&per_eq, &w, &d, &shape, 1e-11, 20, 22);
    let c = compare(&models, &ds, &Settings::default()).expect("compare");
    eprintln!("{}", c.table());
    assert_eq!(c.models[c.best].model, "per_equation", "{}", c.verdict);
    let t = nested(&c, "potential", "per_equation");
    assert!(t.p_value < 1e-6, "{t:?}");
}

/// Measured sweeps are fitted with an error floor, which brings every model's χ² to its
/// expectation: the comparison then ranks by the held-out prediction. On the softened,
/// nonlinearly damped mode's stepped sweeps (four levels up and down), the model with the
/// damping predicts the strongest level better than the Duffing term alone; with a floor and
/// nothing held out the comparison is refused.
#[test]
fn with_an_error_floor_the_held_out_prediction_ranks_the_models() {
    let damped = harmonid_model::parse_str(gen::DAMPED_DUFFING, "damped").expect("model");
    let duffing = harmonid_model::parse_str(
        "mode q1 at 1 MHz\nparam beta1\npotential: beta1/4*q1^4\n",
        "duffing",
    )
    .expect("model");
    let (v, sweeps) = gen::hysteretic_sweeps(4, 24);
    let clean = gen::simulate_sweeps_clean(&damped, &v, &sweeps, &[1.0], 3);
    let ds = gen::add_noise(&clean, 2e-11, 5);
    let models = vec![
        ("duffing".to_string(), duffing),
        ("damped".to_string(), damped),
    ];
    let settings = Settings {
        force_model: harmonid_ident::ForceModel::GainPerMode,
        error_floor: true,
        ..Settings::default()
    };
    let err = harmonid_ident::compare_with_holdout(&models, &ds, &[], &settings)
        .expect_err("a floor and nothing held out");
    assert!(matches!(err, CompareError::FloorWithoutHoldout), "{err}");
    let held = ["up_l03".to_string(), "dn_l03".to_string()];
    let c = harmonid_ident::compare_with_holdout(&models, &ds, &held, &settings).expect("compare");
    eprintln!("{}", c.table());
    assert_eq!(c.ranked_by, "holdout");
    assert_eq!(c.models[c.best].model, "damped", "{}", c.verdict);
    // duffing is nested in damped, but a floor leaves no likelihood-ratio test to print.
    assert!(c.nested.is_empty(), "{:?}", c.nested);
    let table = c.table();
    assert!(!table.contains("likelihood ratio)"), "{table}");
    assert!(table.contains("no likelihood-ratio test"), "{table}");
    let rel = |i: usize| c.models[i].holdout_relative_rms.expect("held out");
    assert!(rel(1) < 0.5 * rel(0), "{} against {}", rel(1), rel(0));
    // The true model predicts its held-out level to about the noise.
    let sigma = c.models[1].holdout_rms_sigma.expect("shot noise");
    assert!(sigma < 2.0, "{sigma}");
    assert!(
        c.verdict.contains("predicts the held-out data best"),
        "{}",
        c.verdict
    );
}

/// A model the measurements left after the holdout do not determine is reported as such and
/// the others are ranked (the uncoupled nanostring without `single_q1`: its `beta1` and `beta2`
/// are then not determined); when none is determined the comparison is refused naming each.
#[test]
fn an_undetermined_model_is_reported_and_the_others_ranked() {
    let ds = harmonid_data::Dataset::load("examples/nanostring_2mode/data").expect("dataset");
    let models = models();
    let held = ["single_q1".to_string()];
    let c = harmonid_ident::compare_with_holdout(
        &[models[0].clone(), models[2].clone()],
        &ds,
        &held,
        &Settings::default(),
    )
    .expect("compare");
    let table = c.table();
    eprintln!("{table}");
    assert_eq!(c.models.len(), 1);
    assert_eq!(c.models[c.best].model, models[0].0);
    assert_eq!(c.not_determined.len(), 1);
    let u = &c.not_determined[0];
    assert_eq!(u.model, models[2].0);
    assert_eq!(u.quantities, ["beta1", "beta2"]);
    assert!(c.verdict.contains("not ranked"), "{}", c.verdict);
    assert!(
        table.contains("not determined: --holdout single_q1"),
        "{table}"
    );
    let json = c.to_json();
    assert!(json.contains("\"not_determined\""), "{json}");
    let held = ["single_q2".to_string()];
    let err = harmonid_ident::compare_with_holdout(
        &[models[0].clone(), models[2].clone()],
        &ds,
        &held,
        &Settings::default(),
    )
    .expect_err("nothing determined");
    assert!(matches!(err, CompareError::NoneDetermined { .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains(&models[0].0) && text.contains(&models[2].0),
        "{text}"
    );
}

//! Consistency checks across measurements (issue 12): a frequency, Q or actuator gain that two
//! measurements see differently, beyond what their uncertainties allow, is a warning naming
//! both; on consistent data the warning is rare (family-wise false-alarm rate ≤ 1 %, checked
//! here by Monte Carlo), and a planted discrepancy is found.
//!
//! The long Monte Carlo (`--ignored --nocapture`) prints the distribution of `z` over many
//! seeds; the short one runs in CI.

use harmonid_testgen as gen;

use gen::{nanostring_2mode_plan, simulate, Design, Values};
use harmonid_data::Dataset;
use harmonid_ident::{consistency_threshold as threshold, Compared, Comparison, FAMILY_ALPHA};
use harmonid_ident::{identify, Report, Settings};
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn model(path: &str) -> harmonid_model::Model {
    harmonid_model::load(&root().join(path)).expect("model")
}

fn print(label: &str, r: &Report) {
    println!("\n{label}: {} comparisons", r.consistency.len());
    for c in &r.consistency {
        println!(
            "  {:?} {}: {} {:.6e} ± {:.2e} vs {} {:.6e} ± {:.2e}: z = {:+.2}",
            c.quantity,
            c.mode,
            c.measurements[0],
            c.values[0],
            c.stderrs[0],
            c.measurements[1],
            c.values[1],
            c.stderrs[1],
            c.z
        );
    }
}

fn find<'a>(r: &'a Report, q: Compared, mode: &str) -> &'a Comparison {
    r.consistency
        .iter()
        .find(|c| c.quantity == q && c.mode == mode)
        .unwrap_or_else(|| panic!("no comparison of {q:?} of {mode}"))
}

fn inconsistency_warnings(r: &Report) -> Vec<&String> {
    r.warnings
        .iter()
        .filter(|w| w.starts_with("inconsistent measurements"))
        .collect()
}

/// The shipped example (issue 12: "mode 2's actuator gain in the coupled measurement came out
/// 1.92 against 1.71 from its single-mode measurement (truth 1.7), unflagged"). With the
/// output-error estimator the coupled measurement's gain is 1.784 ± 0.125 against 1.705 ±
/// 0.005 (z = −0.65): q2 is driven there by one tone at its resonance, where the response is
/// `∝ G·Q`, so that gain is only known as well as `Q2` (6 %). Not flagged, rightly: even the old
/// equation-error 1.92 would be 1.7 standard errors from 1.71. q1's gains (2.498 vs 2.496, 0.2 %
/// each) agree too.
#[test]
fn shipped_example_is_consistent_within_its_uncertainties() {
    let m = model("examples/nanostring_2mode/model.hb");
    let ds = Dataset::load(root().join("examples/nanostring_2mode/data")).expect("dataset");
    let r = identify(&m, &ds, &Settings::default()).expect("identify");
    print("examples/nanostring_2mode/data", &r);
    let g = find(&r, Compared::Gain, "q2");
    let truth: f64 = 1.81 / 1.064_705_882_352_941_2;
    assert!((truth - 1.7).abs() < 1e-12);
    let (single, coupled) = if g.measurements[0] == "single_q2" {
        (0, 1)
    } else {
        (1, 0)
    };
    assert_eq!(g.measurements[coupled], "couple_q1_q2");
    assert!((g.values[single] - 1.705).abs() < 0.005, "{g:?}");
    assert!((g.values[coupled] - 1.784).abs() < 0.01, "{g:?}");
    // Honest uncertainties: 0.3 % in the single-mode measurement, 7 % in the coupled one, each
    // covering the truth.
    assert!(
        (0.002..0.005).contains(&(g.stderrs[single] / g.values[single])),
        "{g:?}"
    );
    assert!(
        (0.05..0.1).contains(&(g.stderrs[coupled] / g.values[coupled])),
        "{g:?}"
    );
    for i in 0..2 {
        assert!((g.values[i] - truth).abs() < 2.0 * g.stderrs[i], "{g:?}");
    }
    assert!(g.z.abs() < 1.0, "{g:?}");
    let g1 = find(&r, Compared::Gain, "q1");
    assert!(
        g1.z.abs() < 2.0 && g1.stderrs[0] / g1.values[0] < 0.003,
        "{g1:?}"
    );
    assert_eq!(r.consistency.len(), 6);
    assert!(inconsistency_warnings(&r).is_empty(), "{:?}", r.warnings);
}

/// The independent dataset with known truth: nothing inconsistent.
#[test]
fn independent_noisy_dataset_is_consistent() {
    let m = model("examples/nanostring_2mode/model.hb");
    let ds = Dataset::load(root().join("tests/data/nanostring_ls50_2mode_noisy")).expect("dataset");
    let r = identify(&m, &ds, &Settings::default()).expect("identify");
    print("tests/data/nanostring_ls50_2mode_noisy", &r);
    assert!(r.consistency.len() >= 4, "{:?}", r.consistency);
    assert!(inconsistency_warnings(&r).is_empty(), "{:?}", r.warnings);
}

/// Simulates the two-mode plan.
fn two_mode(sigma: f64, shots: usize, seed: u64) -> (harmonid_model::Model, Dataset) {
    let m = model("examples/nanostring_2mode/model.hb");
    let (v, d) = nanostring_2mode_plan();
    let ds = simulate(&m, &v, &d, &[0.309, 0.588], sigma, shots, seed);
    (m, ds)
}

/// Whether every estimate of `r` is within 4 stderr of the truth `v` (the joint fit found the
/// right solution).
fn sound(r: &Report, v: &Values) -> bool {
    let near = |e: &harmonid_ident::Estimate, t: f64| (e.value - t).abs() <= 4.0 * e.stderr;
    r.modes
        .values()
        .enumerate()
        .all(|(n, m)| near(&m.f_hz, v.f_hz[n]) && near(&m.q, v.q[n]))
        && v.params.iter().all(|(p, &t)| near(&r.parameters[p], t))
}

/// Outcome of a study of consistent data.
struct Null {
    /// Every `z`, named `Quantity:mode`.
    zs: Vec<(String, f64)>,
    /// Realisations that warned, and how many of those had a joint fit off the truth.
    warned: usize,
    warned_unsound: usize,
    /// Realisations whose joint fit is off the truth.
    unsound: usize,
    /// Comparisons per realisation.
    k: usize,
}

/// All `z` of consistent realisations and how many realisations warned.
fn null_study(
    model_path: &str,
    (v, d): (Values, Vec<Design>),
    shape: &[f64],
    sigma: f64,
    shots: usize,
    seeds: std::ops::Range<u64>,
) -> Null {
    let m = model(model_path);
    let mut out = Null {
        zs: Vec::new(),
        warned: 0,
        warned_unsound: 0,
        unsound: 0,
        k: 0,
    };
    for seed in seeds {
        let ds = simulate(&m, &v, &d, shape, sigma, shots, seed);
        let r = identify(&m, &ds, &Settings::default()).expect("identify");
        assert_eq!(r.estimator, "ml");
        out.k = r.consistency.len();
        let ok = sound(&r, &v);
        out.unsound += usize::from(!ok);
        if !inconsistency_warnings(&r).is_empty() {
            out.warned += 1;
            out.warned_unsound += usize::from(!ok);
        }
        for c in &r.consistency {
            out.zs.push((format!("{:?}:{}", c.quantity, c.mode), c.z));
        }
    }
    out
}

fn summarise(zs: &[(String, f64)]) -> Vec<(String, f64, f64, usize)> {
    let mut names: Vec<String> = zs.iter().map(|z| z.0.clone()).collect();
    names.sort();
    names.dedup();
    println!(
        "\n{:<16} {:>8} {:>8} {:>8} {:>9}",
        "comparison", "n", "mean z", "std z", "|z| > 3"
    );
    names
        .into_iter()
        .map(|name| {
            let v: Vec<f64> = zs.iter().filter(|z| z.0 == name).map(|z| z.1).collect();
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let big = v.iter().filter(|x| x.abs() > 3.0).count();
            println!("{name:<16} {:>8} {mean:>+8.3} {sd:>8.3} {big:>9}", v.len());
            (name, mean, sd, big)
        })
        .collect()
}

#[test]
fn consistent_data_raise_no_warning() {
    let (v, d) = nanostring_2mode_plan();
    let n = null_study(
        "examples/nanostring_2mode/model.hb",
        (v, d),
        &[0.309, 0.588],
        5e-11,
        20,
        300..312,
    );
    let rows = summarise(&n.zs);
    // Two modes: f, Q and |G| of each, compared between the single and the coupled measurement.
    assert_eq!(n.k, 6, "{rows:?}");
    assert_eq!((n.warned, n.unsound), (0, 0));
    for (name, mean, sd, _) in rows {
        // 12 realisations: loose bounds on a standard normal's mean and spread.
        assert!(
            mean.abs() < 1.0 && (0.4..1.7).contains(&sd),
            "{name}: {mean} {sd}"
        );
    }
}

/// One case of the long study: prints the table and the tail rates; returns the fraction of
/// realisations with a sound joint fit that warned (the false-alarm rate of the check itself).
fn long_case(
    label: &str,
    model_path: &str,
    plan: (Values, Vec<Design>),
    shape: &[f64],
    sigma: f64,
    shots: usize,
    seeds: std::ops::Range<u64>,
) -> f64 {
    let total = seeds.end - seeds.start;
    let n = null_study(model_path, plan, shape, sigma, shots, seeds);
    println!("\n{label}: {total} realisations, {} comparisons each", n.k);
    summarise(&n.zs);
    let all = n.zs.len() as f64;
    for t in [2.0, 3.0, threshold(n.k, FAMILY_ALPHA)] {
        let tail = n.zs.iter().filter(|z| z.1.abs() > t).count() as f64 / all;
        println!("P(|z| > {t:.2}) = {tail:.4} per comparison");
    }
    println!(
        "{} of {total} consistent datasets warned (limit {:.2}); {} of them had a joint fit more than 4 stderr off the truth ({} such fits in all)",
        n.warned,
        threshold(n.k, FAMILY_ALPHA),
        n.warned_unsound,
        n.unsound
    );
    (n.warned - n.warned_unsound) as f64 / (total as usize - n.unsound) as f64
}

#[test]
#[ignore = "long Monte Carlo (minutes); run with --ignored --nocapture"]
fn false_alarm_rate_long() {
    let two = "examples/nanostring_2mode/model.hb";
    let shape2 = [0.309, 0.588];
    let mut rates = vec![
        long_case(
            "two-mode, 0.05 nm, 20 shots",
            two,
            nanostring_2mode_plan(),
            &shape2,
            5e-11,
            20,
            10_000..12_000,
        ),
        long_case(
            "two-mode, 0.1 nm, 5 shots",
            two,
            nanostring_2mode_plan(),
            &shape2,
            1e-10,
            5,
            20_000..21_000,
        ),
    ];
    rates.push(long_case(
        "five-mode, 0.01 nm, 30 shots",
        "examples/nanostring_5mode/model.hb",
        gen::nanostring_5mode_plan(),
        &gen::NANOSTRING_SHAPE,
        1e-11,
        30,
        30_000..30_030,
    ));
    for r in rates {
        assert!(r <= 0.02, "{r}");
    }
}

/// The coupled measurement's drive levels of mode 1 written 3 % too low: the gain the fit
/// attributes to that measurement is 3 % higher, ~12 standard errors (q1's gains are known to
/// 0.2 %). The same 3 % on mode 2 would not be flagged: its gain in the coupled measurement is
/// known to only 7 % (one tone at its resonance, where the response is `∝ G·Q` and `Q2` is
/// known to 6 %).
#[test]
fn a_gain_discrepancy_is_flagged() {
    let (m, mut ds) = two_mode(5e-11, 20, 7);
    let mi = ds
        .measurements
        .iter()
        .position(|x| x.spec.name == "couple_q1_q2")
        .expect("coupled");
    if let Some(levels) = ds.measurements[mi].spec.drive_levels_v.as_mut() {
        levels[0] /= 1.03;
        levels[1] /= 1.03;
    }
    ds.manifest.measurements[mi] = ds.measurements[mi].spec.clone();
    let r = identify(&m, &ds, &Settings::default()).expect("identify");
    print("gain of q1 in couple_q1_q2 3 % high", &r);
    let c = find(&r, Compared::Gain, "q1");
    assert!(c.z.abs() > 8.0, "{c:?}");
    let w = inconsistency_warnings(&r);
    assert_eq!(w.len(), 1, "{:?}", r.warnings);
    assert!(
        w[0].contains("actuator gain |G| of q1")
            && w[0].contains("\"single_q1\"")
            && w[0].contains("\"couple_q1_q2\""),
        "{w:?}"
    );
}

/// Mode 1 one Hz higher in the coupled measurement than in its single-mode one (the device
/// changed between them; f1 is known to 0.09 Hz): the frequency of q1 is flagged.
#[test]
fn a_frequency_discrepancy_is_flagged() {
    let m = model("examples/nanostring_2mode/model.hb");
    let (v, d) = nanostring_2mode_plan();
    let shifted = Values {
        f_hz: vec![v.f_hz[0] + 1.0, v.f_hz[1]],
        ..v.clone()
    };
    let shape = [0.309, 0.588];
    let mut ds = simulate(&m, &v, &d, &shape, 5e-11, 20, 11);
    let coupled: Vec<Design> = d
        .iter()
        .filter(|x| x.name == "couple_q1_q2")
        .cloned()
        .collect();
    let other = simulate(&m, &shifted, &coupled, &shape, 5e-11, 20, 12);
    let mi = ds
        .measurements
        .iter()
        .position(|x| x.spec.name == "couple_q1_q2")
        .expect("coupled");
    ds.measurements[mi] = other.measurements[0].clone();
    let r = identify(&m, &ds, &Settings::default()).expect("identify");
    print("f of q1 1 Hz higher in couple_q1_q2", &r);
    let c = find(&r, Compared::Frequency, "q1");
    assert!(
        c.z.abs() > threshold(r.consistency.len(), FAMILY_ALPHA),
        "{c:?}"
    );
    // The per-measurement values are one linearised step from a joint fit that the shift spoils:
    // rough for a discrepancy this large, but on the right side.
    assert!(c.values[1] > c.values[0], "{c:?}");
    let w = inconsistency_warnings(&r);
    assert!(
        w.iter()
            .any(|w| w.starts_with("inconsistent measurements: f of q1")
                && w.contains("\"couple_q1_q2\"")),
        "{:?}",
        r.warnings
    );
}

//! `harmonid plan --instrument` (issue 37, item 3): a plan the lock-in can run. The MFLI beam
//! (`examples/import/beam.hb`) at values like its identification's (a synthetic stand-in for
//! `realdata/mfli_beam`, which CI does not have), planned for the MFLI with MF-MD: every tone,
//! line, summed volt and filter setting is checked against the profile's numbers and the closed
//! forms; the MFLI without the option is refused naming it; hostile values of the new options
//! get messages, never a panic.

use harmonid_experiment::Plan;
use harmonid_plan::{attenuation, nebw_hz, settle_time, LockIn, REJECTION, SETTLE_ACCURACY};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The beam's values near its identification from the MFLI data (f 42.79 Hz, Q 1450, β −93,
/// η 0.50, volts), each with a spread of a few standard errors.
const BEAM_VALUES: &str = r#"
[modes.q1]
f_hz = { value = 42.7909, abs_hz = 0.0012 }
Q = { value = 1450.0, rel = 0.075 }
[parameters]
beta1 = { value = -93.1, rel = 0.045 }
eta1 = { value = 0.495, rel = 0.09 }
"#;

const F: f64 = 42.7909;
const Q: f64 = 1450.0;

/// Runs `harmonid plan beam.hb --values <beam values>` with `args` in `dir`.
fn run_plan(dir: &Path, args: &[&str]) -> (bool, Option<i32>, String, String) {
    let values = dir.join("values.toml");
    std::fs::write(&values, BEAM_VALUES).expect("values");
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("plan")
        .arg(root().join("examples/import/beam.hb"))
        .arg("--values")
        .arg(&values)
        .args(["--shots", "10", "--grid-hz", "0.001", "--gain", "q1=447"])
        .args(args)
        .current_dir(dir)
        .output()
        .expect("runs");
    (
        out.status.success(),
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        flat(&String::from_utf8_lossy(&out.stderr)),
    )
}

/// A message as one line: miette wraps long messages and draws a margin (`│`).
fn flat(text: &str) -> String {
    text.replace(['│', '×'], " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

#[test]
fn an_mfli_mf_plan_of_the_beam_is_within_the_instruments_limits() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (ok, _, stdout, stderr) = run_plan(
        tmp.path(),
        &[
            "--noise",
            "0.0418V",
            "--instrument",
            "mfli-mf",
            "--max-voltage",
            "0.45",
            "--out",
            "p.toml",
        ],
    );
    assert!(ok, "{stderr}");
    let text = std::fs::read_to_string(tmp.path().join("p.toml")).expect("plan");
    let plan = Plan::from_toml(&text, "p.toml").expect("reads back");
    // --noise in volts: the plan says so.
    assert_eq!(plan.displacement_unit, "V");
    assert_eq!(plan.noise.sigma_per_quadrature, 0.0418);
    let p = LockIn::MfliMf.profile().expect("profile");
    let inst = plan.instrument.as_ref().expect("[instrument]");
    assert_eq!(inst.profile, "mfli-mf");
    assert_eq!(inst.max_output_v, 0.45);
    let mut levels = 0;
    for m in &plan.measurements {
        let lines = m.measure_hz.clone().expect("lines");
        assert!(m.drives_hz.len() <= p.oscillators, "{}: tones", m.name);
        assert!(lines.len() <= p.demodulators, "{}: lines {lines:?}", m.name);
        assert!(lines.iter().all(|&f| f > 0.0 && f <= p.max_demod_hz));
        let top = m.drive_levels_v.as_ref().expect("volts");
        let summed: f64 = top.iter().map(|v| v.abs()).sum();
        assert!(
            summed <= 0.45 + 1e-12,
            "{}: {top:?} sum to {summed} V",
            m.name
        );
        assert!(summed <= p.max_output_v);
        // The cap binds: the pair shares 0.45 V (each tone at most half).
        assert!(summed >= 0.44, "{summed}");
        let ladder = if m.levels.is_empty() {
            vec![1.0]
        } else {
            m.levels.clone()
        };
        for (k, &level) in ladder.iter().enumerate() {
            let l = inst
                .levels
                .iter()
                .find(|l| l.measurement == m.name && l.level == level)
                .expect("a level's settings");
            levels += 1;
            for (v, t) in l.drives_v.iter().zip(top) {
                assert!((v - level * t).abs() < 1e-12, "volts of level {k}");
            }
            let sum: f64 = l.drives_v.iter().map(|v| v.abs()).sum();
            assert!((l.output_v - sum).abs() < 1e-12 && l.output_v <= 0.45 + 1e-12);
            assert!(l.oscillators <= p.oscillators && l.demodulators <= p.demodulators);
            assert_eq!(l.passes, 1);
            // The nearest other line: the smallest spacing (the pair's 3-linewidth spacing).
            let mut sorted = lines.clone();
            sorted.sort_by(f64::total_cmp);
            let spacing = sorted
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(f64::INFINITY, f64::min);
            assert!(
                (l.nearest_hz - spacing).abs() < 1e-9,
                "{} vs {spacing}",
                l.nearest_hz
            );
            // The filter: an order and time constant the MFLI has, rejecting that line by 60 dB.
            let (lo, hi) = p.filter_orders;
            assert!((lo..=hi).contains(&l.filter_order));
            let (tmin, tmax) = p.time_constant_s;
            assert!(l.time_constant_s >= tmin && l.time_constant_s <= tmax);
            let a = attenuation(l.filter_order, l.time_constant_s, l.nearest_hz);
            assert!((a * REJECTION - 1.0).abs() < 1e-6, "attenuation {a}");
            assert!((l.nebw_hz - nebw_hz(l.filter_order, l.time_constant_s)).abs() < 1e-15);
            // Settling: the filter's step response plus the ring-down Q/(π f), each to 0.1 %.
            let ring = Q / (std::f64::consts::PI * F) * (1.0 / SETTLE_ACCURACY).ln();
            let filter = settle_time(l.filter_order, SETTLE_ACCURACY) * l.time_constant_s;
            assert!((l.settle_s - (filter + ring)).abs() < 1e-6 * l.settle_s);
            assert!(ring > 70.0 && ring < 80.0, "{ring}");
            // The record holds the plan's 10 shots as independent samples.
            assert!((l.record_s * 2.0 * l.nebw_hz - 10.0).abs() < 1e-9);
            assert_eq!(l.samples, (l.sample_rate_hz * l.record_s).ceil() as u64);
        }
    }
    assert_eq!(levels, inst.levels.len());
    assert!(
        stdout.contains("instrument mfli-mf") && stdout.contains("V summed"),
        "{stdout}"
    );
    assert!(!stderr.contains("integrates at least"), "{stderr}");
    assert!(stderr.contains("settling and recording"), "{stderr}");

    // The plan scored as written, on the same instrument: the same settings.
    let (ok, _, scored, err) = run_plan(
        tmp.path(),
        &[
            "--noise",
            "0.0418V",
            "--instrument",
            "mfli-mf",
            "--max-voltage",
            "0.45",
        ]
        .into_iter()
        .chain(["--evaluate", "p.toml", "--nominal"])
        .collect::<Vec<_>>(),
    );
    assert!(ok, "{err}");
    assert!(scored.contains("instrument mfli-mf"), "{scored}");
    // On the MFLI without MF-MD the two tones are refused, naming the option.
    let (ok, code, _, err) = run_plan(
        tmp.path(),
        &[
            "--noise",
            "0.0418V",
            "--instrument",
            "mfli",
            "--evaluate",
            "p.toml",
            "--nominal",
        ],
    );
    assert!(!ok && code == Some(1), "{err}");
    assert!(
        err.contains("MF-MD") && err.contains("--instrument mfli-mf"),
        "{err}"
    );
}

#[test]
fn the_mfli_without_the_mf_option_refuses_two_tones() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (ok, code, _, err) = run_plan(
        tmp.path(),
        &["--noise", "2uV", "--instrument", "mfli", "--out", "p.toml"],
    );
    assert!(!ok && code == Some(1), "{err}");
    assert!(
        err.contains("two simultaneous tones need the MFLI's MF-MD option")
            && err.contains("--instrument mfli-mf"),
        "{err}"
    );
    assert!(!tmp.path().join("p.toml").exists());
    // The Moku's one oscillator: refused, saying what to use.
    let (ok, _, _, err) = run_plan(
        tmp.path(),
        &["--noise", "2uV", "--instrument", "moku", "--out", "p.toml"],
    );
    assert!(
        !ok && err.contains("Moku") && err.contains("mfli-mf"),
        "{err}"
    );
}

#[test]
fn hostile_instrument_options_get_clear_messages() {
    let tmp = tempfile::tempdir().expect("tmp");
    let base = ["--noise", "0.0418V", "--out", "p.toml"];
    let cases: [(&[&str], &[&str]); 10] = [
        (
            &["--instrument", "sr830"],
            &["unknown instrument `sr830`", "mfli-mf"],
        ),
        (&["--instrument", ""], &["unknown instrument", "mfli-mf"]),
        (
            &["--instrument", "mfli-mf", "--max-voltage", "0"],
            &["--max-voltage 0", "positive"],
        ),
        (
            &["--instrument", "mfli-mf", "--max-voltage=-1"],
            &["--max-voltage -1", "positive"],
        ),
        (
            &["--instrument", "mfli-mf", "--max-voltage", "NaN"],
            &["--max-voltage NaN", "positive"],
        ),
        (
            &["--instrument", "mfli-mf", "--max-voltage", "1e308"],
            &["1e308 V", "at most 10 V"],
        ),
        (
            &["--instrument", "uhfli", "--max-voltage", "2"],
            &["UHFLI", "1.5 V"],
        ),
        (
            &["--instrument", "mfli-mf", "--filter-order", "9"],
            &["--filter-order 9", "1 to 8"],
        ),
        (
            &["--instrument", "moku", "--filter-order", "5"],
            &["--filter-order 5", "1 to 4"],
        ),
        // Lines 0.088 Hz apart at order 1 need τ = 1808 s, beyond the MFLI's 83 s.
        (
            &["--instrument", "mfli-mf", "--filter-order", "1"],
            &["cannot set", "83 s"],
        ),
    ];
    for (args, wanted) in cases {
        let all: Vec<&str> = base.iter().chain(args).copied().collect();
        let (ok, code, _, err) = run_plan(tmp.path(), &all);
        assert!(!ok, "{args:?} accepted");
        assert!(
            code == Some(1) || code == Some(2),
            "{args:?}: exit {code:?}\n{err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        for w in wanted {
            assert!(err.contains(w), "{args:?}: no `{w}` in\n{err}");
        }
        assert!(err.len() < 4000, "{args:?}: {} bytes", err.len());
        assert!(!tmp.path().join("p.toml").exists(), "{args:?} wrote a plan");
    }
    // An instrument without gains: the volts cannot be planned.
    let values = tmp.path().join("values.toml");
    std::fs::write(&values, BEAM_VALUES).expect("values");
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("plan")
        .arg(root().join("examples/import/beam.hb"))
        .arg("--values")
        .arg(&values)
        .args([
            "--noise",
            "2uV",
            "--grid-hz",
            "0.001",
            "--instrument",
            "mfli-mf",
        ])
        .args(["--out", "p.toml"])
        .current_dir(tmp.path())
        .output()
        .expect("runs");
    let err = flat(&String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("--gain q1="), "{err}");
    // --noise in volts: a bad number or sign is refused with the unit's example.
    for bad in ["-2uV", "NaNuV", "uV", "1e400V"] {
        let noise = format!("--noise={bad}");
        let (ok, _, _, err) = run_plan(tmp.path(), &[&noise, "--out", "p.toml"]);
        assert!(
            !ok && err.contains("positive finite σ in volts"),
            "{bad}: {err}"
        );
    }
}

#[test]
fn generic_plans_keep_their_per_tone_cap_and_grid_wording() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (ok, _, _, err) = run_plan(
        tmp.path(),
        &[
            "--noise",
            "0.0418V",
            "--max-voltage",
            "0.45",
            "--out",
            "p.toml",
        ],
    );
    assert!(ok, "{err}");
    let plan = Plan::from_toml(
        &std::fs::read_to_string(tmp.path().join("p.toml")).expect("plan"),
        "p.toml",
    )
    .expect("plan");
    assert!(plan.instrument.is_none());
    assert_eq!(plan.displacement_unit, "V");
    // Each tone alone at most 0.45 V (the generic cap is per tone): the pair sums past it.
    let v = plan.measurements[0].drive_levels_v.clone().expect("volts");
    assert!(
        v.iter().all(|&x| x <= 0.45) && v.iter().sum::<f64>() > 0.45,
        "{v:?}"
    );
    assert!(err.contains("each shot integrates at least"), "{err}");
}

#[test]
fn plan_after_a_round_says_what_the_new_data_add() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path();
    let common = [
        "--noise",
        "0.0418V",
        "--instrument",
        "mfli-mf",
        "--max-voltage",
        "0.45",
    ];
    let args: Vec<&str> = common.iter().copied().chain(["--out", "a.toml"]).collect();
    let (ok, _, _, err) = run_plan(dir, &args);
    assert!(ok, "{err}");
    let model = root().join("examples/import/beam.hb");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .args(args)
            .current_dir(dir)
            .output()
            .expect("runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let m = model.to_str().expect("utf-8 path");
    run(&[
        "simulate",
        m,
        "--values",
        "values.toml",
        "--plan",
        "a.toml",
        "--seed",
        "1",
        "--out",
        "d0",
    ]);
    run(&["identify", m, "d0", "--out", "r0.json"]);
    let args: Vec<&str> = common
        .iter()
        .copied()
        .chain(["--after", "r0.json", "--out", "b.toml"])
        .collect();
    let (ok, _, stdout, err) = run_plan(dir, &args);
    assert!(ok, "{err}");
    // The data are in volts: a σ in metres is refused, naming the data's unit.
    let args: Vec<&str> = [
        "--noise",
        "0.05nm",
        "--instrument",
        "mfli-mf",
        "--after",
        "r0.json",
    ]
    .into_iter()
    .chain(["--out", "c.toml"])
    .collect();
    let (ok, code, _, refused) = run_plan(dir, &args);
    assert!(!ok && code == Some(1), "{refused}");
    assert!(
        refused.contains("whose amplitudes are in V") && refused.contains("--noise 2uV"),
        "{refused}"
    );
    // The table's relative bounds, by quantity.
    let rel: std::collections::BTreeMap<&str, f64> = stdout
        .lines()
        .take_while(|l| !l.starts_with('('))
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            Some((*f.first()?, f.get(3)?.parse().ok()?))
        })
        .collect();
    let added: Vec<&str> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("what the new data add"))
        .skip(1)
        .collect();
    assert_eq!(added.len(), 4, "{stdout}");
    for line in added {
        let f: Vec<&str> = line.split_whitespace().collect();
        let num = |k: usize| f[k].parse::<f64>().expect("a number");
        let (before, alone, both) = (num(1), num(2), num(3));
        // The plan alone is the table's bound; together, independent data add information.
        assert!((alone / rel[f[0]] - 1.0).abs() < 2e-3, "{line}");
        let want = (before.powi(-2) + alone.powi(-2)).powf(-0.5);
        assert!((both / want - 1.0).abs() < 2e-3, "{line}: {want}");
        assert!(both < before.min(alone), "{line}");
    }
}

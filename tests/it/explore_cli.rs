//! `harmonid states` and `harmonid phase-diagram` from the command line (issue 38): the
//! parametron's states and map, and bad input refused before any work.

use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("runs")
}

const MODEL: &str = "examples/parametron/model.hb";
const VALUES: &str = "examples/parametron/values.toml";

#[test]
fn states_of_the_parametron_above_threshold_in_json() {
    let out = run(&[
        "states", MODEL, "--values", VALUES, "--pump", "2000:2e5", "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let states = v["states"].as_array().expect("states");
    let stable: Vec<bool> = states
        .iter()
        .map(|s| s["stable"].as_bool().unwrap_or(false))
        .collect();
    assert_eq!(
        stable,
        [false, true, true],
        "rest unstable, the two phase states stable"
    );
    assert_eq!(v["paths"], 9);
    // a² = (4/3β)·√((λP/2)² − (ωγ)²) at f_p = 2 f0.
    let wg = (std::f64::consts::TAU * 1000.0f64).powi(2) / 1000.0;
    let want = (4.0 / 3.0 / 1e12 * (1e10f64 - wg * wg).sqrt()).sqrt();
    let got = states[1]["amplitudes"]["q1"]["abs"].as_f64().expect("abs");
    assert!((got / want - 1.0).abs() < 1e-9, "{got} vs {want}");
    assert!(states.iter().all(|s| s["lattice"]["continued"] == true));
}

#[test]
fn phase_diagram_writes_the_map_states_and_plot() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (map, states, plot) = (
        dir.path().join("map.csv"),
        dir.path().join("states.csv"),
        dir.path().join("map.svg"),
    );
    let out = run(&[
        "phase-diagram",
        MODEL,
        "--values",
        VALUES,
        "--pump",
        "2000:1e5",
        "--x",
        "pump_hz:1990:2010:21",
        "--y",
        "pump_level:1e3:4e5:11",
        "--out",
        map.to_str().unwrap_or_default(),
        "--states",
        states.to_str().unwrap_or_default(),
        "--plot",
        plot.to_str().unwrap_or_default(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&map).expect("map");
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "x,y,stable,unstable,oscillatory");
    assert_eq!(rows.len(), 1 + 21 * 11);
    // At f_p = 2000 Hz, P = 4e5 (inside the tongue): two stable phase states, the rest unstable.
    assert!(
        rows.contains(&"2000,400000,2,1,0"),
        "{}",
        &text[..200.min(text.len())]
    );
    let st = std::fs::read_to_string(&states).expect("states");
    assert!(st.starts_with("x,y,state,stable,oscillatory,q1_re,q1_im,q1_abs\n"));
    assert!(std::fs::read_to_string(&plot)
        .expect("svg")
        .contains("2 stable, 1 unstable"));
}

#[test]
fn bad_axes_are_refused_before_any_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let map = dir.path().join("map.csv");
    let m = map.to_str().unwrap_or_default();
    let cases: [(&[&str], &str); 4] = [
        (
            &["--x", "pump_hz:1990:2010:1", "--y", "pump_level:1:2:10"],
            "at least 2",
        ),
        (
            &[
                "--x",
                "pump_hz:1990:2010:1001",
                "--y",
                "pump_level:1:2:1000",
            ],
            "1001000 points",
        ),
        (
            &["--x", "pump_hz:1990:2010:10", "--y", "kappa:1:2:10"],
            "`kappa` names nothing in the model",
        ),
        (
            &["--x", "pump_hz:1990:2010:10", "--y", "pump_level:1:nan:10"],
            "not a finite number",
        ),
    ];
    for (axes, want) in cases {
        let mut args = vec![
            "phase-diagram",
            MODEL,
            "--values",
            VALUES,
            "--pump",
            "2000:1e5",
            "--out",
            m,
        ];
        args.extend_from_slice(axes);
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{axes:?}: {err}"
        );
        assert!(!map.exists(), "nothing written");
    }
    let out = run(&[
        "phase-diagram",
        "examples/dispersive_2mode/model.hb",
        "--values",
        "examples/dispersive_2mode/values.toml",
        "--drive",
        "1010",
        "--force",
        "q1=10",
        "--x",
        "freq:995:1030:10",
        "--y",
        "pump_level:1:2:10",
        "--out",
        m,
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("no pump terms"));
}

/// `states` and `phase-diagram` share their excitation options (one `ExcitationArgs`
/// flattened into both); each keeps its own wording of them, and `--drives q1:HZ` still reads
/// as `--drive` in both.
#[test]
fn the_excitation_options_are_shared_and_worded_per_command() {
    let help = |cmd: &str| {
        let out = run(&[cmd, "--help"]);
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
    };
    let (states, map) = (help("states"), help("phase-diagram"));
    for (text, want) in [
        (&states, "--drive <HZ> The drive tone, Hz (`--drives q1:HZ` is read the same, the mode before the colon ignored: the forces name the modes)"),
        (&states, "--force <MODE=N_PER_KG> Force of the tone on a mode, N/kg (peak), as `mode=amplitude`; repeat for several modes"),
        (&states, "--pump <HZ:LEVEL[:PHASE_RAD]> A pump tone, `HZ:LEVEL[:PHASE_RAD]` (the model's `pump` signal); with a drive, at twice the drive tone"),
        (&map, "--drive <HZ> The drive tone, Hz, where the axes do not move it (`--drives q1:HZ` read the same)"),
        (&map, "--force <MODE=N_PER_KG> Force of the tone on a mode, N/kg, as `mode=amplitude`; repeat for several modes"),
        (&map, "--pump <HZ:LEVEL[:PHASE_RAD]> A pump tone, `HZ:LEVEL[:PHASE_RAD]`; with a drive, at twice the drive tone (the two move together on a freq or pump_hz axis)"),
    ] {
        assert!(text.contains(want), "`{want}` not in:\n{text}");
    }
    // The alias and the mode before the colon: the same excitation as `--drive 1000`.
    let args = [
        "--values", VALUES, "--force", "q1=1e6", "--pump", "2000:2e5", "--json",
    ];
    let a = run(&[&["states", MODEL, "--drives", "q1:1000"][..], &args].concat());
    let b = run(&[&["states", MODEL, "--drive", "1000"][..], &args].concat());
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert_eq!(a.stdout, b.stdout);
}

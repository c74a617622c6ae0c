//! Hostile inputs to the command line (issue 11): outputs never destroy a file, inputs never
//! escape their folder, and bad arguments are refused with a message naming them.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn example(path: &str) -> PathBuf {
    root().join("examples/nanostring_2mode").join(path)
}

fn run(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .env("NO_COLOR", "1")
        .output()
        .expect("run harmonid");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // miette wraps long lines with a frame; join them back for the assertions.
    let words: Vec<&str> = text.split_whitespace().filter(|w| *w != "│").collect();
    (out.status.success(), words.join(" "))
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// A copy of the shipped model in a fresh folder.
fn copied_model(dir: &Path) -> PathBuf {
    let m = dir.join("model.hb");
    std::fs::copy(example("model.hb"), &m).expect("copy model");
    m
}

#[test]
fn identify_never_overwrites_its_own_model() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let m = copied_model(tmp.path());
    let before = std::fs::read(&m).expect("read");
    let data = example("data");
    let (ok, text) = run(&["identify", s(&m), s(&data), "--out", s(&m)]);
    assert!(!ok, "{text}");
    assert!(text.contains("is an input of this run"), "{text}");
    assert_eq!(std::fs::read(&m).expect("read"), before);
    // Nor a file of the dataset, under another spelling of its path.
    let csv = data.join(".").join("single_q1.csv");
    let (ok, text) = run(&["identify", s(&m), s(&data), "--per-shot", s(&csv)]);
    assert!(!ok && text.contains("is an input of this run"), "{text}");
}

#[test]
fn per_shot_into_a_missing_folder_fails_before_writing() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let m = copied_model(tmp.path());
    let out = tmp.path().join("result.json");
    let shots = tmp.path().join("missing/shots.csv");
    let (ok, text) = run(&[
        "identify",
        s(&m),
        s(&example("data")),
        "--out",
        s(&out),
        "--per-shot",
        s(&shots),
    ]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("does not exist") && text.contains("missing"),
        "{text}"
    );
    assert!(!out.exists(), "the result was written before the failure");
}

#[cfg(unix)]
#[test]
fn outputs_write_only_regular_files() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let m = copied_model(tmp.path());
    let target = tmp.path().join("precious.txt");
    std::fs::write(&target, "keep").expect("write");
    let link = tmp.path().join("result.json");
    std::os::unix::fs::symlink(&target, &link).expect("symlink");
    let (ok, text) = run(&["identify", s(&m), s(&example("data")), "--out", s(&link)]);
    assert!(!ok && text.contains("symbolic link"), "{text}");
    assert_eq!(std::fs::read(&target).expect("read"), b"keep");
    assert!(std::fs::symlink_metadata(&link)
        .expect("meta")
        .file_type()
        .is_symlink());
    let (ok, text) = run(&["identify", s(&m), s(&example("data")), "--out", "/dev/null"]);
    assert!(!ok && text.contains("device node"), "{text}");
    let (ok, text) = run(&[
        "identify",
        s(&m),
        s(&example("data")),
        "--out",
        s(tmp.path()),
    ]);
    assert!(!ok && text.contains("is a folder"), "{text}");
}

#[cfg(unix)]
#[test]
fn outputs_follow_the_umask() {
    use std::os::unix::fs::PermissionsExt;
    let mode = |p: &Path| std::fs::metadata(p).expect("meta").permissions().mode() & 0o777;
    let tmp = tempfile::tempdir().expect("tempdir");
    // The test harness's umask applies to all: each output matches a plain new file.
    let probe = tmp.path().join("probe");
    std::fs::write(&probe, "x").expect("write");
    let plain = mode(&probe);
    let m = copied_model(tmp.path());
    let result = tmp.path().join("result.json");
    let (ok, text) = run(&["identify", s(&m), s(&example("data")), "--out", s(&result)]);
    assert!(ok, "{text}");
    let curve = tmp.path().join("curve.csv");
    let (ok, text) = sweep(&[
        "--from",
        "207400",
        "--to",
        "207800",
        "--force",
        "q1=1",
        "--points",
        "20",
        "--out",
        s(&curve),
    ]);
    assert!(ok, "{text}");
    let table = tmp.path().join("table.txt");
    let (ok, text) = run(&[
        "mix",
        s(&m),
        "--drives",
        "q1:207572.5,207592.5",
        "--output",
        s(&table),
    ]);
    assert!(ok, "{text}");
    for p in [&result, &curve, &table] {
        let got = mode(p);
        assert_eq!(
            got,
            plain,
            "{}: mode {got:o}, a new file {plain:o}",
            p.display()
        );
    }
}

#[test]
fn identify_refuses_a_non_finite_near_rel() {
    let (ok, text) = run(&[
        "identify",
        s(&example("model.hb")),
        s(&example("data")),
        "--near-rel",
        "nan",
    ]);
    assert!(!ok && text.contains("--near-rel NaN"), "{text}");
}

fn sweep(extra: &[&str]) -> (bool, String) {
    let model = example("model.hb");
    let values = example("values.toml");
    let mut args = vec!["sweep", s(&model), "--values", s(&values)];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn sweep_refuses_bad_numbers_naming_them() {
    let (ok, text) = sweep(&["--from", "207000", "--to", "208500", "--force", "q1=nan"]);
    assert!(!ok && text.contains("not a finite number"), "{text}");
    let (ok, text) = sweep(&["--from=-10", "--to", "208500", "--force", "q1=1"]);
    assert!(
        !ok && text.contains("start frequency") && text.contains("-10"),
        "{text}"
    );
    let (ok, text) = sweep(&["--from", "207000", "--to", "0", "--force", "q1=1"]);
    assert!(!ok && text.contains("stop frequency"), "{text}");
    for (option, value, words) in [
        ("--points", "100000000", "number of sweep points"),
        ("--harmonics", "1000", "highest harmonic"),
    ] {
        let range = ["--from", "207000", "--to", "208500", "--force", "q1=1"];
        let (ok, text) = sweep(&[&range[..], &[option, value]].concat());
        assert!(!ok && text.contains(words), "{option} {value}: {text}");
    }
}

#[test]
fn sweep_far_beyond_the_weakly_nonlinear_regime_is_not_marked_converged() {
    // With --force q1=1e9 and 3 harmonics the curve had h3/h1 = 0.21 and was marked stable.
    let (ok, text) = sweep(&[
        "--from", "207000", "--to", "208500", "--force", "q1=1e9", "--points", "50",
    ]);
    if ok {
        assert!(text.contains("recomputing with --harmonics"), "{text}");
    } else {
        assert!(
            text.contains("not converged") || text.contains("Newton"),
            "{text}"
        );
    }
}

/// A plan of one quick two-tone measurement on mode 1 of the shipped model.
const ONE_MEASUREMENT: &str = r#"
[[measurement]]
name = "single_q1"
drives_hz = [207572.5, 207592.5]
force = { q1 = [3.5, 3.5] }
measure_hz = [207552.5, 207572.5, 207592.5, 207612.5]
"#;

/// `harmonid simulate` of [`ONE_MEASUREMENT`] with the shipped model and values, `--out out`.
fn simulate(dir: &Path, out: &Path, extra: &[&str]) -> (bool, String) {
    let plan = dir.join("plan.toml");
    if !plan.exists() {
        std::fs::write(&plan, ONE_MEASUREMENT).expect("write plan");
    }
    let model = example("model.hb");
    let values = example("values.toml");
    let mut args = vec![
        "simulate",
        s(&model),
        "--values",
        s(&values),
        "--plan",
        s(&plan),
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn simulate_never_empties_a_foreign_folder_without_force() {
    // `simulate --out DIR` emptied any DIR (a thesis) and exited 0.
    let tmp = tempfile::tempdir().expect("tempdir");
    let thesis = tmp.path().join("thesis");
    std::fs::create_dir(&thesis).expect("mkdir");
    std::fs::write(thesis.join("thesis.tex"), "chapter 1").expect("write");
    let (ok, text) = simulate(tmp.path(), &thesis, &[]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("not empty and not a harmonid dataset")
            && text.contains("thesis.tex")
            && text.contains("--force"),
        "{text}"
    );
    assert_eq!(
        std::fs::read(thesis.join("thesis.tex")).expect("kept"),
        b"chapter 1"
    );
    // Asked explicitly, the folder is replaced by the dataset.
    let (ok, text) = simulate(tmp.path(), &thesis, &["--force"]);
    assert!(ok, "{text}");
    assert!(thesis.join("dataset.toml").exists() && !thesis.join("thesis.tex").exists());
    // A dataset folder is replaced without --force (a second run of the same command).
    let (ok, text) = simulate(tmp.path(), &thesis, &[]);
    assert!(ok, "{text}");
    // No staging folder of harmonid's naming is left beside it.
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("list")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(harmonid_files::STAGING_PREFIX))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn simulate_never_replaces_the_folder_of_its_inputs() {
    // The folder holding the plan itself, even with --force.
    let tmp = tempfile::tempdir().expect("tempdir");
    let (ok, text) = simulate(tmp.path(), tmp.path(), &["--force"]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("is an input of this run") && text.contains("plan.toml"),
        "{text}"
    );
    assert!(tmp.path().join("plan.toml").exists());
    // A dataset folder holding the values file (a truth.toml given as --values).
    let ds = tmp.path().join("ds");
    let (ok, text) = simulate(tmp.path(), &ds, &[]);
    assert!(ok, "{text}");
    let model = example("model.hb");
    let truth = ds.join("truth.toml");
    let plan = tmp.path().join("plan.toml");
    let (ok, text) = run(&[
        "simulate",
        s(&model),
        "--values",
        s(&truth),
        "--plan",
        s(&plan),
        "--out",
        s(&ds),
    ]);
    assert!(!ok && text.contains("is an input of this run"), "{text}");
    assert!(truth.exists());
}

#[test]
fn simulate_refuses_zero_steps_per_period_at_once() {
    // `--steps-per-period 0` never ended.
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("ds");
    let (ok, text) = simulate(
        tmp.path(),
        &out,
        &["--time-domain", "--steps-per-period", "0"],
    );
    assert!(!ok, "{text}");
    assert!(text.contains("steps") && text.contains('0'), "{text}");
    assert!(!out.exists());
}

/// Copies of the example's model and values in a fresh folder, with their bytes.
fn copied_inputs(dir: &Path) -> [(PathBuf, Vec<u8>); 2] {
    let m = copied_model(dir);
    let v = dir.join("values.toml");
    std::fs::copy(example("values.toml"), &v).expect("copy values");
    [m, v].map(|p| {
        let bytes = std::fs::read(&p).expect("read");
        (p, bytes)
    })
}

/// Runs `args` once with `option` naming each input in turn: each run must be refused, and leave
/// every input as it was. (`--plot` is refused for the inputs' extensions before the check of
/// inputs, which `identify`'s tests cover; the files must survive either way.)
fn refuses_every_input_as(option: &str, args: &[&str], inputs: &[(PathBuf, Vec<u8>)]) {
    for (target, _) in inputs {
        let mut all = args.to_vec();
        all.extend([option, s(target)]);
        let (ok, text) = run(&all);
        assert!(!ok, "{option} {}: {text}", target.display());
        let why = if option == "--plot" {
            "unknown figure format"
        } else {
            "is an input of this run"
        };
        assert!(text.contains(why), "{option}: {text}");
        for (p, bytes) in inputs {
            assert_eq!(
                &std::fs::read(p).expect("read"),
                bytes,
                "{option} changed {}",
                p.display()
            );
        }
    }
}

#[test]
fn plan_never_replaces_its_inputs() {
    // `plan M --values V --out M` used to replace the model with the plan and exit 0.
    let tmp = tempfile::tempdir().expect("tempdir");
    let inputs = copied_inputs(tmp.path());
    let plan = tmp.path().join("plan.toml");
    std::fs::copy(example("plan.toml"), &plan).expect("copy plan");
    let common = [
        "plan",
        s(&inputs[0].0),
        "--values",
        s(&inputs[1].0),
        "--noise",
        "0.05nm",
        "--shots",
        "20",
    ];
    refuses_every_input_as("--out", &common, &inputs);
    // Scoring a plan: the plan is an input too.
    let mut evaluate = common.to_vec();
    evaluate.extend(["--evaluate", s(&plan)]);
    let mut with_plan = inputs.to_vec();
    with_plan.push((plan.clone(), std::fs::read(&plan).expect("read")));
    for option in ["--bounds", "--plot"] {
        refuses_every_input_as(option, &evaluate, &with_plan);
    }
}

#[test]
fn sweep_never_replaces_its_inputs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let inputs = copied_inputs(tmp.path());
    let args = [
        "sweep",
        s(&inputs[0].0),
        "--values",
        s(&inputs[1].0),
        "--from",
        "207500",
        "--to",
        "207700",
        "--force",
        "q1=0.5",
    ];
    for option in ["--out", "--plot"] {
        refuses_every_input_as(option, &args, &inputs);
    }
    let mut two_tone = args.to_vec();
    two_tone.extend(["--two-tone", "20"]);
    refuses_every_input_as("--out", &two_tone, &inputs);
}

#[test]
fn mix_never_replaces_its_inputs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let inputs = copied_inputs(tmp.path());
    let args = ["mix", s(&inputs[0].0), "--drives", "q1:207572,207592"];
    refuses_every_input_as("--output", &args, &inputs[..1]);
    // With the tones from a dataset, its manifest is an input as well.
    let data = example("data");
    let manifest = data.join("dataset.toml");
    let before = std::fs::read(&manifest).expect("read");
    let (ok, text) = run(&[
        "mix",
        s(&inputs[0].0),
        "--dataset",
        s(&data),
        "--measurement",
        "single_q1",
        "--output",
        s(&manifest),
    ]);
    assert!(!ok && text.contains("is an input of this run"), "{text}");
    assert_eq!(std::fs::read(&manifest).expect("read"), before);
}

#[test]
fn a_message_quotes_a_window_of_a_long_line() {
    // An unknown key after 2,000 tones on one line printed the whole 50 kB line.
    let tmp = tempfile::tempdir().expect("tempdir");
    let tones: Vec<String> = (0..2000).map(|i| format!("{}.5", 207000 + i)).collect();
    let mut plan = std::fs::read_to_string(example("plan.toml")).expect("plan");
    plan.push_str(&format!(
        "\n[[measurement]]\nname = \"long\"\ndrives_hz = [207572.5]\nforce = {{ q1 = [1.0] }}\nmeasure_hz = [{}], bogus = 3\n",
        tones.join(", ")
    ));
    let path = tmp.path().join("long.toml");
    std::fs::write(&path, &plan).expect("write");
    let model = example("model.hb");
    let values = example("values.toml");
    let out = tmp.path().join("ds");
    let (ok, text) = run(&[
        "simulate",
        s(&model),
        "--values",
        s(&values),
        "--plan",
        s(&path),
        "--out",
        s(&out),
    ]);
    assert!(!ok, "{text}");
    assert!(text.len() < 1500, "{} bytes: {text}", text.len());
    assert!(
        text.contains("bogus = 3") && text.contains("long.toml:"),
        "{text}"
    );
    // A values file that is not TOML, past its long line's 2,000 numbers.
    let bad = tmp.path().join("values.toml");
    std::fs::write(&bad, format!("x = [{}] ]\n", tones.join(", "))).expect("write");
    let plan = example("plan.toml");
    let (ok, text) = run(&[
        "simulate",
        s(&model),
        "--values",
        s(&bad),
        "--plan",
        s(&plan),
        "--out",
        s(&out),
    ]);
    assert!(!ok, "{text}");
    assert!(text.len() < 1000, "{} bytes: {text}", text.len());
    assert!(
        text.contains("line 1, column") && text.contains("] ]"),
        "{text}"
    );
    assert!(!out.exists());
}

// ---- Hostile inputs (issue 37; reproducers in ../shared/hostile) ----

#[test]
fn plan_refuses_a_billion_draws_before_any_work() {
    // hostile 13: `--draws 1000000000` aborted on a 72 GB allocation after the design.
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("p.toml");
    let (model, values) = (example("model.hb"), example("values.toml"));
    let started = std::time::Instant::now();
    let (ok, text) = run(&[
        "plan",
        s(&model),
        "--values",
        s(&values),
        "--noise",
        "50pm",
        "--draws",
        "1000000000",
        "--out",
        s(&out),
    ]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("--draws") && text.contains("at most 10000") && text.contains("1000000000"),
        "{text}"
    );
    assert!(
        started.elapsed().as_secs() < 20,
        "refused before the design"
    );
    assert!(!out.exists());
    // The bound itself is accepted as far as the check goes.
    assert!(harmonid_plan::check_draws(harmonid_plan::MAX_DRAWS).is_ok());
}

#[test]
fn sweep_quotes_a_huge_frequency_as_written() {
    // hostile 14: `--from 1e300` was printed as a 301-digit number filling the message.
    let (ok, text) = sweep(&["--from", "1e300", "--to", "inf", "--force", "q1=3.5"]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("start frequency (Hz) = 1e300 is not allowed") && text.contains("1e15"),
        "{text}"
    );
    assert!(!text.contains("0000000000"), "{text}");
}

const TABLE_MAP: &str = "[columns]\nfreq_hz = \"f\"\nx = \"X\"\ny = \"Y\"\n[conventions]\namplitude = \"peak\"\nquadrature = \"x+iy\"\ndisplacement_unit = \"V\"\n[drive]\nlevel = 0.1\nphase_rad = 0.0\n";

/// A table of 41 rows of a Lorentzian (rows 2..=42 of the file), row `at` (1-based file line)
/// replaced by `row` when given.
fn lorentzian_table(at: usize, row: Option<&str>) -> String {
    let mut lines = vec!["f,X,Y".to_string()];
    for i in 0..41 {
        let d = (i as f64 - 20.0) / 5.0;
        let (x, y) = (1e-3 / (1.0 + d * d), -2e-4 * d * 5.0 / (1.0 + d * d));
        lines.push(format!("{},{x},{y}", 100.0 + i as f64 * 0.5));
    }
    if let Some(r) = row {
        lines[at - 1] = r.to_string();
    }
    lines.join("\n") + "\n"
}

/// `harmonid import FORMAT FILE ARGS --out DIR/outds` on `bytes` written as `name`; the
/// message, whether it ran, and the folder (its `outds` the dataset). The output folder must
/// not exist after a refusal.
fn import(
    format: &str,
    name: &str,
    bytes: &[u8],
    extra: &[&str],
) -> (bool, String, tempfile::TempDir) {
    let dir = tempfile::tempdir().expect("tempdir");
    let tmp = dir.path();
    let input = tmp.join(name);
    std::fs::write(&input, bytes).expect("write input");
    let map = tmp.join("map.toml");
    std::fs::write(&map, TABLE_MAP).expect("write map");
    let out = tmp.join("outds");
    let mut args = vec!["import", format, s(&input), "--out", s(&out)];
    if format == "table" {
        args.extend(["--map", s(&map)]);
    } else {
        args.extend(["--amplitude", "rms", "--quadrature", "x+iy", "--volts"]);
    }
    args.extend_from_slice(extra);
    let (ok, text) = run(&args);
    if !ok {
        assert!(!out.exists(), "a refusal leaves no output: {text}");
    }
    (ok, text, dir)
}

#[test]
fn import_refuses_bad_rows_naming_the_file_row_and_value() {
    // hostile 3, 5, 6: a 1e308 amplitude was printed as 309 digits and blamed on the dataset
    // folder never written; an `inf` frequency joined the step before it and row 12 was blamed.
    let cases = [
        ("105,1e308,1e308", "amplitude (1e308, 1e308)"),
        (
            "inf,1e-3,1e-4",
            "drive frequency inf is not a positive, finite frequency",
        ),
        (
            "1e308,1e-3,1e-4",
            "drive frequency 1e308 is not a positive, finite frequency",
        ),
        ("-105,1e-3,1e-4", "drive frequency -105 is not a positive"),
        ("105,nan,1e-4", "amplitude (NaN, 0.0001) is not finite"),
    ];
    for (row, words) in cases {
        let (ok, text, _) = import(
            "table",
            "f.csv",
            lorentzian_table(11, Some(row)).as_bytes(),
            &[],
        );
        assert!(!ok, "{row}: {text}");
        assert!(
            text.contains("f.csv, row 11:") && text.contains(words),
            "{row}: {text}"
        );
        assert!(
            !text.contains("outds") && !text.contains("0000000000"),
            "{row}: {text}"
        );
    }
    // hostile 4: the same in a LabOne demodulator CSV (RMS: ×√2 overflows nothing now).
    let mut z = String::from("chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1\n");
    for k in 0..10 {
        for j in 0..5 {
            let x = if (k, j) == (1, 2) { "1e308" } else { "1e-3" };
            let tick = 1_000_000 + k * 60_000_000 + j * 6_000_000;
            z += &format!("0;{tick};{x};{x};{};0;0;0;0;0\n", 1000 + k);
        }
    }
    let (ok, text, _) = import("zi-csv", "z.csv", z.as_bytes(), &["--clockbase-hz", "60e6"]);
    assert!(
        !ok && text.contains("z.csv, row 9: amplitude (1e308, 1e308)"),
        "{text}"
    );
    assert!(!text.contains("0000000000"), "{text}");
}

#[test]
fn import_sweeper_refuses_bad_rows_naming_the_file_and_row() {
    let sweeper = |f3: &str, sd: &str| {
        let mut s = String::from("grid;bandwidth;count;x;xstddev;y;ystddev;frequency\n");
        for k in 0..10 {
            let f = if k == 3 {
                f3.to_string()
            } else {
                (1000 + k).to_string()
            };
            s += &format!("{f};10.0;5;1e-3;{sd};2e-4;{sd};{f}\n");
        }
        s
    };
    // hostile 7: a 1e308 frequency was blamed on the dataset folder never written.
    let (ok, text, _) = import(
        "zi-sweeper",
        "s.csv",
        sweeper("1e308", "1e-5").as_bytes(),
        &[],
    );
    assert!(!ok, "{text}");
    assert!(
        text.contains("s.csv, row 5: drive frequency 1e308"),
        "{text}"
    );
    // hostile 9: a negative standard deviation was imported as a positive noise.
    let (ok, text, _) = import("zi-sweeper", "s.csv", sweeper("1003", "-1").as_bytes(), &[]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("s.csv, row 2: column \"xstddev\": -1 is negative"),
        "{text}"
    );
    // A zero deviation in one quadrature is allowed (the other carries the noise).
    let ok_one = sweeper("1003", "1e-5").replace(";1e-3;1e-5;", ";1e-3;0;");
    let (ok, text, _) = import("zi-sweeper", "s.csv", ok_one.as_bytes(), &[]);
    assert!(ok, "{text}");
}

#[test]
fn import_quotes_a_binary_header_as_a_short_escaped_excerpt() {
    // hostile 1, 2: a binary file's first "line" (kilobytes) was quoted whole as the header.
    let mut bytes: Vec<u8> = (0..5000u32)
        .map(|i| b"\"\x01,;a\xff"[(i % 6) as usize])
        .collect();
    bytes.truncate(5000);
    let lossy = String::from_utf8_lossy(&bytes).into_owned();
    for (format, first) in [
        ("table", "no column \"f\""),
        ("zi-sweeper", "no column \"grid\""),
    ] {
        let (ok, text, _) = import(format, "bin.csv", lossy.as_bytes(), &[]);
        assert!(!ok, "{text}");
        assert!(
            text.contains("bin.csv, row 1") && text.contains(first),
            "{text}"
        );
        assert!(text.len() < 1_200, "{format}: {} bytes: {text}", text.len());
        assert!(
            !text.contains('\u{1}') && text.contains("\\u{1}"),
            "escaped: {text}"
        );
    }
}

#[test]
fn import_reads_a_table_with_a_byte_order_mark() {
    // hostile 8: Excel's "CSV UTF-8" BOM made 'no column "f" (found: f, X, Y)'.
    let bytes = [
        b"\xEF\xBB\xBF".as_slice(),
        lorentzian_table(0, None).as_bytes(),
    ]
    .concat();
    let (ok, text, out) = import("table", "x.csv", &bytes, &[]);
    assert!(ok, "{text}");
    let manifest =
        std::fs::read_to_string(out.path().join("outds/dataset.toml")).expect("manifest");
    assert!(
        manifest.contains("100.0") && manifest.contains("120.0"),
        "{manifest}"
    );
}

#[test]
fn import_moku_refuses_a_negative_demodulation_frequency() {
    // hostile 10: "-1000 Hz" in the header was imported as +1000 Hz.
    let mut m = String::from("% Moku:Pro Lock-in Amplifier\n% Demodulation frequency -1000 Hz\n% Time (s), Channel 1 (V), Channel 2 (V)\n");
    for j in 0..10 {
        m += &format!("0.{j}, 1e-3, 1e-1\n");
    }
    let moku = ["--channels", "x,y", "--output-gain", "1"];
    let (ok, text, _) = import("moku-csv", "m.csv", m.as_bytes(), &moku);
    assert!(!ok, "{text}");
    assert!(
        text.contains("m.csv, row 2: the header's demodulation frequency is -1000 Hz")
            && text.contains("--demod-hz"),
        "{text}"
    );
    let (ok, text, _) = import(
        "moku-csv",
        "m.csv",
        m.as_bytes(),
        &[&moku[..], &["--demod-hz=-5"]].concat(),
    );
    assert!(
        !ok && text.contains("--demod-hz") && text.contains("-5"),
        "{text}"
    );
    // Given explicitly, the positive frequency is used.
    let (ok, text, out) = import(
        "moku-csv",
        "m.csv",
        m.as_bytes(),
        &[&moku[..], &["--demod-hz", "1000"]].concat(),
    );
    assert!(ok, "{text}");
    let manifest =
        std::fs::read_to_string(out.path().join("outds/dataset.toml")).expect("manifest");
    assert!(manifest.contains("drives_hz = [[1000.0]]"), "{manifest}");
}

#[test]
fn compare_refuses_a_model_compared_with_itself() {
    // hostile 11: `compare ds m.hb m.hb` said "the data barely support m.hb (BIC 0.0 below
    // m.hb's)" and exited 0.
    let tmp = tempfile::tempdir().expect("tempdir");
    let m = copied_model(tmp.path());
    let data = example("data");
    let (ok, text) = run(&["compare", s(&data), s(&m), s(&m)]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("model 1") && text.contains("model 2") && text.contains("are the same file"),
        "{text}"
    );
    // A copy under another name, with a comment: the same model.
    let copy = tmp.path().join("copy.hb");
    let source = std::fs::read_to_string(&m).expect("read");
    std::fs::write(&copy, format!("# a copy\n{source}")).expect("write");
    let (ok, text) = run(&["compare", s(&data), s(&m), s(&copy)]);
    assert!(!ok, "{text}");
    assert!(text.contains("are the same model"), "{text}");
}

#[test]
fn noise_study_refuses_noise_above_every_line() {
    // hostile 18: σ = 1e10 m against lines of 1e-8 m exited 0 with estimates "within 0.1 % of
    // the truth" (each fit stayed at its start).
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("ns.csv");
    let (ok, text) = run(&[
        "noise-study",
        "--sigma",
        "1e-12,1e10",
        "--realisations",
        "2",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("noise level 1e10")
            && text.contains("strongest line (8.807e-9 m")
            && text.contains("meaningless"),
        "{text}"
    );
    assert!(!out.exists());
}

#[test]
fn report_refuses_a_result_of_another_model_or_dataset() {
    // hostile 17: a three-mode model's result, reported against the two-mode data, headlined
    // that result's fit, shots and values as the two-mode model's.
    let tmp = tempfile::tempdir().expect("tempdir");
    let (model, data) = (example("model.hb"), example("data"));
    let result = tmp.path().join("r.json");
    let (ok, text) = run(&["identify", s(&model), s(&data), "--out", s(&result)]);
    assert!(ok, "{text}");
    let out = tmp.path().join("rep");
    let report =
        |m: &Path, r: &Path| run(&["report", s(m), s(&data), "--result", s(r), "--out", s(&out)]);

    let three = root().join("examples/cubic_3mode/model.hb");
    let (ok, text) = report(&three, &result);
    assert!(!ok, "{text}");
    assert!(
        text.contains("is a result of another model: its modes are q1, q2;")
            && text.contains("cubic_3mode/model.hb has q1, q2, q3")
            && text.contains("harmonid identify"),
        "{text}"
    );
    let renamed = tmp.path().join("renamed.hb");
    let source = std::fs::read_to_string(&model).expect("read");
    std::fs::write(&renamed, source.replace("g12", "g_12")).expect("write");
    let (ok, text) = report(&renamed, &result);
    assert!(!ok, "{text}");
    assert!(
        text.contains("its parameters are beta1, beta2, g12;")
            && text.contains("renamed.hb has beta1, beta2, g_12"),
        "{text}"
    );
    let json = std::fs::read_to_string(&result).expect("read");
    let foreign = tmp.path().join("foreign.json");
    std::fs::write(&foreign, json.replace("\"single_q1\"", "\"single_q3\"")).expect("write");
    let (ok, text) = report(&model, &foreign);
    assert!(!ok, "{text}");
    assert!(
        text.contains("is a result of another dataset: its measurements are couple_q1_q2, single_q2, single_q3;"),
        "{text}"
    );
    assert!(!out.exists());
    // Its own model and dataset: reported.
    let (ok, text) = report(&model, &result);
    assert!(ok && out.join("index.html").exists(), "{text}");
}

#[test]
fn import_force_never_deletes_a_folder_holding_a_model_or_values() {
    // `import --force` replaced any non-dataset folder: a folder holding the model and values
    // of a study was deleted. The same guard as simulate's (harmonid_files::check_output_dir).
    let table = lorentzian_table(0, None);
    let tmp = tempfile::tempdir().expect("tempdir");
    let input = tmp.path().join("t.csv");
    std::fs::write(&input, &table).expect("write");
    let map = tmp.path().join("map.toml");
    std::fs::write(&map, TABLE_MAP).expect("write");
    let study = tmp.path().join("study");
    std::fs::create_dir(&study).expect("mkdir");
    std::fs::copy(example("model.hb"), study.join("model.hb")).expect("copy");
    std::fs::copy(example("values.toml"), study.join("values.toml")).expect("copy");
    let import = |out: &Path| {
        run(&[
            "import",
            "table",
            s(&input),
            "--map",
            s(&map),
            "--out",
            s(out),
            "--force",
        ])
    };
    let (ok, text) = import(&study);
    assert!(!ok, "{text}");
    assert!(
        text.contains("even with --force")
            && (text.contains("study/model.hb") || text.contains("study/values.toml")),
        "{text}"
    );
    assert!(study.join("model.hb").exists() && study.join("values.toml").exists());
    // simulate --force: the same refusal.
    let (ok, text) = simulate(tmp.path(), &study, &["--force"]);
    assert!(!ok && text.contains("even with --force"), "{text}");
    // A folder of other files is still replaced when forced, and a dataset without --force.
    let scratch = tmp.path().join("scratch");
    std::fs::create_dir(&scratch).expect("mkdir");
    std::fs::write(scratch.join("notes.txt"), "old").expect("write");
    let (ok, text) = import(&scratch);
    assert!(ok && scratch.join("dataset.toml").exists(), "{text}");
    let (ok, text) = run(&[
        "import",
        "table",
        s(&input),
        "--map",
        s(&map),
        "--out",
        s(&scratch),
    ]);
    assert!(ok, "{text}");
}

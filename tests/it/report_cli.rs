//! `harmonid report` end to end on the shipped two-mode example dataset: the page and every figure are
//! written, every figure is an SVG with axes, text and data, the structure of the SVGs is
//! snapshotted (not pixels), a headless Chromium parses the page and finds every figure drawn,
//! and a folder that is not a report is never overwritten.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The two-mode example dataset (20 shots, 0.05 nm).
fn dataset() -> PathBuf {
    root().join("examples/nanostring_2mode/data")
}

fn report(args: &[&Path]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("report")
        .args(args)
        .output()
        .expect("run harmonid");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Every `<svg>…</svg>` of an HTML text.
fn svgs(html: &str) -> Vec<&str> {
    html.split("<svg")
        .skip(1)
        .map(|s| s.split("</svg>").next().unwrap_or(""))
        .collect()
}

/// An SVG is drawn when it has axes (lines or polylines), tick or label text, and data marks.
fn assert_drawn(svg: &str, what: &str) {
    let count = |tag: &str| svg.matches(tag).count();
    assert!(count("<text") >= 4, "{what}: no axis text");
    assert!(
        count("<polyline") + count("<line") + count("<path") >= 2,
        "{what}: no axes"
    );
    assert!(
        count("<circle") + count("<rect") + count("<polygon") >= 3,
        "{what}: no data"
    );
}

#[test]
fn two_mode_report_has_every_figure() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("report");
    let (ok, stdout, stderr) = report(&[
        &root().join("examples/nanostring_2mode/model.hb"),
        &dataset(),
        Path::new("--out"),
        &out,
    ]);
    assert!(ok, "report failed: {stderr}");
    assert!(stdout.contains("index.html"), "{stdout}");
    let html = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    assert!(
        !html.contains("http://")
            || html.matches("http://").count() == html.matches("http://www.w3.org").count(),
        "the page must not fetch anything"
    );
    assert!(!html.contains("<script"), "no scripts");
    for id in [
        "parameters",
        "equations",
        "spectra",
        "histograms",
        "potential",
    ] {
        assert!(
            html.contains(&format!("id=\"{id}\"")),
            "section {id} missing"
        );
    }
    // 3 spectra (one per measurement), 4 mode quantities + 3 parameters, the potential matrix.
    let figs = svgs(&html);
    assert_eq!(figs.len(), 3 + 4 + 3 + 1, "figures on the page");
    for (k, s) in figs.iter().enumerate() {
        assert_drawn(s, &format!("figure {k}"));
    }
    let mut stems: Vec<String> = std::fs::read_dir(out.join("figures"))
        .expect("figures/")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect();
    stems.sort();
    insta::assert_snapshot!("report_2mode_files", stems.join("\n"));
    for name in &stems {
        let bytes = std::fs::read(out.join("figures").join(name)).expect("figure");
        if name.ends_with(".png") {
            assert_eq!(&bytes[1..4], b"PNG", "{name}");
            assert!(bytes.len() > 5000, "{name}: suspiciously small PNG");
        }
    }
    // The spectra name their lines; the values table holds the parameters and their truth.
    for label in ["f1", "2f1−f2", "drive tone", "sideband", "mixing product"] {
        assert!(html.contains(label), "{label} missing");
    }
    for p in ["beta1", "beta2", "g12", "f_q1", "Q_q2"] {
        assert!(
            html.contains(&format!(">{p}<")),
            "{p} missing from the table"
        );
    }
    let spectrum = std::fs::read_to_string(out.join("figures/spectrum_couple_q1_q2_p0.svg"))
        .expect("spectrum svg");
    insta::assert_snapshot!(
        "report_2mode_spectrum_structure",
        harmonid_plot::svg_structure(&spectrum)
    );

    // A second run replaces the report; a folder that is not a report is refused untouched.
    let (ok, _, stderr) = report(&[
        &root().join("examples/nanostring_2mode/model.hb"),
        &dataset(),
        Path::new("--out"),
        &out,
    ]);
    assert!(ok, "{stderr}");
    let foreign = tmp.path().join("thesis");
    std::fs::create_dir(&foreign).expect("dir");
    std::fs::write(foreign.join("chapter1.tex"), "x").expect("file");
    let (ok, _, stderr) = report(&[
        &root().join("examples/nanostring_2mode/model.hb"),
        &dataset(),
        Path::new("--out"),
        &foreign,
    ]);
    assert!(!ok && stderr.contains("not a harmonid report"), "{stderr}");
    assert_eq!(std::fs::read_dir(&foreign).expect("ls").count(), 1);

    chromium_draws_every_figure(&out.join("index.html"), figs.len());
    assert!(
        !html.contains("id=\"responses\""),
        "a frequency response without sweeps"
    );
}

/// Chromium (Debian's `chromium`, installed by .ci/run) parses the page; its DOM holds every
/// figure as an SVG element with axes, text and data. Returns the DOM (`None`: no Chromium).
fn chromium_draws_every_figure(index: &Path, n_figures: usize) -> Option<String> {
    let Some(bin) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        eprintln!(
            "SKIPPED the browser check: no chromium on this machine (install it with `apt-get install -y chromium`; .ci/run does)"
        );
        return None;
    };
    let profile = tempfile::tempdir().expect("profile dir");
    let out = Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", index.display()))
        .output()
        .expect("run chromium");
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dom = String::from_utf8_lossy(&out.stdout);
    let figs = svgs(&dom);
    assert_eq!(figs.len(), n_figures, "figures in Chromium's DOM");
    for (k, s) in figs.iter().enumerate() {
        assert_drawn(s, &format!("figure {k} in Chromium's DOM"));
    }
    Some(dom.into_owned())
}

/// A result written by `harmonid identify --out` is read with the type that wrote it
/// (`harmonid_ident::Report::from_json`): the page shows its values and says why there are no
/// histograms; a file that is not a result, and a report over its own dataset, are refused.
#[test]
fn report_from_a_result_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let model = root().join("examples/nanostring_2mode/model.hb");
    let result = tmp.path().join("r.json");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("identify")
        .arg(&model)
        .arg(dataset())
        .arg("--out")
        .arg(&result)
        .output()
        .expect("identify");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let out = tmp.path().join("report");
    let from_result = || {
        report(&[
            &model,
            &dataset(),
            Path::new("--result"),
            &result,
            Path::new("--out"),
            &out,
        ])
    };
    let (ok, stdout, stderr) = from_result();
    assert!(ok, "{stdout}{stderr}");
    let html = std::fs::read_to_string(out.join("index.html")).expect("page");
    assert!(html.contains("Values from the result"), "source named");
    assert!(stderr.contains("no histograms"), "{stderr}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&result).expect("result")).expect("json");
    let g12 = r["parameters"]["g12"]["value"].as_f64().expect("g12");
    assert!(
        html.contains(&harmonid_plot::style::num(g12, 8)),
        "the page shows the result's g12 = {g12}"
    );
    std::fs::write(&result, r#"{"format": "something else"}"#).expect("write");
    let (ok, _, stderr) = from_result();
    assert!(!ok && stderr.contains("not a harmonid result"), "{stderr}");
    let (ok, _, _) = report(&[&model, &dataset(), Path::new("--out"), &dataset()]);
    assert!(!ok, "a report over its own dataset folder");
    assert!(dataset().join("dataset.toml").is_file());
}

use harmonid_testgen as gen;

/// Not a timed test: the time of the report of a five-mode dataset (15 measurements, 30 shots),
/// printed for the docs. Run with `cargo test --release --test it -- report_cli:: --ignored
/// --nocapture`.
#[test]
#[ignore]
fn five_mode_report_time() {
    let model_path = root().join("examples/nanostring_5mode/model.hb");
    let model = harmonid_model::load(&model_path).expect("model");
    let (v, d) = gen::nanostring_5mode_plan();
    let ds = gen::simulate(&model, &v, &d, &gen::NANOSTRING_SHAPE, 5e-12, 30, 5);
    let tmp = tempfile::tempdir().expect("tmp");
    let data = tmp.path().join("data");
    ds.write(&data).expect("write dataset");
    let out = tmp.path().join("report");
    let t = std::time::Instant::now();
    let (ok, stdout, stderr) = report(&[&model_path, &data, Path::new("--out"), &out]);
    let secs = t.elapsed().as_secs_f64();
    assert!(ok, "{stderr}");
    println!("five-mode report, 15 measurements, 30 shots: {secs:.2} s wall ({stdout})");
    // The default identification inside it, alone (harmonid identify on the same data).
    let result = tmp.path().join("r.json");
    let t = std::time::Instant::now();
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("identify")
        .arg(&model_path)
        .arg(&data)
        .arg("--out")
        .arg(&result)
        .output()
        .expect("identify");
    let ident = t.elapsed().as_secs_f64();
    assert!(st.status.success());
    println!("  of which the default identification (harmonid identify): {ident:.2} s wall");
    // The report from that result (reconstructions, figures, page; no per-shot histograms).
    let t = std::time::Instant::now();
    let (ok, _, stderr) = report(&[
        &model_path,
        &data,
        Path::new("--result"),
        &result,
        Path::new("--out"),
        &out,
    ]);
    assert!(ok, "{stderr}");
    println!(
        "  report --result (no identification): {:.2} s wall",
        t.elapsed().as_secs_f64()
    );
}

/// The synthetic hysteretic sweeps (testgen): the softened Duffing mode with its nonlinear
/// damping lowered to `eta1 = 1e17` (testgen's 5e18 damps the top level out of bistability),
/// `levels` drive levels swept up and down through the folds, `steps` steps a sweep, one shot
/// a step, kept in nm; noise `sigma` m per quadrature (0: the clean simulation).
fn hysteretic(
    levels: usize,
    steps: usize,
    sigma: f64,
) -> (harmonid_model::Model, gen::Values, harmonid_data::Dataset) {
    let model = harmonid_model::parse_str(gen::DAMPED_DUFFING, "softening.hb").expect("model");
    let (mut v, sweeps) = gen::hysteretic_sweeps(levels, steps);
    v.params.insert("eta1".into(), 1e17);
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps, &[1.0], 1);
    let mut ds = if sigma > 0.0 {
        gen::add_noise(&clean, sigma, 7)
    } else {
        clean
    };
    ds.manifest.displacement_unit = "nm".into();
    (model, v, ds)
}

/// A report of stepped sweeps draws one frequency-response figure per drive level and one of
/// every level, not one spectrum per step; its axes are in the dataset's unit, its stage cells
/// name sweeps, and Chromium finds the figures on the page.
#[test]
fn sweep_report_draws_frequency_responses() {
    let (_, _, ds) = hysteretic(3, 30, 2e-11);
    let tmp = tempfile::tempdir().expect("tmp");
    let data = tmp.path().join("data");
    ds.write(&data).expect("dataset");
    let model = tmp.path().join("softening.hb");
    std::fs::write(&model, gen::DAMPED_DUFFING).expect("model");
    let result = tmp.path().join("r.json");
    let st = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("identify")
        .args([&model, &data])
        .args(["--error-floor", "--out"])
        .arg(&result)
        .output()
        .expect("identify");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let out = tmp.path().join("report");
    let (ok, _, stderr) = report(&[
        &model,
        &data,
        Path::new("--result"),
        &result,
        Path::new("--out"),
        &out,
    ]);
    assert!(ok, "{stderr}");
    let html = std::fs::read_to_string(out.join("index.html")).expect("page");
    assert!(
        html.contains("id=\"responses\""),
        "no frequency-response section"
    );
    assert!(
        !html.contains("id=\"fig-spectrum_"),
        "a spectrum of a sweep step"
    );
    let mut stems: Vec<String> = std::fs::read_dir(out.join("figures"))
        .expect("figures/")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.ends_with(".svg"))
        .collect();
    stems.sort();
    assert_eq!(
        stems.len(),
        4,
        "one figure per level and one of every level: {stems:?}"
    );
    assert_eq!(stems[0], "response_all.svg");
    assert!(
        stems[1..].iter().all(|s| s.starts_with("response_level_")),
        "{stems:?}"
    );
    for s in svgs(&html) {
        assert_drawn(s, "a response figure");
        for label in ["|X| (nm)", "Re X (nm)", "Im X (nm)", "arg X − arg F (°)"] {
            assert!(s.contains(label), "axis label {label} missing");
        }
    }
    assert!(
        html.contains("up_l00…dn_l02 (6 sweeps, 180 steps)") || html.contains("up_l00, dn_l00"),
        "the stage cell names the sweeps"
    );
    assert!(!html.contains("up_l00[1]"), "a step named in a table");
    let all = std::fs::read_to_string(out.join("figures/response_all.svg")).expect("svg");
    insta::assert_snapshot!(
        "report_sweeps_response_structure",
        harmonid_plot::svg_structure_without_ticks(&all)
    );
    if let Some(dom) = chromium_draws_every_figure(&out.join("index.html"), 4) {
        // The browser shows the overview first, in the frequency-response section, with its
        // axes in the dataset's unit and both sweep directions in the legend.
        let section = dom
            .split("id=\"responses\"")
            .nth(1)
            .expect("section in the DOM");
        let first = section.split("<figure").nth(1).expect("a figure");
        assert!(
            first.contains("id=\"fig-response_all\""),
            "the overview is first"
        );
        for label in [
            "|X| (nm)",
            "Im X (nm)",
            "up-sweep",
            "down-sweep",
            "model, unstable",
        ] {
            assert!(first.contains(label), "{label} not in Chromium's figure");
        }
    }
}

/// The physics of the frequency-response figure, on the clean simulation with the true model
/// and forces in place of the identified ones: the measured points are the model's steady
/// state followed step by step (1e-6 relative), each lies on the drawn continuation curve, and
/// the curve where it has one solution is the steady state harmonid_sim's harmonic balance
/// gives at that frequency (1e-6 relative).
#[test]
fn response_curve_is_the_harmonic_balance_steady_state() {
    use harmonid_report::response;
    use num_complex::Complex64;
    let (model, v, clean) = hysteretic(3, 30, 0.0);
    let (_, _, noisy) = hysteretic(3, 30, 2e-11);
    let settings = harmonid_ident::Settings {
        error_floor: true,
        ..harmonid_ident::Settings::default()
    };
    let mut rep = harmonid_ident::identify(&model, &noisy, &settings).expect("identify");
    // The true forces: the drive level (N/kg) at phase 0.
    for m in &clean.measurements {
        let f = m.spec.drives_hz[0];
        let level = m.spec.drive_levels_v.as_ref().expect("levels")[0];
        let fr = harmonid_data::result::ForceResult {
            f_hz: f,
            amplitude: level,
            phase_rad: 0.0,
        };
        rep.forces
            .insert(m.spec.name.clone(), [("q1".to_string(), vec![fr])].into());
    }
    let truth = harmonid_sim::NumericModel::from_model(&model, &gen::model_values(&model, &v))
        .expect("numeric");
    let fams = response::families(&clean);
    assert_eq!(fams.len(), 3);
    let nm_per_unit = 1e-9;
    let mut on_curve = 0;
    for fam in &fams {
        let r = response::family_response(Some(&truth), &rep, &clean, fam);
        assert_eq!(r.unit, "nm");
        assert_eq!(r.sweeps.len(), 2, "up and down");
        let c = r.model.as_ref().expect("model curve");
        // Measured = model followed step by step.
        for s in &r.sweeps {
            let mx = s.model.as_ref().expect("model at steps");
            for (k, (a, b)) in s.x.iter().zip(mx).enumerate() {
                assert!(
                    (a - b).norm() <= 1e-6 * a.norm(),
                    "{} step {k}: {a} against {b}",
                    s.name
                );
            }
            // ... and on the drawn curve: the nearest segment through the step's frequency.
            for (&f, x) in s.f_hz.iter().zip(&s.x) {
                let d = (0..c.f_hz.len() - 1)
                    .filter(|&i| (c.f_hz[i] - f) * (c.f_hz[i + 1] - f) <= 0.0)
                    .map(|i| {
                        let t = (f - c.f_hz[i]) / (c.f_hz[i + 1] - c.f_hz[i]);
                        (c.x[i] + (c.x[i + 1] - c.x[i]) * t - x).norm() / x.norm()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(d < 5e-3, "{} at {f} Hz: {d:.2e} off the curve", s.name);
                on_curve += 1;
            }
        }
        // The curve where it has one solution: harmonid_sim's steady state (ramped from rest).
        let folds: Vec<f64> = (1..c.f_hz.len() - 1)
            .filter(|&i| (c.f_hz[i] - c.f_hz[i - 1]) * (c.f_hz[i + 1] - c.f_hz[i]) < 0.0)
            .map(|i| c.f_hz[i])
            .collect();
        let (lo, hi) = folds
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &f| {
                (a.min(f), b.max(f))
            });
        let mut checked = 0;
        for i in (0..c.f_hz.len()).step_by(9) {
            let f = c.f_hz[i];
            if f >= lo - 1.0 && f <= hi + 1.0 {
                continue;
            }
            let drive = harmonid_sim::Excitation {
                pumps: Vec::new(),
                tones_hz: vec![f],
                force: vec![vec![c.force[0]]],
            };
            let st =
                harmonid_sim::steady_state(&truth, &drive, &harmonid_sim::HbSettings::default())
                    .expect("steady state");
            assert!(st.converged());
            let x: Complex64 = st.at_point(&[1.0], f) / nm_per_unit;
            assert!(
                (x - c.x[i]).norm() <= 1e-6 * x.norm(),
                "{} at {f} Hz: curve {} against HB {x}",
                fam.label,
                c.x[i]
            );
            checked += 1;
        }
        assert!(checked >= 5, "{}: {checked} points checked", fam.label);
        assert!(
            c.stable.iter().all(|&s| s) || !folds.is_empty(),
            "unstable points without a fold"
        );
    }
    assert_eq!(on_curve, 180);
    // The top level is bistable: its curve folds twice and has an unstable part.
    let top = response::family_response(Some(&truth), &rep, &clean, &fams[2]);
    let c = top.model.expect("curve");
    assert!(
        c.stable.iter().any(|&s| !s),
        "no unstable branch at the top level"
    );
}

/// Not a check: writes the synthetic hysteretic sweeps (12 levels, 48 steps a sweep: 1,152
/// steps, 2e-11 m noise, in nm) and their model to `$HARMONID_KEEP_SWEEPS` for the docs'
/// figure and the page-size check (`harmonid identify --error-floor`, then `harmonid report
/// --result`). Run with `HARMONID_KEEP_SWEEPS=/tmp/sweeps cargo test --release --test it --
/// report_cli::keep_sweeps --ignored`.
#[test]
#[ignore]
fn keep_sweeps() {
    let dir = std::env::var("HARMONID_KEEP_SWEEPS").expect("HARMONID_KEEP_SWEEPS=DIR");
    let (_, _, ds) = hysteretic(12, 48, 2e-11);
    ds.write(Path::new(&dir).join("data")).expect("dataset");
    std::fs::write(Path::new(&dir).join("softening.hb"), gen::DAMPED_DUFFING).expect("model");
    let (_, _, small) = hysteretic(4, 40, 2e-11);
    small.write(Path::new(&dir).join("small")).expect("dataset");
}

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
}

/// Chromium (Debian's `chromium`, installed by .ci/run) parses the page; its DOM holds every
/// figure as an SVG element with axes, text and data.
fn chromium_draws_every_figure(index: &Path, n_figures: usize) {
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
        return;
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

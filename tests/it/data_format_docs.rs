//! The worked example of docs/data-format.md runs as the page says: its model and dataset blocks
//! (each after a `<!-- file: NAME -->` marker) written to a folder, `harmonid identify` on them,
//! and the identified values are the ones the page quotes. The page's lock-in conversion script
//! turns the page's lock-in export into the page's CSV (when python3 is installed).

use std::path::Path;
use std::process::Command;

const PAGE: &str = include_str!("../../docs/data-format.md");

/// The fenced block after `<!-- file: NAME -->`.
fn file_block(name: &str) -> &'static str {
    let marker = format!("<!-- file: {name} -->");
    let at = PAGE.find(&marker).unwrap_or_else(|| panic!("no {marker}"));
    fenced_after(at)
}

/// The body of the first fenced block starting at or after byte `at` of the page.
fn fenced_after(at: usize) -> &'static str {
    let open = at + PAGE[at..].find("```").expect("an opening fence");
    let body = open + PAGE[open..].find('\n').expect("fence line") + 1;
    let len = PAGE[body..].find("```").expect("a closing fence");
    &PAGE[body..body + len]
}

fn write_example(dir: &Path) {
    for name in [
        "duffing.hb",
        "my_dataset/dataset.toml",
        "my_dataset/two_tone.csv",
    ] {
        let path = dir.join(name);
        std::fs::create_dir_all(path.parent().expect("parent")).expect("mkdir");
        std::fs::write(&path, file_block(name)).expect("write");
    }
}

#[test]
fn the_worked_example_identifies_the_values_the_page_quotes() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_example(dir.path());
    assert!(PAGE.contains("harmonid identify duffing.hb my_dataset --out result.json"));
    let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .current_dir(dir.path())
        .args([
            "identify",
            "duffing.hb",
            "my_dataset",
            "--out",
            "result.json",
        ])
        .output()
        .expect("run harmonid");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("result.json")).expect("result.json");
    let r: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(r["format"], "harmonid-result/1");
    let value = |v: &serde_json::Value| v["value"].as_f64().expect("a value");
    // The values the data were simulated with (quoted on the page); six-digit data.
    let f = value(&r["modes"]["q1"]["f_hz"]);
    let q = value(&r["modes"]["q1"]["Q"]);
    let beta = value(&r["parameters"]["beta1"]);
    let gain = r["gains"]["two_tone"]["q1"]["amplitude"]
        .as_f64()
        .expect("gain");
    println!("f {f}, Q {q}, beta1 {beta:e}, |G| {gain}");
    assert!((f - 207582.0).abs() < 1e-4, "f = {f}");
    assert!((q / 116232.0 - 1.0).abs() < 1e-5, "Q = {q}");
    assert!((beta / 2.68e22 - 1.0).abs() < 1e-4, "beta1 = {beta:e}");
    assert!((gain / 2.5 - 1.0).abs() < 1e-5, "gain = {gain}");
    assert!(PAGE.contains("`f_q1 = 207582.000 Hz`, `Q_q1 = 1.16232e5`, `beta1 = 2.6800e22`"));
    assert!(r
        .get("warnings")
        .is_some_and(|w| w.as_array().is_some_and(|w| w.is_empty())));
}

#[test]
fn the_conversion_script_turns_the_lockin_export_into_the_example_csv() {
    let python = ["python3", "python"].into_iter().find(|p| {
        Command::new(p)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    });
    let Some(python) = python else {
        println!("skipped: no python3 on PATH to run the page's conversion script");
        return;
    };
    let export = fenced_after(
        PAGE.find("```text\nrecord,frequency_hz")
            .expect("export block"),
    );
    let script = fenced_after(PAGE.find("```python").expect("python block"));
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("my_dataset")).expect("mkdir");
    std::fs::write(dir.path().join("lockin_export.csv"), export).expect("write");
    std::fs::write(dir.path().join("lockin_to_harmonid.py"), script).expect("write");
    let out = Command::new(python)
        .current_dir(dir.path())
        .arg("lockin_to_harmonid.py")
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = std::fs::read_to_string(dir.path().join("my_dataset/two_tone.csv")).expect("csv");
    assert_eq!(
        got.replace("\r\n", "\n"),
        file_block("my_dataset/two_tone.csv")
    );
}

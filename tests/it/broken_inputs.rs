//! The corpus of broken datasets and plans (`tests/fixtures/datasets/*/`,
//! `tests/fixtures/plans/*.toml`): one fixture per rule of the data format
//! (docs/data-format.md) and of the plan (docs/simulation.md), each refused with a message naming
//! the file (and the row, key or span) — never a panic, never a result. The plain-text rendering
//! of every refusal is snapshotted (insta, `tests/snapshots/broken_inputs__*.snap`).
//! `tests/fixtures/valid/` holds the dataset and the plan they are each one change away from.

use harmonid::data::Dataset;
use harmonid_experiment::Plan;
use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// The diagnostic as a user sees it, without colours, the checkout's path removed. Lines are not
/// wrapped: miette wraps before the path is removed, so a wrapped rendering would depend on
/// where the repository is checked out.
fn render(d: &dyn Diagnostic) -> String {
    let handler = GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor())
        .with_width(10_000)
        .with_links(false);
    let mut out = String::new();
    handler
        .render_report(&mut out, d)
        .expect("render into a String");
    let root = format!("{}/", env!("CARGO_MANIFEST_DIR"));
    out.replace(&root, "")
}

/// The entries of `dir`, sorted, with their names.
fn entries(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(Result::ok)
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.path()))
        .collect();
    v.sort();
    v
}

#[test]
fn the_valid_dataset_and_plan_are_accepted() {
    let ds = Dataset::load(fixtures().join("valid/dataset")).expect("the valid dataset");
    assert_eq!(ds.measurements[0].n_shots, 2);
    let text = std::fs::read_to_string(fixtures().join("valid/plan.toml")).expect("read");
    let plan = Plan::from_toml(&text, "plan.toml").expect("the valid plan");
    assert_eq!(plan.measurements.len(), 1);
}

#[test]
fn every_broken_dataset_is_refused_naming_its_file() {
    let all = entries(&fixtures().join("datasets"));
    assert!(all.len() >= 30, "{} fixtures", all.len());
    for (name, dir) in all {
        let rule = std::fs::read_to_string(dir.join("dataset.toml"))
            .ok()
            .and_then(|t| t.lines().next().map(str::to_string))
            .unwrap_or_default();
        let e = match Dataset::load(&dir) {
            Ok(_) => panic!("{name} ({rule}) was accepted"),
            Err(e) => e,
        };
        let text = render(&e);
        assert!(
            text.contains(&format!("tests/fixtures/datasets/{name}/")),
            "{name}: the message names no file of the dataset:\n{text}"
        );
        assert!(e.code().is_some(), "{name}: no diagnostic code:\n{text}");
        insta::assert_snapshot!(format!("dataset_{name}"), text);
    }
}

#[test]
fn every_broken_plan_is_refused_pointing_at_its_key() {
    let all = entries(&fixtures().join("plans"));
    assert!(all.len() >= 20, "{} fixtures", all.len());
    for (name, path) in all {
        let text = std::fs::read_to_string(&path).expect("read");
        let e = match Plan::from_toml(&text, &name) {
            Ok(_) => panic!("{name} was accepted"),
            Err(e) => e,
        };
        let shown = render(&e);
        assert!(shown.contains(&name), "{name}: no file named:\n{shown}");
        insta::assert_snapshot!(format!("plan_{}", name.trim_end_matches(".toml")), shown);
    }
}

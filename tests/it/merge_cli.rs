//! `harmonid merge`: two simulated rounds of the nanostring example pooled into one dataset and
//! identified; datasets that disagree on a key (displacement unit, point shape) refused, naming
//! the key, with nothing written; one folder given twice or an output that is a file refused.

use harmonid::data::Dataset;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn example(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples/nanostring_2mode")
        .join(file)
}

fn harmonid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .output()
        .expect("run harmonid")
}

fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Simulates the example's plan into `dir/<name>` with `seed`.
fn simulate(dir: &Path, name: &str, seed: &str) -> PathBuf {
    let out = dir.join(name);
    let st = harmonid(&[
        "simulate",
        path(&example("model.hb")),
        "--values",
        path(&example("values.toml")),
        "--plan",
        path(&example("plan.toml")),
        "--seed",
        seed,
        "--out",
        path(&out),
    ]);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    out
}

/// A copy of dataset folder `from` at `to` with `dataset.toml`'s text edited by `edit`.
fn edited_copy(from: &Path, to: &Path, edit: impl Fn(String) -> String) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read_dir").flatten() {
        std::fs::copy(e.path(), to.join(e.file_name())).expect("copy");
    }
    let m = to.join("dataset.toml");
    let text = std::fs::read_to_string(&m).expect("read");
    let changed = edit(text.clone());
    assert_ne!(changed, text, "the edit changed nothing");
    std::fs::write(&m, changed).expect("write");
}

#[test]
fn two_rounds_merge_and_identify_and_mismatches_are_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let r1 = simulate(tmp.path(), "round1", "1");
    let r2 = simulate(tmp.path(), "round2", "2");
    let merged = tmp.path().join("merged");
    let st = harmonid(&["merge", path(&r1), path(&r2), "--out", path(&merged)]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(st.status.success(), "{err}");
    assert!(err.contains("round2_single_q1"), "{err}");
    let ds = Dataset::load(&merged).expect("merged dataset");
    assert_eq!(ds.measurements.len(), 6);
    assert!(ds.measurement("round1_couple_q1_q2").is_some());
    assert!(ds.measurement("round2_couple_q1_q2").is_some());
    let one = Dataset::load(&r1).expect("round 1");
    assert_eq!(ds.truth.is_some(), one.truth.is_some());
    if let Some(t) = &ds.truth {
        assert!(
            t.forces.contains_key("round2_single_q2"),
            "{:?}",
            t.forces.keys()
        );
    }
    let result = tmp.path().join("result.json");
    let st = harmonid(&[
        "identify",
        path(&example("model.hb")),
        path(&merged),
        "--out",
        path(&result),
    ]);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let json = std::fs::read_to_string(&result).expect("result");
    assert!(json.contains("round2_couple_q1_q2"));

    // Merging again into the same folder (a dataset) is fine; into an input is not.
    let st = harmonid(&["merge", path(&r1), path(&r2), "--out", path(&merged)]);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let st = harmonid(&["merge", path(&r1), path(&r2), "--out", path(&r1), "--force"]);
    assert!(!st.status.success());

    let nm = tmp.path().join("round_nm");
    edited_copy(&r2, &nm, |t| {
        t.replace("displacement_unit = \"m\"", "displacement_unit = \"nm\"")
    });
    let shape = tmp.path().join("round_shape");
    edited_copy(&r2, &shape, |t| {
        t.replace("q1 = 0.3090169943749474", "q1 = 0.3")
    });
    for (odd, key) in [(&nm, "displacement_unit"), (&shape, "shape.q1")] {
        let out = tmp.path().join("refused");
        let st = harmonid(&["merge", path(&r1), path(odd), "--out", path(&out)]);
        let err = String::from_utf8_lossy(&st.stderr);
        assert!(!st.status.success(), "{err}");
        assert!(err.contains(key), "{err}");
        assert!(err.contains("merge_mismatch"), "{err}");
        assert!(!out.exists(), "a refused merge wrote {}", out.display());
    }

    // One folder given twice, an output that is a file: said so, nothing written.
    let st = harmonid(&["merge", path(&r1), path(&r1), "--out", path(&merged)]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(!st.status.success() && err.contains("given twice"), "{err}");
    let file = tmp.path().join("result.json");
    let st = harmonid(&["merge", path(&r1), path(&r2), "--out", path(&file)]);
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        !st.status.success() && err.contains("output folder"),
        "{err}"
    );
    assert!(std::fs::read_to_string(&file)
        .expect("kept")
        .contains("round2"));
}

//! A standard output closed early (`harmonid identify ... | head -1`) is no error: the command
//! drops the rest of its output, still writes its files, exits 0 and prints no panic.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `harmonid ARGS` with its standard output a pipe whose reader reads at most `keep`
/// bytes and then closes it. With `keep == 0` the reader closes before the command has printed
/// anything, so every write meets the closed pipe (no race with the command's output).
/// Returns (exit success, bytes read, standard error).
fn run_closed_early(args: &[&str], keep: usize) -> (bool, Vec<u8>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .args(args)
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run harmonid");
    let mut stdout = child.stdout.take().expect("a piped stdout");
    let mut got = vec![0u8; keep];
    if keep > 0 {
        stdout.read_exact(&mut got).expect("the first bytes");
    }
    drop(stdout);
    let out = child.wait_with_output().expect("harmonid exits");
    (
        out.status.success(),
        got,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn identify_into_a_closed_pipe_exits_quietly_and_writes_its_files() {
    let dir = tempfile::tempdir().expect("temp dir");
    let result = dir.path().join("result.json");
    let shots = dir.path().join("shots.csv");
    for keep in [0, 8] {
        let _ = std::fs::remove_file(&result);
        let (ok, got, stderr) = run_closed_early(
            &[
                "identify",
                "examples/nanostring_2mode/model.hb",
                "examples/nanostring_2mode/data",
                "--estimator",
                "linear",
                "--out",
                result.to_str().expect("utf-8 path"),
                "--per-shot",
                shots.to_str().expect("utf-8 path"),
            ],
            keep,
        );
        assert!(ok, "exit status not 0 (keep {keep}); stderr:\n{stderr}");
        assert!(!stderr.contains("panicked"), "stderr:\n{stderr}");
        assert!(!stderr.contains("Broken pipe"), "stderr:\n{stderr}");
        assert!(
            std::fs::read_to_string(&result)
                .expect("the result is still written")
                .contains("\"format\": \"harmonid-result/1\""),
            "keep {keep}"
        );
        if keep > 0 {
            // What was read is the start of the printed summary.
            assert!(
                std::str::from_utf8(&got).is_ok_and(|t| !t.trim().is_empty()),
                "{got:?}"
            );
        }
    }
}

#[test]
fn plan_table_into_a_closed_pipe_exits_quietly() {
    let (ok, _, stderr) = run_closed_early(
        &[
            "plan",
            "examples/nanostring_2mode/model.hb",
            "--values",
            "examples/nanostring_2mode/values.toml",
            "--noise",
            "0.05nm",
            "--shots",
            "20",
            "--evaluate",
            "examples/nanostring_2mode/plan.toml",
        ],
        0,
    );
    assert!(ok, "stderr:\n{stderr}");
    assert!(!stderr.contains("panicked"), "stderr:\n{stderr}");
}

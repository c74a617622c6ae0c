//! [`Dataset::merge`]: sweeps keep their steps under prefixed names, truth is kept only when
//! identical, a name clash the folders cannot part is refused.

use super::*;

const MANIFEST: &str = r#"
format = "harmonid-dataset/1"
displacement_unit = "nm"
[nominal_hz]
q1 = 100.0
[[measurement]]
name = "single"
drives_hz = [100.0]
[[sweep]]
name = "up"
direction = "up"
drives_hz = [[100.0], [101.0], [102.0]]
"#;

fn csv(file: &str) -> String {
    if file.starts_with("up") {
        let mut s = String::from("step,shot,freq_hz,re,im\n");
        for k in 0..3 {
            s.push_str(&format!("{k},0,{},{k},1\n", 100 + k));
        }
        s
    } else {
        "shot,freq_hz,re,im\n0,100.0,1,2\n".to_string()
    }
}

fn load(dir: &str, manifest: &str) -> Dataset {
    Dataset::from_readers(Path::new(dir), manifest, None, |f| {
        Ok(std::io::Cursor::new(csv(f)))
    })
    .expect("dataset")
}

#[test]
fn sweeps_keep_their_steps_under_the_folder_prefix() {
    let mut a = load("lab/r1", MANIFEST);
    let b = load("lab/r2", MANIFEST);
    a.truth = Some(Truth::default());
    let m = Dataset::merge(&[a, b]).expect("merge");
    let names: Vec<&str> = m
        .measurements
        .iter()
        .map(|m| m.spec.name.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "r1_single",
            "r1_up[0]",
            "r1_up[1]",
            "r1_up[2]",
            "r2_single",
            "r2_up[0]",
            "r2_up[1]",
            "r2_up[2]"
        ]
    );
    assert!(m.truth.is_none());
    assert!(
        m.notes.iter().any(|n| n.contains("truth.toml dropped")),
        "{:?}",
        m.notes
    );
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("merged");
    m.write(&out).expect("write");
    let back = Dataset::load(&out).expect("read back");
    assert_eq!(back.manifest.sweeps.len(), 2);
    assert_eq!(back.measurements.len(), 8);
    assert_eq!(
        back.measurement("r2_up[2]").expect("step").data,
        m.measurements[7].data
    );
}

#[test]
fn disagreements_and_unpartable_names_are_refused() {
    let a = load("a/r", MANIFEST);
    let err = Dataset::merge(&[a.clone(), load("b/r", MANIFEST)]).expect_err("clash");
    assert!(
        matches!(err, DatasetError::MergeNameClash { ref renamed, .. } if renamed == "r_single"),
        "{err}"
    );
    let other = MANIFEST.replace("displacement_unit = \"nm\"", "displacement_unit = \"m\"");
    let err = Dataset::merge(&[a, load("b/s", &other)]).expect_err("unit");
    let text = err.to_string();
    assert!(
        text.contains("displacement_unit") && text.contains("\"m\"") && text.contains("b/s"),
        "{text}"
    );
}

/// Rounds of the lab loop carry the guesses of their plans as nominal frequencies: those may
/// differ, the last input's are kept, unless a line would change its mode.
#[test]
fn nominal_frequencies_may_differ_while_every_line_keeps_its_mode() {
    let a = load("lab/r1", MANIFEST);
    let b = load("lab/r2", &MANIFEST.replace("q1 = 100.0", "q1 = 100.5"));
    let m = Dataset::merge(&[a, b]).expect("merge");
    assert_eq!(m.manifest.nominal_hz["q1"], 100.5);
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("nominal frequencies differ")),
        "{:?}",
        m.notes
    );
    // Two modes: the line at 101 Hz is q1's under r1's guess (q2 at 103 Hz) but q2's under
    // r2's (q2 at 101.2 Hz).
    let two = |q2: &str| MANIFEST.replace("q1 = 100.0", &format!("q1 = 100.0\nq2 = {q2}"));
    let a = load("lab/r1", &two("103.0"));
    let b = load("lab/r2", &two("101.2"));
    let err = Dataset::merge(&[a, b]).expect_err("attribution changes");
    let text = err.to_string();
    assert!(
        text.contains("101 Hz") && text.contains("mode q1") && text.contains("to q2"),
        "{text}"
    );
}

#[test]
fn a_folder_given_twice_is_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("r1");
    load("lab/r1", MANIFEST).write(&dir).expect("write");
    let a = Dataset::load(&dir).expect("read");
    let err = Dataset::merge(&[a.clone(), a]).expect_err("twice");
    assert!(
        matches!(err, DatasetError::MergeTwice { .. }) && err.to_string().contains("given twice"),
        "{err}"
    );
}

/// Rounds simulated on one device have the same modes and equations but their own forces: the
/// merged truth keeps the device and every round's forces under the merged names.
#[test]
fn truths_of_one_device_are_merged_with_every_rounds_forces() {
    let force = |a: f64| {
        BTreeMap::from([(
            "q1".to_string(),
            TruthForce {
                amplitude: vec![a],
                phase_rad: vec![0.0],
            },
        )])
    };
    let truth = |a: f64| Truth {
        modes: BTreeMap::from([(
            "q1".to_string(),
            TruthMode {
                f_hz: 100.0,
                q: 1e3,
            },
        )]),
        forces: BTreeMap::from([("single".to_string(), force(a))]),
        ..Truth::default()
    };
    let mut a = load("lab/r1", MANIFEST);
    let mut b = load("lab/r2", MANIFEST);
    a.truth = Some(truth(1.0));
    b.truth = Some(truth(2.0));
    let m = Dataset::merge(&[a.clone(), b.clone()]).expect("merge");
    let t = m.truth.as_ref().expect("kept");
    assert_eq!(t.forces["r1_single"]["q1"].amplitude, [1.0]);
    assert_eq!(t.forces["r2_single"]["q1"].amplitude, [2.0]);
    b.truth
        .as_mut()
        .expect("truth")
        .modes
        .get_mut("q1")
        .expect("q1")
        .q = 2e3;
    let m = Dataset::merge(&[a, b]).expect("merge");
    assert!(m.truth.is_none());
}

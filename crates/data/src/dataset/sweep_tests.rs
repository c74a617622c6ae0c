//! Stepped sweeps: reading with settling, writing back, and refusing broken ones.

use super::*;

const MANIFEST: &str = r#"
format = "harmonid-dataset/1"
displacement_unit = "nm"
[[sweep]]
name = "up"
direction = "up"
drives_hz = [[100.0], [101.0], [102.0]]
drive_levels_v = [[0.1], [0.2], [0.3]]
drive_phases_rad = [0.0]
settle_s = 0.25
"#;

/// Three steps, five samples each at 0.1 s spacing; sample `j` of step `k` is `(k, j)` nm, so
/// which survived settling is visible in the values.
fn sweep_csv(with_time: bool) -> String {
    let mut s = String::from(if with_time {
        "step,shot,time_s,freq_hz,re,im\n"
    } else {
        "step,shot,freq_hz,re,im\n"
    });
    for k in 0..3 {
        for j in 0..5 {
            let f = 100.0 + k as f64;
            if with_time {
                s.push_str(&format!("{k},{j},{},{f},{k},{j}\n", 0.1 * j as f64));
            } else {
                s.push_str(&format!("{k},{j},{f},{k},{j}\n"));
            }
        }
    }
    s
}

fn load(manifest: &str, csv: &str) -> Result<Dataset, DatasetError> {
    Dataset::from_readers(Path::new("d"), manifest, None, |_| Ok(csv.as_bytes()))
}

#[test]
fn settling_by_time_drops_the_early_samples_and_says_so_once() {
    let ds = load(MANIFEST, &sweep_csv(true)).expect("sweep");
    assert_eq!(ds.measurements.len(), 3);
    for (k, m) in ds.measurements.iter().enumerate() {
        assert_eq!(m.spec.name, format!("up[{k}]"));
        assert_eq!(
            m.spec.sweep,
            Some(SweepStep {
                sweep: "up".into(),
                step: k
            })
        );
        assert_eq!(m.spec.drives_hz, vec![100.0 + k as f64]);
        assert_eq!(m.spec.drive_levels_v, Some(vec![[0.1, 0.2, 0.3][k]]));
        assert_eq!(m.spec.drive_phases_rad, Some(vec![0.0]));
        // time 0, 0.1, 0.2 dropped: samples 3 and 4 kept, renumbered 0 and 1.
        assert_eq!(m.n_shots, 2);
        assert_eq!(m.amplitude(0, 0, 0), Complex64::new(k as f64, 3.0) * 1e-9);
        assert_eq!(m.amplitude(1, 0, 0), Complex64::new(k as f64, 4.0) * 1e-9);
    }
    assert_eq!(
        ds.notes,
        vec![
            "sweep \"up\": 3 steps (up); 9 of 15 samples dropped as settling (time_s < 0.25 s)"
                .to_string()
        ]
    );
    assert_eq!(
        ds.input_files(),
        vec![Path::new("d/dataset.toml"), Path::new("d/up.csv")]
    );
}

#[test]
fn settling_by_count_drops_the_first_samples_of_each_step() {
    let manifest = MANIFEST.replace("settle_s = 0.25", "settle_samples = 4");
    let ds = load(&manifest, &sweep_csv(false)).expect("sweep");
    assert!(ds.measurements.iter().all(|m| m.n_shots == 1));
    assert_eq!(
        ds.measurements[2].amplitude(0, 0, 0),
        Complex64::new(2.0, 4.0) * 1e-9
    );
    assert!(ds.notes[0].contains("12 of 15 samples dropped as settling (the first 4 of each step)"));
}

#[test]
fn a_sweep_written_and_read_back_is_the_same_settled_sweep() {
    let ds = load(MANIFEST, &sweep_csv(true)).expect("sweep");
    let out = tempfile::tempdir().expect("tempdir");
    let dir = out.path().join("copy");
    ds.write(&dir).expect("write");
    let text = std::fs::read_to_string(dir.join("dataset.toml")).expect("manifest");
    assert!(!text.contains("settle"), "settling already applied: {text}");
    assert!(!text.contains("[[measurement]]"), "{text}");
    let back = Dataset::load(&dir).expect("read back");
    assert_eq!(back.measurements, ds.measurements);
    assert_eq!(back.manifest.sweeps[0].direction, Direction::Up);
    assert_eq!(
        back.manifest.sweeps[0].drive_phases_rad,
        Some(PerStep::Same(vec![0.0]))
    );
    assert!(
        back.notes.is_empty(),
        "nothing dropped, nothing said: {:?}",
        back.notes
    );
}

#[test]
fn a_subset_of_steps_keeps_its_sweep_and_an_empty_sweep_is_dropped() {
    let ds = load(MANIFEST, &sweep_csv(true)).expect("sweep");
    let odd: Vec<Measurement> = ds
        .measurements
        .iter()
        .filter(|m| m.spec.name != "up[1]")
        .cloned()
        .collect();
    let sub = Dataset::from_parts("sub", ds.manifest.clone(), odd, None).expect("subset");
    assert_eq!(
        sub.manifest.sweeps[0].drives_hz,
        vec![vec![100.0], vec![102.0]]
    );
    let mut other = ds.manifest.clone();
    other
        .sweeps
        .push(SweepSpec::new("down", Direction::Down, vec![vec![5.0]]));
    let same = Dataset::from_parts("sub", other, ds.measurements.clone(), None).expect("drop");
    assert_eq!(same.manifest.sweeps.len(), 1);
}

#[test]
fn broken_sweeps_are_refused_with_what_to_do() {
    let cases: Vec<(String, String, &str)> = vec![
        (
            MANIFEST.replace("direction = \"up\"", "direction = \"down\""),
            sweep_csv(true),
            "step 1 is at 101 Hz after step 0 at 100 Hz",
        ),
        (
            MANIFEST.replace(
                "drives_hz = [[100.0], [101.0], [102.0]]\ndrive_levels_v = [[0.1], [0.2], [0.3]]",
                "drives_hz = [[100.0]]\ndrive_levels_v = [0.1]",
            ),
            sweep_csv(true),
            "sweep \"up\" is declared direction = \"up\" but has 1 step: a sweep up or down needs at least two steps",
        ),
        (
            MANIFEST.to_string(),
            sweep_csv(false),
            "settle_s = 0.25 needs a time_s column",
        ),
        (
            MANIFEST.replace("settle_s = 0.25", "settle_s = 9"),
            sweep_csv(true),
            "no sample is later than settle_s",
        ),
        (
            MANIFEST.replace("settle_s = 0.25", "settle_samples = 5"),
            sweep_csv(false),
            "settle_samples = 5 drops all 5 samples",
        ),
        (
            MANIFEST.replace("[[0.1], [0.2], [0.3]]", "[[0.1], [0.2]]"),
            sweep_csv(true),
            "drive_levels_v lists 2 steps but drives_hz lists 3",
        ),
        (
            MANIFEST
                .replace("[[100.0], [101.0], [102.0]]", "[[100.0], [101.0]]")
                .replace("[[0.1], [0.2], [0.3]]", "[0.1]"),
            sweep_csv(true),
            "\"2\" is not a step of this sweep (0 to 1",
        ),
        (
            MANIFEST.replace("settle_s = 0.25", "settle_s = 0.25\nsettle_samples = 1"),
            sweep_csv(true),
            "settle_s or settle_samples, not both",
        ),
        (
            MANIFEST.replace("direction = \"up\"\n", ""),
            sweep_csv(true),
            "direction",
        ),
        (
            format!("{MANIFEST}[[measurement]]\nname = \"up\"\ndrives_hz = [100.0]\n"),
            sweep_csv(true),
            "names must be unique",
        ),
    ];
    for (manifest, csv, says) in cases {
        let e = load(&manifest, &csv).expect_err(says).to_string();
        assert!(e.contains(says), "{says}: {e}");
    }
}

/// A drive ladder: three steps at the same tone, the level rising.
fn ladder(levels: &str) -> String {
    format!(
        "format = \"harmonid-dataset/1\"\n[[sweep]]\nname = \"ramp\"\ndirection = \"level\"\ndrives_hz = [[100.0], [100.0], [100.0]]\ndrive_levels_v = {levels}\ndrive_phases_rad = [0.0]\n"
    )
}

fn ladder_csv() -> String {
    let mut s = String::from("step,shot,freq_hz,re,im\n");
    for k in 0..3 {
        s.push_str(&format!("{k},0,100.0,{k},1\n"));
    }
    s
}

#[test]
fn a_drive_ladder_reads_as_steps_and_writes_back_as_a_ladder() {
    let ds = load(&ladder("[[0.1], [0.2], [0.4]]"), &ladder_csv()).expect("ladder");
    assert_eq!(ds.measurements.len(), 3);
    assert_eq!(ds.measurements[2].spec.name, "ramp[2]");
    assert_eq!(ds.measurements[2].spec.drive_levels_v, Some(vec![0.4]));
    let out = tempfile::tempdir().expect("tempdir");
    ds.write(out.path().join("copy")).expect("write");
    let back = Dataset::load(out.path().join("copy")).expect("read back");
    assert_eq!(back.manifest.sweeps[0].direction, Direction::Level);
    assert_eq!(back.measurements, ds.measurements);
}

#[test]
fn a_drive_ladder_with_other_tones_or_a_falling_level_is_refused() {
    let moved =
        ladder("[0.1]").replace("[[100.0], [100.0], [100.0]]", "[[100.0], [100.5], [100.0]]");
    let e = load(&moved, &ladder_csv()).expect_err("moved").to_string();
    assert!(
        e.contains("step 1's tones [100.5] Hz differ from step 0's [100.0] Hz"),
        "{e}"
    );
    let falling = ladder("[[0.1], [0.3], [0.2]]");
    let e = load(&falling, &ladder_csv())
        .expect_err("falling")
        .to_string();
    assert!(
        e.contains("step 2's drive levels [0.2] are below step 1's [0.3]"),
        "{e}"
    );
}

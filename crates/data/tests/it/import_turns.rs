//! A sweep that turns back (up then down at one level, as a lab records hysteresis) becomes an
//! up and a down sweep in every importer: table (text and MATLAB), zi-csv, zi-hdf5, zi-sweeper
//! (bidirectional mode) and moku-csv. Each input holds the same five frequencies up then down,
//! the response of the step `k` a known number, so the two legs are checked value by value.

use crate::fixtures::{conv, write, zi_csv_record};
use harmonid_data::import::{moku_csv, zi_csv, zi_hdf5, zi_sweeper, Settle};
use harmonid_data::{Dataset, Direction};
use num_complex::Complex64;
use std::fmt::Write as _;
use std::path::Path;

/// Up 100..104 Hz, then down 103..100 Hz (the turning point is measured once).
const DRIVES: [f64; 9] = [
    100.0, 101.0, 102.0, 103.0, 104.0, 103.0, 102.0, 101.0, 100.0,
];

/// The file's value (RMS volts, x + iy) at step `k`: the down leg differs from the up leg at
/// the same frequency (another branch).
fn value(k: usize) -> Complex64 {
    Complex64::new(1e-3 * (k + 1) as f64, -2e-4 * (k * k) as f64)
}

/// `ds` has exactly the sweeps `<base>_up` (steps 0..5) and `<base>_down` (steps 5..9), each
/// step's first sample √2 times [`value`].
fn assert_up_and_down(ds: &Dataset, base: &str, what: &str) {
    let names: Vec<&str> = ds.manifest.sweeps.iter().map(|s| s.name.as_str()).collect();
    let (up, down) = (format!("{base}_up"), format!("{base}_down"));
    assert_eq!(names, [up.as_str(), down.as_str()], "{what}");
    assert_eq!(ds.manifest.sweeps[0].direction, Direction::Up, "{what}");
    assert_eq!(ds.manifest.sweeps[1].direction, Direction::Down, "{what}");
    assert_eq!(ds.measurements.len(), DRIVES.len(), "{what}");
    for (k, m) in ds.measurements.iter().enumerate() {
        assert_eq!(m.spec.drives_hz, vec![DRIVES[k]], "{what} step {k}");
        let want = value(k) * std::f64::consts::SQRT_2;
        let got = m.amplitude(0, 0, 0);
        assert!(
            (got - want).norm() <= 1e-12 * want.norm(),
            "{what} step {k}: {got} vs {want}"
        );
    }
}

#[test]
fn zi_csv_and_moku_csv_split_a_sweep_that_turns_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = zi_csv_record(&DRIVES, value);
    let p = write(dir.path(), "dev1_demods_0_sample_00000.csv", &s);
    let opts = zi_csv::Options {
        clockbase_hz: 60.0,
        drive_level: Some(0.1),
        drive_phase_rad: None,
    };
    let (ds, _) =
        zi_csv::import(&[p], &conv(), Settle::default(), &opts, Path::new("o")).expect("zi-csv");
    assert_up_and_down(&ds, "sweep", "zi-csv");

    let mut files = Vec::new();
    for (k, &f) in DRIVES.iter().enumerate() {
        let z = value(k);
        let text = format!(
            "% Moku:Go Lock-in Amplifier\n% Demodulation frequency {f} Hz\n% Time (s), Channel 1 (V), Channel 2 (V)\n0.0, {:e}, {:e}\n",
            z.re, z.im
        );
        files.push(write(dir.path(), &format!("step{k}.csv"), &text));
    }
    let opts = moku_csv::Options {
        channels: moku_csv::Channels::XY,
        output_gain: 1.0,
        output_offset_v: 0.0,
        phase_unit: None,
        demod_hz: Vec::new(),
        drive_level: None,
    };
    let (ds, _) = moku_csv::import(&files, &conv(), Settle::default(), &opts, Path::new("o"))
        .expect("moku-csv");
    assert_up_and_down(&ds, "sweep", "moku-csv");
}

#[test]
fn zi_sweeper_bidirectional_is_an_up_and_a_down_sweep() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = String::from("grid;x;y;xstddev;ystddev;count\n");
    for (k, &f) in DRIVES.iter().enumerate() {
        let z = value(k);
        let _ = writeln!(s, "{f:?};{:e};{:e};1e-6;1e-6;100", z.re, z.im);
    }
    let p = write(dir.path(), "sweep_demod0.csv", &s);
    let opts = zi_sweeper::Options {
        drive_level: Some(0.1),
        ..Default::default()
    };
    let (ds, _) = zi_sweeper::import(&[p], &conv(), &opts, Path::new("o")).expect("sweeper");
    assert_up_and_down(&ds, "sweep", "zi-sweeper");
}

#[test]
fn zi_hdf5_splits_a_record_that_turns_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("rec.h5");
    let mut b = hdf5_pure::FileBuilder::new();
    let mut rec = b.create_group("000");
    let mut d = rec.create_group("dev4955");
    let mut demods = d.create_group("demods");
    let mut g = demods.create_group("0");
    let mut sample = g.create_group("sample");
    let ts: Vec<u64> = (0..DRIVES.len() as u64).map(|k| 1000 + 60 * k).collect();
    let zs: Vec<Complex64> = (0..DRIVES.len()).map(value).collect();
    sample.create_dataset("timestamp").with_u64_data(&ts);
    sample
        .create_dataset("x")
        .with_f64_data(&zs.iter().map(|z| z.re).collect::<Vec<_>>());
    sample
        .create_dataset("y")
        .with_f64_data(&zs.iter().map(|z| z.im).collect::<Vec<_>>());
    sample.create_dataset("frequency").with_f64_data(&DRIVES);
    g.add_group(sample.finish());
    demods.add_group(g.finish());
    d.add_group(demods.finish());
    rec.add_group(d.finish());
    b.add_group(rec.finish());
    b.write(&path).expect("write h5");
    let opts = zi_hdf5::Options {
        clockbase_hz: 60.0,
        demods: Vec::new(),
        drive_level: None,
    };
    let (ds, _) = zi_hdf5::import(&[path], &conv(), Settle::default(), &opts, Path::new("o"))
        .expect("zi-hdf5");
    assert_up_and_down(&ds, "000_dev4955", "zi-hdf5");
}

#[test]
fn table_text_splits_and_holdout_takes_the_file_name() {
    use harmonid_data::import::table;
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = String::from("# f X Y\n");
    for (k, &f) in DRIVES.iter().enumerate() {
        let z = value(k);
        let _ = writeln!(s, "{f:?} {:e} {:e}", z.re, z.im);
    }
    let p = write(dir.path(), "Measurements_A=0.32%.txt", &s);
    let map = write(
        dir.path(),
        "map.toml",
        "[columns]\nfreq_hz = 1\nx = 2\ny = 3\n[conventions]\namplitude = \"rms\"\nquadrature = \"x+iy\"\ndisplacement_unit = \"V\"\n",
    );
    let mapping = table::Mapping::load(&map).expect("mapping");
    let (ds, _) = table::import(&[p], &mapping, Path::new("o")).expect("table");
    assert_up_and_down(&ds, "Measurements_A=0.32%", "table");
    for sw in &ds.manifest.sweeps {
        assert_eq!(sw.source.as_deref(), Some("Measurements_A=0.32%.txt"));
    }
    // --holdout by the file (with or without its folder), by the readable name, by a leg.
    let both = ["Measurements_A=0.32%_up", "Measurements_A=0.32%_down"].map(String::from);
    let held = |g: &str| ds.resolve_names(&[g.to_string()]);
    assert_eq!(held("Measurements_A=0.32%.txt"), both);
    assert_eq!(held("../lab/Measurements_A=0.32%.txt"), both);
    assert_eq!(held("Measurements_A=0.32%"), both);
    assert_eq!(held("Measurements_A=0.32%_up"), [both[0].clone()]);
    assert_eq!(held("nothing"), ["nothing"]);
    // Written and read back, the source stays.
    let out = dir.path().join("ds");
    ds.write(&out).expect("write");
    let back = Dataset::load(&out).expect("read back");
    assert_eq!(
        back.manifest.sweeps[1].source.as_deref(),
        Some("Measurements_A=0.32%.txt")
    );
    assert!(out.join("Measurements_A=0.32%_down.csv").exists());
}

/// Two sweeper files on the same frequencies (two drive levels given together, the natural
/// first try with a 12-level measurement) are refused naming the second file and `merge`,
/// not read as two demodulators ("an averaged step is one sample" before).
#[test]
fn zi_sweeper_files_of_two_levels_are_refused_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut paths = Vec::new();
    for (n, scale) in [("level_a.csv", 1.0), ("level_b.csv", 2.0)] {
        let mut s = String::from("grid;x;y;xstddev;ystddev;count;frequency\n");
        for (k, &f) in DRIVES.iter().enumerate() {
            let z = value(k) * scale;
            let _ = writeln!(s, "{f:?};{:e};{:e};1e-6;1e-6;100;{f:?}", z.re, z.im);
        }
        paths.push(write(dir.path(), n, &s));
    }
    let opts = zi_sweeper::Options::default();
    let err = match zi_sweeper::import(&paths, &conv(), &opts, Path::new("o")) {
        Ok(_) => panic!("two levels' files read as two demodulators"),
        Err(e) => e.to_string(),
    };
    for want in [
        "level_b.csv",
        "same frequencies",
        "level_a.csv",
        "100 Hz",
        "harmonid merge",
    ] {
        assert!(err.contains(want), "{want} missing: {err}");
    }
}

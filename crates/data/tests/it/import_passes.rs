//! Sweeps of several passes (up, down, up, … in one file: a LabOne sweeper in bidirectional
//! mode with several loops, or a hand-made table) become one ordered sweep per pass; rows where
//! nothing was measured (a LabOne sweep stopped early writes its grid to the end, NaN) are
//! dropped at a sweep's end with a warning, refused inside one unless asked. Small in-memory
//! files; every value checked.

use crate::fixtures::{conv, write, zi_csv_record};
use harmonid_data::import::{table, zi_csv, zi_sweeper, Settle};
use harmonid_data::{Dataset, Direction};
use num_complex::Complex64;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The file's value (RMS volts) at row `k`: distinct per row, so each pass is checked by value.
fn value(k: usize) -> Complex64 {
    Complex64::new(1e-3 * (k + 1) as f64, -1e-4 * (k * k) as f64)
}

/// Up 100..103, down 102..100, up 101..103: three passes.
const THREE: [f64; 10] = [
    100.0, 101.0, 102.0, 103.0, 102.0, 101.0, 100.0, 101.0, 102.0, 103.0,
];

/// The sweeps of `ds` by name, direction and steps, and every step's drive and first value
/// against `drives` and [`value`] (row k of the file is step k of the dataset).
fn assert_passes(ds: &Dataset, want: &[(&str, Direction, usize)], drives: &[f64]) {
    let got: Vec<(&str, Direction, usize)> = ds
        .manifest
        .sweeps
        .iter()
        .map(|s| (s.name.as_str(), s.direction, s.drives_hz.len()))
        .collect();
    assert_eq!(got, want);
    assert_eq!(ds.measurements.len(), drives.len());
    for (k, m) in ds.measurements.iter().enumerate() {
        assert_eq!(m.spec.drives_hz, vec![drives[k]], "step {k}");
        let want = value(k) * std::f64::consts::SQRT_2;
        assert!(
            (m.amplitude(0, 0, 0) - want).norm() <= 1e-12 * want.norm(),
            "step {k}"
        );
    }
}

fn table_text(drives: &[f64], level: Option<&[f64]>) -> String {
    let mut s = String::from("# f X Y level\n");
    for (k, &f) in drives.iter().enumerate() {
        let z = value(k);
        let l = level.map_or(0.1, |l| l[k]);
        let _ = writeln!(s, "{f:?} {:e} {:e} {l}", z.re, z.im);
    }
    s
}

const MAP: &str = "[columns]\nfreq_hz = 1\nx = 2\ny = 3\ndrive_level = 4\n[conventions]\namplitude = \"rms\"\nquadrature = \"x+iy\"\ndisplacement_unit = \"V\"\n";

fn import_table(
    dir: &Path,
    name: &str,
    text: &str,
    map: &str,
) -> Result<(Dataset, String), String> {
    let p = write(dir, name, text);
    let m = write(dir, "map.toml", map);
    let mapping = table::Mapping::load(&m).map_err(|e| e.to_string())?;
    table::import(&[p], &mapping, Path::new("o")).map_err(|e| e.to_string())
}

#[test]
fn table_three_passes_and_two_loops_per_level() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (ds, note) =
        import_table(dir.path(), "hyst.txt", &table_text(&THREE, None), MAP).expect("three passes");
    use Direction::{Down, Up};
    assert_passes(
        &ds,
        &[
            ("level_0.1_up", Up, 4),
            ("level_0.1_down", Down, 3),
            ("level_0.1_up_2", Up, 3),
        ],
        &THREE,
    );
    assert!(
        note.contains(
            "level_0.1 turned back: 3 passes (level_0.1_up, level_0.1_down, level_0.1_up_2)"
        ),
        "{note}"
    );
    // Two levels, each two loops (four passes): cut by level, then by pass.
    let loops = [
        100.0, 101.0, 102.0, 101.0, 100.0, 101.0, 102.0, 101.0, 100.0,
    ];
    let drives: Vec<f64> = loops.iter().chain(&loops).copied().collect();
    let levels: Vec<f64> = (0..18).map(|k| if k < 9 { 0.1 } else { 0.2 }).collect();
    let (ds, note) = import_table(
        dir.path(),
        "loops.txt",
        &table_text(&drives, Some(&levels)),
        MAP,
    )
    .expect("loops");
    let mut want = Vec::new();
    for l in ["level_0.1", "level_0.2"] {
        for (s, d, n) in [
            ("_up", Up, 3),
            ("_down", Down, 2),
            ("_up_2", Up, 2),
            ("_down_2", Down, 2),
        ] {
            want.push((format!("{l}{s}"), d, n));
        }
    }
    let want: Vec<(&str, Direction, usize)> =
        want.iter().map(|(s, d, n)| (s.as_str(), *d, *n)).collect();
    assert_passes(&ds, &want, &drives);
    assert!(note.contains("2 sweeps turned back: 8 passes"), "{note}");
}

/// Without a level column, three passes may be levels merged: refused, naming the sweep and
/// both ways out; a level given for the file accepts them.
#[test]
fn table_passes_without_a_level_are_refused_unless_one_level_is_given() {
    let dir = tempfile::tempdir().expect("tempdir");
    let map = MAP.replace("drive_level = 4\n", "");
    let e = import_table(dir.path(), "hyst.txt", &table_text(&THREE, None), &map)
        .expect_err("no level");
    for want in [
        "hyst.txt",
        "sweep \"hyst\" turns back 2 times (3 passes",
        "drive_level",
        "[drive] level",
    ] {
        assert!(e.contains(want), "{want} missing: {e}");
    }
    let (ds, _) = import_table(
        dir.path(),
        "hyst.txt",
        &table_text(&THREE, None),
        &format!("{map}[drive]\nlevel = 0.1\n"),
    )
    .expect("one level");
    let names: Vec<&str> = ds.manifest.sweeps.iter().map(|s| s.name.as_str()).collect();
    // A single file cut by level is named by it.
    assert_eq!(names, ["level_0.1_up", "level_0.1_down", "level_0.1_up_2"]);
    // One turn without a level imports as before.
    let (ds, _) = import_table(dir.path(), "hyst.txt", &table_text(&THREE[..7], None), &map)
        .expect("one turn");
    let names: Vec<&str> = ds.manifest.sweeps.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["hyst_up", "hyst_down"]);
}

/// A LabOne demodulator record through the generic path: three passes.
#[test]
fn zi_csv_three_passes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = zi_csv_record(&THREE, value);
    let p = write(dir.path(), "dev1_demods_0_sample_00000.csv", &s);
    let opts = zi_csv::Options {
        clockbase_hz: 60.0,
        drive_level: None,
        drive_phase_rad: None,
    };
    let (ds, note) =
        zi_csv::import(&[p], &conv(), Settle::default(), &opts, Path::new("o")).expect("zi-csv");
    use Direction::{Down, Up};
    assert_passes(
        &ds,
        &[
            ("sweep_up", Up, 4),
            ("sweep_down", Down, 3),
            ("sweep_up_2", Up, 3),
        ],
        &THREE,
    );
    assert!(note.contains("sweep turned back: 3 passes"), "{note}");
}

/// A sweeper CSV of `drives`, rows `nan` (0-based) written as a stopped sweeper writes them.
fn sweeper(dir: &Path, drives: &[f64], nan: &[usize]) -> PathBuf {
    let mut s = String::from("grid;x;y;xstddev;ystddev;count\n");
    for (k, &f) in drives.iter().enumerate() {
        if nan.contains(&k) {
            let _ = writeln!(s, "{f:?};nan;NaN;nan;nan;0");
        } else {
            let z = value(k);
            let _ = writeln!(s, "{f:?};{:e};{:e};1e-6;1e-6;100", z.re, z.im);
        }
    }
    write(dir, "sweep_demod0.csv", &s)
}

fn import_sweeper(p: PathBuf, drop_nan_rows: bool) -> Result<(Dataset, String), String> {
    let opts = zi_sweeper::Options {
        drive_level: Some(0.1),
        drop_nan_rows,
    };
    zi_sweeper::import(&[p], &conv(), &opts, Path::new("o")).map_err(|e| e.to_string())
}

#[test]
fn zi_sweeper_two_loops_are_four_passes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let loops = [
        100.0, 101.0, 102.0, 101.0, 100.0, 101.0, 102.0, 101.0, 100.0,
    ];
    let (ds, note) = import_sweeper(sweeper(dir.path(), &loops, &[]), false).expect("loops");
    use Direction::{Down, Up};
    assert_passes(
        &ds,
        &[
            ("sweep_up", Up, 3),
            ("sweep_down", Down, 2),
            ("sweep_up_2", Up, 2),
            ("sweep_down_2", Down, 2),
        ],
        &loops,
    );
    assert!(
        note.contains("4 passes (sweep_up, sweep_down, sweep_up_2, sweep_down_2)"),
        "{note}"
    );
    // Stopped in the second pass up: the warning names it as the dataset does.
    let (ds, _) = import_sweeper(sweeper(dir.path(), &loops, &[7, 8]), false).expect("stopped");
    assert!(
        ds.notes[0]
            .contains("rows 9 to 10) at the end of the sweep (it stopped in \"sweep_up_2\")"),
        "{:?}",
        ds.notes
    );
}

/// A bidirectional sweep stopped in its down pass: the rest of the grid NaN is dropped with one
/// warning naming the file, the sweep and the rows; nothing NaN in the dataset.
#[test]
fn zi_sweeper_stopped_early_drops_its_tail_with_a_warning() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bidir = [100.0, 101.0, 102.0, 103.0, 102.0, 101.0, 100.0];
    let (ds, _) = import_sweeper(sweeper(dir.path(), &bidir, &[5, 6]), false).expect("stopped");
    use Direction::Up;
    // The down pass keeps one step: no direction.
    assert_passes(
        &ds,
        &[("sweep_up", Up, 4), ("sweep_down", Direction::Unordered, 1)],
        &bidir[..5],
    );
    assert_eq!(ds.notes.len(), 1, "{:?}", ds.notes);
    let w = &ds.notes[0];
    for want in [
        "sweep_demod0.csv",
        "2 rows (rows 7 to 8)",
        "at the end of the sweep (it stopped in \"sweep_down\")",
        "dropped",
    ] {
        assert!(w.contains(want), "{want} missing: {w}");
    }
    for m in &ds.measurements {
        assert!(m.amplitude(0, 0, 0).norm().is_finite());
    }
    // Stopped in the up pass: the down pass never reached is left out, in the same warning.
    let (ds, _) =
        import_sweeper(sweeper(dir.path(), &bidir, &[3, 4, 5, 6]), false).expect("stopped");
    assert_passes(&ds, &[("sweep_up", Up, 3)], &bidir[..3]);
    assert_eq!(ds.notes.len(), 1, "{:?}", ds.notes);
    assert!(
        ds.notes[0]
            .contains("4 rows (rows 5 to 8) at the end of the sweep (it stopped in \"sweep_up\")"),
        "{:?}",
        ds.notes
    );
    // A point missing at the end of a pass inside the sweep is a gap, not its end.
    let e = import_sweeper(sweeper(dir.path(), &bidir, &[3]), false).expect_err("gap at the turn");
    assert!(e.contains("row 5") && e.contains("inside sweep"), "{e}");
    // Nothing measured at all: refused.
    let e = import_sweeper(sweeper(dir.path(), &bidir, &[0, 1, 2, 3, 4, 5, 6]), false)
        .expect_err("all NaN");
    assert!(
        e.contains("no measured row: all 7 rows have every value NaN"),
        "{e}"
    );
}

/// A NaN point between measured ones is refused with its row and the option to pass; with the
/// option it is dropped with a warning. A row with only x NaN is refused either way.
#[test]
fn nan_inside_a_sweep_is_refused_unless_asked() {
    let dir = tempfile::tempdir().expect("tempdir");
    let up = [100.0, 101.0, 102.0, 103.0, 104.0];
    let e = import_sweeper(sweeper(dir.path(), &up, &[2]), false).expect_err("gap");
    for want in [
        "sweep_demod0.csv, row 4",
        "inside sweep \"sweep\"",
        "--drop-nan-rows",
        "drop_nan_rows = true",
    ] {
        assert!(e.contains(want), "{want} missing: {e}");
    }
    let e = import_sweeper(sweeper(dir.path(), &up, &[0]), false).expect_err("leading");
    assert!(
        e.contains("row 2") && e.contains("before the first measured row"),
        "{e}"
    );
    let (ds, _) = import_sweeper(sweeper(dir.path(), &up, &[2]), true).expect("dropped");
    let fs: Vec<f64> = ds.manifest.sweeps[0]
        .drives_hz
        .iter()
        .map(|d| d[0])
        .collect();
    assert_eq!(fs, [100.0, 101.0, 103.0, 104.0]);
    assert_eq!(ds.manifest.sweeps[0].direction, Direction::Up);
    assert!(
        ds.notes[0].contains("1 row (row 4) inside sweep \"sweep\"")
            && ds.notes[0].contains("--drop-nan-rows"),
        "{:?}",
        ds.notes
    );
    // Table: a level's tail of NaN rows before the next level is its end; a gap inside
    // needs the mapping's drop_nan_rows; a row with x NaN but y measured is refused.
    let mut s = String::from("f x y level\n");
    for (l, nan) in [(0.1, [false, false, true]), (0.2, [false, true, false])] {
        for (k, f) in [100.0, 101.0, 102.0].iter().enumerate() {
            let v = if nan[k] {
                "NaN NaN".to_string()
            } else {
                format!("{} 1e-4", 1e-3 * (k + 1) as f64)
            };
            let _ = writeln!(s, "{f} {v} {l}");
        }
    }
    let map = MAP
        .replace("= 1\n", "= \"f\"\n")
        .replace("= 2\n", "= \"x\"\n")
        .replace("= 3\n", "= \"y\"\n")
        .replace("= 4\n", "= \"level\"\n");
    let e = import_table(dir.path(), "levels.txt", &s, &map).expect_err("gap in level 0.2");
    assert!(
        e.contains("levels.txt, row 6") && e.contains("inside sweep \"level_0.2\""),
        "{e}"
    );
    let (ds, _) = import_table(
        dir.path(),
        "levels.txt",
        &s,
        &format!("drop_nan_rows = true\n{map}"),
    )
    .expect("dropped");
    let steps: Vec<usize> = ds
        .manifest
        .sweeps
        .iter()
        .map(|s| s.drives_hz.len())
        .collect();
    assert_eq!(steps, [2, 2]);
    assert_eq!(ds.notes.len(), 2, "{:?}", ds.notes);
    assert!(
        ds.notes[0].contains("1 row (row 4) at the end of sweep \"level_0.1\""),
        "{:?}",
        ds.notes
    );
    let partial = s.replace("NaN NaN 0.1", "NaN 1e-4 0.1");
    let e = import_table(
        dir.path(),
        "levels.txt",
        &partial,
        &format!("drop_nan_rows = true\n{map}"),
    )
    .expect_err("x NaN only");
    assert!(e.contains("row 4") && e.contains("not finite"), "{e}");
}

//! Reading, writing and refusing datasets.

use super::*;

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).expect("write test file");
}

const MANIFEST: &str = r#"
format = "harmonid-dataset/1"
description = "test"
displacement_unit = "nm"
[[point]]
name = "p0"
shape = { q1 = 0.5 }
[nominal_hz]
q1 = 1000.0
[[measurement]]
name = "m1"
drives_hz = [990.0, 1010.0]
drive_levels_v = [1.0, 1.0]
drive_phases_rad = [0.0, 0.5]
"#;

fn good_dir() -> tempfile::TempDir {
    let d = tempfile::tempdir().expect("tempdir");
    write(d.path(), "dataset.toml", MANIFEST);
    write(
        d.path(),
        "m1.csv",
        "shot,freq_hz,re,im,extra\n0,970,1,2,x\n0,990,3,4,x\n0,1010,5,6,x\n1,1010,7,8,x\n1,990,9,10,x\n1,970,11,12,x\n",
    );
    d
}

#[test]
fn reads_and_converts_units() {
    let d = good_dir();
    let ds = Dataset::load(d.path()).expect("load");
    let m = &ds.measurements[0];
    assert_eq!(m.freqs_hz, vec![970.0, 990.0, 1010.0]);
    assert_eq!(m.n_shots, 2);
    assert_eq!(m.points, vec![0]);
    assert!((m.amplitude(0, 1, 0) - Complex64::new(3e-9, 4e-9)).norm() < 1e-22);
    assert!((m.amplitude(1, 0, 0) - Complex64::new(11e-9, 12e-9)).norm() < 1e-22);
    assert_eq!(m.freq_index(1010.0), Some(2));
    assert!(ds.truth.is_none());
    assert!(ds.check_modes(&["q1", "q2"]).is_ok());
    let e = ds.check_modes(&["x1"]).expect_err("unknown mode");
    assert!(e.to_string().contains("\"q1\" is not declared"), "{e}");
}

#[test]
fn write_then_read_round_trips() {
    let d = good_dir();
    let mut ds = Dataset::load(d.path()).expect("load");
    ds.truth = Some(Truth {
        noise: Some(TruthNoise {
            sigma_per_quadrature: 0.1,
            shots: Some(2),
        }),
        ..Truth::default()
    });
    let out = tempfile::tempdir().expect("tempdir");
    let target = out.path().join("copy");
    ds.write(&target).expect("write");
    // Overwrite works too.
    ds.write(&target).expect("rewrite");
    let back = Dataset::load(&target).expect("load back");
    assert_eq!(back.manifest, ds.manifest);
    assert_eq!(back.truth, ds.truth);
    let (a, b) = (&back.measurements[0], &ds.measurements[0]);
    assert_eq!(a.freqs_hz, b.freqs_hz);
    for (x, y) in a.data.iter().zip(&b.data) {
        assert!((x - y).norm() <= 1e-15 * y.norm(), "{x} vs {y}");
    }
    // No temporary folders are left behind.
    let n = std::fs::read_dir(out.path()).expect("read_dir").count();
    assert_eq!(n, 1);
}

fn expect_err(csv: &str, needle: &str) {
    let d = tempfile::tempdir().expect("tempdir");
    write(d.path(), "dataset.toml", MANIFEST);
    write(d.path(), "m1.csv", csv);
    let e = Dataset::load(d.path()).expect_err("should fail");
    let s = e.to_string();
    assert!(s.contains("m1.csv"), "no file name in: {s}");
    assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
}

#[test]
fn bad_csv_inputs_are_located() {
    expect_err("shot,freq_hz,re\n0,990,1\n", "missing column \"im\"");
    expect_err("shot,freq_hz,re,im\n0,990,1,2\n0,1010,1\n", "row 3");
    expect_err("shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2,3\n", "row 3");
    expect_err("shot,freq_hz,re,im\n0,990,NaN,2\n0,1010,1,2\n", "row 2");
    expect_err(
        "shot,freq_hz,re,im\n0,990,1,inf\n0,1010,1,2\n",
        "not finite",
    );
    expect_err("shot,freq_hz,re,im\n0,990,1,x\n", "not a number");
    expect_err(
        "shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2\n1,990,1,2\n1,1011,1,2\n",
        "different frequency set",
    );
    expect_err(
        "shot,freq_hz,re,im\n0,990,1,2\n0,1011,1,2\n",
        "drive frequency 1010",
    );
    expect_err(
        "shot,freq_hz,re,im\n0,990,1,2\n0,990,1,2\n0,1010,1,2\n",
        "appears twice",
    );
    expect_err(
        "shot,freq_hz,re,im,point\n0,990,1,2,p9\n0,1010,1,2,p0\n",
        "point \"p9\" is not declared",
    );
    expect_err("shot,freq_hz,re,im\n0,-990,1,2\n", "positive");
    expect_err("shot,freq_hz,re,im\n", "no data rows");
}

#[test]
fn from_parts_checks_and_sorts_like_a_file() {
    let d = good_dir();
    let ds = Dataset::load(d.path()).expect("load");
    let m = &ds.measurements[0];
    // The same measurement with its frequencies reversed comes back sorted.
    let mut rev = m.clone();
    rev.freqs_hz.reverse();
    rev.data = (0..m.n_shots)
        .flat_map(|s| (0..3).rev().map(move |f| (s, f)))
        .map(|(s, f)| m.amplitude(s, f, 0))
        .collect();
    let built =
        Dataset::from_parts("arrays", ds.manifest.clone(), vec![rev], None).expect("from_parts");
    assert_eq!(built.measurements[0], *m);
    assert_eq!(built.manifest, ds.manifest);
    let fail = |edit: &dyn Fn(&mut Measurement), needle: &str| {
        let mut x = m.clone();
        edit(&mut x);
        let e = Dataset::from_parts("arrays", ds.manifest.clone(), vec![x], None)
            .expect_err("should fail");
        let s = e.to_string();
        assert!(s.starts_with("arrays"), "no origin in: {s}");
        assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
    };
    fail(&|x| x.data.truncate(5), "= 6");
    fail(&|x| x.data[4].im = f64::NAN, "shot 1 at 990 Hz");
    fail(&|x| x.freqs_hz[0] = 990.0, "appears twice");
    fail(&|x| x.freqs_hz[2] = 1011.0, "drive frequency 1010");
    fail(&|x| x.freqs_hz[0] = -1.0, "positive");
    fail(&|x| x.points = vec![3], "declared points");
    fail(&|x| x.spec.drive_levels_v = None, "give both");
}

#[test]
fn bad_manifests_are_reported() {
    let d = tempfile::tempdir().expect("tempdir");
    write(
        d.path(),
        "m1.csv",
        "shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2\n",
    );
    for (text, needle) in [
        (
            MANIFEST.replace("harmonid-dataset/1", "v0"),
            "format is \"v0\"",
        ),
        (
            MANIFEST.replace("\"nm\"", "\"furlong\""),
            "displacement_unit",
        ),
        (
            MANIFEST.replace("drive_levels_v = [1.0, 1.0]", "drive_levels_v = [1.0]"),
            "1 entries",
        ),
        (MANIFEST.replace("drives_hz", "drives"), "dataset.toml"),
        (
            MANIFEST.replace("name = \"m1\"", "name = \"m1\"\nfile = \"../x.csv\""),
            "inside the dataset folder",
        ),
    ] {
        write(d.path(), "dataset.toml", &text);
        let e = Dataset::load(d.path()).expect_err("should fail");
        let s = e.to_string();
        assert!(s.contains("dataset.toml"), "{s}");
        assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
    }
}

#[test]
fn missing_file_names_the_path() {
    let d = tempfile::tempdir().expect("tempdir");
    write(d.path(), "dataset.toml", MANIFEST);
    let e = Dataset::load(d.path()).expect_err("should fail");
    assert!(e.to_string().contains("m1.csv"));
}

fn manifest_err(text: &str, csv: &str) -> String {
    let d = tempfile::tempdir().expect("tempdir");
    write(d.path(), "dataset.toml", text);
    write(d.path(), "m1.csv", csv);
    Dataset::load(d.path())
        .expect_err("should fail")
        .to_string()
}

const CSV_OK: &str = "shot,freq_hz,re,im\n0,990,1,2\n0,1010,1,2\n";

#[test]
fn wrong_drives_are_refused_with_their_place() {
    // A duplicate tone gave g12 = -5.8e23 (truth 8.57e22) with only a warning.
    let s = manifest_err(
        &MANIFEST.replace("[990.0, 1010.0]", "[990.0, 990.0]"),
        CSV_OK,
    );
    assert!(
        s.contains("dataset.toml") && s.contains("drive tones 1 and 2 are the same frequency"),
        "{s}"
    );
    let s = manifest_err(
        &MANIFEST.replace("[990.0, 1010.0]", "[990.0, 990.0000000001]"),
        CSV_OK,
    );
    assert!(s.contains("same frequency"), "coincident tones: {s}");
    // drive_levels_v = [0, 0] gave beta1 = -5.4e23 "determined" and a NaN gain.
    let s = manifest_err(
        &MANIFEST.replace("drive_levels_v = [1.0, 1.0]", "drive_levels_v = [0.0, 0.0]"),
        CSV_OK,
    );
    assert!(
        s.contains("drive_levels_v[0] = 0") && s.contains("non-zero"),
        "{s}"
    );
    let s = manifest_err(
        &MANIFEST.replace("drive_levels_v = [1.0, 1.0]", "drive_levels_v = [1.0, nan]"),
        CSV_OK,
    );
    assert!(s.contains("finite"), "{s}");
    let s = manifest_err(
        &MANIFEST.replace("[990.0, 1010.0]", "[990.0, 1e300]"),
        CSV_OK,
    );
    assert!(s.contains("drive frequency 1e300"), "{s}");
}

#[test]
fn empty_and_degenerate_manifests_are_refused() {
    // No measurement gave an all-null result with exit 0.
    let head = MANIFEST.split("[[measurement]]").next().expect("head");
    let s = manifest_err(head, CSV_OK);
    assert!(
        s.contains("no [[measurement]] or [[sweep]] is listed"),
        "{s}"
    );
    // `file = "."` named the folder itself.
    let s = manifest_err(
        &MANIFEST.replace("name = \"m1\"", "name = \"m1\"\nfile = \".\""),
        CSV_OK,
    );
    assert!(
        s.contains("must name a CSV file inside the dataset folder"),
        "{s}"
    );
    let s = manifest_err(
        &MANIFEST.replace("drives_hz = [990.0, 1010.0]", "drives_hz = []"),
        CSV_OK,
    );
    assert!(s.contains("drives_hz is empty"), "{s}");
}

#[test]
fn values_beyond_the_fit_scaling_are_refused() {
    // One value of 1e308 nulled beta1, f1 and Q1 with a misleading reason.
    let s = manifest_err(MANIFEST, "shot,freq_hz,re,im\n0,990,1e308,2\n0,1010,1,2\n");
    assert!(
        s.contains("m1.csv, row 2") && s.contains("not a resonator's displacement"),
        "{s}"
    );
    let s = manifest_err(MANIFEST, "shot,freq_hz,re,im\n0,990,1,2\n0,1e300,1,2\n");
    assert!(
        s.contains("row 3") && s.contains("largest frequency"),
        "{s}"
    );
}

#[test]
fn long_fields_are_shortened_in_messages() {
    let long = "x".repeat(100_000);
    let s = manifest_err(MANIFEST, &format!("shot,freq_hz,re,im\n0,990,{long},2\n"));
    assert!(
        s.contains("row 2") && s.len() < 400,
        "{}",
        &s[..s.len().min(400)]
    );
}

#[cfg(unix)]
#[test]
fn links_out_of_the_folder_are_not_read() {
    let root = tempfile::tempdir().expect("tempdir");
    let ds = root.path().join("ds");
    std::fs::create_dir(&ds).expect("mkdir");
    write(&ds, "dataset.toml", MANIFEST);
    // A foreign file whose first line would be echoed by a CSV error.
    write(root.path(), "passwd", "root:x:0:0:root:/root:/bin/bash\n");
    std::os::unix::fs::symlink(root.path().join("passwd"), ds.join("m1.csv")).expect("symlink");
    let e = Dataset::load(&ds).expect_err("outside");
    let s = e.to_string();
    assert!(s.contains("m1.csv") && s.contains("outside"), "{s}");
    assert!(!s.contains("root:x"), "foreign content printed: {s}");
    // The manifest itself may not be a link out either.
    std::fs::remove_file(ds.join("m1.csv")).expect("rm");
    write(&ds, "m1.csv", CSV_OK);
    std::fs::remove_file(ds.join("dataset.toml")).expect("rm");
    std::os::unix::fs::symlink(root.path().join("passwd"), ds.join("dataset.toml"))
        .expect("symlink");
    let s = Dataset::load(&ds).expect_err("outside").to_string();
    assert!(s.contains("outside") && !s.contains("root:x"), "{s}");
}

#[test]
fn writing_never_replaces_a_foreign_folder() {
    let d = good_dir();
    let ds = Dataset::load(d.path()).expect("load");
    let out = tempfile::tempdir().expect("tempdir");
    let thesis = out.path().join("thesis");
    std::fs::create_dir(&thesis).expect("mkdir");
    write(&thesis, "chapter1.tex", "years of work");
    let e = ds.write(&thesis).expect_err("foreign folder");
    let s = e.to_string();
    assert!(
        s.contains("not a harmonid dataset") && s.contains("chapter1.tex"),
        "{s}"
    );
    let help = miette::Diagnostic::help(&e)
        .map(|h| h.to_string())
        .unwrap_or_default();
    assert!(help.contains("--force"), "{help}");
    assert!(thesis.join("chapter1.tex").exists());
    // Forced, it is replaced; the inputs of the run are still protected.
    let model = thesis.join("chapter1.tex");
    let inputs = [model.as_path()];
    let opts = harmonid_files::DirWrite {
        force: true,
        inputs: &inputs,
    };
    assert!(ds.write_with(&thesis, opts).is_err());
    let opts = harmonid_files::DirWrite {
        force: true,
        inputs: &[],
    };
    ds.write_with(&thesis, opts).expect("forced");
    assert!(Dataset::load(&thesis).is_ok());
    // Writing a dataset over the folder it was read from is refused: its files are inputs.
    let files = ds.input_files();
    let inputs: Vec<&Path> = files.iter().map(|p| p.as_path()).collect();
    let opts = harmonid_files::DirWrite {
        force: true,
        inputs: &inputs,
    };
    assert!(ds.write_with(d.path(), opts).is_err());
}

#[test]
fn in_memory_readers_give_the_same_dataset() {
    let d = good_dir();
    let from_disk = Dataset::load(d.path()).expect("load");
    let csv = std::fs::read(d.path().join("m1.csv")).expect("read");
    let from_mem =
        Dataset::from_readers(d.path(), MANIFEST, None, |_| Ok(&csv[..])).expect("from readers");
    assert_eq!(from_disk, from_mem);
}

/// Peak resident memory of this process, bytes (Linux; 0 elsewhere).
fn peak_rss() -> usize {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<usize>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// A 1M-row CSV (1000 shots × 1000 frequencies) read with bounded memory: ≤ 100 bytes per row
/// above the process's peak before (it took 1.3 kB per row). Run alone, by hand:
/// `cargo test --release -p harmonid-ident --lib -- --ignored million_rows --test-threads 1`.
#[test]
#[ignore = "writes a 40 MB file; a measurement, run by hand"]
fn million_rows_stream_in_bounded_memory() {
    let d = tempfile::tempdir().expect("tempdir");
    let manifest =
        "format = \"harmonid-dataset/1\"\n[[measurement]]\nname = \"m1\"\ndrives_hz = [1000.0]\n";
    write(d.path(), "dataset.toml", manifest);
    {
        use std::io::Write as _;
        let f = std::fs::File::create(d.path().join("m1.csv")).expect("create");
        let mut w = std::io::BufWriter::new(f);
        writeln!(w, "shot,freq_hz,re,im").expect("write");
        for s in 0..1000 {
            for k in 0..1000 {
                writeln!(
                    w,
                    "{s},{},{:e},{:e}",
                    500.0 + k as f64,
                    1e-9 * k as f64,
                    -2e-9
                )
                .expect("write");
            }
        }
    }
    let before = peak_rss();
    let ds = Dataset::load(d.path()).expect("load");
    let after = peak_rss();
    assert_eq!(ds.measurements[0].n_shots, 1000);
    let per_row = (after.saturating_sub(before)) as f64 / 1e6;
    eprintln!("peak memory above the start: {per_row:.1} bytes per row");
    assert!(per_row <= 100.0, "{per_row} bytes per row");
}

#[test]
fn select_lines_keeps_every_shot_and_point_of_the_chosen_lines() {
    let spec = MeasurementSpec::new("m", vec![10.0]);
    let mut m = Measurement::zeros(spec.clone(), vec![10.0, 20.0, 30.0], vec![0, 1], 2);
    for s in 0..2 {
        for f in 0..3 {
            for p in 0..2 {
                *m.amplitude_mut(s, f, p) = Complex64::new((100 * s + 10 * f + p) as f64, 1.0);
            }
        }
    }
    let r = m.select_lines(spec, &[2, 0]);
    assert_eq!(r.freqs_hz, vec![30.0, 10.0]);
    assert_eq!((r.n_shots, r.points.clone()), (2, vec![0, 1]));
    assert_eq!(r.amplitude(1, 0, 1), Complex64::new(121.0, 1.0));
    assert_eq!(r.amplitude(0, 1, 0), Complex64::new(0.0, 1.0));
}

#[test]
fn a_noise_given_with_the_data_is_read_in_unit_and_its_rules_are_kept() {
    let d = tempfile::tempdir().expect("tempdir");
    write(d.path(), "dataset.toml", MANIFEST);
    // Rows out of frequency order: the noise follows its row.
    write(
        d.path(),
        "m1.csv",
        "shot,freq_hz,re,im,std,samples\n0,1010,5,6,0.3,10\n0,970,1,2,0.1,10\n0,990,3,4,0.2,12\n",
    );
    let ds = Dataset::load(d.path()).expect("load");
    let g = ds.measurements[0].noise.as_ref().expect("noise");
    // nm → m.
    for (got, want) in g.std.iter().zip([0.1e-9, 0.2e-9, 0.3e-9]) {
        assert!((got - want).abs() <= 1e-24, "{got} vs {want}");
    }
    assert_eq!(g.samples, vec![10, 12, 10]);
    // Refused: std without samples, one sample, a zero std, two shots with a given noise.
    for (csv, expect) in [
        ("shot,freq_hz,re,im,std\n0,970,1,2,0.1\n0,990,3,4,0.1\n0,1010,5,6,0.1\n", "go together"),
        ("shot,freq_hz,re,im,std,samples\n0,970,1,2,0.1,1\n0,990,3,4,0.1,2\n0,1010,5,6,0.1,2\n", "at least 2"),
        ("shot,freq_hz,re,im,std,samples\n0,970,1,2,0,5\n0,990,3,4,0.1,5\n0,1010,5,6,0.1,5\n", "must be positive"),
        (
            "shot,freq_hz,re,im,std,samples\n0,970,1,2,0.1,5\n0,990,3,4,0.1,5\n0,1010,5,6,0.1,5\n1,970,1,2,0.1,5\n1,990,3,4,0.1,5\n1,1010,5,6,0.1,5\n",
            "give one shot",
        ),
    ] {
        write(d.path(), "m1.csv", csv);
        let e = Dataset::load(d.path()).expect_err(expect).to_string();
        assert!(e.contains(expect), "{e}");
    }
}

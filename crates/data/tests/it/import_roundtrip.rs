//! Round trips: a known stepped sweep written in a vendor's layout, with that vendor's
//! conventions (RMS, x−iy, degrees, acceleration, a volts-to-metres scale), imported back,
//! equals the original to 1e-12.

use harmonid_data::import::{table, zi_csv, Amplitude, Conventions, Quadrature, Response, Settle};
use harmonid_data::Dataset;
use num_complex::Complex64;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A Duffing-like response of step `k` (drive `f`) at harmonic `h`, sample `j`, in metres.
fn truth(f: f64, h: usize, j: usize) -> Complex64 {
    let w0 = 2.0 * PI * 100.0;
    let w = 2.0 * PI * f;
    let lin = 1.0 / Complex64::new(w0 * w0 - w * w, w * w0 / 50.0);
    lin * (1e-3 / h as f64).powi(h as i32 - 1) * (1.0 + 1e-4 * j as f64)
}

const STEPS: [f64; 4] = [98.0, 99.5, 100.25, 101.0];

/// Every amplitude of `ds`, against [`truth`], to `tol` relative.
fn assert_equal(ds: &Dataset, samples: usize, first_sample: usize, harmonics: usize, tol: f64) {
    assert_eq!(ds.measurements.len(), STEPS.len());
    for (k, m) in ds.measurements.iter().enumerate() {
        assert_eq!(m.spec.drives_hz, vec![STEPS[k]]);
        assert_eq!(m.n_shots, samples);
        assert_eq!(m.freqs_hz.len(), harmonics);
        for j in 0..samples {
            for h in 1..=harmonics {
                let want = truth(STEPS[k], h, j + first_sample);
                let got = m.amplitude(j, h - 1, 0);
                assert!(
                    (got - want).norm() <= tol * want.norm(),
                    "step {k} sample {j} harmonic {h}: {got} vs {want}"
                );
            }
        }
    }
}

#[test]
fn zi_csv_round_trip_rms_conjugate_scaled_with_settling() {
    let dir = tempfile::tempdir().expect("tempdir");
    let clock = 60e6;
    let k_m_per_v = 2.5e-7;
    let mut files = Vec::new();
    for h in 1..=2 {
        let mut s = String::from("chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1\n");
        let mut tick: u64 = 1_000_000;
        for &f in &STEPS {
            for j in 0..5 {
                // The file: RMS volts, x − iy.
                let z = truth(f, h, j).conj() / std::f64::consts::SQRT_2 / k_m_per_v;
                let _ = writeln!(
                    s,
                    "0;{tick};{:e};{:e};{:?};0;0;0;0;0",
                    z.re,
                    z.im,
                    f * h as f64
                );
                tick += 6_000_000; // 0.1 s
            }
            tick += 60_000_000;
        }
        let p = dir
            .path()
            .join(format!("dev4955_demods_{}_sample_00000.csv", h - 1));
        std::fs::write(&p, s).expect("write");
        files.push(p);
    }
    let conv = Conventions {
        amplitude: Amplitude::Rms,
        quadrature: Quadrature::XMinusIY,
        response: Response::Displacement,
        metres_per_unit: Some(k_m_per_v),
        displacement_unit: "m".into(),
        phase_unit: None,
        frequency_scale: None,
    };
    let settle = Settle {
        settle_s: Some(0.15),
        settle_samples: None,
    };
    let opts = zi_csv::Options {
        clockbase_hz: clock,
        drive_level: Some(0.2),
        drive_phase_rad: None,
    };
    let (ds, note) =
        zi_csv::import(&files, &conv, settle, &opts, Path::new("out")).expect("import");
    // Samples at 0, 0.1 s dropped: 3 of 5 kept per step.
    assert_equal(&ds, 3, 2, 2, 1e-12);
    assert!(note.contains("8 of 20 samples dropped"), "{note}");
    assert_eq!(
        ds.manifest.sweeps[0].direction,
        harmonid_data::Direction::Up
    );
    // Written and read back: the same dataset.
    let out = dir.path().join("ds");
    ds.write(&out).expect("write");
    let back = Dataset::load(&out).expect("read back");
    assert_eq!(back.measurements.len(), 4);
    assert_equal(&back, 3, 2, 2, 1e-12);

    // A negative or non-finite settling time is refused, naming the setting.
    for bad in [-0.1, f64::NAN] {
        let neg = Settle {
            settle_s: Some(bad),
            settle_samples: None,
        };
        let e = zi_csv::import(&files, &conv, neg, &opts, Path::new("out"))
            .expect_err("bad settle_s")
            .to_string();
        assert!(e.contains("settle_s") && e.contains("0 or more"), "{e}");
    }

    // A timestamp going backwards (sample loss, mixed files) is refused with its row.
    let text = std::fs::read_to_string(&files[0]).expect("read");
    let mut lines: Vec<&str> = text.lines().collect();
    lines.swap(3, 4);
    std::fs::write(&files[0], lines.join("\n")).expect("write");
    let e = zi_csv::import(&files, &conv, settle, &opts, Path::new("out"))
        .expect_err("backwards")
        .to_string();
    assert!(e.contains("row 5") && e.contains("samples lost"), "{e}");
}

#[test]
fn table_csv_round_trip_polar_degrees_acceleration() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = String::from("%f\tR\tphase_deg\tlevel\n");
    for &f in &STEPS {
        for j in 0..2 {
            // The file: acceleration, peak, polar in degrees.
            let w = 2.0 * PI * f;
            let a = truth(f, 1, j) * -(w * w);
            let _ = writeln!(s, "{f:?}\t{:e}\t{:e}\t0.3", a.norm(), a.arg().to_degrees());
        }
    }
    let p = dir.path().join("sweep.txt");
    std::fs::write(&p, s).expect("write");
    let mapping_text = r#"
[columns]
freq_hz = "f"
r = "R"
theta = "phase_deg"
drive_level = "level"
[conventions]
amplitude = "peak"
quadrature = "x+iy"
phase_unit = "deg"
response = "acceleration"
displacement_unit = "m"
metres_per_unit = 1.0
"#;
    let map = dir.path().join("map.toml");
    std::fs::write(&map, mapping_text).expect("write");
    let mapping = table::Mapping::load(&map).expect("mapping");
    let (ds, _) =
        table::import(std::slice::from_ref(&p), &mapping, Path::new("out")).expect("import");
    assert_equal(&ds, 2, 0, 1, 1e-12);
    assert_eq!(
        ds.measurements[0].spec.drive_levels_v,
        Some(vec![0.3]),
        "the level column"
    );

    // A missing convention names its key; nothing is guessed.
    std::fs::write(&map, mapping_text.replace("phase_unit = \"deg\"\n", "")).expect("write");
    let e = table::Mapping::load(&map)
        .expect_err("no phase unit")
        .to_string();
    assert!(e.contains("phase_unit"), "{e}");
    std::fs::write(&map, mapping_text.replace("metres_per_unit = 1.0\n", "")).expect("write");
    let e = table::Mapping::load(&map)
        .expect_err("no scale")
        .to_string();
    assert!(e.contains("metres_per_unit"), "{e}");
    // A NaN row is refused with its row.
    std::fs::write(&map, mapping_text).expect("write");
    let mapping = table::Mapping::load(&map).expect("mapping");
    std::fs::write(
        &p,
        "f\tR\tphase_deg\tlevel\n98\t1e-3\t10\t0.3\n98\tNaN\t10\t0.3\n",
    )
    .expect("write");
    let e = table::import(&[p], &mapping, Path::new("out"))
        .expect_err("NaN")
        .to_string();
    assert!(
        e.contains("row 3") && e.contains("NaN rows must be removed"),
        "{e}"
    );
}

#[test]
fn table_mat_round_trip_struct_array_one_sweep_per_element() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut elements = Vec::new();
    for level in [0.1, 0.4] {
        let (mut f, mut x, mut y, mut l) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for &fs in &STEPS {
            let z = truth(fs, 1, 0);
            f.push(fs);
            x.push(z.re);
            y.push(z.im);
            l.push(level);
        }
        let mut map = matrw::__private::IndexMap::new();
        map.insert("freq".to_string(), matrw::MatVariable::from(f));
        map.insert("x".to_string(), matrw::MatVariable::from(x));
        map.insert("y".to_string(), matrw::MatVariable::from(y));
        map.insert("level".to_string(), matrw::MatVariable::from(l));
        elements.push(matrw::MatVariable::Structure(matrw::Structure::new(map)));
    }
    let array = matrw::StructureArray::from_structures(vec![1, 2], elements);
    let mut top = matrw::__private::IndexMap::new();
    top.insert(
        "runs".to_string(),
        matrw::MatVariable::StructureArray(array),
    );
    let mut file = matrw::MatFile::new();
    file.insert(
        "S",
        matrw::MatVariable::Structure(matrw::Structure::new(top)),
    );
    let p: PathBuf = dir.path().join("runs.mat");
    matrw::save_matfile_v7(p.to_str().expect("utf-8 path"), file, true).expect("save");
    let mapping_text = r#"
[columns]
freq_hz = "S.runs(*).freq"
x = "S.runs(*).x"
y = "S.runs(*).y"
drive_level = "S.runs(*).level"
[conventions]
amplitude = "peak"
quadrature = "x+iy"
displacement_unit = "m"
metres_per_unit = 1.0
"#;
    let map = dir.path().join("map.toml");
    std::fs::write(&map, mapping_text).expect("write");
    let mapping = table::Mapping::load(&map).expect("mapping");
    let (ds, _) =
        table::import(std::slice::from_ref(&p), &mapping, Path::new("out")).expect("import");
    assert_eq!(ds.manifest.sweeps.len(), 2);
    assert_eq!(ds.manifest.sweeps[1].name, "runs_2");
    assert_eq!(ds.measurements.len(), 8);
    for (i, m) in ds.measurements.iter().enumerate() {
        let want = truth(STEPS[i % 4], 1, 0);
        assert!((m.amplitude(0, 0, 0) - want).norm() <= 1e-12 * want.norm());
        assert_eq!(m.spec.drive_levels_v, Some(vec![[0.1, 0.4][i / 4]]));
    }
    // A path that does not exist names what does.
    std::fs::write(&map, mapping_text.replace("S.runs(*).y", "S.runs(*).z")).expect("write");
    let mapping = table::Mapping::load(&map).expect("mapping");
    let e = table::import(&[p], &mapping, Path::new("out"))
        .expect_err("no field z")
        .to_string();
    assert!(
        e.contains("no field \"z\"") && e.contains("freq, x, y, level"),
        "{e}"
    );
}

#[test]
fn moku_csv_round_trip_polar_cycles_gain_offset_rms_conjugate() {
    use harmonid_data::import::{moku_csv, PhaseUnit};
    let dir = tempfile::tempdir().expect("tempdir");
    let (gain, offset, k_m_per_v) = (10.0, 0.125, 4e-8);
    let mut files = Vec::new();
    for (k, &f) in STEPS.iter().enumerate() {
        let mut s = String::from("% Moku:Go Lock-in Amplifier\n");
        // The last file's header has no frequency: --demod-hz gives them all then.
        if k < 3 {
            let _ = writeln!(s, "% Demodulation frequency {} kHz, phase 0 deg", f / 1e3);
        }
        s.push_str(
            "% Acquisition rate: 1.0000000000e+01 Hz\n% Time (s), Channel 1 (V), Channel 2 (V)\n",
        );
        for j in 0..5 {
            // The file: RMS, x − iy, polar with θ in cycles, after the output gain and offset.
            let z = truth(f, 1, j).conj() / std::f64::consts::SQRT_2 / k_m_per_v;
            let cycles = z.arg() / (2.0 * PI);
            let _ = writeln!(
                s,
                "{:e}, {:e}, {:e}",
                0.1 * j as f64,
                z.norm() * gain + offset,
                cycles * gain + offset
            );
        }
        let p = dir.path().join(format!("step{k}.csv"));
        std::fs::write(&p, s).expect("write");
        files.push(p);
    }
    let conv = Conventions {
        amplitude: Amplitude::Rms,
        quadrature: Quadrature::XMinusIY,
        response: Response::Displacement,
        metres_per_unit: Some(k_m_per_v),
        displacement_unit: "m".into(),
        phase_unit: Some(PhaseUnit::Cycles),
        frequency_scale: None,
    };
    let settle = Settle {
        settle_s: Some(0.15),
        settle_samples: None,
    };
    let mut opts = moku_csv::Options {
        channels: moku_csv::Channels::RTheta,
        output_gain: gain,
        output_offset_v: offset,
        phase_unit: Some(PhaseUnit::Cycles),
        demod_hz: Vec::new(),
        drive_level: Some(0.5),
    };
    // Without --demod-hz, the file lacking the header line is refused by name.
    let e = moku_csv::import(&files, &conv, settle, &opts, Path::new("out"))
        .expect_err("no frequency")
        .to_string();
    assert!(e.contains("step3.csv") && e.contains("--demod-hz"), "{e}");
    opts.demod_hz = STEPS.to_vec();
    let (ds, note) =
        moku_csv::import(&files, &conv, settle, &opts, Path::new("out")).expect("import");
    assert_equal(&ds, 3, 2, 1, 1e-12);
    assert!(note.contains("8 of 20 samples dropped"), "{note}");
    let imported = ds.manifest.import.as_ref().expect("[import]");
    assert_eq!(imported.format, "moku-csv");
    assert_eq!(imported.conventions.phase_unit, Some(PhaseUnit::Cycles));
    // Three headers and --demod-hz agree; a header read as Hz is the same steps.
    opts.demod_hz.clear();
    std::fs::remove_file(&files[3]).expect("remove");
    let (three, _) = moku_csv::import(&files[..3], &conv, settle, &opts, Path::new("out"))
        .expect("import from headers");
    for (k, m) in three.measurements.iter().enumerate() {
        assert!((m.spec.drives_hz[0] - STEPS[k]).abs() <= 1e-9 * STEPS[k]);
    }

    // A Theta channel without its unit, a zero gain, a time going backwards: refused.
    let no_unit = moku_csv::Options {
        phase_unit: None,
        ..opts.clone()
    };
    let e = moku_csv::import(&files[..3], &conv, settle, &no_unit, Path::new("out"))
        .expect_err("no unit")
        .to_string();
    assert!(e.contains("--phase-unit"), "{e}");
    let zero_gain = moku_csv::Options {
        output_gain: 0.0,
        ..opts.clone()
    };
    let e = moku_csv::import(&files[..3], &conv, settle, &zero_gain, Path::new("out"))
        .expect_err("zero gain")
        .to_string();
    assert!(e.contains("--output-gain"), "{e}");
    let text = std::fs::read_to_string(&files[0]).expect("read");
    let mut lines: Vec<&str> = text.lines().collect();
    let n = lines.len();
    lines.swap(n - 1, n - 2);
    std::fs::write(&files[0], lines.join("\n")).expect("write");
    let e = moku_csv::import(&files[..3], &conv, settle, &opts, Path::new("out"))
        .expect_err("backwards")
        .to_string();
    assert!(
        e.contains("step0.csv") && e.contains("does not follow"),
        "{e}"
    );
}

/// A LabOne HDF5 save of `records` records, each with demodulators 0 (the drive) and 1 (its
/// second harmonic) sampling the [`STEPS`] sweep: RMS, x − iy, volts at `k` m/V, 5 samples
/// per step 0.1 s apart, `clock` ticks per second.
fn zi_hdf5_file(path: &Path, records: usize, k: f64, clock: f64) {
    let mut b = hdf5_pure::FileBuilder::new();
    for rec in 0..records {
        let mut dev = b.create_group(&format!("{rec:03}"));
        let mut d = dev.create_group("dev4955");
        let mut demods = d.create_group("demods");
        for h in 1..=2usize {
            let (mut ts, mut xs, mut ys, mut fs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            let mut tick: u64 = 1_000_000;
            for &f in &STEPS {
                for j in 0..5 {
                    let z = truth(f, h, j).conj() / std::f64::consts::SQRT_2 / k;
                    ts.push(tick);
                    xs.push(z.re);
                    ys.push(z.im);
                    fs.push(f * h as f64);
                    tick += (0.1 * clock) as u64;
                }
                tick += clock as u64;
            }
            let mut g = demods.create_group(&(h - 1).to_string());
            let mut sample = g.create_group("sample");
            sample.create_dataset("timestamp").with_u64_data(&ts);
            sample.create_dataset("x").with_f64_data(&xs);
            sample.create_dataset("y").with_f64_data(&ys);
            sample.create_dataset("frequency").with_f64_data(&fs);
            g.add_group(sample.finish());
            demods.add_group(g.finish());
        }
        d.add_group(demods.finish());
        dev.add_group(d.finish());
        b.add_group(dev.finish());
    }
    b.write(path).expect("write h5");
}

#[test]
fn zi_hdf5_round_trip_two_demodulators_two_records() {
    use harmonid_data::import::zi_hdf5;
    let dir = tempfile::tempdir().expect("tempdir");
    let (k, clock) = (2.5e-7, 1.8e9);
    let path = dir.path().join("sweep.h5");
    zi_hdf5_file(&path, 2, k, clock);
    let conv = Conventions {
        amplitude: Amplitude::Rms,
        quadrature: Quadrature::XMinusIY,
        response: Response::Displacement,
        metres_per_unit: Some(k),
        displacement_unit: "m".into(),
        phase_unit: None,
        frequency_scale: None,
    };
    let settle = Settle {
        settle_s: Some(0.15),
        settle_samples: None,
    };
    let opts = zi_hdf5::Options {
        clockbase_hz: clock,
        demods: Vec::new(),
        drive_level: Some(0.2),
    };
    let (ds, note) = zi_hdf5::import(
        std::slice::from_ref(&path),
        &conv,
        settle,
        &opts,
        Path::new("out"),
    )
    .expect("import");
    // Two records, two sweeps of the same steps.
    assert_eq!(ds.manifest.sweeps.len(), 2);
    assert_eq!(ds.manifest.sweeps[0].name, "000_dev4955");
    assert!(note.contains("16 of 40 samples dropped"), "{note}");
    let first = Dataset {
        measurements: ds.measurements[..4].to_vec(),
        ..ds.clone()
    };
    assert_equal(&first, 3, 2, 2, 1e-12);
    // Only demodulator 0: one line per step.
    let one = zi_hdf5::Options {
        demods: vec![0],
        ..opts.clone()
    };
    let (ds1, _) = zi_hdf5::import(
        std::slice::from_ref(&path),
        &conv,
        settle,
        &one,
        Path::new("out"),
    )
    .expect("import demod 0");
    assert!(ds1.measurements.iter().all(|m| m.freqs_hz.len() == 1));
    // Refused: no clock base; a demodulator that is not there; a file that is not HDF5.
    let no_clock = zi_hdf5::Options {
        clockbase_hz: f64::NAN,
        ..opts.clone()
    };
    let e = zi_hdf5::import(
        std::slice::from_ref(&path),
        &conv,
        settle,
        &no_clock,
        Path::new("out"),
    )
    .expect_err("no clock")
    .to_string();
    assert!(e.contains("--clockbase-hz"), "{e}");
    let missing = zi_hdf5::Options {
        demods: vec![0, 3],
        ..opts.clone()
    };
    let e = zi_hdf5::import(
        std::slice::from_ref(&path),
        &conv,
        settle,
        &missing,
        Path::new("out"),
    )
    .expect_err("no demod 3")
    .to_string();
    assert!(
        e.contains("demods/3/sample/") && e.contains("need x, y"),
        "{e}"
    );
    let text = dir.path().join("not.h5");
    std::fs::write(&text, "chunk;timestamp\n").expect("write");
    let e = zi_hdf5::import(
        std::slice::from_ref(&text),
        &conv,
        settle,
        &opts,
        Path::new("out"),
    )
    .expect_err("not hdf5")
    .to_string();
    assert!(e.contains("not.h5") && e.contains("HDF5"), "{e}");
}

#[test]
fn table_units_are_checked_against_the_conventions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("t.csv");
    // Phases in degrees (up to 170), in a column whose name does not say so.
    std::fs::write(
        &data,
        "f,X (V),Y (mV),R,phase,phase (deg)\n# a comment line, then a blank one\n\n98,1e-3,2e-3,1e-3,170,170\n99,1e-3,2e-3,1e-3,-120,-120\n",
    )
    .expect("write");
    let try_map = |columns: &str, phase_unit: &str| -> String {
        let map = dir.path().join("m.toml");
        std::fs::write(
            &map,
            format!(
                "[columns]\nfreq_hz = \"f\"\n{columns}\n[conventions]\namplitude = \"peak\"\nquadrature = \"x+iy\"\ndisplacement_unit = \"V\"\nphase_unit = \"{phase_unit}\"\n"
            ),
        )
        .expect("write map");
        match table::Mapping::load(&map)
            .and_then(|m| table::import(std::slice::from_ref(&data), &m, Path::new("out")))
        {
            Ok(_) => "imported".into(),
            Err(e) => e.to_string(),
        }
    };
    // x in V, y in mV: mixed units.
    let e = try_map("x = \"X (V)\"\ny = \"Y (mV)\"", "rad");
    assert!(e.contains("mixed units") && e.contains("mV"), "{e}");
    // A column named in degrees declared in radians.
    let e = try_map("r = \"R\"\ntheta = \"phase (deg)\"", "rad");
    assert!(e.contains("phase (deg)") && e.contains("phase_unit"), "{e}");
    // Degrees in an unnamed column declared in radians: the values give it away, by the line
    // of the file (the comment and blank lines counted).
    let e = try_map("r = \"R\"\ntheta = \"phase\"", "rad");
    assert!(
        e.contains("t.csv, row 4") && e.contains("reaches 170"),
        "{e}"
    );
    // Declared in degrees: imported.
    assert_eq!(try_map("r = \"R\"\ntheta = \"phase\"", "deg"), "imported");
    assert_eq!(
        try_map("r = \"R\"\ntheta = \"phase (deg)\"", "deg"),
        "imported"
    );
}

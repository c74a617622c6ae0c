//! Round trips from a dataset harmonid simulated: a stepped-sine sweep of a Duffing mode with
//! nonlinear damping (`harmonid_testgen::stepped_sweep_plan`, noisy shots), written in each
//! vendor's layout with that vendor's conventions (RMS, x − iy, polar in cycles or degrees, an
//! output gain and offset, volts to metres, millimetres), imported back by `harmonid import`'s
//! code, equals the original to 1e-12 of each step's largest amplitude.

use harmonid::data::import::{
    moku_csv, table, zi_csv, zi_hdf5, Amplitude, Conventions, PhaseUnit, Quadrature, Response,
    Settle,
};
use harmonid::data::Dataset;
use harmonid_testgen as gen;
use num_complex::Complex64;
use std::f64::consts::{PI, SQRT_2};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Volts per metre of the simulated sensor.
const K_M_PER_V: f64 = 2.0e-7;
/// Device ticks per second (MFLI).
const CLOCK: f64 = 60e6;

fn simulated() -> Dataset {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    gen::simulate(&model, &v, &d, &[1.0], 2e-11, 4, 17)
}

/// The steps of the first drive level (40 one-tone steps).
fn first_level(ds: &Dataset) -> Vec<&harmonid::data::Measurement> {
    ds.measurements.iter().take(40).collect()
}

/// Every imported step equals the original's: drive, lines, every shot's amplitude.
fn assert_same(orig: &[&harmonid::data::Measurement], got: &Dataset, level: Option<f64>) {
    assert_eq!(got.measurements.len(), orig.len());
    for (o, g) in orig.iter().zip(&got.measurements) {
        let f = o.spec.drives_hz[0];
        assert!(
            (g.spec.drives_hz[0] - f).abs() <= 1e-12 * f,
            "{}",
            g.spec.name
        );
        assert_eq!(g.freqs_hz.len(), o.freqs_hz.len());
        assert_eq!(g.n_shots, o.n_shots);
        if let Some(l) = level {
            assert_eq!(g.spec.drive_levels_v.as_deref(), Some(&[l][..]));
        }
        let big = o.data.iter().map(|x| x.norm()).fold(0.0, f64::max);
        for (a, b) in o.data.iter().zip(&g.data) {
            assert!(
                (a - b).norm() <= 1e-12 * big,
                "{}: {b} imported, {a} simulated",
                g.spec.name
            );
        }
    }
}

/// What the instrument wrote for `x` (m): RMS, x − iy, volts.
fn rms_conj_volts(x: Complex64) -> Complex64 {
    x.conj() / SQRT_2 / K_M_PER_V
}

fn conv(amplitude: Amplitude, quadrature: Quadrature, phase: Option<PhaseUnit>) -> Conventions {
    Conventions {
        amplitude,
        quadrature,
        response: Response::Displacement,
        metres_per_unit: Some(K_M_PER_V),
        displacement_unit: "m".into(),
        phase_unit: phase,
        frequency_scale: None,
    }
}

/// The ticks of sample `j` of step `k`: 0.1 s apart, 1 s between steps.
fn tick(k: usize, j: usize) -> u64 {
    1_000_000 + (k as u64) * 60_000_000 + (j as u64) * 6_000_000
}

#[test]
fn zi_csv_from_a_simulated_sweep() {
    let ds = simulated();
    let steps = first_level(&ds);
    let level = steps[0].spec.drive_levels_v.as_ref().expect("levels")[0];
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = String::from("chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1\n");
    for (k, m) in steps.iter().enumerate() {
        for j in 0..m.n_shots {
            let z = rms_conj_volts(m.amplitude(j, 0, 0));
            let f = m.freqs_hz[0];
            let _ = writeln!(s, "0;{};{:e};{:e};{f:?};0;0;0;0;0", tick(k, j), z.re, z.im);
        }
    }
    let p = dir.path().join("dev4955_demods_0_sample_00000.csv");
    std::fs::write(&p, s).expect("write");
    let opts = zi_csv::Options {
        clockbase_hz: CLOCK,
        drive_level: Some(level),
        drive_phase_rad: None,
    };
    let (got, _) = zi_csv::import(
        &[p],
        &conv(Amplitude::Rms, Quadrature::XMinusIY, None),
        Settle::default(),
        &opts,
        Path::new("out"),
    )
    .expect("import");
    assert_same(&steps, &got, Some(level));
}

#[test]
fn zi_hdf5_from_a_simulated_sweep() {
    let ds = simulated();
    let steps = first_level(&ds);
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut ts, mut xs, mut ys, mut fs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, m) in steps.iter().enumerate() {
        for j in 0..m.n_shots {
            let z = rms_conj_volts(m.amplitude(j, 0, 0));
            ts.push(tick(k, j));
            xs.push(z.re);
            ys.push(z.im);
            fs.push(m.freqs_hz[0]);
        }
    }
    let mut b = hdf5_pure::FileBuilder::new();
    let mut rec = b.create_group("000");
    let mut dev = rec.create_group("dev4955");
    let mut demods = dev.create_group("demods");
    let mut d0 = demods.create_group("0");
    let mut sample = d0.create_group("sample");
    sample.create_dataset("timestamp").with_u64_data(&ts);
    sample.create_dataset("x").with_f64_data(&xs);
    sample.create_dataset("y").with_f64_data(&ys);
    sample.create_dataset("frequency").with_f64_data(&fs);
    d0.add_group(sample.finish());
    demods.add_group(d0.finish());
    dev.add_group(demods.finish());
    rec.add_group(dev.finish());
    b.add_group(rec.finish());
    let p = dir.path().join("stream.h5");
    b.write(&p).expect("write h5");
    let opts = zi_hdf5::Options {
        clockbase_hz: CLOCK,
        demods: Vec::new(),
        drive_level: None,
    };
    let (got, _) = zi_hdf5::import(
        &[p],
        &conv(Amplitude::Rms, Quadrature::XMinusIY, None),
        Settle::default(),
        &opts,
        Path::new("out"),
    )
    .expect("import");
    assert_same(&steps, &got, None);
}

#[test]
fn moku_csv_from_a_simulated_sweep() {
    let ds = simulated();
    let steps = first_level(&ds);
    let dir = tempfile::tempdir().expect("tempdir");
    let (gain, offset) = (4.0, 0.25);
    let mut files: Vec<PathBuf> = Vec::new();
    for (k, m) in steps.iter().enumerate() {
        let f = m.freqs_hz[0];
        let mut s = format!(
            "% Moku:Pro Lock-in Amplifier\n% Demodulation frequency {f:?} Hz\n% Time (s), Channel 1 (V), Channel 2 (V)\n"
        );
        for j in 0..m.n_shots {
            // Peak R and θ in cycles, x + iy, after the output gain and offset.
            let z = m.amplitude(j, 0, 0) / K_M_PER_V;
            let cycles = z.arg() / (2.0 * PI);
            let _ = writeln!(
                s,
                "{:e}, {:e}, {:e}",
                0.1 * j as f64,
                z.norm() * gain + offset,
                cycles * gain + offset
            );
        }
        let p = dir.path().join(format!("step_{k:03}.csv"));
        std::fs::write(&p, s).expect("write");
        files.push(p);
    }
    let opts = moku_csv::Options {
        channels: moku_csv::Channels::RTheta,
        output_gain: gain,
        output_offset_v: offset,
        phase_unit: Some(PhaseUnit::Cycles),
        demod_hz: Vec::new(),
        drive_level: None,
    };
    let (got, _) = moku_csv::import(
        &files,
        &conv(
            Amplitude::Peak,
            Quadrature::XPlusIY,
            Some(PhaseUnit::Cycles),
        ),
        Settle::default(),
        &opts,
        Path::new("out"),
    )
    .expect("import");
    assert_same(&steps, &got, None);
}

#[test]
fn table_from_a_simulated_sweep_all_levels() {
    let ds = simulated();
    let all: Vec<&harmonid::data::Measurement> = ds.measurements.iter().collect();
    let dir = tempfile::tempdir().expect("tempdir");
    // Millimetres, polar in degrees, one row per sample, the drive level per row.
    let mut s = String::from("freq,amp_mm,phase_deg,level\n");
    for m in &all {
        let level = m.spec.drive_levels_v.as_ref().expect("levels")[0];
        for j in 0..m.n_shots {
            let z = m.amplitude(j, 0, 0) * 1e3;
            let _ = writeln!(
                s,
                "{:?},{:e},{:e},{level:e}",
                m.freqs_hz[0],
                z.norm(),
                z.arg().to_degrees()
            );
        }
    }
    let p = dir.path().join("sweep.csv");
    std::fs::write(&p, s).expect("write");
    let map = dir.path().join("map.toml");
    std::fs::write(
        &map,
        r#"[columns]
freq_hz = "freq"
r = "amp_mm"
theta = "phase_deg"
drive_level = "level"
[conventions]
amplitude = "peak"
quadrature = "x+iy"
phase_unit = "deg"
displacement_unit = "m"
metres_per_unit = 1e-3
"#,
    )
    .expect("write map");
    let mapping = table::Mapping::load(&map).expect("mapping");
    let (got, _) = table::import(&[p], &mapping, Path::new("out")).expect("import");
    // Four levels: four sweeps, cut where the level changes.
    assert_eq!(got.manifest.sweeps.len(), 4);
    assert_same(&all, &got, None);
    for (o, g) in all.iter().zip(&got.measurements) {
        assert_eq!(g.spec.drive_levels_v, o.spec.drive_levels_v);
    }
}

#[test]
fn zi_sweeper_from_a_simulated_sweep_with_its_noise() {
    use harmonid::data::import::zi_sweeper;
    let ds = simulated();
    let steps = first_level(&ds);
    let dir = tempfile::tempdir().expect("tempdir");
    // The sweeper's point: the mean of the step's shots and the standard deviation of each
    // quadrature (n − 1), RMS volts, x − iy; up then back down (bidirectional).
    let mut s = String::from("grid;bandwidth;count;x;xstddev;y;ystddev;frequency\n");
    let mut want: Vec<(f64, Complex64, f64)> = Vec::new();
    let order: Vec<usize> = (0..steps.len()).chain((0..steps.len()).rev()).collect();
    for &k in &order {
        let m = steps[k];
        let n = m.n_shots as f64;
        let mean: Complex64 = (0..m.n_shots)
            .map(|j| m.amplitude(j, 0, 0))
            .sum::<Complex64>()
            / n;
        let var = |part: fn(Complex64) -> f64| {
            (0..m.n_shots)
                .map(|j| (part(m.amplitude(j, 0, 0)) - part(mean)).powi(2))
                .sum::<f64>()
                / (n - 1.0)
        };
        let (vx, vy) = (var(|z| z.re), var(|z| z.im));
        let z = rms_conj_volts(mean);
        let f = m.freqs_hz[0];
        let _ = writeln!(
            s,
            "{f:?};10.0;{};{:e};{:e};{:e};{:e};{f:?}",
            m.n_shots,
            z.re,
            vx.sqrt() / SQRT_2 / K_M_PER_V,
            z.im,
            vy.sqrt() / SQRT_2 / K_M_PER_V
        );
        want.push((f, mean, ((vx + vy) / 2.0).sqrt()));
    }
    let p = dir.path().join("dev4955_sweeper_demods_0.csv");
    std::fs::write(&p, s).expect("write");
    let (got, _) = zi_sweeper::import(
        &[p],
        &conv(Amplitude::Rms, Quadrature::XMinusIY, None),
        &zi_sweeper::Options::default(),
        Path::new("out"),
    )
    .expect("import");
    // Up and down: two sweeps.
    assert_eq!(got.manifest.sweeps.len(), 2);
    assert_eq!(
        got.manifest.sweeps[0].direction,
        harmonid::data::Direction::Up
    );
    assert_eq!(
        got.manifest.sweeps[1].direction,
        harmonid::data::Direction::Down
    );
    assert_eq!(got.measurements.len(), want.len());
    for (g, (f, mean, std)) in got.measurements.iter().zip(&want) {
        assert_eq!(g.n_shots, 1);
        assert!((g.spec.drives_hz[0] - f).abs() <= 1e-12 * f);
        assert!(
            (g.data[0] - mean).norm() <= 1e-12 * mean.norm(),
            "{}",
            g.spec.name
        );
        let noise = g.noise.as_ref().expect("noise given");
        assert!((noise.std[0] - std).abs() <= 1e-12 * std, "{}", g.spec.name);
        assert_eq!(noise.samples[0], 4);
    }
}

/// Writes `csv` and `map` into `dir` and imports the table with the mapping.
fn import_table(
    dir: &Path,
    csv: &str,
    map: &str,
) -> Result<Dataset, harmonid::data::import::ImportError> {
    let p = dir.join("sweep.csv");
    std::fs::write(&p, csv).expect("write");
    let m = dir.join("map.toml");
    std::fs::write(&m, map).expect("write map");
    let mapping = table::Mapping::load(&m).expect("mapping");
    table::import(&[p], &mapping, Path::new("out")).map(|(ds, _)| ds)
}

/// Rows `f,x,y[,level]` of a lab's sweep up then down at each level of `levels`, two samples a
/// step.
fn up_and_down(levels: &[f64], with_level: bool) -> String {
    let mut s = String::from(if with_level {
        "f,x,y,level\n"
    } else {
        "f,x,y\n"
    });
    for &l in levels {
        for f in [100.0, 101.0, 102.0, 103.0, 102.0, 101.0, 100.0] {
            for _ in 0..2 {
                let _ = write!(s, "{f:?},{:e},{:e}", 1e-3 * l, -2e-3 * l);
                let _ = if with_level {
                    writeln!(s, ",{l:?}")
                } else {
                    writeln!(s)
                };
            }
        }
    }
    s
}

const XY_MAP: &str = r#"[columns]
freq_hz = "f"
x = "x"
y = "y"
[conventions]
amplitude = "peak"
quadrature = "x+iy"
displacement_unit = "V"
"#;

#[test]
fn table_sweep_up_and_down_per_level_is_an_up_and_a_down_sweep() {
    use harmonid::data::Direction;
    let dir = tempfile::tempdir().expect("tempdir");
    let map = XY_MAP.replace("y = \"y\"\n", "y = \"y\"\ndrive_level = \"level\"\n");
    let ds = import_table(dir.path(), &up_and_down(&[0.1, 0.2], true), &map).expect("import");
    let got: Vec<(&str, Direction, usize)> = ds
        .manifest
        .sweeps
        .iter()
        .map(|s| (s.name.as_str(), s.direction, s.drives_hz.len()))
        .collect();
    assert_eq!(
        got,
        [
            ("level_0.1_up", Direction::Up, 4),
            ("level_0.1_down", Direction::Down, 3),
            ("level_0.2_up", Direction::Up, 4),
            ("level_0.2_down", Direction::Down, 3),
        ]
    );
    // One step stays unordered (a direction needs two steps).
    let one = "f,x,y\n100.0,1e-3,2e-3\n100.0,1e-3,2e-3\n";
    let ds = import_table(dir.path(), one, XY_MAP).expect("import one step");
    assert_eq!(ds.manifest.sweeps[0].direction, Direction::Unordered);
}

#[test]
fn table_without_a_level_column_refuses_levels_merged_into_one_sweep() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Two levels up and down, the level column not mapped: one sweep that comes back twice.
    let err = import_table(dir.path(), &up_and_down(&[0.1, 0.2], true), XY_MAP)
        .expect_err("levels merged")
        .to_string();
    assert!(err.contains("[columns] drive_level"), "{err}");
    assert!(err.contains("several drive levels merged"), "{err}");
    // One level up and down without a level column is two sweeps, not a refusal.
    let ds = import_table(dir.path(), &up_and_down(&[0.1], false), XY_MAP).expect("one level");
    assert_eq!(ds.manifest.sweeps.len(), 2);
}

#[test]
fn table_sweep_column_of_text_labels_names_the_sweeps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = String::from("f,x,y,run\n");
    for (run, fs) in [
        ("s00", [100.0, 101.0, 102.0]),
        ("s01", [102.0, 101.0, 100.0]),
    ] {
        for f in fs {
            let _ = writeln!(s, "{f:?},1e-3,-2e-3,{run}");
        }
    }
    let map = XY_MAP.replace("y = \"y\"\n", "y = \"y\"\nsweep = \"run\"\n");
    let ds = import_table(dir.path(), &s, &map).expect("text labels");
    let names: Vec<&str> = ds.manifest.sweeps.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["s00", "s01"]);
    // Numeric labels keep their names (sweep_1).
    let ds = import_table(dir.path(), &s.replace("s00", "1").replace("s01", "2"), &map)
        .expect("numeric labels");
    assert_eq!(ds.manifest.sweeps[0].name, "sweep_1");
}

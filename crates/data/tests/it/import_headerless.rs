//! A lock-in text export as a lab has it: no header line, `#` comments before and between the
//! sweeps, an up and a down sweep per drive level, the top level swept up only. Generated here
//! from a Duffing oscillator's harmonic-balance response (branch-following, so the up and the
//! down sweeps of the bistable levels differ), imported with columns mapped by number, and
//! checked sweep by sweep and value by value. Then the hostile variants of the same paths.

use harmonid_data::import::table;
use harmonid_data::Direction;
use num_complex::Complex64;
use std::f64::consts::{PI, SQRT_2};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Linear resonance (Hz), quality factor, and the drive steps (Hz) of every sweep.
const F0: f64 = 100.0;
const Q: f64 = 50.0;
const LEVELS: usize = 12;
const STEPS: usize = 41;

fn drive_hz(k: usize) -> f64 {
    90.0 + 0.5 * k as f64
}

/// Drive level `l` (0-based), V.
fn level_v(l: usize) -> f64 {
    0.05 * (l + 1) as f64
}

/// The complex amplitude (peak, V) of `x'' + c x' + w0² x + g x³ = F cos wt` at `f_hz`, on the
/// branch whose squared amplitude is closest to `prev` (branch following: a sweep stays on its
/// branch until it ends at a fold). Returns `(z, |z|²)`.
fn duffing(f_hz: f64, force: f64, prev: f64) -> (Complex64, f64) {
    let w0 = 2.0 * PI * F0;
    let c = w0 / Q;
    // The top level's peak (F / (c w0) = 12 mV) sits 8 Hz (4 linewidths) up the backbone.
    let a_top = 12e-3;
    let g = 4.0 * 8.0 * c * w0 / (3.0 * a_top * a_top);
    let w = 2.0 * PI * f_hz;
    let d = w0 * w0 - w * w;
    // |z|² = u solves (9/16) g² u³ + (3/2) g d u² + (d² + c² w²) u − F² = 0.
    let p = |u: f64| {
        ((0.5625 * g * g * u + 1.5 * g * d) * u + d * d + c * c * w * w) * u - force * force
    };
    let top = force * force / (c * w).powi(2) * 1.01;
    let grid: Vec<f64> = (0..=4000).map(|i| top * i as f64 / 4000.0).collect();
    let mut roots = Vec::new();
    for s in grid.windows(2) {
        let (mut a, mut b) = (s[0], s[1]);
        if p(a) == 0.0 {
            roots.push(a);
        } else if p(a).signum() != p(b).signum() {
            for _ in 0..200 {
                let m = 0.5 * (a + b);
                if p(a).signum() == p(m).signum() {
                    a = m
                } else {
                    b = m
                }
            }
            roots.push(0.5 * (a + b));
        }
    }
    let u = roots
        .into_iter()
        .min_by(|a, b| (a - prev).abs().total_cmp(&(b - prev).abs()))
        .expect("a cubic with a positive constant term has a positive root");
    let z = force / Complex64::new(d + 0.75 * g * u, c * w);
    (z, u)
}

/// The force of level `l`: its peak response at resonance is (l + 1) mV.
fn force(l: usize) -> f64 {
    let w0 = 2.0 * PI * F0;
    1e-3 * (l + 1) as f64 * (w0 / Q) * w0
}

/// One expected step: level, direction (true up), step index, drive, peak amplitude.
type Expected = (usize, bool, usize, f64, Complex64);

/// The file (RMS volts, columns `index level freq X Y`, tab-separated, no header, `#` comments)
/// and every step it holds. The down sweep starts at the top frequency again, as a lab's does:
/// that repeated step joins the up sweep's last (one step of two samples).
fn lockin_file() -> (String, Vec<Expected>) {
    let mut s = String::from(
        "# lock-in export, demodulator 1\n# no header line; columns: index, drive (V), frequency (Hz), X (V rms), Y (V rms)\n\n",
    );
    let mut want = Vec::new();
    let mut row = 0;
    for l in 0..LEVELS {
        let mut u = 0.0;
        let legs: &[bool] = if l + 1 == LEVELS {
            &[true]
        } else {
            &[true, false]
        };
        for &up in legs {
            let _ = writeln!(
                s,
                "# level {} V, sweep {}",
                level_v(l),
                if up { "up" } else { "down" }
            );
            for i in 0..STEPS {
                let k = if up { i } else { STEPS - 1 - i };
                let f = drive_hz(k);
                let (z, next) = duffing(f, force(l), u);
                u = next;
                let r = z / SQRT_2;
                let _ = writeln!(s, "{row}\t{}\t{f:?}\t{:e}\t{:e}", level_v(l), r.re, r.im);
                row += 1;
                // The turning point's repeat is the up sweep's step, not a down one.
                if up || i > 0 {
                    want.push((l, up, if up { i } else { i - 1 }, f, z));
                }
            }
        }
    }
    (s, want)
}

const MAPPING: &str = r#"
[columns]
freq_hz = 3
x = 4
y = 5
drive_level = 2
[conventions]
amplitude = "rms"
quadrature = "x+iy"
displacement_unit = "V"
"#;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

fn import(dir: &Path, data: &str, mapping: &str) -> Result<harmonid_data::Dataset, String> {
    let p = write(dir, "lockin.txt", data);
    let map = write(dir, "map.toml", mapping);
    let mapping = table::Mapping::load(&map).map_err(|e| e.to_string())?;
    table::import(&[p], &mapping, Path::new("out"))
        .map(|(ds, _)| ds)
        .map_err(|e| e.to_string())
}

#[test]
fn a_headerless_lockin_file_is_12_up_and_11_down_sweeps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (text, want) = lockin_file();
    let ds = import(dir.path(), &text, MAPPING).expect("import");
    let sweeps = &ds.manifest.sweeps;
    let ups: Vec<_> = sweeps.iter().filter(|s| s.name.ends_with("_up")).collect();
    let downs: Vec<_> = sweeps
        .iter()
        .filter(|s| s.name.ends_with("_down"))
        .collect();
    assert_eq!((ups.len(), downs.len(), sweeps.len()), (12, 11, 23));
    for s in &ups {
        assert_eq!(
            (s.direction, s.drives_hz.len()),
            (Direction::Up, STEPS),
            "{}",
            s.name
        );
    }
    for s in &downs {
        assert_eq!(
            (s.direction, s.drives_hz.len()),
            (Direction::Down, STEPS - 1),
            "{}",
            s.name
        );
    }
    assert_eq!(ups[0].name, "level_0.05_up");
    assert_eq!(downs[10].name, "level_0.55_down");
    assert_eq!(
        ups[11].name, "level_0.6000000000000001_up",
        "the top level, up only"
    );
    // Every value, on its own branch.
    assert_eq!(ds.measurements.len(), want.len());
    for (l, up, k, f, z) in want {
        let name = format!(
            "{}[{k}]",
            sweeps
                .iter()
                .filter(|s| s.name.ends_with(if up { "_up" } else { "_down" }))
                .nth(l)
                .expect("sweep")
                .name
        );
        let m = ds
            .measurements
            .iter()
            .find(|m| m.spec.name == name)
            .expect("step");
        assert_eq!(m.spec.drives_hz, vec![f], "{name}");
        assert_eq!(m.spec.drive_levels_v, Some(vec![level_v(l)]), "{name}");
        let got = m.amplitude(0, 0, 0);
        assert!((got - z).norm() <= 1e-12 * z.norm(), "{name}: {got} vs {z}");
    }
    // The bistable levels: the up sweep stays on the upper branch past where the down sweep
    // comes back on the lower one, at some frequency at least twice as high.
    let amps = |sweep: &str| -> Vec<(f64, f64)> {
        ds.measurements
            .iter()
            .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| s.sweep == sweep))
            .map(|m| (m.spec.drives_hz[0], m.amplitude(0, 0, 0).norm()))
            .collect()
    };
    let (up, down) = (amps("level_0.55_up"), amps("level_0.55_down"));
    let ratio = up
        .iter()
        .filter_map(|&(f, a)| down.iter().find(|d| d.0 == f).map(|d| a / d.1))
        .fold(0.0, f64::max);
    assert!(ratio > 2.0, "up/down at most {ratio}: not two branches");
}

#[test]
fn a_header_line_commented_or_not_and_any_separator_read_the_same() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rows = "1;0.1;99.5;1e-3;-2e-3\n2;0.1;100;2e-3;-1e-3\n3;0.1;100.5;1e-3;-3e-4\n";
    let named = MAPPING
        .replace("freq_hz = 3", "freq_hz = \"f\"")
        .replace("x = 4", "x = \"X\"");
    let base = import(dir.path(), &rows.replace(';', "\t"), MAPPING).expect("tabs");
    let amps = |ds: &harmonid_data::Dataset| -> Vec<Complex64> {
        ds.measurements
            .iter()
            .map(|m| m.amplitude(0, 0, 0))
            .collect()
    };
    for (what, text, mapping) in [
        ("semicolons", rows.to_string(), MAPPING.to_string()),
        ("commas", rows.replace(';', ","), MAPPING.to_string()),
        ("spaces", rows.replace(';', "   "), MAPPING.to_string()),
        (
            "comments inside",
            format!("% moku-like\n{}# pause\n\n{}", &rows[..22], &rows[22..]),
            MAPPING.to_string(),
        ),
        ("a header", format!("i;lvl;f;X;Y\n{rows}"), named.clone()),
        (
            "a # header",
            format!("# i;lvl;f;X;Y\n{rows}"),
            named.clone(),
        ),
        (
            "a BOM and a header",
            format!("\u{feff}i;lvl;f;X;Y\n{rows}"),
            named.clone(),
        ),
        (
            "a BOM, no header",
            format!("\u{feff}{rows}"),
            MAPPING.to_string(),
        ),
    ] {
        let ds = import(dir.path(), &text, &mapping).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(amps(&ds), amps(&base), "{what}");
    }
}

/// The error of importing `data` with `mapping`, which must name every one of `parts`.
fn refused(dir: &Path, data: &str, mapping: &str, parts: &[&str]) {
    let e = import(dir, data, mapping).expect_err("refused");
    for p in parts {
        assert!(e.contains(p), "no {p:?} in: {e}");
    }
    assert!(e.len() < 600, "{} characters: {e}", e.len());
}

#[test]
fn hostile_column_numbers_and_files_are_refused_by_line_and_column() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let rows = "1 0.1 99.5 1e-3 -2e-3\n2 0.1 100 2e-3 -1e-3\n3 0.1 100.5 1e-3 -3e-4\n";
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = 0"),
        &["column 0", "numbered from 1"],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = -3"),
        &["column -3", "numbered from 1"],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = 2.5"),
        &["2.5", "whole number", "x = 2"],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = true"),
        &["1-based column number"],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = \"\""),
        &["empty column name"],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = 9"),
        &[
            "lockin.txt",
            "row 1",
            "5 fields",
            "x = column 9",
            "from 1 to 5",
        ],
    );
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = 99999999999999999999"),
        &["1-based column number"],
    );
    refused(
        d,
        "# only\n% comments\n\n",
        MAPPING,
        &["lockin.txt", "no data", "3 lines", "comments"],
    );
    refused(d, "", MAPPING, &["empty"]);
    // Mixed separators: the detected separator, the other one, and the key to set.
    refused(
        d,
        &rows.replacen(" 2e-3", ",2e-3", 1).replace(' ', ";"),
        MAPPING,
        &["row 2", "field", "mixed separators", "delimiter"],
    );
    refused(
        d,
        &rows.replace(" 1e-3 ", " 1,5e-3 "),
        MAPPING,
        &[
            "row 1",
            "2 fields (separated by \",\")",
            "mixed separators",
            "delimiter = \" \"",
        ],
    );
    refused(
        d,
        &rows.replace(' ', ";").replace("1e-3", "1,5"),
        MAPPING,
        &["row 1", "decimal comma"],
    );
    // A header name against a headerless file, and a name not in the header.
    refused(
        d,
        rows,
        &MAPPING.replace("x = 4", "x = \"X\""),
        &["line 1", "no header line", "\"X\"", "x = 2"],
    );
    refused(
        d,
        &format!("i lvl f X Y\n{rows}"),
        &MAPPING.replace("x = 4", "x = \"Xrms\""),
        &[
            "row 1",
            "no column \"Xrms\"",
            "found: \"i\"",
            "by its 1-based number",
        ],
    );
    refused(
        d,
        "i lvl f X Y\n# only comments after the header\n",
        MAPPING,
        &["row 1", "no data rows after the header"],
    );
    refused(
        d,
        rows,
        &format!("delimiter = \"|\"\n{MAPPING}"),
        &["delimiter", "\"|\"", "\";\""],
    );
    // A 1 MB line: one cut excerpt, no megabyte in the message.
    let long = format!("1 0.1 99.5 {} -2e-3\n", "7".repeat(1 << 20) + "x");
    refused(
        d,
        &long,
        MAPPING,
        &["row 1", "field 4", "is not a number", "…"],
    );
}

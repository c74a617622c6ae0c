//! Every figure renders from small hand-made data: SVG structure (element counts, texts) is
//! snapshotted, not pixels; the PNGs go to the test's temporary folder for looking at.

use harmonid_plot::*;
use std::path::PathBuf;

fn spectrum() -> Spectrum {
    let mut lines = Vec::new();
    let f1 = 207_582.0;
    let f2 = 415_842.0;
    // Two tones at f1 ± 10 Hz and their sidebands; one tone at f2 and its mixing products.
    for (k, amp) in [
        (-3i32, 2e-11),
        (-1, 4e-9),
        (1, 3e-9),
        (3, 1.5e-11),
        (5, 3e-13),
        (-5, 4e-13),
    ] {
        let f = f1 + 10.0 * k as f64;
        let kind = if k.abs() == 1 {
            LineKind::Drive
        } else {
            LineKind::Sideband
        };
        let label = match k {
            -1 => "fa".into(),
            1 => "fb".into(),
            // As harmonid_spectral's formatter writes them: positive term first.
            _ if k < 0 => format!("{}fa−{}fb", (1 - k) / 2, -(k + 1) / 2).replace("−1fb", "−fb"),
            _ => format!("{}fb−{}fa", (k + 1) / 2, (k - 1) / 2).replace("−1fa", "−fa"),
        };
        lines.push(SpectrumLine {
            f_hz: f,
            measured: amp,
            reconstructed: Some(amp * 1.05),
            residual: Some(amp * 0.06),
            kind,
            label,
        });
    }
    for (k, amp) in [(-2i32, 2e-12), (0, 5e-9), (2, 2.2e-12)] {
        lines.push(SpectrumLine {
            f_hz: f2 + 10.0 * k as f64,
            measured: amp,
            reconstructed: Some(amp * 0.97),
            residual: Some(amp * 0.03 + 1e-14),
            kind: if k == 0 {
                LineKind::Drive
            } else {
                LineKind::Mixing
            },
            label: if k == 0 {
                "fc".into()
            } else {
                format!("fc{:+}(fb−fa)", k / 2)
            },
        });
    }
    Spectrum {
        title: "coupled_q1q2 at p0".into(),
        unit: "m".into(),
        lines,
        residual_in_sigmas: false,
        noise_floor: Some(1e-13),
    }
}

fn histogram() -> Histogram {
    // Deterministic pseudo-normal values around 2.1e10.
    let mut values: Vec<f64> = (0..30)
        .map(|i| {
            let u = ((i * 37 % 30) as f64 + 0.5) / 30.0 - 0.5;
            2.1e10 * (1.0 + 0.02 * (u * 3.0))
        })
        .collect();
    values.push(2.6e10);
    Histogram {
        name: "gamma12".into(),
        unit: "1/(m² s²)".into(),
        values,
        outliers: vec![30],
        value: 2.1e10,
        stderr: 2.1e10 * 0.004,
        std: 2.1e10 * 0.018,
        truth: Some(2.12e10),
    }
}

fn response() -> ResponseCurve {
    // A hardening Duffing curve parametrised by amplitude (frequency as a function of a).
    let (f0, g, bw, fa) = (1000.0f64, 4.0, 2.0, 1.0);
    let mut f = Vec::new();
    let mut a = Vec::new();
    let mut st = Vec::new();
    let n = 400;
    for i in 0..n {
        let amp = 0.02 + 1.4 * i as f64 / n as f64;
        let fb = f0 + g * amp * amp;
        let d2 = (fa / amp).powi(2) - bw * bw;
        if d2 < 0.0 {
            continue;
        }
        f.push(fb - d2.sqrt());
        a.push(amp);
        st.push(true);
    }
    for i in (0..n).rev() {
        let amp = 0.02 + 1.4 * i as f64 / n as f64;
        let fb = f0 + g * amp * amp;
        let d2 = (fa / amp).powi(2) - bw * bw;
        if d2 < 0.0 {
            continue;
        }
        f.push(fb + d2.sqrt());
        a.push(amp);
        st.push(!(0.25..=0.3).contains(&amp));
    }
    ResponseCurve {
        title: "Duffing response".into(),
        y_label: "|q1| at f (m)".into(),
        branches: vec![Branch {
            label: "q1".into(),
            f_hz: f,
            amp: a,
            stable: st,
        }],
        jumps: vec![
            Jump {
                f_hz: 1004.0,
                from: 0.9,
                to: 0.2,
                up: true,
            },
            Jump {
                f_hz: 1001.0,
                from: 0.25,
                to: 0.6,
                up: false,
            },
        ],
        backbone: (0..50)
            .map(|i| {
                let amp = 1.4 * i as f64 / 50.0;
                (f0 + g * amp * amp, amp)
            })
            .collect(),
        measured: Vec::new(),
    }
}

/// A linear resonance at 1 kHz (Q 100, in V) at two levels: the model's circle and, for each
/// level, an up-sweep and a down-sweep on it.
fn frequency_response() -> FrequencyResponse {
    let x = |f: f64, level: f64| {
        let (w0, w) = (1000.0f64, f);
        let (re, im) = (w0 * w0 - w * w, w * w0 / 100.0);
        let d = re * re + im * im;
        (level * 1e6 * re / d, -level * 1e6 * im / d)
    };
    let family = |level: f64| {
        let f_model: Vec<f64> = (0..200).map(|i| 960.0 + 0.4 * i as f64).collect();
        let f_up: Vec<f64> = (0..20).map(|i| 962.0 + 4.0 * i as f64).collect();
        let f_down: Vec<f64> = f_up.iter().rev().map(|f| f + 1.0).collect();
        ResponseFamily {
            label: format!("level {level}"),
            sweeps: vec![
                MeasuredSweep {
                    name: "up".into(),
                    mark: SweepMark::Up,
                    x: f_up.iter().map(|&f| x(f, level)).collect(),
                    f_hz: f_up,
                },
                MeasuredSweep {
                    name: "down".into(),
                    mark: SweepMark::Down,
                    x: f_down.iter().map(|&f| x(f, level)).collect(),
                    f_hz: f_down,
                },
            ],
            model: Some(ModelBranch {
                x: f_model.iter().map(|&f| x(f, level)).collect(),
                stable: f_model
                    .iter()
                    .map(|&f| !(999.0..1001.0).contains(&f))
                    .collect(),
                f_hz: f_model,
            }),
        }
    };
    FrequencyResponse {
        title: "two levels".into(),
        unit: "V".into(),
        families: vec![family(0.1), family(0.2)],
    }
}

fn noise() -> NoiseStudy {
    let levels: Vec<f64> = (0..6).map(|k| 10f64.powi(k - 3)).collect();
    let panel = |name: &str, truth: f64| NoisePanel {
        name: name.into(),
        unit: "Hz".into(),
        truth: Some(truth),
        levels: levels.clone(),
        estimates: levels
            .iter()
            .map(|l| {
                (0..10)
                    .map(|i| truth * (1.0 + 1e-3 * l * (i as f64 - 4.5)))
                    .collect()
            })
            .collect(),
    };
    NoiseStudy {
        title: "noise study".into(),
        level_label: "noise σ (nm)".into(),
        panels: vec![
            panel("f1", 207_582.0),
            panel("Q1", 5000.0),
            panel("beta1", 3e9),
            panel("gamma12", 2e10),
        ],
    }
}

fn potential() -> PotentialMatrix {
    let modes = vec!["q1".to_string(), "q2".to_string(), "q3".to_string()];
    let g = 15;
    let cell = |a: f64| PotentialCell::Map {
        n: g,
        x: (-1.0, 1.0),
        y: (-1.0, 1.0),
        values: (0..g * g)
            .map(|k| {
                let (x, y) = ((k % g) as f64 / 7.0 - 1.0, (k / g) as f64 / 7.0 - 1.0);
                0.25 * (x.powi(4) + y.powi(4)) + 0.5 * a * x * x * y * y
            })
            .collect(),
    };
    let curve = PotentialCell::Curve {
        q: (0..21).map(|i| i as f64 / 10.0 - 1.0).collect(),
        u: (0..21)
            .map(|i| 0.25 * (i as f64 / 10.0 - 1.0).powi(4))
            .collect(),
    };
    let cells = (0..3)
        .map(|i| {
            (0..3)
                .map(|j| {
                    if i == j {
                        curve.clone()
                    } else {
                        cell(1.0 + (i + j) as f64)
                    }
                })
                .collect()
        })
        .collect();
    PotentialMatrix {
        title: "U_nl".into(),
        modes,
        cells,
        note: "lower: identified · upper: truth".into(),
    }
}

fn out_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("figures")
}

fn check(name: &str, fig: &impl Figure) {
    let svg = to_svg(fig).expect("renders");
    assert!(svg.starts_with("<svg"), "{name}: not an SVG");
    insta::assert_snapshot!(name, svg_structure(&svg));
    std::fs::create_dir_all(out_dir()).expect("temp dir");
    save(fig, &out_dir().join(format!("{name}.png")), &[]).expect("png");
    let png = std::fs::read(out_dir().join(format!("{name}.png"))).expect("png written");
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn spectrum_renders() {
    check("spectrum", &spectrum());
}

#[test]
fn histogram_renders() {
    check("histogram", &histogram());
}

#[test]
fn response_renders() {
    check("response", &response());
}

#[test]
fn frequency_response_renders() {
    check("frequency_response", &frequency_response());
    let mut one = frequency_response();
    one.families.truncate(1);
    let svg = to_svg(&one).expect("renders");
    for label in [
        "|X| (V)",
        "Re X (V)",
        "Im X (V)",
        "up-sweep",
        "down-sweep",
        "model, unstable",
    ] {
        assert!(svg.contains(label), "{label} missing");
    }
}

#[test]
fn noise_renders() {
    check("noise", &noise());
}

#[test]
fn potential_renders() {
    check("potential", &potential());
}

#[test]
fn empty_figures_are_errors() {
    let s = Spectrum {
        title: "x".into(),
        unit: "m".into(),
        lines: vec![],
        residual_in_sigmas: false,
        noise_floor: None,
    };
    assert!(matches!(to_svg(&s), Err(PlotError::Empty { .. })));
    assert!(matches!(
        save(&histogram(), std::path::Path::new("a.pdf"), &[]),
        Err(PlotError::Format { .. })
    ));
}

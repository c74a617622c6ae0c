//! Designed drive plans for round-trip tests and benches, simulated by the experiment layer
//! (`harmonid_experiment::Plan::simulate`: harmonic balance, truncation and stability checks,
//! seeded noise) into an in-memory [`Dataset`].
//!
//! A dev-only crate (`publish = false`): the root package's tests and benches use it as
//! `use harmonid_testgen as gen;`, one compiled copy instead of a `#[path]` module in each.

use harmonid_data::{Dataset, Manifest, Measurement, Point};
use harmonid_experiment::{Plan, PlanMeasurement, PlanNoise, Settings};
use harmonid_model::Model;
use harmonid_sim::{ModeValues, ModelValues, NoiseGen};
use std::collections::BTreeMap;

/// One designed measurement: tones as (frequency Hz, mode index, force N/kg).
#[derive(Debug, Clone)]
pub struct Design {
    /// The measurement's name.
    pub name: String,
    /// The drive tones.
    pub tones: Vec<(f64, usize, f64)>,
    /// Modes observed besides the driven ones (their resonance region is measured too).
    pub observe: Vec<usize>,
}

/// True values: f (Hz), Q per mode; parameters by name.
#[derive(Debug, Clone)]
pub struct Values {
    /// Resonance frequency per mode, Hz.
    pub f_hz: Vec<f64>,
    /// Quality factor per mode.
    pub q: Vec<f64>,
    /// Parameter values by name.
    pub params: BTreeMap<String, f64>,
}

/// Standard designs: one two-tone measurement per mode (tones at f_n ∓ `detune_lw` linewidths),
/// one three-tone measurement per pair `(n, m)` in `pairs` (two tones near n, one at f_m +
/// `detune_lw/2` linewidths).
pub fn designs(
    v: &Values,
    names: &[String],
    force: &[f64],
    detune_lw: f64,
    pairs: &[(usize, usize)],
) -> Vec<Design> {
    let mut out = Vec::new();
    for n in 0..v.f_hz.len() {
        let d = detune_lw * v.f_hz[n] / v.q[n];
        out.push(Design {
            name: format!("single_{}", names[n]),
            tones: vec![(v.f_hz[n] - d, n, force[n]), (v.f_hz[n] + d, n, force[n])],
            observe: Vec::new(),
        });
    }
    for &(n, m) in pairs {
        let d = detune_lw * v.f_hz[n] / v.q[n];
        let e = 0.5 * detune_lw * v.f_hz[m] / v.q[m];
        out.push(Design {
            name: format!("couple_{}_{}", names[n], names[m]),
            tones: vec![
                (v.f_hz[n] - d, n, force[n]),
                (v.f_hz[n] + d, n, force[n]),
                (v.f_hz[m] + e, m, 0.5 * force[m]),
            ],
            observe: Vec::new(),
        });
    }
    out
}

/// The model's values as a values file would give them.
pub fn model_values(model: &Model, v: &Values) -> ModelValues {
    let mut mv = ModelValues::default();
    for (n, m) in model.modes.iter().enumerate() {
        mv.modes.insert(
            m.name.clone(),
            ModeValues {
                f_hz: Some(v.f_hz[n]),
                q: Some(v.q[n]),
            },
        );
    }
    mv.parameters = v.params.clone();
    mv
}

/// The values of `examples/{example}/values.toml` (the inverse of [`model_values`]): the one
/// statement of an example's values, for tests that design their own plans around them.
pub fn example_values(example: &str, names: &[String]) -> Values {
    // The workspace root, two levels above this crate.
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(example)
        .join("values.toml");
    let mv = harmonid_experiment::read_values(&path).unwrap_or_else(|e| panic!("{e}"));
    let mode = |n: &String| &mv.modes[n];
    Values {
        f_hz: names.iter().map(|n| mode(n).f_hz.expect("f_hz")).collect(),
        q: names.iter().map(|n| mode(n).q.expect("Q")).collect(),
        params: mv.parameters.clone(),
    }
}

/// Simulates every design as one measurement plan and returns the dataset: one point with
/// `shape`, the model's nominal frequencies, every tone's force as its drive level (phase 0),
/// `shots` shots of Gaussian noise `sigma` per quadrature (m). Kept per measurement: the drive
/// tones and the default lines near the resonance of a driven or observed mode whose amplitude
/// exceeds 1e-7 of the measurement's largest (the sideband clusters a lock-in would record).
/// The same as [`add_noise`] on [`simulate_clean`] (the noise realisation differs).
pub fn simulate(
    model: &Model,
    v: &Values,
    designs: &[Design],
    shape: &[f64],
    sigma: f64,
    shots: usize,
    seed: u64,
) -> Dataset {
    add_noise(
        &simulate_clean(model, v, designs, shape, shots),
        sigma,
        seed,
    )
}

/// The plan measurements of `designs` for modes `names`: each tone's force on its mode (N/kg,
/// phase 0), its drive level the force itself (so the gains are one), no pumps, no ladder.
pub fn plan_measurements(designs: &[Design], names: &[String]) -> Vec<PlanMeasurement> {
    designs
        .iter()
        .map(|d| {
            let mut force = BTreeMap::new();
            for (k, &(_, n, f)) in d.tones.iter().enumerate() {
                force
                    .entry(names[n].clone())
                    .or_insert_with(|| vec![0.0; d.tones.len()])[k] = f;
            }
            PlanMeasurement {
                name: d.name.clone(),
                drives_hz: d.tones.iter().map(|t| t.0).collect(),
                force,
                phase_rad: BTreeMap::new(),
                measure_hz: None,
                drive_levels_v: Some(d.tones.iter().map(|t| t.2).collect()),
                drive_phases_rad: Some(vec![0.0; d.tones.len()]),
                pumps_hz: Vec::new(),
                pump_levels: None,
                pump_phases_rad: None,
                bandwidth_hz: None,
                levels: Vec::new(),
            }
        })
        .collect()
}

/// [`simulate`] without noise: every shot is the noise-free steady state (the truth's noise
/// is 0). The steady state does not depend on the noise, so a Monte Carlo simulates it once
/// and draws each realisation by [`add_noise`].
pub fn simulate_clean(
    model: &Model,
    v: &Values,
    designs: &[Design],
    shape: &[f64],
    shots: usize,
) -> Dataset {
    let settings = Settings {
        noise: false,
        min_line_rel: 1e-7,
        ..Settings::default()
    };
    let names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
    let plan = Plan {
        description: "synthetic round trip".into(),
        displacement_unit: "m".into(),
        points: vec![Point {
            name: "p0".into(),
            shape: names.iter().cloned().zip(shape.iter().copied()).collect(),
        }],
        nominal_hz: names
            .iter()
            .enumerate()
            .map(|(n, name)| (name.clone(), model.modes[n].nominal_hz.unwrap_or(v.f_hz[n])))
            .collect(),
        noise: PlanNoise {
            sigma_per_quadrature: 1e-12,
            shots,
        },
        measurements: plan_measurements(designs, &names),
        instrument: None,
    };
    let mut ds = plan
        .simulate(model, &model_values(model, v), &settings)
        .unwrap_or_else(|e| panic!("{e}"))
        .dataset;
    for (m, d) in ds.measurements.iter_mut().zip(designs) {
        let near = |f: f64| {
            d.tones
                .iter()
                .map(|t| t.1)
                .chain(d.observe.iter().copied())
                .any(|n| (f - v.f_hz[n]).abs() <= 0.005 * v.f_hz[n])
        };
        keep_lines(m, near);
    }
    ds
}

/// Keeps the measured frequencies `keep` says yes to (every shot and point).
pub fn keep_lines(m: &mut Measurement, keep: impl Fn(f64) -> bool) {
    let idx: Vec<usize> = (0..m.freqs_hz.len())
        .filter(|&f| keep(m.freqs_hz[f]))
        .collect();
    *m = m.select_lines(m.spec.clone(), &idx);
}

/// `clean` with independent Gaussian noise `sigma` (m) on the real and imaginary part of every
/// amplitude of every shot (seeded; the truth's noise set to `sigma`).
pub fn add_noise(clean: &Dataset, sigma: f64, seed: u64) -> Dataset {
    let mut ds = clean.clone();
    let mut gen = NoiseGen::new(seed);
    for m in &mut ds.measurements {
        harmonid_experiment::add_noise(m, sigma, &mut gen);
    }
    if let Some(n) = ds.truth.as_mut().and_then(|t| t.noise.as_mut()) {
        n.sigma_per_quadrature = sigma;
    }
    ds
}

/// Mode shapes of a string at x = L/10 for modes 1..5: sin(nπ/10).
pub const NANOSTRING_SHAPE: [f64; 5] = [
    0.309_016_994_374_947_45,
    0.587_785_252_292_473_1,
    0.809_016_994_374_947_5,
    0.951_056_516_295_153_5,
    1.0,
];

/// Values (the paper's Table S2) and the three-measurement drive plan of the two-mode nanostring
/// example: tone pairs 20 Hz apart around each resonance (mode 2 just below its hardening
/// resonance), then both pairs' mode-1 tones with one tone on mode 2.
pub fn nanostring_2mode_plan() -> (Values, Vec<Design>) {
    let v = Values {
        f_hz: vec![207582.0, 415842.0],
        q: vec![116232.0, 599173.0],
        params: [("beta1", 2.68e22), ("beta2", 3.7e23), ("g12", 8.57e22)]
            .iter()
            .map(|(k, x)| (k.to_string(), *x))
            .collect(),
    };
    let (c1, c2) = (207582.5, 415841.5);
    let d = vec![
        Design {
            name: "single_q1".into(),
            tones: vec![(c1 - 10.0, 0, 3.5), (c1 + 10.0, 0, 3.5)],
            observe: vec![],
        },
        Design {
            name: "single_q2".into(),
            tones: vec![(c2 - 10.0, 1, 1.81), (c2 + 10.0, 1, 1.81)],
            observe: vec![],
        },
        Design {
            name: "couple_q1_q2".into(),
            tones: vec![(c1 - 10.0, 0, 3.5), (c1 + 10.0, 0, 3.5), (c2, 1, 1.81)],
            observe: vec![],
        },
    ];
    (v, d)
}

/// The two-mode nanostring's values with a plan that determines every parameter at 0.1 nm and
/// 20 shots: tone pairs 5.5 linewidths either side of each resonance ([`designs`]) and the
/// pair on q1 with one tone on q2, mode 2 driven with 0.8 N/kg (close to its fold: 1.2 N/kg
/// is unstable). The paper's plan ([`nanostring_2mode_plan`]) drives mode 2 14 linewidths off
/// resonance, where β2 is only known to 45 % at 0.1 nm (relative Cramér–Rao bound with 20
/// shots; this plan: 12 %).
pub fn nanostring_2mode_fold_plan() -> (Values, Vec<Design>) {
    let (v, _) = nanostring_2mode_plan();
    let names: Vec<String> = (1..=2).map(|n| format!("q{n}")).collect();
    let d = designs(&v, &names, &[3.5, 0.8], 5.5, &[(0, 1)]);
    (v, d)
}

/// Values and the 15-measurement drive plan (5 single, 10 pairs) for the five-mode nanostring
/// example: Duffing terms scaling as n⁴ (tension), couplings as n²m²; 3.5 N/kg on every
/// mode, which determines β3–β5 and the couplings among q3–q5 poorly (the higher modes are
/// stiffer and respond less).
pub fn nanostring_5mode_plan() -> (Values, Vec<Design>) {
    let v = nanostring_5mode_values();
    let d = nanostring_5mode_designs(&v, &[3.5; 5]);
    (v, d)
}

/// The plan of [`nanostring_5mode_plan`] with each mode's force scaled to the same fraction of
/// its fold as mode 1's 3.5 N/kg: the fold of a Duffing resonance is reached at a force
/// `∝ ω³/(Q^{3/2} √β)`, here `∝ n / Q_n^{3/2}`, so `F_n = 3.5 · n · (Q_1/Q_n)^{3/2}` N/kg
/// (3.5 to 41.8). Every parameter is determined (relative Cramér–Rao bound at most 0.14 at
/// 0.1 nm and 30 shots, g45); 30 % more force makes a steady state unstable.
pub fn nanostring_5mode_fold_plan() -> (Values, Vec<Design>) {
    let v = nanostring_5mode_values();
    let force: Vec<f64> = (0..5)
        .map(|n| 3.5 * (n as f64 + 1.0) * (v.q[0] / v.q[n]).powf(1.5))
        .collect();
    let d = nanostring_5mode_designs(&v, &force);
    (v, d)
}

/// The five-mode nanostring's values: Duffing terms scaling as n⁴ (tension), couplings as
/// n²m².
fn nanostring_5mode_values() -> Values {
    let f1 = 207582.0;
    let f_hz: Vec<f64> = [1.0, 2.0033, 3.0075, 4.0139, 5.0226]
        .iter()
        .map(|k| k * f1)
        .collect();
    let q = vec![116232.0, 99173.0, 87000.0, 76000.0, 65000.0];
    let beta1 = 2.68e22;
    let mut params = BTreeMap::new();
    for n in 1..=5 {
        params.insert(format!("beta{n}"), beta1 * f64::from(n).powi(4));
    }
    for n in 1..=5 {
        for m in n + 1..=5 {
            params.insert(
                format!("g{n}{m}"),
                3.2 * beta1 * f64::from(n * n * m * m) / 3.0 * 0.25,
            );
        }
    }
    Values { f_hz, q, params }
}

/// One two-tone measurement per mode and one three-tone measurement per pair, with `force`
/// (N/kg) per mode ([`designs`], tones 5.5 linewidths off resonance).
fn nanostring_5mode_designs(v: &Values, force: &[f64]) -> Vec<Design> {
    let names: Vec<String> = (1..=5).map(|n| format!("q{n}")).collect();
    let mut pairs = Vec::new();
    for n in 0..5 {
        for m in n + 1..5 {
            pairs.push((n, m));
        }
    }
    designs(v, &names, force, 5.5, &pairs)
}

/// The true forces of a simulated dataset per measurement, mode and tone (N/kg, complex;
/// the layout of `ForwardModel::theta_from`).
pub fn truth_forces(ds: &Dataset, modes: &[String]) -> Vec<Vec<Vec<num_complex::Complex64>>> {
    let truth = ds
        .truth
        .as_ref()
        .expect("a simulated dataset has its truth");
    ds.measurements
        .iter()
        .map(|m| {
            let per_mode = &truth.forces[&m.spec.name];
            modes
                .iter()
                .map(|n| match per_mode.get(n) {
                    Some(f) => f
                        .amplitude
                        .iter()
                        .zip(&f.phase_rad)
                        .map(|(&a, &p)| num_complex::Complex64::from_polar(a, p))
                        .collect(),
                    None => vec![num_complex::Complex64::new(0.0, 0.0); m.spec.drives_hz.len()],
                })
                .collect()
        })
        .collect()
}

/// A committed plan and its values (`plan.toml` and `values.toml` in `dir`), simulated by
/// the experiment layer without noise, `shots` identical shots per measurement (the plan's
/// own lines, `measure_hz`); the values as [`Values`] in the model's mode order.
pub fn simulate_plan_file(model: &Model, dir: &std::path::Path, shots: usize) -> (Values, Dataset) {
    let text = std::fs::read_to_string(dir.join("plan.toml")).expect("plan.toml");
    let mut plan = Plan::from_toml(&text, "plan.toml").unwrap_or_else(|e| panic!("{e}"));
    plan.noise.shots = shots;
    let mv = harmonid_experiment::read_values(&dir.join("values.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let settings = Settings {
        noise: false,
        ..Settings::default()
    };
    let ds = plan
        .simulate(model, &mv, &settings)
        .unwrap_or_else(|e| panic!("{e}"))
        .dataset;
    let mode = |name: &str| mv.modes.get(name).copied().unwrap_or_default();
    let v = Values {
        f_hz: model
            .modes
            .iter()
            .map(|m| mode(&m.name).f_hz.expect("f_hz in values.toml"))
            .collect(),
        q: model
            .modes
            .iter()
            .map(|m| mode(&m.name).q.expect("Q in values.toml"))
            .collect(),
        params: mv.parameters.clone(),
    };
    (v, ds)
}

/// `plan` simulated by the experiment layer at the values `v` without noise, `shots`
/// identical shots per measurement (the plan's own lines): a designed plan held in memory,
/// for devices drawn by a test ([`ten_mode_family`]) rather than read from an example.
pub fn simulate_plan(model: &Model, plan: &Plan, v: &Values, shots: usize) -> Dataset {
    let mut plan = plan.clone();
    plan.noise.shots = shots;
    let settings = Settings {
        noise: false,
        ..Settings::default()
    };
    plan.simulate(model, &model_values(model, v), &settings)
        .unwrap_or_else(|e| panic!("{e}"))
        .dataset
}

/// Values of `examples/three_wave/values.toml`; a tone pair 5.5 linewidths either side of each
/// resonance (forces for about 7.5 nm, a quarter of a linewidth of Duffing shift; three times that makes single_q1 of the three-wave set parametrically unstable: f3 − f2 = f1), and q1 and q2
/// driven together with q3 observed (it responds at f1 + f2 through κ).
pub fn three_wave_plan() -> (Values, Vec<Design>) {
    let names: Vec<String> = (1..=3).map(|n| format!("q{n}")).collect();
    let v = example_values("three_wave", &names);
    let mut d = designs(&v, &names, &[165.0, 333.0, 735.0], 5.5, &[(0, 1)]);
    d[3].observe = vec![2];
    (v, d)
}

/// Values of `examples/cubic_3mode/values.toml` (Q of q1 fixed by the model); tone pairs as
/// [`three_wave_plan`], and each pair driven together with the third mode observed (μ makes it
/// respond at 2f1 − f2 = f3, 2f1 − f3 = f2, f2 + f3 − f1 = f1).
pub fn cubic_3mode_plan() -> (Values, Vec<Design>) {
    let names: Vec<String> = (1..=3).map(|n| format!("q{n}")).collect();
    let v = example_values("cubic_3mode", &names);
    let mut d = designs(
        &v,
        &names,
        &[165.0, 140.0, 190.0],
        5.5,
        &[(0, 1), (0, 2), (1, 2)],
    );
    d[3].observe = vec![2];
    d[4].observe = vec![1];
    d[5].observe = vec![0];
    (v, d)
}

/// Values of `examples/damped_2mode/values.toml`, and a plan for nonlinear damping: q1's tone
/// pair (2 linewidths either side) at two levels (linear response 2.5 and 10 nm: the damping
/// shows in how the response grows), q2's pair at 10 nm, and q1's weaker pair with a tone on
/// q2's resonance (q2 moving damps q1 through eta12).
pub fn damped_2mode_plan() -> (Values, Vec<Design>) {
    let names: Vec<String> = (1..=2).map(|n| format!("q{n}")).collect();
    let v = example_values("damped_2mode", &names);
    // Force for a linear peak response of `x` m: x w^2 / Q.
    let force = |n: usize, x: f64| x * (std::f64::consts::TAU * v.f_hz[n]).powi(2) / v.q[n];
    let pair = |n: usize, x: f64| {
        let d = 2.0 * v.f_hz[n] / v.q[n];
        vec![
            (v.f_hz[n] - d, n, force(n, x)),
            (v.f_hz[n] + d, n, force(n, x)),
        ]
    };
    let design = |name: &str, tones: Vec<(f64, usize, f64)>| Design {
        name: name.into(),
        tones,
        observe: Vec::new(),
    };
    let mut couple = pair(0, 2.5e-9);
    couple.push((v.f_hz[1], 1, force(1, 1e-8)));
    let d = vec![
        design("single_q1_low", pair(0, 2.5e-9)),
        design("single_q1_high", pair(0, 1e-8)),
        design("single_q2", pair(1, 1e-8)),
        design("couple_q1_q2", couple),
    ];
    (v, d)
}

/// One Duffing mode at 1 MHz with nonlinear damping `eta1 q1² q̇1` (issue 20), as a model file.
pub const DAMPED_DUFFING: &str = "
    mode q1 at 1 MHz
    param beta1, eta1
    potential: beta1/4*q1^4
    eom q1 += eta1*q1^2*d(q1)
";

/// Values of [`DAMPED_DUFFING`]: Q = 2e4, `beta1` shifting the resonance by about a linewidth
/// at 10 nm, and the given `eta1` (5e18 adds 0.4 linewidth of damping at 10 nm).
pub fn damped_duffing_values(eta1: f64) -> Values {
    Values {
        f_hz: vec![1.0e6],
        q: vec![2.0e4],
        params: [("beta1", 2.6e25), ("eta1", eta1)]
            .iter()
            .map(|(k, x)| (k.to_string(), *x))
            .collect(),
    }
}

/// A stepped-sine sweep of [`DAMPED_DUFFING`] as a lock-in records it: one tone and one line
/// per step, 40 steps over ±5 linewidths at each of four levels (linear peak response 1, 2.5,
/// 5 and 10 nm).
pub fn stepped_sweep_plan() -> (Values, Vec<Design>) {
    let v = damped_duffing_values(5.0e18);
    let (f, q) = (v.f_hz[0], v.q[0]);
    let w = std::f64::consts::TAU * f;
    let lw = f / q;
    let mut d = Vec::new();
    for (l, x) in [1e-9, 2.5e-9, 5e-9, 1e-8].iter().enumerate() {
        for s in 0..40 {
            d.push(Design {
                name: format!("l{l}_s{s:02}"),
                tones: vec![(f + lw * (s as f64 / 4.0 - 5.0), 0, x * w * w / q)],
                observe: Vec::new(),
            });
        }
    }
    (v, d)
}

/// One single-tone stepped sweep of mode 0 as a lock-in records it: its name, the order the
/// steps were measured in, and each step's tone (Hz) and force (N/kg, recorded as the drive
/// level, phase 0).
#[derive(Debug, Clone)]
pub struct SteppedSweep {
    /// The `[[sweep]]`'s name.
    pub name: String,
    /// Up or down.
    pub direction: harmonid_data::Direction,
    /// `(tone Hz, force N/kg)` per step, in measurement order.
    pub steps: Vec<(f64, f64)>,
}

/// Simulates `sweeps` the way the experiment runs them (no noise, `shots` identical shots,
/// one point with `shape`, the drive line measured): each sweep's first step by the drive
/// ramp from rest, every later step from the previous step's state
/// ([`harmonid_sim::stepped_sweep`]), so an up-sweep stays on the high branch of a
/// hardening resonance through its bistable range and jumps down past the fold, and a
/// down-sweep the other way. The dataset holds one `[[sweep]]` per sweep, each step a
/// measurement `name[k]` with its [`harmonid_data::SweepStep`].
pub fn simulate_sweeps_clean(
    model: &Model,
    v: &Values,
    sweeps: &[SteppedSweep],
    shape: &[f64],
    shots: usize,
) -> Dataset {
    use harmonid_data::{PerStep, SweepSpec, SweepStep};
    use harmonid_sim::{stepped_sweep, Excitation, HbSettings, NumericModel};
    use num_complex::Complex64;
    let numeric =
        NumericModel::from_model(model, &model_values(model, v)).unwrap_or_else(|e| panic!("{e}"));
    let nm = model.modes.len();
    let mut manifest = Manifest::new("stepped sweeps simulated by following their branches");
    manifest.points = vec![Point {
        name: "p0".into(),
        shape: model
            .modes
            .iter()
            .map(|m| m.name.clone())
            .zip(shape.iter().copied())
            .collect(),
    }];
    manifest.nominal_hz = model
        .modes
        .iter()
        .zip(&v.f_hz)
        .map(|(m, &f)| (m.name.clone(), f))
        .collect();
    let settings = HbSettings::default();
    let mut measurements = Vec::new();
    for sw in sweeps {
        let mut spec = SweepSpec::new(
            sw.name.clone(),
            sw.direction,
            sw.steps.iter().map(|&(f, _)| vec![f]).collect(),
        );
        spec.drive_levels_v = Some(PerStep::Each(
            sw.steps.iter().map(|&(_, x)| vec![x]).collect(),
        ));
        spec.drive_phases_rad = Some(PerStep::Same(vec![0.0]));
        let drives: Vec<Excitation> = sw
            .steps
            .iter()
            .map(|&(f, x)| {
                let mut force = vec![vec![Complex64::new(0.0, 0.0)]; nm];
                force[0][0] = Complex64::new(x, 0.0);
                Excitation {
                    pumps: Vec::new(),
                    tones_hz: vec![f],
                    force,
                }
            })
            .collect();
        let states = stepped_sweep(&numeric, &drives, &settings).unwrap_or_else(|e| panic!("{e}"));
        for (k, (&(f, _), state)) in sw.steps.iter().zip(&states).enumerate() {
            assert!(
                state.converged(),
                "{} step {k} at {f} Hz: {}",
                sw.name,
                state.status
            );
            let mut step = spec.step_spec(k);
            step.sweep = Some(SweepStep {
                sweep: sw.name.clone(),
                step: k,
            });
            let x = state.at_point(shape, f);
            measurements.push(Measurement {
                spec: step,
                freqs_hz: vec![f],
                points: vec![0],
                n_shots: shots,
                data: vec![x; shots],
                noise: None,
            });
        }
        manifest.sweeps.push(spec);
    }
    Dataset {
        dir: std::path::PathBuf::new(),
        manifest,
        measurements,
        truth: None,
        notes: Vec::new(),
    }
}

/// A lab's stepped-sine frequency response of [`DAMPED_DUFFING`] softened (`beta1 < 0`): at
/// each of `levels` drive levels (linear peak response 1 to 20 nm, evenly spaced) one sweep up
/// and one down through ±6 linewidths around the resonance, `steps` steps each, so that the top
/// levels are bistable and each direction jumps at its own fold (`eta1` = 5e17, a tenth of
/// [`stepped_sweep_plan`]'s: that much damping would keep every level below its fold). Names `up_l{level}` and
/// `dn_l{level}`; `2 · levels · steps` steps in all. For [`simulate_sweeps_clean`].
pub fn hysteretic_sweeps(levels: usize, steps: usize) -> (Values, Vec<SteppedSweep>) {
    let mut v = damped_duffing_values(5.0e17);
    v.params.insert("beta1".into(), -2.6e25);
    let (f, q) = (v.f_hz[0], v.q[0]);
    let w = std::f64::consts::TAU * f;
    let lw = f / q;
    let mut sweeps = Vec::new();
    for l in 0..levels {
        let x = 1e-9 + 19e-9 * l as f64 / (levels.max(2) - 1) as f64;
        let force = x * w * w / q;
        let up: Vec<(f64, f64)> = (0..steps)
            .map(|s| {
                (
                    f + lw * (12.0 * s as f64 / (steps.max(2) - 1) as f64 - 6.0),
                    force,
                )
            })
            .collect();
        let down = up.iter().rev().copied().collect();
        sweeps.push(SteppedSweep {
            name: format!("up_l{l:02}"),
            direction: harmonid_data::Direction::Up,
            steps: up,
        });
        sweeps.push(SteppedSweep {
            name: format!("dn_l{l:02}"),
            direction: harmonid_data::Direction::Down,
            steps: down,
        });
    }
    (v, sweeps)
}

/// A seeded uniform draw in `[0, 1)` (SplitMix64: a generator with no dependency, enough to
/// scatter test devices reproducibly).
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A factor log-uniform in `[1/spread, spread]`.
    fn factor(&mut self, spread: f64) -> f64 {
        spread.powf(2.0 * self.next() - 1.0)
    }
}

/// The ten-mode string family of issue 40: the values of `examples/nanostring_10mode` (mode
/// order `q1..q10`) with each Q, each Duffing β and each coupling g multiplied by its own
/// factor drawn log-uniformly within ×/÷ 2 (seeded by `seed`), the frequencies as in the
/// example: plausible neighbours of the example the identification must converge on.
pub fn ten_mode_family(seed: u64) -> Values {
    let names: Vec<String> = (1..=10).map(|n| format!("q{n}")).collect();
    let mut v = example_values("nanostring_10mode", &names);
    let mut rng = SplitMix(seed ^ 0x4840_0000_0000_0028);
    for q in &mut v.q {
        *q *= rng.factor(2.0);
    }
    for p in v.params.values_mut() {
        *p *= rng.factor(2.0);
    }
    v
}

/// The ten-mode string with every Q at 1.3·10⁵ (the example's values otherwise): the device
/// of issue 40 whose output-error fit stopped unconverged (χ²/dof 320 where a correct model
/// gives 1.04) before the staged start.
pub fn ten_mode_uniform_q() -> Values {
    let names: Vec<String> = (1..=10).map(|n| format!("q{n}")).collect();
    let mut v = example_values("nanostring_10mode", &names);
    v.q.iter_mut().for_each(|q| *q = 1.3e5);
    v
}

/// A parameter's name in the index families of the string models: `beta3`, `g1_2`; two
/// indices are joined by an underscore (as the model language spells `g[1,2]`).
fn family_name(base: &str, idx: &[usize]) -> String {
    let idx: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
    format!("{base}{}", idx.join("_"))
}

/// The `n`-mode string model (`n` flexural modes `f_k = k·207.58 kHz·(1 + 0.002 k²)`, a
/// Duffing term per mode and every pairwise dispersive coupling, written with index families
/// as `examples/nanostring_10mode/model.hb`) and its values (`Q_k = 116232/(1 + 0.15 (k − 1))`,
/// `β_k = β₁ k⁴`, `g_kl = 3.2 β₁ k² l²/12`, `β₁ = 2.68·10²²`): the ten-mode example's formulas
/// for any `n` (twenty modes: 20 + 190 unknown parameters).
pub fn string_model(n: usize) -> (Model, Values) {
    let f = |k: usize| k as f64 * 207_580.0 * (1.0 + 0.002 * (k * k) as f64);
    let mut text = format!(
        "# {n} flexural modes of a nanostring: a Duffing term per mode and every pairwise\n# dispersive coupling (harmonid_testgen::string_model).\n\n"
    );
    for k in 1..=n {
        text.push_str(&format!("mode q{k} at {:.3} kHz\n", f(k) / 1e3));
    }
    text.push_str(&format!(
        "\nfor i in 1..{n} {{\n    param beta[i]\n    potential: beta[i]/4 * q[i]^4\n}}\n\nfor i<j in 1..{n} {{\n    param g[i,j] >= 0\n    potential: g[i,j]/2 * q[i]^2 * q[j]^2\n}}\n"
    ));
    let model = harmonid_model::parse_str(&text, &format!("string_{n}mode.hb"))
        .unwrap_or_else(|e| panic!("{e:?}"));
    let beta1 = 2.68e22;
    let mut params = BTreeMap::new();
    for k in 1..=n {
        params.insert(family_name("beta", &[k]), beta1 * (k as f64).powi(4));
        for l in k + 1..=n {
            let g = 3.2 * beta1 * (k * k * l * l) as f64 / 12.0;
            params.insert(family_name("g", &[k, l]), g);
        }
    }
    let v = Values {
        f_hz: (1..=n)
            .map(|k| model.modes[k - 1].nominal_hz.unwrap_or(f(k)))
            .collect(),
        q: (1..=n)
            .map(|k| 116_232.0 / (1.0 + 0.15 * (k - 1) as f64))
            .collect(),
        params,
    };
    (model, v)
}

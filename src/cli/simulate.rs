//! `harmonid simulate MODEL --values V --plan P --out DIR`: simulate measurements and write a
//! dataset folder (DATA_FORMAT layout, with truth.toml).

use harmonid_ident::dataset::{
    Dataset, Manifest, Measurement, MeasurementSpec, Point, Truth, TruthForce, TruthMode,
    TruthNoise,
};
use harmonid_sim::{
    self as sim, Excitation, HbSettings, ModeValues, ModelValues, NoiseGen, NumericModel, Start,
    TdSettings,
};
use miette::{miette, IntoDiagnostic, WrapErr};
use num_complex::Complex64;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Arguments of `harmonid simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Parameter values: a TOML file (`[modes.q1] f_hz = .., Q = ..`, `[parameters] beta1 = ..`,
    /// optionally `[eom.q1] "q1^3" = ..` as in truth.toml) or an identification result (`.json`).
    #[arg(long)]
    pub values: PathBuf,
    /// The measurement plan (TOML; see docs/simulation.md).
    #[arg(long)]
    pub plan: PathBuf,
    /// Output dataset folder (replaced if it exists).
    #[arg(long)]
    pub out: PathBuf,
    /// Simulate in the time domain with lock-in demodulation instead of harmonic balance.
    #[arg(long)]
    pub time_domain: bool,
    /// With --time-domain: start from rest instead of from the harmonic-balance state.
    #[arg(long)]
    pub from_rest: bool,
    /// With --time-domain: integration steps per period of the highest frequency (refined
    /// automatically until the local error meets --rtol).
    #[arg(long, default_value_t = 16)]
    pub steps_per_period: usize,
    /// With --time-domain: local error tolerance per step, relative to each mode's linear
    /// response; the demodulated amplitudes come out accurate to about 10x this.
    #[arg(long, default_value_t = 1e-9)]
    pub rtol: f64,
    /// With --time-domain: RMS of white noise added to every sample of the measured signal, nm
    /// (demodulated with it, as a lock-in would; every shot is then its own run). Adds to the
    /// plan's per-quadrature [noise].
    #[arg(long, default_value_t = 0.0, requires = "time_domain")]
    pub noise_rms_nm: f64,
    /// Intermodulation order of the harmonic-balance lattice.
    #[arg(long, default_value_t = 9)]
    pub order: usize,
    /// Also report how much widening the lattice (order + 2, window × 1.5, direct harmonics
    /// wherever they fall) changes the result.
    #[arg(long)]
    pub check_truncation: bool,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Check each measurement's steady state for stability (Hill's method, slow-flow form)
    /// and warn when a state is unstable.
    #[arg(long)]
    pub check_stability: bool,
}

/// The measurement plan file.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Plan {
    #[serde(default)]
    pub(crate) description: String,
    #[serde(default = "unit_m")]
    pub(crate) displacement_unit: String,
    #[serde(default, rename = "point")]
    pub(crate) points: Vec<Point>,
    #[serde(default)]
    pub(crate) nominal_hz: BTreeMap<String, f64>,
    #[serde(default)]
    noise: PlanNoise,
    #[serde(rename = "measurement")]
    pub(crate) measurements: Vec<PlanMeasurement>,
}

fn unit_m() -> String {
    "m".into()
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanNoise {
    /// Std of Gaussian noise added to re and im of every amplitude, in displacement_unit.
    #[serde(default)]
    sigma_per_quadrature: f64,
    /// Number of shots (noise realisations) per measurement.
    #[serde(default)]
    shots: Option<usize>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PlanMeasurement {
    pub(crate) name: String,
    pub(crate) drives_hz: Vec<f64>,
    /// Force amplitude per tone on each mode, N/kg (`q1 = [3.5, 3.5, 0.0]`).
    force: BTreeMap<String, Vec<f64>>,
    /// Force phase per tone on each mode, rad (default 0).
    #[serde(default)]
    phase_rad: BTreeMap<String, Vec<f64>>,
    /// Measured frequencies, Hz; default: every drive tone and lattice frequency near a
    /// resonance (not the static offset nor far even-order lines, `sim::measured_lines`).
    #[serde(default)]
    pub(crate) measure_hz: Option<Vec<f64>>,
    #[serde(default)]
    drive_levels_v: Option<Vec<f64>>,
    #[serde(default)]
    drive_phases_rad: Option<Vec<f64>>,
    #[serde(default)]
    bandwidth_hz: Option<f64>,
}

/// Reads a values file: TOML ([`ModelValues`]) or an identification result JSON.
pub fn read_values(path: &Path) -> miette::Result<ModelValues> {
    let text = std::fs::read_to_string(path)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot read the values file {}", path.display()))?;
    if path.extension().is_some_and(|e| e == "json") {
        let report = harmonid_ident::Report::from_json(&text)
            .into_diagnostic()
            .wrap_err_with(|| {
                format!(
                    "{} is not an identification result (harmonid-result/1)",
                    path.display()
                )
            })?;
        Ok(values_of_report(&report))
    } else {
        // Accept a truth.toml too: keep only the keys a values file knows.
        let v: toml::Table = toml::from_str(&text)
            .into_diagnostic()
            .wrap_err_with(|| format!("{} is not valid TOML", path.display()))?;
        let mut t = toml::Table::new();
        for key in ["modes", "parameters", "eom"] {
            if let Some(x) = v.get(key) {
                t.insert(key.into(), x.clone());
            }
        }
        if let Some(k) = v
            .keys()
            .find(|k| !["modes", "parameters", "eom", "forces", "noise"].contains(&k.as_str()))
        {
            return Err(miette!(
                "{}: unknown table `{k}` (a values file has [modes.<mode>], [parameters] and optionally [eom.<mode>])",
                path.display()
            ));
        }
        toml::Value::Table(t)
            .try_into::<ModelValues>()
            .into_diagnostic()
            .wrap_err_with(|| {
                format!(
                    "{}: expected [modes.<mode>] f_hz/Q, [parameters] name = value, [eom.<mode>]",
                    path.display()
                )
            })
    }
}

/// The values of an identification result: each mode's f and Q, each parameter's value (an
/// undetermined, NaN value is left out); when the result has no parameters, its `eom`
/// coefficients.
fn values_of_report(r: &harmonid_ident::Report) -> ModelValues {
    let finite = |x: f64| x.is_finite().then_some(x);
    let mut out = ModelValues::default();
    for (k, m) in &r.modes {
        out.modes.insert(
            k.clone(),
            ModeValues {
                f_hz: finite(m.f_hz.value),
                q: finite(m.q.value),
            },
        );
    }
    for (k, e) in &r.parameters {
        if let Some(x) = finite(e.value) {
            out.parameters.insert(k.clone(), x);
        }
    }
    if out.parameters.is_empty() {
        for (mode, terms) in &r.eom {
            let map = terms
                .iter()
                .filter_map(|(k, x)| x.map(|x| (k.clone(), x)))
                .collect();
            out.eom.insert(mode.clone(), map);
        }
    }
    out
}

/// Loads the model file and evaluates it with the values file.
pub fn numeric_model(model: &Path, values: &Path) -> miette::Result<NumericModel> {
    let m = harmonid_model::load(model).map_err(miette::Report::new)?;
    let v = read_values(values)?;
    NumericModel::from_model(&m, &v)
        .into_diagnostic()
        .wrap_err_with(|| {
            format!(
                "cannot evaluate {} with {}",
                model.display(),
                values.display()
            )
        })
}

pub(crate) fn excitation(model: &NumericModel, m: &PlanMeasurement) -> miette::Result<Excitation> {
    let nd = m.drives_hz.len();
    for k in m.force.keys().chain(m.phase_rad.keys()) {
        if !model.mode_names.contains(k) {
            return Err(miette!(
                "measurement {}: force on `{k}`, which is not a mode of the model ({})",
                m.name,
                model.mode_names.join(", ")
            ));
        }
    }
    let mut force = Vec::new();
    for n in &model.mode_names {
        let a = m.force.get(n).cloned().unwrap_or_else(|| vec![0.0; nd]);
        let p = m.phase_rad.get(n).cloned().unwrap_or_else(|| vec![0.0; nd]);
        if a.len() != nd || p.len() != nd {
            return Err(miette!(
                "measurement {}: force.{n} and phase_rad.{n} need one entry per drive tone ({nd})",
                m.name
            ));
        }
        force.push(
            a.iter()
                .zip(&p)
                .map(|(&a, &p)| Complex64::from_polar(a, p))
                .collect(),
        );
    }
    Ok(Excitation {
        tones_hz: m.drives_hz.clone(),
        force,
    })
}

/// Parses a measurement plan (TOML text; `origin` names it in errors).
pub(crate) fn parse_plan(text: &str, origin: &str) -> miette::Result<Plan> {
    toml::from_str(text).into_diagnostic().wrap_err_with(|| {
        format!("{origin}: not a valid measurement plan (see docs/simulation.md)")
    })
}

/// Metres per displacement unit of the plan.
pub(crate) fn plan_unit(plan: &Plan, origin: &str) -> miette::Result<f64> {
    harmonid_ident::dataset::unit_scale(&plan.displacement_unit)
        .ok_or_else(|| miette!("{origin}: displacement_unit must be m, um, nm or pm"))
}

/// Mode shapes of the plan's measurement points (one point of unit shapes when none is given).
pub(crate) fn point_shapes(model: &NumericModel, plan: &Plan) -> Vec<Vec<f64>> {
    if plan.points.is_empty() {
        vec![vec![1.0; model.n_modes()]]
    } else {
        plan.points
            .iter()
            .map(|p| model.mode_names.iter().map(|n| p.shape_of(n)).collect())
            .collect()
    }
}

/// The dataset manifest of a plan (without measurements).
pub(crate) fn plan_manifest(model: &NumericModel, plan: &Plan) -> Manifest {
    let mut manifest = Manifest::new(plan.description.clone());
    manifest.displacement_unit = plan.displacement_unit.clone();
    manifest.points = plan.points.clone();
    manifest.nominal_hz = if plan.nominal_hz.is_empty() {
        model
            .mode_names
            .iter()
            .cloned()
            .zip(model.f_hz.iter().copied())
            .collect()
    } else {
        plan.nominal_hz.clone()
    };
    manifest
}

/// The harmonic-balance steady state of one planned measurement (lattice of intermodulation
/// order `order`, holding every measured frequency) with the excitation it was solved for; an
/// error when Newton does not converge.
pub(crate) fn plan_steady_state(
    model: &NumericModel,
    pm: &PlanMeasurement,
    order: usize,
) -> miette::Result<(sim::SteadyState, Excitation)> {
    let drive = excitation(model, pm)?;
    let mut hs = HbSettings::default();
    hs.lattice.order = order;
    if let Some(f) = &pm.measure_hz {
        hs.lattice.extra_hz = f.clone();
    }
    let st = sim::steady_state(model, &drive, &hs)
        .into_diagnostic()
        .wrap_err_with(|| format!("measurement {}", pm.name))?;
    if !st.converged() {
        return Err(miette!(
            "measurement {}: harmonic balance did not converge ({:?}, residual {:.2e}); try a smaller drive, a higher --order, or --time-domain",
            pm.name, st.status, st.residual
        ));
    }
    for s in &st.drive_jumps {
        eprintln!(
            "note: measurement {}: the drive ramp met a fold at {:.2} % of the drive and the state jumped (slow-flow landing), as a drive-up experiment would",
            pm.name,
            100.0 * s
        );
    }
    Ok((st, drive))
}

/// The frequencies a planned measurement reads: the plan's `measure_hz`, or by default the drive
/// tones and the lattice lines near a resonance (never the static offset, which a lock-in
/// dataset cannot hold, nor far even-order lines; `sim::measured_lines`).
pub(crate) fn measured_hz(
    model: &NumericModel,
    drive: &Excitation,
    pm: &PlanMeasurement,
    st: &sim::SteadyState,
    window_rel: f64,
) -> Vec<f64> {
    pm.measure_hz
        .clone()
        .unwrap_or_else(|| sim::measured_lines(model, drive, &st.lattice_hz, window_rel))
}

/// The dataset spec of a planned measurement.
pub(crate) fn plan_spec(pm: &PlanMeasurement) -> MeasurementSpec {
    MeasurementSpec {
        name: pm.name.clone(),
        file: None,
        drives_hz: pm.drives_hz.clone(),
        drive_levels_v: pm.drive_levels_v.clone(),
        drive_phases_rad: pm.drive_phases_rad.clone(),
        bandwidth_hz: pm.bandwidth_hz,
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    if !(args.noise_rms_nm.is_finite() && args.noise_rms_nm >= 0.0) {
        return Err(miette!(
            "--noise-rms-nm {}: expected a finite RMS ≥ 0 in nm",
            args.noise_rms_nm
        ));
    }
    let model = numeric_model(&args.model, &args.values)?;
    let text = std::fs::read_to_string(&args.plan)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot read the plan {}", args.plan.display()))?;
    let plan = parse_plan(&text, &args.plan.display().to_string())?;
    let unit = plan_unit(&plan, &args.plan.display().to_string())?;
    let shots = plan.noise.shots.unwrap_or(1).max(1);
    let sigma_m = plan.noise.sigma_per_quadrature * unit;
    let shapes = point_shapes(&model, &plan);
    let manifest = plan_manifest(&model, &plan);
    let mut truth = Truth {
        modes: model
            .mode_names
            .iter()
            .enumerate()
            .map(|(n, name)| {
                (
                    name.clone(),
                    TruthMode {
                        f_hz: model.f_hz[n],
                        q: model.q_factor[n],
                    },
                )
            })
            .collect(),
        eom: (0..model.n_modes())
            .map(|n| (model.mode_names[n].clone(), model.eom_map(n)))
            .collect(),
        forces: BTreeMap::new(),
        noise: Some(TruthNoise {
            sigma_per_quadrature: plan.noise.sigma_per_quadrature,
            shots: Some(shots),
        }),
    };
    let mut noise = NoiseGen::new(args.seed);
    let mut measurements = Vec::new();
    for (mi, pm) in plan.measurements.iter().enumerate() {
        let drive = excitation(&model, pm)?;
        let mut hs = HbSettings::default();
        hs.lattice.order = args.order;
        if let Some(f) = &pm.measure_hz {
            hs.lattice.extra_hz = f.clone();
        }
        let st = if args.check_truncation {
            let rep = sim::convergence_report(
                &model,
                &drive,
                &hs,
                pm.measure_hz.as_deref().unwrap_or(&[]),
            )
            .into_diagnostic()?;
            eprintln!(
                "{}: widening the lattice ({} → {} lines) changes the amplitudes by {:.2e} of the largest",
                pm.name, rep.lattice_sizes.0, rep.lattice_sizes.1, rep.change
            );
            rep.state
        } else {
            sim::steady_state(&model, &drive, &hs)
                .into_diagnostic()
                .wrap_err_with(|| format!("measurement {}", pm.name))?
        };
        if !st.converged() {
            return Err(miette!(
                "measurement {}: harmonic balance did not converge ({:?}, residual {:.2e}); try a smaller drive, a higher --order, or --time-domain",
                pm.name, st.status, st.residual
            ));
        }
        if args.check_stability {
            let v = sim::check_stability(&model, &drive, &st)
                .into_diagnostic()
                .wrap_err_with(|| format!("measurement {}: stability check", pm.name))?;
            if v.stable {
                eprintln!(
                    "{}: stable (perturbations decay at {:.3e} 1/s; linear resonator: {:.3e} 1/s)",
                    pm.name, -v.growth_rate, v.linear_decay_rate
                );
            } else {
                eprintln!(
                    "warning: {}: the steady state is UNSTABLE (perturbations grow at {:.3e} 1/s): an experiment would not stay on it. Try a smaller drive, the other side of the fold (sweep the drive frequency the other way), or --time-domain --from-rest to see where the motion settles",
                    pm.name, v.growth_rate
                );
            }
        }
        let freqs = measured_hz(&model, &drive, pm, &st, hs.lattice.window_rel);
        // With per-sample noise in the time domain every shot is its own run (own seed).
        let runs = if args.time_domain && args.noise_rms_nm > 0.0 {
            shots
        } else {
            1
        };
        let mut per_run: Vec<Vec<Vec<Complex64>>> = Vec::with_capacity(runs);
        for run_idx in 0..runs {
            let values: Vec<Vec<Complex64>> = if args.time_domain {
                let start = if args.from_rest {
                    Start::Rest
                } else {
                    let (q, v) = st.state_at(0.0);
                    Start::State { q, v }
                };
                let ts = TdSettings {
                    steps_per_period: args.steps_per_period,
                    rtol: args.rtol,
                    noise_rms: args.noise_rms_nm * 1e-9,
                    seed: args
                        .seed
                        .wrapping_add(1 + run_idx as u64)
                        .wrapping_add((mi as u64) << 32),
                    ..TdSettings::default()
                };
                let r = sim::simulate_lockin(&model, &drive, &freqs, &shapes, &start, &ts)
                    .into_diagnostic()
                    .wrap_err_with(|| format!("measurement {}", pm.name))?;
                eprintln!(
                    "{}: time domain, {} steps, {} lock-in samples per window, settled to {:.1e}",
                    pm.name, r.steps, r.samples, r.settle_change
                );
                r.points
            } else {
                shapes
                    .iter()
                    .map(|s| freqs.iter().map(|&f| st.at_point(s, f)).collect())
                    .collect()
            };
            per_run.push(values);
        }
        let spec = plan_spec(pm);
        let point_idx: Vec<usize> = (0..plan.points.len()).collect();
        let mut meas = Measurement::zeros(spec, freqs.clone(), point_idx, shots);
        for s in 0..shots {
            let values = &per_run[s.min(per_run.len() - 1)];
            for (f, _) in freqs.iter().enumerate() {
                for (p, row) in values.iter().enumerate() {
                    let mut z = row[f];
                    if sigma_m > 0.0 {
                        z += noise.complex(sigma_m);
                    }
                    if !(z.re.is_finite() && z.im.is_finite()) {
                        return Err(miette!(
                            "measurement {}: a non-finite amplitude; nothing written",
                            pm.name
                        ));
                    }
                    *meas.amplitude_mut(s, f, p) = z;
                }
            }
        }
        measurements.push(meas);
        let mut per_mode = BTreeMap::new();
        for (n, name) in model.mode_names.iter().enumerate() {
            if drive.force[n].iter().any(|z| z.norm() > 0.0) {
                per_mode.insert(
                    name.clone(),
                    TruthForce {
                        amplitude: drive.force[n].iter().map(|z| z.norm()).collect(),
                        phase_rad: drive.force[n].iter().map(|z| z.arg()).collect(),
                    },
                );
            }
        }
        truth.forces.insert(pm.name.clone(), per_mode);
        eprintln!(
            "{}: {} frequencies, lattice {} lines, residual {:.1e}",
            pm.name,
            freqs.len(),
            st.lattice_hz.len(),
            st.residual
        );
    }
    let ds = Dataset {
        dir: args.out.clone(),
        manifest,
        measurements,
        truth: Some(truth),
    };
    ds.write(&args.out)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot write the dataset {}", args.out.display()))?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

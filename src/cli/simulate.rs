//! `harmonid simulate MODEL --values V --plan P --out DIR`: simulate measurements and write a
//! dataset folder (the layout of docs/data-format.md, with truth.toml). The work is
//! [`harmonid_experiment::Plan::simulate`]; this file parses arguments and prints.

use harmonid_experiment::{self as experiment, Engine, Plan, Settings, TimeDomain, Truncation};
use harmonid_sim::NumericModel;
use miette::{IntoDiagnostic, WrapErr};
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
    /// Output dataset folder: created, or replaced when it is empty or a harmonid dataset.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace `--out` even when it is a non-empty folder that is not a harmonid dataset (never
    /// a folder holding the model, values or plan, or any model, values, plan or result file).
    #[arg(long)]
    pub force: bool,
    /// Simulate in the time domain with lock-in demodulation instead of harmonic balance.
    #[arg(long)]
    pub time_domain: bool,
    /// With --time-domain: start from rest instead of from the harmonic-balance state.
    #[arg(long, requires = "time_domain")]
    pub from_rest: bool,
    /// With --time-domain: integration steps per period of the highest frequency (4 to 512;
    /// refined automatically until the local error meets --rtol).
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
    /// Intermodulation order of the harmonic-balance lattice to start from (raised
    /// automatically until the measured lines change by less than 1e-6 of the largest).
    #[arg(long, default_value_t = 9)]
    pub order: usize,
    /// Write states whose truncation check fails (the measured lines still change by more than
    /// 1e-6 at order 17) instead of refusing.
    #[arg(long)]
    pub allow_truncation: bool,
    /// Write unstable steady states (Hill's method) instead of refusing.
    #[arg(long)]
    pub allow_unstable: bool,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Accepted for older scripts: stability is always checked now.
    #[arg(long, hide = true)]
    pub check_stability: bool,
    /// Accepted for older scripts: truncation is always checked now.
    #[arg(long, hide = true)]
    pub check_truncation: bool,
}

/// Reads a values file: TOML or an identification result (`.json`).
pub fn read_values(path: &Path) -> miette::Result<harmonid_sim::ModelValues> {
    Ok(experiment::read_values(path)?)
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

/// Reads and checks a plan file.
pub fn read_plan(path: &Path) -> miette::Result<Plan> {
    let text = std::fs::read_to_string(path)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot read the plan {}", path.display()))?;
    Ok(Plan::from_toml(&text, &path.display().to_string())?)
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let inputs = [args.model.as_path(), &args.values, &args.plan];
    let opts = harmonid_files::DirWrite {
        force: args.force,
        inputs: &inputs,
    };
    // Before any work: a run that cannot write its output fails at once.
    harmonid_files::check_output_dir(&args.out, opts).map_err(miette::Report::new)?;
    let model = numeric_model(&args.model, &args.values)?;
    let plan = read_plan(&args.plan)?;
    let settings = Settings {
        engine: if args.time_domain {
            Engine::TimeDomain(TimeDomain {
                from_rest: args.from_rest,
                steps_per_period: args.steps_per_period,
                rtol: args.rtol,
                noise_rms_m: args.noise_rms_nm * 1e-9,
            })
        } else {
            Engine::HarmonicBalance
        },
        order: args.order,
        truncation: Truncation {
            required: !args.allow_truncation,
            ..Truncation::default()
        },
        check_stability: true,
        allow_unstable: args.allow_unstable,
        noise: true,
        seed: args.seed,
        min_line_rel: 0.0,
        stop_at_fold: false,
    };
    let pb = super::progress::spinner(&format!(
        "simulating {} measurement(s){}",
        plan.measurements.len(),
        if args.time_domain {
            " in the time domain"
        } else {
            ""
        }
    ));
    let sim = plan.simulate_numeric(&model, &settings);
    pb.finish_and_clear();
    let sim = sim?;
    for r in &sim.reports {
        for s in &r.drive_jumps {
            eprintln!(
                "note: {}: the drive ramp met a fold at {:.2} % of the drive and the state jumped (slow-flow landing), as a drive-up experiment would",
                r.name,
                100.0 * s
            );
        }
        let stab = match &r.stability {
            Some(v) if v.stable => format!(
                "stable (perturbations decay at {:.3e} 1/s; linear resonator: {:.3e} 1/s)",
                -v.growth_rate, v.linear_decay_rate
            ),
            Some(v) => format!("UNSTABLE (perturbations grow at {:.3e} 1/s)", v.growth_rate),
            None => "stability not checked".into(),
        };
        eprintln!("{}: {stab}", r.name);
        let trunc = match r.truncation_change {
            Some(c) => format!(
                ", order {} (widening changes the lines by {c:.1e})",
                r.order
            ),
            None => String::new(),
        };
        eprintln!(
            "{}: {} frequencies, lattice {} lines{trunc}, residual {:.1e}",
            r.name, r.measured, r.lattice_lines, r.residual
        );
        if let Some((steps, samples, change)) = r.time_domain {
            eprintln!(
                "{}: time domain, {steps} steps, {samples} lock-in samples per window, settled to {change:.1e}",
                r.name
            );
        }
        for n in &r.notes {
            eprintln!("warning: {}: {n}", r.name);
        }
    }
    for l in &sim.lost_levels {
        eprintln!(
            "warning: {}: level {} of its ladder ({:.3} of the forces) is left out of the dataset: it has no stable steady state on this device ({})",
            l.measurement, l.level, l.fraction, l.why
        );
    }
    let mut ds = sim.dataset;
    ds.dir = args.out.clone();
    ds.write_with(&args.out, opts)
        .map_err(miette::Report::new)
        .wrap_err_with(|| format!("cannot write the dataset {}", args.out.display()))?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

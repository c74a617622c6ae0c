//! `harmonid plan MODEL --values GUESS --noise SIGMA --shots N (--out plan.toml | --evaluate
//! plan.toml)`: design a drive-tone plan, or score one, by the Cramér–Rao bounds of the
//! model's unknowns (`harmonid_plan`).

use crate::cli::common::{check_outputs, print_out, write_output};
use harmonid_data::Point;
use harmonid_experiment::{guess_from_reports, read_guess, read_result, Plan};
use harmonid_plan::{
    design_for_instrument, evaluate, lockin_lines, lockin_plan, lockin_time_s, robustness,
    DesignSettings, Evaluation, GuessRange, InstrumentSettings, LockIn,
};
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::PathBuf;

/// Arguments of `harmonid plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Guessed values (TOML `[modes.*]`/`[parameters]`, a truth.toml or a result JSON). A
    /// value may carry its uncertainty (`beta1 = { value = 6e23, factor = 2 }`, `Q = { value =
    /// 4.5e5, rel = 0.3 }`, `f_hz = { value = 207600, abs_hz = 3 }`; a result's estimates are
    /// spread by 3 standard errors); the others get defaults (f ± 2 linewidths, Q ± 30 %,
    /// parameters ×/÷ 2). The plan is designed to survive every device of that range.
    #[arg(long)]
    pub values: PathBuf,
    /// An identification result of this device (`identify --out`; repeatable, one per round of
    /// measurements): the estimates, combined over the results by inverse-variance weights,
    /// ± 3 standard errors, narrow the --values guess's range where they are determined (the
    /// lab loop: plan, measure, identify, plan --after the results).
    #[arg(long, value_name = "RESULT.json")]
    pub after: Vec<PathBuf>,
    /// Design and score at the guess only, as if it were the device (no range, no corners).
    #[arg(long)]
    pub nominal: bool,
    /// Each measurement's drive ladder: fractions of its designed forces, rising, each in
    /// (0, 1] (`--ladder 0.5,0.75,1`; `--ladder 1` for none). A level with no stable state
    /// on the device costs that level, not the measurement. Default: 0.5,0.75,1 over the
    /// guess's range, none with --nominal.
    #[arg(long, value_delimiter = ',', value_name = "FRACTIONS")]
    pub ladder: Option<Vec<f64>>,
    /// Devices drawn from the guess's range for the plan's median and worst bounds.
    #[arg(long, value_name = "N", default_value_t = harmonid_plan::DEFAULT_DRAWS)]
    pub draws: usize,
    /// Per-quadrature noise σ of every lock-in amplitude, in the dataset's unit: metres, or
    /// with a unit (`0.05nm`, `50pm`, `1e-10m`); volts for data kept in the instrument's volts
    /// (`2uV`, `0.04V`, `3mV`, `5nV`: the plan's `displacement_unit` is then `V`).
    #[arg(long)]
    pub noise: String,
    /// Shots per measurement.
    #[arg(long, default_value_t = 1)]
    pub shots: usize,
    /// Write the designed plan here (TOML, what `simulate --plan` reads); written atomically,
    /// only when every unknown is identifiable.
    #[arg(
        long,
        conflicts_with = "evaluate",
        required_unless_present = "evaluate"
    )]
    pub out: Option<PathBuf>,
    /// Score this plan instead of designing one.
    #[arg(long)]
    pub evaluate: Option<PathBuf>,
    /// Also write the relative bounds as JSON (`{"modes": {"q1": {"f_hz": .., "Q": ..}},
    /// "parameters": {..}}`).
    #[arg(long)]
    pub bounds: Option<PathBuf>,
    /// Most measured lines per measurement (the lock-in's limit).
    #[arg(long, default_value_t = 32)]
    pub max_frequencies: usize,
    /// Most measurements in the designed plan.
    #[arg(long)]
    pub max_measurements: Option<usize>,
    /// Instrument frequency grid, Hz: every tone and so every measured line is a multiple (a
    /// multi-frequency lock-in's base frequency; a shot integrates at least 1/grid s).
    #[arg(
        long = "grid-hz",
        visible_alias = "bandwidth",
        value_name = "HZ",
        default_value_t = 0.5
    )]
    pub grid_hz: f64,
    /// An actuator gain, N/kg per volt: `--gain q1=0.35` (repeatable). With gains the plan's
    /// drive levels are volts.
    #[arg(long, value_name = "MODE=GAIN")]
    pub gain: Vec<String>,
    /// Take the actuator gains from an identification result (each mode's |G|: its common
    /// gain, else the median over measurements; a --gain wins).
    #[arg(long, value_name = "RESULT.json")]
    pub gains_from: Option<PathBuf>,
    /// Largest drive level, V (needs a gain for every driven mode): per tone with the generic
    /// instrument; with an --instrument profile the tones' summed amplitude on the one output
    /// (default: the profile's output range).
    #[arg(long, value_name = "V")]
    pub max_voltage: Option<f64>,
    /// The lock-in that runs the plan: mfli, mfli-mf (with the MF-MD option), hf2li (with
    /// HF2-MF), uhfli (with UHF-MF), moku, or generic (no instrument limits). A profile holds
    /// the plan to its oscillators, demodulators and output range, caps the tones' summed
    /// volts, and writes per level the drive volts, the demodulator filter, the settling time
    /// and the samples (the plan's `[instrument]`); it needs the actuator gains (--gain or
    /// --gains-from).
    #[arg(long, value_name = "NAME", default_value = "generic")]
    pub instrument: LockIn,
    /// The demodulator filter's order (poles, 6 dB/octave each) with an --instrument profile;
    /// default: the order that settles fastest while rejecting the nearest other line by 60 dB.
    #[arg(long, value_name = "N")]
    pub filter_order: Option<u32>,
    /// Largest drive force per tone, N/kg.
    #[arg(long)]
    pub max_force: Option<f64>,
    /// Wall-clock budget of the whole design, s: once spent, each measurement still to design
    /// keeps the first feasible candidate (or the best tried so far), the final pass skips the
    /// truncation check of the measurements it has not reached, and the devices drawn from the
    /// range are scored only as far as it went (at least one); the plan says what was
    /// skipped. 0 for no budget.
    #[arg(long, value_name = "SECONDS", default_value_t = 120.0)]
    pub time_budget: f64,
    /// A measurement point with the mode shapes there: `--point q1=0.309,q2=0.588`
    /// (repeatable; default: modal amplitudes).
    #[arg(long, value_name = "MODE=SHAPE,...")]
    pub point: Vec<String>,
    /// Also draw the plan to this file, `.svg` or `.png`: per measurement, each mode's linear
    /// response, the tones and the lines the plan predicts (with their combinations) against
    /// the noise.
    #[arg(long, value_name = "FILE.svg|png")]
    pub plot: Option<PathBuf>,
}

/// Volt units `--noise` reads, with how many of each make one volt (longest suffix first).
const VOLT_UNITS: [(&str, f64); 5] = [
    ("mV", 1e3),
    ("uV", 1e6),
    ("µV", 1e6),
    ("nV", 1e9),
    ("V", 1.0),
];

/// Parses `0.05nm`, `50pm`, `1e-10`, `1e-10m` into metres, or `2uV`, `0.04 V` into volts (a
/// positive σ), with the dataset unit it is in (`m` or `V`).
fn parse_sigma(s: &str) -> miette::Result<(f64, &'static str)> {
    let t = s.trim();
    let quoted: String = t.chars().take(40).collect();
    if let Some((unit, per)) = VOLT_UNITS.iter().find(|(u, _)| t.ends_with(u)) {
        return match t[..t.len() - unit.len()].trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok((v / per, harmonid_data::units::VOLTS)),
            _ => Err(miette!(
                "--noise {quoted}: expected a positive finite σ in volts, e.g. 2uV or 0.04V"
            )),
        };
    }
    match harmonid_data::parse_length(t) {
        Ok(v) if v > 0.0 => Ok((v, "m")),
        Ok(_) => Err(miette!(
            "--noise {quoted}: expected a positive σ, e.g. 0.05nm (or 2uV for data in volts)"
        )),
        Err(e) => Err(miette!(
            "--noise {quoted}: {e}; data kept in volts take volts (2uV, 0.04V)"
        )),
    }
}

fn parse_point(i: usize, s: &str) -> miette::Result<Point> {
    let mut shape = std::collections::BTreeMap::new();
    for part in s.split(',') {
        let (m, v) = part.split_once('=').ok_or_else(|| {
            miette!("--point {s}: expected MODE=SHAPE pairs, e.g. q1=0.309,q2=0.588")
        })?;
        let v: f64 = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| miette!("--point {s}: `{v}` is not a number"))?;
        shape.insert(m.trim().to_string(), v);
    }
    Ok(Point {
        name: format!("p{i}"),
        shape,
    })
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let guess = read_guess(&args.values)?;
    let values = values_with_parameters(&model, guess.values, &args.values)?;
    let mut results = Vec::with_capacity(args.after.len());
    for p in &args.after {
        results.push(read_result(p)?);
    }
    let found = guess_from_reports(&results);
    if !results.is_empty() {
        eprintln!(
            "{} result(s): {} estimates with a standard error narrow the guess (± {} combined standard errors)",
            results.len(),
            found.spread.len(),
            harmonid_experiment::RESULT_SPREAD_STDERR
        );
    }
    let (sigma, unit) = parse_sigma(&args.noise)?;
    check_noise_unit(&results, &args.after, &args.noise, unit)?;
    if args.shots == 0 {
        return Err(miette!("--shots must be at least 1"));
    }
    harmonid_plan::check_draws(args.draws)?;
    let inst = InstrumentSettings {
        lockin: args.instrument,
        max_voltage: args.max_voltage,
        filter_order: args.filter_order,
    };
    inst.checked()?;
    let inputs: Vec<&std::path::Path> = [
        Some(&args.model),
        Some(&args.values),
        args.evaluate.as_ref(),
    ]
    .into_iter()
    .flatten()
    .chain(&args.after)
    .map(|p| p.as_path())
    .collect();
    let outputs: Vec<&std::path::Path> = [args.out.as_ref(), args.bounds.as_ref()]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    check_outputs(&outputs, &inputs)?;
    if let Some(p) = &args.plot {
        super::figure::check(p, &inputs)?;
    }
    let (values, range) = if args.nominal {
        let g = harmonid_experiment::Guess {
            values,
            spread: guess.spread,
        };
        (g.updated_by(&found).values, None)
    } else {
        let r = GuessRange::new(&model, &values, &guess.spread)?.narrowed(&model, &found)?;
        eprintln!(
            "the guess's range (the plan is checked over it; --nominal for the guess alone):"
        );
        for line in r.describe() {
            eprintln!("  {line}");
        }
        if r.entries()
            .iter()
            .any(|e| e.name.starts_with("f_hz:") && !e.given)
        {
            eprintln!(
                "note: a frequency known only to ± {} linewidths keeps every drive weak (the \
                 resonance may sit under any tone); identify a low-drive measurement first and \
                 plan --after its result (its estimates ± 3 standard errors narrow the range)",
                harmonid_plan::DEFAULT_F_LINEWIDTHS
            );
        }
        (r.guess().clone(), Some(r))
    };
    let (plan, ev) = if let Some(path) = &args.evaluate {
        evaluate_plan(&args, &model, &values, range.as_ref(), sigma, &inst, path)?
    } else {
        design_plan(&args, &model, &values, range, (sigma, unit), &inst, &inputs)?
    };
    print_out(format_args!("{}", ev.table()));
    if let Some(i) = &plan.instrument {
        print_out(format_args!("{}\n", lockin_lines(i).join("\n")));
    }
    if let Some(text) = what_new_data_add(&found, &ev) {
        print_out(format_args!("{text}"));
    }
    if let Some(b) = &args.bounds {
        let text = serde_json::to_string_pretty(&ev.to_json()).into_diagnostic()?;
        write_output(b, text.as_bytes(), &inputs)?;
    }
    if let Some(path) = &args.plot {
        let fig = figure(&model, &values, &plan, sigma, args.shots)?;
        super::figure::save(&fig, path, &inputs)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// `--evaluate`: scores the plan at `path` (over `range` when there is one) and, with an
/// instrument profile, checks it against the instrument and derives its lock-in settings.
fn evaluate_plan(
    args: &Args,
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    range: Option<&GuessRange>,
    sigma: f64,
    inst: &InstrumentSettings,
    path: &std::path::Path,
) -> miette::Result<(Plan, Evaluation)> {
    let text = std::fs::read_to_string(path)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot read the plan {}", path.display()))?;
    let mut plan = Plan::from_toml(&text, &path.display().to_string())?;
    if inst.lockin != LockIn::Generic {
        let num = harmonid_sim::NumericModel::from_model(model, values).into_diagnostic()?;
        plan.noise.shots = args.shots;
        plan.instrument = Some(lockin_plan(&plan, &num, inst).wrap_err_with(|| {
            format!(
                "{}: cannot be run on --instrument {}",
                path.display(),
                inst.lockin
            )
        })?);
    }
    let pb = super::progress::spinner("scoring the plan");
    let ev = evaluate(model, values, &plan, sigma, args.shots).and_then(|mut ev| {
        if let Some(r) = range {
            ev.robustness = Some(robustness(model, r, &plan, sigma, args.shots, args.draws)?);
        }
        Ok(ev)
    });
    pb.finish_and_clear();
    Ok((plan, ev?))
}

/// `--out`: designs the plan (held to the instrument's profile) and writes it, in the noise's
/// unit, saying how long the lock-in takes to run it.
#[allow(clippy::too_many_arguments)]
fn design_plan(
    args: &Args,
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    range: Option<GuessRange>,
    (sigma, unit): (f64, &str),
    inst: &InstrumentSettings,
    inputs: &[&std::path::Path],
) -> miette::Result<(Plan, Evaluation)> {
    let points = args
        .point
        .iter()
        .enumerate()
        .map(|(i, s)| parse_point(i, s))
        .collect::<miette::Result<Vec<_>>>()?;
    let settings = DesignSettings {
        sigma_m: sigma,
        shots: args.shots,
        max_frequencies: args.max_frequencies,
        max_measurements: args.max_measurements,
        grid_hz: args.grid_hz,
        max_force: args.max_force.unwrap_or(f64::INFINITY),
        gains: gains(args)?,
        max_voltage: args.max_voltage,
        points,
        time_budget_s: (args.time_budget > 0.0).then_some(args.time_budget),
        ladder: args
            .ladder
            .clone()
            .unwrap_or_else(|| harmonid_plan::default_ladder(range.is_some())),
        range,
        draws: args.draws,
    };
    let pb = super::progress::bar(0, "designing measurement", false);
    let designed = design_for_instrument(model, values, &settings, inst, &mut |step| {
        pb.set_length(step.total as u64);
        pb.set_position(step.done as u64);
        pb.set_message(step.name.to_string());
    });
    pb.finish_and_clear();
    let (mut plan, ev) = designed?;
    plan.displacement_unit = unit.to_string();
    for note in &ev.notes {
        eprintln!("note: {note}");
    }
    if let Some(out) = &args.out {
        write_output(out, plan.to_toml().as_bytes(), inputs)?;
        let recorded: usize = plan
            .measurements
            .iter()
            .map(|m| m.levels.len().max(1))
            .sum();
        let shots = recorded * args.shots;
        let time = match &plan.instrument {
            Some(i) => format!(
                "on {}: {:.4e} s of settling and recording in all (per level below)",
                i.profile,
                lockin_time_s(i)
            ),
            None => format!(
                "on a {} Hz grid each shot integrates at least {} s, the plan's {shots} shots at least {} s (a multi-frequency lock-in's base period; --instrument gives a lock-in's own times)",
                args.grid_hz,
                1.0 / args.grid_hz,
                shots as f64 / args.grid_hz
            ),
        };
        eprintln!(
            "wrote {} ({} measurements, {recorded} with their ladders' levels; {time})",
            out.display(),
            plan.measurements.len(),
        );
    }
    Ok((plan, ev))
}

/// Refuses a `--noise` in metres for data in volts, or the reverse: the plan's σ is in the unit
/// of the data the `--after` results were identified from (their dataset's `dataset.toml`,
/// when it can be read from here; a result whose dataset cannot is not checked).
fn check_noise_unit(
    results: &[harmonid_data::result::Report],
    paths: &[PathBuf],
    noise: &str,
    unit: &str,
) -> miette::Result<()> {
    let volts = harmonid_data::units::VOLTS;
    for (r, path) in results.iter().zip(paths) {
        let manifest = std::path::Path::new(&r.dataset).join("dataset.toml");
        let Ok(text) = std::fs::read_to_string(&manifest) else {
            continue;
        };
        let Some(data_unit) = text
            .parse::<toml::Table>()
            .ok()
            .and_then(|t| t.get("displacement_unit")?.as_str().map(String::from))
        else {
            continue;
        };
        if (data_unit == volts) != (unit == volts) {
            let example = if data_unit == volts { "2uV" } else { "0.05nm" };
            return Err(miette!(
                "--noise {}: a σ in {}, but {} was identified from {} whose amplitudes are in {data_unit}: give the noise in the data's unit (e.g. --noise {example})",
                noise.chars().take(40).collect::<String>(),
                if unit == volts { "volts" } else { "metres" },
                path.display(),
                manifest.display()
            ));
        }
    }
    Ok(())
}

/// With `--after` results: per quantity, the relative standard error of the existing data
/// (the results combined), the new plan's bound alone, and both together (`1/√(1/a² + 1/b²)`,
/// independent data; correlations between quantities are not used). `None` without results.
fn what_new_data_add(found: &harmonid_experiment::Guess, ev: &Evaluation) -> Option<String> {
    if found.spread.is_empty() {
        return None;
    }
    let mut out = String::from(
        "what the new data add (relative standard errors: the --after results combined, the plan alone, both):\n",
    );
    for b in &ev.bounds.quantities {
        let Some(harmonid_experiment::Spread::Abs(a)) = found.spread.get(&b.name) else {
            continue;
        };
        let before = a / harmonid_experiment::RESULT_SPREAD_STDERR / b.value.abs();
        let both = (before.powi(-2) + b.rel.powi(-2)).powf(-0.5);
        out.push_str(&format!(
            "  {:<14} {:>10.3e} {:>10.3e} {:>10.3e}  ({:.2}× smaller)\n",
            b.name,
            before,
            b.rel,
            both,
            before / both
        ));
    }
    Some(out)
}

/// The actuator gains (N/kg per V) of `--gain` and `--gains-from`.
fn gains(args: &Args) -> miette::Result<std::collections::BTreeMap<String, f64>> {
    let mut out = std::collections::BTreeMap::new();
    if let Some(path) = &args.gains_from {
        let r = read_result(path)?;
        // Each mode's |G| over the measurements (the common gain alone when there is one).
        let mut per_mode: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
        let common = r.gains.get("all");
        for (meas, modes) in &r.gains {
            if common.is_some() && meas != "all" {
                continue;
            }
            for (mode, g) in modes {
                if g.amplitude.is_finite() && g.amplitude > 0.0 {
                    per_mode.entry(mode.clone()).or_default().push(g.amplitude);
                }
            }
        }
        for (mode, mut list) in per_mode {
            list.sort_by(f64::total_cmp);
            out.insert(mode, list[list.len() / 2]);
        }
        if out.is_empty() {
            return Err(miette!(
                "--gains-from {}: the result has no actuator gains (identify with drive levels in the dataset gives them)",
                path.display()
            ));
        }
    }
    for g in &args.gain {
        let parsed = g
            .split_once('=')
            .and_then(|(m, v)| Some((m.trim().to_string(), v.trim().parse::<f64>().ok()?)))
            .filter(|(_, v)| v.is_finite() && *v > 0.0);
        let Some((mode, v)) = parsed else {
            return Err(miette!(
                "--gain {g}: expected MODE=GAIN with a positive gain in N/kg per volt, e.g. q1=0.35"
            ));
        };
        out.insert(mode, v);
    }
    Ok(out)
}

/// The guess with every parameter: a `truth.toml` or a result of a per-equation model gives
/// `[eom]` coefficients only, and planning needs the parameters (`harmonid_experiment::
/// parameters_from_eom`); says on standard error what it derived and how well the model's form
/// reproduces the coefficients.
fn values_with_parameters(
    model: &harmonid_model::Model,
    values: harmonid_sim::ModelValues,
    path: &std::path::Path,
) -> miette::Result<harmonid_sim::ModelValues> {
    let origin = path.display().to_string();
    let Some(d) = harmonid_experiment::parameters_from_eom(model, &values, &origin)? else {
        return Ok(values);
    };
    let list: Vec<String> = d
        .derived
        .iter()
        .map(|(n, v)| format!("{n} = {v:.6e}"))
        .collect();
    eprintln!(
        "{origin}: parameters from its {} [eom] coefficients by least squares: {}",
        d.coefficients,
        list.join(", ")
    );
    if let Some((label, misfit)) = d.worst.filter(|(_, m)| *m > 1e-9) {
        eprintln!(
            "warning: the model's form misses the given coefficients by up to {misfit:.2e} of \
             their equation's largest ({label}): the guess is the model's nearest"
        );
    }
    Ok(d.values)
}

/// The plan's figure: its measurements simulated without noise, the noise σ of one shot.
fn figure(
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    plan: &Plan,
    sigma: f64,
    shots: usize,
) -> miette::Result<harmonid_plot::PlanFigure> {
    let numeric = harmonid_sim::NumericModel::from_model(model, values).into_diagnostic()?;
    let sim = plan.simulate_numeric(
        &numeric,
        &harmonid_experiment::Settings {
            noise: false,
            ..Default::default()
        },
    )?;
    let mut excitations = Vec::with_capacity(plan.measurements.len());
    for m in &plan.measurements {
        excitations.push(m.excitation(&numeric)?);
    }
    Ok(harmonid_report::plan::plan_figure(
        &numeric,
        &excitations,
        &sim.dataset,
        Some(sigma),
        &format!(
            "plan: {} measurement(s), {shots} shot(s) each; predicted lines (noise-free) over the linear responses",
            plan.measurements.len()
        ),
    ))
}

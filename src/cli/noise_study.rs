//! `harmonid noise-study`: the robustness study of the paper's Supplementary Note V as a command.
//!
//! The measurements of a plan (default: the three measurements of the two-mode nanostring
//! identification, single_q1, single_q2 and couple_q1_q2) are simulated once without noise
//! ([`harmonid_experiment::Plan::simulate`]); then, for every noise level and every realisation,
//! seeded Gaussian noise is added to the demodulated amplitudes and the model is re-identified.
//! Levels are given as the per-quadrature σ of the lock-in amplitudes (default), as an
//! amplitude spectral density seen through the lock-in's equivalent noise bandwidth, or as the
//! RMS of white noise on the time signal ([`harmonid_experiment::NoiseLevel`] converts each to
//! σ). White noise demodulated over whole periods is exactly that Gaussian, so the default route
//! is statistically the same as adding the noise to the time signal and demodulating;
//! `--time-domain` does the latter literally.

use crate::cli::common::{check_outputs, write_output};
use crate::cli::simulate::read_plan;
use harmonid_data::Dataset;
use harmonid_experiment::{
    add_noise, values_from_toml, Engine, NoiseLevel, Plan, Settings, TimeDomain,
};
use harmonid_ident::{ForceModel, Problem, Report, Settings as IdentSettings};
use harmonid_sim::{self as sim, NoiseGen, NumericModel};
use miette::{miette, IntoDiagnostic, WrapErr};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

/// The default model: the two-mode nanostring example, compiled in so the command runs from any
/// folder.
pub const DEFAULT_MODEL: &str = include_str!("../../examples/nanostring_2mode/model.hb");

/// Parameter values of the paper's Table S2 (the nanostring with 50 µm supports), used when no
/// `--values` file is given: the two-mode example's own values file.
pub const DEFAULT_VALUES: &str = include_str!("../../examples/nanostring_2mode/values.toml");

/// The default plan: the three measurements of Supplementary Note V (tones 20 Hz apart). Unlike
/// `examples/nanostring_2mode/plan.toml` it gives no drive levels, so every tone's force is a free
/// unknown as in the paper's study.
pub const DEFAULT_PLAN: &str = r#"
description = "nanostring, three measurements of the two-mode identification (Supplementary Note V)"
displacement_unit = "m"

[[point]]
name = "p0"
shape = { q1 = 0.3090169943749474, q2 = 0.5877852522924731 }

[[measurement]]
name = "single_q1"
drives_hz = [207572.5, 207592.5]
force = { q1 = [3.5, 3.5] }
measure_hz = [207492.5, 207512.5, 207532.5, 207552.5, 207572.5, 207592.5, 207612.5, 207632.5, 207652.5, 207672.5]

[[measurement]]
name = "single_q2"
drives_hz = [415831.5, 415851.5]
force = { q2 = [1.81, 1.81] }
measure_hz = [415751.5, 415771.5, 415791.5, 415811.5, 415831.5, 415851.5, 415871.5, 415891.5, 415911.5, 415931.5]

[[measurement]]
name = "couple_q1_q2"
drives_hz = [207572.5, 207592.5, 415841.5]
force = { q1 = [3.5, 3.5, 0.0], q2 = [0.0, 0.0, 1.81] }
measure_hz = [207492.5, 207512.5, 207532.5, 207552.5, 207572.5, 207592.5, 207612.5, 207632.5, 207652.5, 207672.5, 415761.5, 415781.5, 415801.5, 415821.5, 415841.5, 415861.5, 415881.5, 415901.5, 415921.5]
"#;

/// Most realisations per level.
const MAX_REALISATIONS: usize = 10_000;
/// Most noise levels.
const MAX_LEVELS: usize = 64;
/// Most identifications of one study.
const MAX_TASKS: usize = 200_000;
/// Most time-domain runs of one study (about a second each).
const MAX_TD_RUNS: usize = 2_000;

/// Arguments of `harmonid noise-study`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`); default: the two-mode nanostring example (built in).
    pub model: Option<PathBuf>,
    /// Parameter values (TOML as for `harmonid simulate`, or a result JSON); default: the
    /// paper's Table S2 values of the two-mode nanostring.
    #[arg(long)]
    pub values: Option<PathBuf>,
    /// Measurement plan (TOML as for `harmonid simulate`); default: the three measurements of
    /// Supplementary Note V. Its [noise] table is ignored.
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// Noise levels as the standard deviation of each quadrature (re, im) of the lock-in
    /// amplitudes, comma separated, in metres or with a unit (`5e-14`, `0.05pm`); default: one
    /// per decade from 1e-15 to 1e-10 m.
    #[arg(long, value_delimiter = ',', value_name = "SIGMA,..", conflicts_with_all = ["asd", "levels_nm"])]
    pub sigma: Option<Vec<String>>,
    /// Noise levels as a one-sided amplitude spectral density, m/√Hz (or with a length unit:
    /// `10fm` = 10 fm/√Hz), comma separated; σ = ASD·√(2·ENBW) (see --enbw-hz).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ASD,..",
        conflicts_with = "levels_nm"
    )]
    pub asd: Option<Vec<String>>,
    /// Noise levels as the RMS of white noise on the time signal, nm, comma separated;
    /// σ = RMS·√(2/N) with N = --sample-rate-hz × --window-s samples per lock-in window.
    #[arg(long, value_delimiter = ',', value_name = "NM,NM,..")]
    pub levels_nm: Option<Vec<f64>>,
    /// Noise realisations (independent identifications) per level.
    #[arg(long, default_value_t = 30)]
    pub realisations: usize,
    /// Seed of the noise (each level and realisation has its own stream derived from it).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Lock-in integration time per measurement, s (200 ms as in the paper).
    #[arg(long, default_value_t = 0.2)]
    pub window_s: f64,
    /// Equivalent noise bandwidth of the lock-in, Hz, for --asd (default: 1/(2·window), the
    /// boxcar average over the window).
    #[arg(long)]
    pub enbw_hz: Option<f64>,
    /// Sample rate of the time signal, Hz, for --levels-nm (default: 8 samples per period of
    /// the highest measured frequency, as the time-domain lock-in emulation samples; at least
    /// twice the highest measured frequency).
    #[arg(long)]
    pub sample_rate_hz: Option<f64>,
    /// Simulate every realisation in the time domain with noise added to the samples and
    /// demodulate (faithful to the paper, much slower: seconds per measurement and
    /// realisation; the window is then the lock-in's, a whole number of periods of every
    /// frequency, not --window-s). Levels as --levels-nm.
    #[arg(long, conflicts_with_all = ["sigma", "asd"])]
    pub time_domain: bool,
    /// Intermodulation order of the harmonic-balance lattice.
    #[arg(long, default_value_t = 9)]
    pub order: usize,
    /// Write the table of estimates per level to this CSV (and a Markdown table beside it,
    /// same name with `.md`).
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Also draw the study (every quantity's estimates with their mean ± 3σ against the noise
    /// level, the truth dashed; the paper's Fig. S3) to this file, `.svg` or `.png`.
    #[arg(long, value_name = "FILE.svg|png")]
    pub plot: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// A length with an optional unit suffix (`harmonid_data::units`), in metres.
fn parse_length(s: &str, option: &str) -> miette::Result<f64> {
    harmonid_data::parse_length(s).map_err(|e| match e {
        harmonid_data::LengthError::OutOfRange => {
            miette!("{option} {s}: not a noise level (finite, ≥ 0)")
        }
        e => miette!("{option} {s}: {e}"),
    })
}

/// The study's noise levels as given, sorted.
fn levels(args: &Args) -> miette::Result<Vec<NoiseLevel>> {
    let mut out: Vec<NoiseLevel> = if let Some(l) = &args.levels_nm {
        let mut v = Vec::new();
        for &x in l {
            if !(x.is_finite() && x >= 0.0) {
                return Err(miette!(
                    "--levels-nm: {x} is not a noise RMS (finite, ≥ 0, in nm)"
                ));
            }
            v.push(NoiseLevel::TimeRms(x * 1e-9));
        }
        v
    } else if args.time_domain {
        (-3..=2)
            .map(|e| NoiseLevel::TimeRms(10f64.powi(e) * 1e-9))
            .collect()
    } else if let Some(l) = &args.asd {
        l.iter()
            .map(|s| parse_length(s, "--asd").map(NoiseLevel::Asd))
            .collect::<miette::Result<_>>()?
    } else if let Some(l) = &args.sigma {
        l.iter()
            .map(|s| parse_length(s, "--sigma").map(NoiseLevel::SigmaPerQuadrature))
            .collect::<miette::Result<_>>()?
    } else {
        (-15..=-10)
            .map(|e| NoiseLevel::SigmaPerQuadrature(10f64.powi(e)))
            .collect()
    };
    if out.is_empty() || out.len() > MAX_LEVELS {
        return Err(miette!(
            "{} noise levels: give between 1 and {MAX_LEVELS}",
            out.len()
        ));
    }
    out.sort_by(|a, b| a.value().total_cmp(&b.value()));
    Ok(out)
}

/// How a level is labelled in the tables.
fn level_unit(l: &NoiseLevel) -> &'static str {
    match l {
        NoiseLevel::SigmaPerQuadrature(_) => "sigma per quadrature (m)",
        NoiseLevel::Asd(_) => "ASD (m/√Hz)",
        NoiseLevel::TimeRms(_) => "time-signal RMS (m)",
    }
}

/// Statistics of one quantity at one noise level.
#[derive(Debug, Clone)]
pub struct LevelStat {
    /// Quantity name (`f_hz(q1)`, `Q(q1)`, or a parameter name).
    pub quantity: String,
    /// True value.
    pub truth: f64,
    /// Mean over the realisations with a finite estimate.
    pub mean: f64,
    /// Standard deviation over them (n − 1).
    pub std: f64,
    /// Realisations with a finite estimate.
    pub n: usize,
}

/// The quantities reported: `(name, truth)`.
fn quantities(
    model: &NumericModel,
    prob: &Problem,
    values: &sim::ModelValues,
) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for (n, name) in model.mode_names.iter().enumerate() {
        out.push((format!("f_hz({name})"), model.f_hz[n]));
        out.push((format!("Q({name})"), model.q_factor[n]));
    }
    for p in &prob.param_names {
        out.push((
            p.clone(),
            values.parameters.get(p).copied().unwrap_or(f64::NAN),
        ));
    }
    out
}

/// Per-realisation estimates of the quantities, in [`quantities`] order.
fn estimates(model: &NumericModel, prob: &Problem, rep: &Report) -> Vec<f64> {
    let mut out = Vec::new();
    let first = |e: Option<&harmonid_ident::Estimate>| {
        e.and_then(|e| e.per_shot.first().copied())
            .unwrap_or(f64::NAN)
    };
    for name in &model.mode_names {
        let m = rep.modes.get(name);
        out.push(first(m.map(|m| &m.f_hz)));
        out.push(first(m.map(|m| &m.q)));
    }
    for p in &prob.param_names {
        out.push(first(rep.parameters.get(p)));
    }
    out
}

/// The study's inputs, each from its file or the built-in default.
struct Inputs {
    model_origin: String,
    ast: harmonid_model::Model,
    values: sim::ModelValues,
    plan: Plan,
}

fn inputs(args: &Args) -> miette::Result<Inputs> {
    let (ast, model_origin) = match &args.model {
        Some(p) => (
            harmonid_model::load(p).map_err(miette::Report::new)?,
            p.display().to_string(),
        ),
        None => {
            let origin = "examples/nanostring_2mode/model.hb (built in)";
            (
                harmonid_model::parse_str(DEFAULT_MODEL, origin).map_err(miette::Report::new)?,
                origin.to_string(),
            )
        }
    };
    let values = match &args.values {
        Some(p) => crate::cli::simulate::read_values(p)?,
        None => values_from_toml(DEFAULT_VALUES, "the built-in Table S2 values")?,
    };
    let mut plan = match &args.plan {
        Some(p) => read_plan(p)?,
        None => Plan::from_toml(DEFAULT_PLAN, "the default plan")?,
    };
    plan.noise = Default::default();
    Ok(Inputs {
        model_origin,
        ast,
        values,
        plan,
    })
}

/// The study as a figure: one panel per quantity, every realisation's estimate at its level.
/// `per[level][quantity]` holds the estimates; `quants` names the quantities with their truth.
fn figure(
    levels: &[NoiseLevel],
    quants: &[(String, f64)],
    per: &[Vec<Vec<f64>>],
) -> harmonid_plot::NoiseStudy {
    let level_label = levels.first().map_or("noise level", |l| match l {
        NoiseLevel::SigmaPerQuadrature(_) => "noise σ per quadrature (m)",
        NoiseLevel::Asd(_) => "noise ASD (m/√Hz)",
        NoiseLevel::TimeRms(_) => "noise RMS of the time signal (m)",
    });
    let panels = quants
        .iter()
        .enumerate()
        .map(|(q, (name, truth))| harmonid_plot::NoisePanel {
            name: name.clone(),
            unit: if name.starts_with("f_hz(") {
                "Hz".into()
            } else {
                String::new()
            },
            truth: truth.is_finite().then_some(*truth),
            levels: levels.iter().map(NoiseLevel::value).collect(),
            estimates: per.iter().map(|lv| lv[q].clone()).collect(),
        })
        .collect();
    harmonid_plot::NoiseStudy {
        title: "identified values against the measurement noise (mean ± 3σ over the realisations)"
            .into(),
        level_label: level_label.into(),
        panels,
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let levels = levels(&args)?;
    // Refuse unwritable outputs before the study, not after it.
    let mut outputs: Vec<&std::path::Path> = args.out.iter().map(|p| p.as_path()).collect();
    let md_path = args.out.as_ref().map(|p| p.with_extension("md"));
    outputs.extend(md_path.as_deref());
    outputs.extend(args.plot.as_deref());
    let input_files: Vec<&std::path::Path> = [&args.model, &args.values, &args.plan]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    check_outputs(&outputs, &input_files)?;
    if let Some(p) = &args.plot {
        super::figure::check(p, &input_files)?;
    }
    let n_tasks = check_counts(&args, levels.len())?;
    let Inputs {
        model_origin,
        ast,
        values,
        plan,
    } = inputs(&args)?;
    let model = NumericModel::from_model(&ast, &values)
        .into_diagnostic()
        .wrap_err_with(|| format!("cannot evaluate {model_origin} with the values"))?;
    if args.time_domain && n_tasks * plan.measurements.len() > MAX_TD_RUNS {
        return Err(miette!(
            "--time-domain: {n_tasks} realisations × {} measurements are as many time-domain runs (about a second each); at most {MAX_TD_RUNS}",
            plan.measurements.len()
        ));
    }
    let clean_settings = Settings {
        order: args.order,
        noise: false,
        ..Settings::default()
    };
    let clean = plan.simulate_numeric(&model, &clean_settings)?.dataset;
    let (enbw, n_samples, sigmas) = lock_in_sigmas(&args, &clean, &levels)?;
    check_signal(&clean, &levels, &sigmas)?;
    let settings = IdentSettings {
        force_model: ForceModel::Auto,
        min_shots_for_weights: 0,
        ..IdentSettings::default()
    };
    let prob = Problem::new(&ast, &clean, &settings).map_err(miette::Report::new)?;
    let quants = quantities(&model, &prob, &values);
    let stream = |level: usize, r: usize| {
        args.seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((level as u64) << 32 | r as u64)
    };
    // One dataset of a realisation: clean + noise (HB) or a noisy time-domain run.
    let make = |level: usize, r: usize| -> miette::Result<Dataset> {
        if args.time_domain {
            let td = Settings {
                engine: Engine::TimeDomain(TimeDomain {
                    noise_rms_m: levels[level].value(),
                    ..TimeDomain::default()
                }),
                seed: stream(level, r),
                ..clean_settings.clone()
            };
            let td = Settings { noise: true, ..td };
            return Ok(plan.simulate_numeric(&model, &td)?.dataset);
        }
        let mut ds = clean.clone();
        let mut gen = NoiseGen::new(stream(level, r));
        for m in &mut ds.measurements {
            add_noise(m, sigmas[level], &mut gen);
        }
        Ok(ds)
    };

    let tasks: Vec<(usize, usize)> = (0..levels.len())
        .flat_map(|l| (0..args.realisations).map(move |r| (l, r)))
        .collect();
    let bar = super::progress::bar(tasks.len() as u64, "identifications", args.quiet);
    let t0 = std::time::Instant::now();
    let results: Vec<miette::Result<Vec<f64>>> = tasks
        .par_iter()
        .map(|&(l, r)| {
            let ds = make(l, r)?;
            let fit = prob.fit(&ds).map_err(miette::Report::new)?;
            let rep = harmonid_ident::report_from_shots(&model_origin, &ds, &prob, &fit);
            bar.inc(1);
            Ok(estimates(&model, &prob, &rep))
        })
        .collect();
    bar.finish_and_clear();
    let elapsed = t0.elapsed().as_secs_f64();
    let mut per: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); quants.len()]; levels.len()];
    for (&(l, _), res) in tasks.iter().zip(results) {
        let est = res?;
        for (q, v) in est.into_iter().enumerate() {
            per[l][q].push(v);
        }
    }
    let stats: Vec<Vec<LevelStat>> = per
        .iter()
        .map(|lv| {
            lv.iter()
                .zip(&quants)
                .map(|(vals, (name, truth))| level_stat(name, *truth, vals))
                .collect()
        })
        .collect();
    let md = markdown(&levels, &sigmas, &stats);
    crate::cli::common::print_out(format_args!(
        "noise study: {} levels × {} realisations, {} identifications in {:.2} s ({})\n",
        levels.len(),
        args.realisations,
        tasks.len(),
        elapsed,
        if args.time_domain {
            "time domain with noisy samples".to_string()
        } else {
            format!(
                "harmonic balance + lock-in noise; window {} s, ENBW {enbw:.3} Hz, {n_samples:.3e} samples per window",
                args.window_s
            )
        }
    ));
    crate::cli::common::print_out(format_args!("{md}"));
    crate::cli::common::print_out(format_args!("{}", summary(&levels, &stats)));
    if let (Some(out), Some(md_path)) = (&args.out, &md_path) {
        write_output(out, csv(&levels, &sigmas, &stats).as_bytes(), &input_files)?;
        write_output(md_path, md.as_bytes(), &input_files)?;
        crate::cli::common::print_out(format_args!(
            "wrote {} and {}\n",
            out.display(),
            md_path.display()
        ));
    }
    if let Some(path) = &args.plot {
        super::figure::save(&figure(&levels, &quants, &per), path, &input_files)?;
        crate::cli::common::print_out(format_args!("wrote {}\n", path.display()));
    }
    Ok(())
}

/// The noise σ of each level per lock-in quadrature (m), with the equivalent noise bandwidth
/// and samples per window it assumes (from `--sample-rate-hz`, `--window-s` and `--enbw-hz`,
/// checked against the highest measured frequency of `clean`).
fn lock_in_sigmas(
    args: &Args,
    clean: &Dataset,
    levels: &[NoiseLevel],
) -> miette::Result<(f64, f64, Vec<f64>)> {
    let f_hi = clean
        .measurements
        .iter()
        .flat_map(|m| m.freqs_hz.iter().copied())
        .fold(0.0, f64::max);
    let fs = args.sample_rate_hz.unwrap_or(8.0 * f_hi);
    if !(fs.is_finite() && fs > 2.0 * f_hi) {
        return Err(miette!(
            "--sample-rate-hz {fs}: the time signal must be sampled faster than twice the highest measured frequency ({:.6e} Hz)",
            2.0 * f_hi
        ));
    }
    let enbw = args.enbw_hz.unwrap_or(0.5 / args.window_s);
    if !(enbw.is_finite() && enbw > 0.0) {
        return Err(miette!(
            "--enbw-hz {enbw}: expected a positive bandwidth in Hz"
        ));
    }
    let n_samples = fs * args.window_s;
    let sigmas: Vec<f64> = levels.iter().map(|l| l.sigma_m(enbw, n_samples)).collect();
    Ok((enbw, n_samples, sigmas))
}

/// Refuses, before the identifications, a level whose noise σ per quadrature is at least the
/// plan's strongest line (noise-free): every line is then under the noise, each fit stays near
/// its start, and a row of estimates "within 0.1 % of the truth" would only echo the start.
fn check_signal(clean: &Dataset, levels: &[NoiseLevel], sigmas: &[f64]) -> miette::Result<()> {
    let strongest = clean
        .measurements
        .iter()
        .flat_map(|m| m.data.iter().map(|z| z.norm()))
        .fold(0.0, f64::max);
    if let Some(l) = sigmas.iter().position(|&s| s >= strongest) {
        return Err(miette!(
            help = "study noise levels below the signal: the default levels run from 1e-15 to 1e-10 m per quadrature",
            "noise level {} ({}) gives σ = {} m per quadrature, at least the plan's strongest line ({} m, noise-free): every line would be under the noise and the estimates meaningless (each fit stays at its start)",
            harmonid_files::number(levels[l].value()),
            level_unit(&levels[l]),
            harmonid_files::number(sigmas[l]),
            format!("{strongest:.3e}")
        ));
    }
    Ok(())
}

/// Refuses a study too small or too large before any work: at least two realisations, at most
/// [`MAX_TASKS`] identifications, a positive window. Returns the number of identifications.
fn check_counts(args: &Args, n_levels: usize) -> miette::Result<usize> {
    if !(2..=MAX_REALISATIONS).contains(&args.realisations) {
        return Err(miette!(
            "--realisations {}: at least 2 are needed for a spread, at most {MAX_REALISATIONS}",
            args.realisations
        ));
    }
    let n_tasks = n_levels * args.realisations;
    if n_tasks > MAX_TASKS {
        return Err(miette!(
            "{} levels × {} realisations = {n_tasks} identifications; at most {MAX_TASKS}",
            n_levels,
            args.realisations
        ));
    }
    if !(args.window_s.is_finite() && args.window_s > 0.0 && args.window_s <= 1e4) {
        return Err(miette!(
            "--window-s {}: expected a positive time in seconds (at most 1e4)",
            args.window_s
        ));
    }
    Ok(n_tasks)
}

/// Mean and spread of the finite values.
pub fn level_stat(name: &str, truth: f64, vals: &[f64]) -> LevelStat {
    let fin: Vec<f64> = vals.iter().copied().filter(|v| v.is_finite()).collect();
    let n = fin.len();
    let mean = if n > 0 {
        fin.iter().sum::<f64>() / n as f64
    } else {
        f64::NAN
    };
    let std = if n > 1 {
        (fin.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        f64::NAN
    };
    LevelStat {
        quantity: name.to_string(),
        truth,
        mean,
        std,
        n,
    }
}

fn csv(levels: &[NoiseLevel], sigmas: &[f64], stats: &[Vec<LevelStat>]) -> String {
    let mut s = String::from(
        "level,level_unit,sigma_per_quadrature_m,quantity,truth,mean,std,mean_minus_3std,mean_plus_3std,rel_bias,rel_3std,n\n",
    );
    for (l, row) in stats.iter().enumerate() {
        for st in row {
            let _ = writeln!(
                s,
                "{:e},{},{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}",
                levels[l].value(),
                level_unit(&levels[l]),
                sigmas[l],
                st.quantity,
                st.truth,
                st.mean,
                st.std,
                st.mean - 3.0 * st.std,
                st.mean + 3.0 * st.std,
                (st.mean - st.truth) / st.truth,
                3.0 * st.std / st.truth.abs(),
                st.n
            );
        }
    }
    s
}

fn markdown(levels: &[NoiseLevel], sigmas: &[f64], stats: &[Vec<LevelStat>]) -> String {
    let mut s = String::new();
    let (Some(first), Some(l0)) = (stats.first(), levels.first()) else {
        return s;
    };
    let _ = write!(s, "| {} | σ per quadrature (m) |", level_unit(l0));
    for st in first {
        let _ = write!(s, " {} |", st.quantity);
    }
    let _ = write!(s, "\n|---|---|");
    for _ in first {
        let _ = write!(s, "---|");
    }
    let _ = write!(s, "\n| truth | |");
    for st in first {
        let _ = write!(s, " {:.6e} |", st.truth);
    }
    s.push('\n');
    for (l, row) in stats.iter().enumerate() {
        let _ = write!(s, "| {:.0e} | {:.2e} |", levels[l].value(), sigmas[l]);
        for st in row {
            let _ = write!(
                s,
                " {:.6e} ± {:.1e} ({}) |",
                st.mean,
                3.0 * st.std,
                rel(3.0 * st.std / st.truth.abs())
            );
        }
        s.push('\n');
    }
    s.push_str("\nmean ± 3σ over the realisations (3σ relative to the truth in parentheses)\n");
    s
}

fn rel(x: f64) -> String {
    if !x.is_finite() {
        "n/a".into()
    } else if x >= 0.1 {
        format!("{:.0} %", 100.0 * x)
    } else {
        format!("{:.1e}", x)
    }
}

/// Per quantity: the highest noise level up to which every level has the mean within 1 % of the
/// truth and 3σ below 10 % of it.
fn summary(levels: &[NoiseLevel], stats: &[Vec<LevelStat>]) -> String {
    let mut s = String::from("\nreliable (|bias| < 1 % and 3σ < 10 % of the truth) up to:\n");
    let Some(first) = stats.first() else {
        return s;
    };
    for (q, st0) in first.iter().enumerate() {
        let ok = |l: usize| {
            let st = &stats[l][q];
            let t = st.truth.abs();
            st.n > 1 && (st.mean - st.truth).abs() < 0.01 * t && 3.0 * st.std < 0.1 * t
        };
        let mut best: Option<f64> = None;
        for (l, level) in levels.iter().enumerate() {
            if ok(l) {
                best = Some(level.value());
            } else {
                break;
            }
        }
        let _ = writeln!(
            s,
            "  {:<12} {}",
            st0.quantity,
            match best {
                Some(b) => format!("{b:.0e} ({})", level_unit(&levels[0])),
                None => "not even at the lowest level".into(),
            }
        );
    }
    s
}

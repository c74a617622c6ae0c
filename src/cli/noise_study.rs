//! `harmonid noise-study`: the robustness study of the paper's Supplementary Note V as a command.
//!
//! The measurements of a plan (default: the three measurements of the two-mode nanostring
//! identification, single_q1, single_q2 and couple_q1_q2) are simulated once without noise; then,
//! for every noise level (RMS of white noise added to the time signal, nm) and every
//! realisation, seeded Gaussian noise is added to the demodulated amplitudes and the model is
//! re-identified. White noise of RMS `r` on `N` lock-in samples gives each quadrature of each
//! amplitude an independent Gaussian error of std `r·sqrt(2/N)` ([`sim::lockin_noise_sigma`]),
//! so the default route (harmonic balance + that noise) is statistically the same as adding the
//! noise to the time signal and demodulating; `--time-domain` does the latter literally.

use crate::cli::common::write_atomic;
use crate::cli::simulate::{
    self, excitation, measured_hz, numeric_model, parse_plan, plan_manifest, plan_spec,
    plan_steady_state, plan_unit, point_shapes, Plan,
};
use harmonid_ident::{Dataset, ForceModel, Measurement, Problem, Report, Settings};
use harmonid_sim::{self as sim, NoiseGen, NumericModel, Start, TdSettings};
use miette::{miette, IntoDiagnostic, WrapErr};
use num_complex::Complex64;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

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

/// Arguments of `harmonid noise-study`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    #[arg(default_value = "examples/nanostring_2mode/model.hb")]
    pub model: PathBuf,
    /// Parameter values (TOML as for `harmonid simulate`, or a result JSON); default: the
    /// paper's Table S2 values of the two-mode nanostring.
    #[arg(long)]
    pub values: Option<PathBuf>,
    /// Measurement plan (TOML as for `harmonid simulate`); default: the three measurements of
    /// Supplementary Note V. Its [noise] table is ignored.
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// Noise levels: RMS of the white noise in the time signal, nm, comma separated
    /// (default: one per decade from 1e-3 to 1e2).
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
    /// Sample rate of the time signal, Hz (default: 8 samples per period of the highest
    /// measured frequency, as the time-domain lock-in emulation samples).
    #[arg(long)]
    pub sample_rate_hz: Option<f64>,
    /// Simulate every realisation in the time domain with noise added to the samples and
    /// demodulate (faithful to the paper, much slower: seconds per measurement and
    /// realisation; the window is then the lock-in's, a whole number of periods of every
    /// frequency, not --window-s).
    #[arg(long)]
    pub time_domain: bool,
    /// Intermodulation order of the harmonic-balance lattice.
    #[arg(long, default_value_t = 9)]
    pub order: usize,
    /// Write the table of estimates per level to this CSV (and a Markdown table beside it,
    /// same name with `.md`).
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
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

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let dir = tempfile::tempdir().into_diagnostic()?;
    let values_path = match &args.values {
        Some(p) => p.clone(),
        None => {
            let p = dir.path().join("values.toml");
            std::fs::write(&p, DEFAULT_VALUES).into_diagnostic()?;
            p
        }
    };
    let model = numeric_model(&args.model, &values_path)?;
    let values = simulate::read_values(&values_path)?;
    let ast = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let (plan_text, origin) = match &args.plan {
        Some(p) => (
            std::fs::read_to_string(p)
                .into_diagnostic()
                .wrap_err_with(|| format!("cannot read the plan {}", p.display()))?,
            p.display().to_string(),
        ),
        None => (DEFAULT_PLAN.to_string(), "the default plan".to_string()),
    };
    let plan: Plan = parse_plan(&plan_text, &origin)?;
    let unit = plan_unit(&plan, &origin)?;
    let mut levels: Vec<f64> = args
        .levels_nm
        .clone()
        .unwrap_or_else(|| (-3..=2).map(|e| 10f64.powi(e)).collect());
    levels.sort_by(f64::total_cmp);
    if let Some(l) = levels.iter().find(|l| !(l.is_finite() && **l >= 0.0)) {
        return Err(miette!(
            "--levels-nm: {l} is not a noise RMS (finite, ≥ 0, in nm)"
        ));
    }
    if args.realisations < 2 {
        return Err(miette!(
            "--realisations {}: at least 2 are needed for a spread",
            args.realisations
        ));
    }
    if !(args.window_s.is_finite() && args.window_s > 0.0) {
        return Err(miette!("--window-s must be a positive time in seconds"));
    }
    let shapes = point_shapes(&model, &plan);
    let mut manifest = plan_manifest(&model, &plan);

    // Clean amplitudes, [measurement][point][freq], in metres, and the HB states.
    let mut clean = Vec::new();
    let mut states = Vec::new();
    let mut f_hi: f64 = 0.0;
    for pm in &plan.measurements {
        let (st, drive) = plan_steady_state(&model, pm, args.order)?;
        let freqs = measured_hz(
            &model,
            &drive,
            pm,
            &st,
            sim::HbSettings::default().lattice.window_rel,
        );
        f_hi = freqs.iter().copied().fold(f_hi, f64::max);
        let v: Vec<Vec<Complex64>> = shapes
            .iter()
            .map(|s| freqs.iter().map(|&f| st.at_point(s, f)).collect())
            .collect();
        clean.push((plan_spec(pm), freqs, v));
        states.push(st);
    }
    manifest.measurements = clean.iter().map(|c| c.0.clone()).collect();
    let fs = args.sample_rate_hz.unwrap_or(8.0 * f_hi);
    if !(fs.is_finite() && fs > 0.0) {
        return Err(miette!("--sample-rate-hz must be a positive frequency"));
    }
    let n_samples = fs * args.window_s;
    let settings = Settings {
        force_model: ForceModel::Auto,
        min_shots_for_weights: 0,
        ..Settings::default()
    };

    // One dataset of a realisation: clean + noise (HB) or a noisy time-domain run.
    let n_points = plan.points.len();
    let make = |level: usize, r: usize| -> miette::Result<Dataset> {
        let rms_m = levels[level] * 1e-9;
        let stream = args
            .seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((level as u64) << 32 | r as u64);
        let mut gen = NoiseGen::new(stream);
        let sigma_m = sim::lockin_noise_sigma(rms_m, n_samples);
        let mut measurements = Vec::new();
        for (mi, (spec, freqs, v)) in clean.iter().enumerate() {
            let noisy: Vec<Vec<Complex64>> = if args.time_domain {
                let pm = &plan.measurements[mi];
                let drive = excitation(&model, pm)?;
                let (q, vel) = states[mi].state_at(0.0);
                let ts = TdSettings {
                    steps_per_period: 16,
                    noise_rms: rms_m,
                    seed: stream.wrapping_add(mi as u64),
                    ..TdSettings::default()
                };
                sim::simulate_lockin(
                    &model,
                    &drive,
                    freqs,
                    &shapes,
                    &Start::State { q, v: vel },
                    &ts,
                )
                .into_diagnostic()
                .wrap_err_with(|| format!("measurement {}", pm.name))?
                .points
            } else {
                v.iter()
                    .map(|row| row.iter().map(|&z| z + gen.complex(sigma_m)).collect())
                    .collect()
            };
            let mut meas =
                Measurement::zeros(spec.clone(), freqs.clone(), (0..n_points).collect(), 1);
            for (f, _) in freqs.iter().enumerate() {
                for (p, row) in noisy.iter().enumerate() {
                    *meas.amplitude_mut(0, f, p) = row[f] / unit;
                }
            }
            measurements.push(meas);
        }
        Ok(Dataset {
            dir: PathBuf::from("noise-study"),
            manifest: manifest.clone(),
            measurements,
            truth: None,
        })
    };

    // Problem structure from the clean data.
    let ds0 = make_clean(&clean, &manifest, unit, n_points);
    let prob = Problem::new(&ast, &ds0, &settings).map_err(|e| miette!("{e}"))?;
    let quants = quantities(&model, &prob, &values);

    let tasks: Vec<(usize, usize)> = (0..levels.len())
        .flat_map(|l| (0..args.realisations).map(move |r| (l, r)))
        .collect();
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(tasks.len() as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} identifications {pos}/{len} {wide_bar} {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t0 = std::time::Instant::now();
    let results: Vec<miette::Result<Vec<f64>>> = tasks
        .par_iter()
        .map(|&(l, r)| {
            let ds = make(l, r)?;
            let fit = prob.fit(&ds).map_err(|e| miette::miette!("{e}"))?;
            let rep = Report::new(&args.model.display().to_string(), &ds, &prob, &fit);
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
    let sigmas: Vec<f64> = levels
        .iter()
        .map(|&l| sim::lockin_noise_sigma(l * 1e-9, n_samples))
        .collect();
    let md = markdown(&levels, &stats);
    println!(
        "noise study: {} levels × {} realisations, {} identifications in {:.2} s ({})",
        levels.len(),
        args.realisations,
        tasks.len(),
        elapsed,
        if args.time_domain {
            "time domain with noisy samples".to_string()
        } else {
            format!(
                "harmonic balance + lock-in noise, {:.3e} samples per window of {} s",
                n_samples, args.window_s
            )
        }
    );
    print!("{md}");
    print!("{}", summary(&levels, &stats));
    if let Some(out) = &args.out {
        write_atomic(out, csv(&levels, &sigmas, &stats).as_bytes())?;
        let md_path = out.with_extension("md");
        write_atomic(&md_path, md.as_bytes())?;
        println!("wrote {} and {}", out.display(), md_path.display());
    }
    Ok(())
}

/// One clean measurement: spec, measured frequencies, amplitudes `[point][freq]` (m).
type Clean = (
    harmonid_ident::MeasurementSpec,
    Vec<f64>,
    Vec<Vec<Complex64>>,
);

fn make_clean(
    clean: &[Clean],
    manifest: &harmonid_ident::Manifest,
    unit: f64,
    n_points: usize,
) -> Dataset {
    let measurements = clean
        .iter()
        .map(|(spec, freqs, v)| {
            let mut m = Measurement::zeros(spec.clone(), freqs.clone(), (0..n_points).collect(), 1);
            for f in 0..freqs.len() {
                for (p, row) in v.iter().enumerate() {
                    *m.amplitude_mut(0, f, p) = row[f] / unit;
                }
            }
            m
        })
        .collect();
    Dataset {
        dir: PathBuf::from("noise-study"),
        manifest: manifest.clone(),
        measurements,
        truth: None,
    }
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

fn csv(levels: &[f64], sigmas: &[f64], stats: &[Vec<LevelStat>]) -> String {
    let mut s = String::from(
        "noise_rms_nm,sigma_per_quadrature_m,quantity,truth,mean,std,mean_minus_3std,mean_plus_3std,rel_bias,rel_3std,n\n",
    );
    for (l, row) in stats.iter().enumerate() {
        for st in row {
            let _ = writeln!(
                s,
                "{:e},{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}",
                levels[l],
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

fn markdown(levels: &[f64], stats: &[Vec<LevelStat>]) -> String {
    let mut s = String::new();
    let Some(first) = stats.first() else {
        return s;
    };
    let _ = write!(s, "| noise RMS (nm) |");
    for st in first {
        let _ = write!(s, " {} |", st.quantity);
    }
    let _ = write!(s, "\n|---|");
    for _ in first {
        let _ = write!(s, "---|");
    }
    let _ = write!(s, "\n| truth |");
    for st in first {
        let _ = write!(s, " {:.6e} |", st.truth);
    }
    s.push('\n');
    for (l, row) in stats.iter().enumerate() {
        let _ = write!(s, "| {:.0e} |", levels[l]);
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
fn summary(levels: &[f64], stats: &[Vec<LevelStat>]) -> String {
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
        for (l, &level) in levels.iter().enumerate() {
            if ok(l) {
                best = Some(level);
            } else {
                break;
            }
        }
        let _ = writeln!(
            s,
            "  {:<12} {}",
            st0.quantity,
            match best {
                Some(b) => format!("{b:.0e} nm RMS"),
                None => "not even at the lowest level".into(),
            }
        );
    }
    s
}

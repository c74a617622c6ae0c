//! `harmonid identify MODEL DATASET --out result.json`: identify the model's unknowns from a
//! measured dataset (sequential stages by default), print a summary table, write the result.

use crate::cli::common::{check_outputs, print_out, write_output, ForceArgs};
use harmonid_ident::{identify, identify_with_holdout, Background, Estimator, Settings};
use miette::miette;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `harmonid identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`), e.g. examples/nanostring_2mode/model.hb.
    pub model: PathBuf,
    /// The dataset folder (with dataset.toml; layout in docs/data-format.md).
    pub dataset: PathBuf,
    /// Where to write the result (JSON, `harmonid-result/1`); written atomically.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write every shot's estimates to this CSV (for histograms).
    #[arg(long, value_name = "FILE.csv")]
    pub per_shot: Option<PathBuf>,
    /// Fit everything in one problem instead of the sequential stages (for comparison).
    #[arg(long)]
    pub joint: bool,
    #[command(flatten)]
    pub forces: ForceArgs,
    /// Nominal resonance frequency of a mode, overriding the dataset's and the model's:
    /// `--nominal q1=207.58e3` (Hz). Repeatable.
    #[arg(long, value_name = "MODE=HZ")]
    pub nominal: Vec<String>,
    /// A drive tone must lie within this relative distance of a nominal resonance, or (a step
    /// of a sweep) of its sweep's own resonance: the step of largest response, a peak inside
    /// the sweep.
    #[arg(long, default_value_t = 0.05)]
    pub near_rel: f64,
    /// Do not weight rows by the noise estimated from the scatter across shots (per-shot and
    /// pooled equation-error fits).
    #[arg(long)]
    pub unweighted: bool,
    /// The estimator of the reported values (`ml` falls back to `linear` with a warning when the
    /// model cannot be simulated).
    #[arg(long, default_value_t, value_parser = estimator_parser())]
    pub estimator: Estimator,
    /// Also print and write the Cramér–Rao bound of every quantity at the estimate (`crlb`
    /// in the result), for the force model in use and the noise from the shot scatter.
    #[arg(long)]
    pub crlb: bool,
    /// Add an error floor to the shot noise, estimated with the fit (one value per
    /// quadrature for every line): for measured data whose steps carry errors the scatter of
    /// their own samples does not see. The χ² verdict is then not a test; judge by --holdout.
    #[arg(long)]
    pub error_floor: bool,
    /// Fit a measurement background with the model, per mode on every measured line at a
    /// drive tone (shared by all measurements; in the data's unit): `drive` a complex
    /// feedthrough B times the drive level V e^{iφ}, `slope` a complex S times the drive times
    /// (f − f_mode) in Hz from the mode's nominal resonance, `constant` a complex offset C
    /// independent of the drive. Reported with standard errors (`background` in the result);
    /// drive and slope need the dataset's drive levels. Output-error estimator only.
    #[arg(long, value_name = "drive[,slope][,constant]", value_parser = background_parser)]
    pub background: Option<Background>,
    /// Fit without these measurements, then report how well the estimate predicts them (RMS
    /// in noise units and relative; their forces or gains are refitted, the model fixed).
    /// A name is a measurement's or a sweep's, or an imported sweep's source: its input file
    /// (`Measurements_A=0.32%.txt`) or its label as written.
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]")]
    pub holdout: Vec<String>,
}

/// `--estimator`: the library's names, with its descriptions as the help of each value.
fn estimator_parser() -> impl clap::builder::TypedValueParser<Value = Estimator> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(
        Estimator::ALL.map(|e| PossibleValue::new(e.name()).help(e.description())),
    )
    // Only the names above pass the parser, and each reads back.
    .map(|name| name.parse::<Estimator>().unwrap_or_default())
}

/// `--background`: the library's words, refusing an unknown one with the valid ones.
pub fn background_parser(s: &str) -> Result<Background, String> {
    s.parse::<Background>().map_err(|e| e.to_string())
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let ds = super::common::load_dataset(&args.dataset)?;
    // Refuse unwritable outputs (or ones that are inputs) before the fit, not after it.
    let dataset_files = ds.input_files();
    let mut inputs: Vec<&std::path::Path> = vec![args.model.as_path()];
    inputs.extend(dataset_files.iter().map(|p| p.as_path()));
    let outputs: Vec<&std::path::Path> = [&args.out, &args.per_shot]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    check_outputs(&outputs, &inputs)?;
    if !(args.near_rel.is_finite() && args.near_rel > 0.0 && args.near_rel < 1.0) {
        return Err(miette!(
            "--near-rel {}: expected a relative distance between 0 and 1, e.g. --near-rel 0.05",
            args.near_rel
        ));
    }
    let mut nominal_hz = BTreeMap::new();
    for s in &args.nominal {
        let (name, hz) = s.split_once('=').ok_or_else(|| {
            miette!("--nominal {s}: expected MODE=HZ, e.g. --nominal q1=207.58e3")
        })?;
        let hz: f64 = hz
            .trim()
            .parse()
            .ok()
            .filter(|f: &f64| f.is_finite() && *f > 0.0)
            .ok_or_else(|| miette!("--nominal {s}: \"{hz}\" is not a positive frequency in Hz"))?;
        if model.mode_index(name.trim()).is_none() {
            return Err(miette!(
                "--nominal {s}: the model declares no mode \"{}\" (modes: {})",
                name.trim(),
                model.mode_names().join(", ")
            ));
        }
        nominal_hz.insert(name.trim().to_string(), hz);
    }
    let settings = Settings {
        force_model: args.forces.force_model(),
        joint: args.joint,
        nominal_hz,
        near_rel: args.near_rel,
        min_shots_for_weights: if args.unweighted { 0 } else { 5 },
        estimator: args.estimator,
        crlb: args.crlb,
        error_floor: args.error_floor,
        background: args.background.unwrap_or_default(),
        ..Settings::default()
    };
    let pb = super::progress::spinner(&format!(
        "identifying ({} measurement(s), {} shot(s))",
        ds.measurements.len(),
        ds.measurements.first().map_or(0, |m| m.n_shots)
    ));
    let report = if args.holdout.is_empty() {
        identify(&model, &ds, &settings)
    } else {
        // The names the lab gave (an input file, a sweep label) as the dataset's names.
        identify_with_holdout(&model, &ds, &ds.resolve_names(&args.holdout), &settings)
    };
    pb.finish_and_clear();
    let mut report = report.map_err(miette::Report::new)?;
    report.model = args.model.display().to_string();
    print_out(format_args!("{}", report.summary(ds.truth.as_ref())));
    if let Some(out) = &args.out {
        write_output(out, report.to_json().as_bytes(), &inputs)?;
        print_out(format_args!("wrote {}\n", out.display()));
    }
    if let Some(path) = &args.per_shot {
        write_output(path, report.per_shot_csv().as_bytes(), &inputs)?;
        print_out(format_args!("wrote {}\n", path.display()));
    }
    Ok(())
}

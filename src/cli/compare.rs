//! `harmonid compare DATASET MODEL_A MODEL_B [...]`: the same data fitted by each model, ranked
//! by information criteria, with a likelihood-ratio test for every nested pair; with
//! `--holdout`, each model's prediction of the held-out data beside; with `--error-floor`,
//! ranked by that prediction (`harmonid_ident::compare_with_holdout`).

use crate::cli::common::{check_outputs, print_out, write_output, ForceArgs};
use harmonid_ident::{compare_with_holdout, Settings};
use std::path::PathBuf;

/// Arguments of `harmonid compare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset folder (with dataset.toml).
    pub dataset: PathBuf,
    /// Two or more model files (`*.hb`) describing the same modes.
    #[arg(num_args = 2.., required = true)]
    pub models: Vec<PathBuf>,
    /// Print the comparison as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON to this file (written atomically).
    #[arg(long, value_name = "FILE.json")]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub forces: ForceArgs,
    /// Fit every model with an error floor added to the shot noise (as `identify
    /// --error-floor`): for measured sweeps whose steps scatter more than their own samples
    /// say. Every χ² then equals its expectation, so the models are ranked by how well they
    /// predict the --holdout data, which this needs.
    #[arg(long)]
    pub error_floor: bool,
    /// Fit every model without these measurements or sweeps, then report how well each
    /// predicts them (relative RMS and noise sigmas).
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]")]
    pub holdout: Vec<String>,
    /// Fit a measurement background with every model (as `identify --background`): per mode
    /// on every measured line at a drive tone, `drive` a complex feedthrough times the drive
    /// level, `slope` a complex slope times the drive times (f − f_mode), `constant` a
    /// drive-independent complex offset. Its unknowns count in every model's.
    #[arg(long, value_name = "drive[,slope][,constant]", value_parser = crate::cli::identify::background_parser)]
    pub background: Option<harmonid_ident::Background>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let ds = super::common::load_dataset(&args.dataset)?;
    let mut models = Vec::with_capacity(args.models.len());
    for path in &args.models {
        let m = harmonid_model::load(path).map_err(miette::Report::new)?;
        models.push((path.display().to_string(), m));
    }
    refuse_same_models(&args.models, &models)?;
    let dataset_files = ds.input_files();
    let mut inputs: Vec<&std::path::Path> = args.models.iter().map(|p| p.as_path()).collect();
    inputs.extend(dataset_files.iter().map(|p| p.as_path()));
    if let Some(out) = &args.out {
        check_outputs(&[out.as_path()], &inputs)?;
    }
    let settings = Settings {
        force_model: args.forces.force_model(),
        error_floor: args.error_floor,
        background: args.background.clone().unwrap_or_default(),
        ..Settings::default()
    };
    let pb = super::progress::spinner(&format!("fitting {} models", models.len()));
    let c = compare_with_holdout(&models, &ds, &args.holdout, &settings);
    pb.finish_and_clear();
    let c = c.map_err(miette::Report::new)?;
    let json = c.to_json();
    if args.json {
        print_out(format_args!("{json}\n"));
    } else {
        print_out(format_args!("{}", c.table()));
    }
    if let Some(out) = &args.out {
        write_output(out, json.as_bytes(), &inputs)?;
        eprintln!("wrote {}", out.display());
    }
    Ok(())
}

/// Two models that are one file, or the same modes, parameters and equations, are refused
/// naming both: fitted twice, they differ by nothing, and a ranking of them ("the data barely
/// support m.hb, ΔBIC 0.0") reads as a verdict on nothing.
fn refuse_same_models(
    paths: &[PathBuf],
    models: &[(String, harmonid_model::Model)],
) -> miette::Result<()> {
    // The model as its report shows it, without the first line (which names the file).
    let body = |m: &harmonid_model::Model| {
        let text = m.to_text();
        text.split_once('\n')
            .map_or(String::new(), |(_, b)| b.to_string())
    };
    let bodies: Vec<String> = models.iter().map(|(_, m)| body(m)).collect();
    for j in 1..paths.len() {
        for i in 0..j {
            let why = if harmonid_files::same_file(&paths[i], &paths[j]) {
                "the same file"
            } else if bodies[i] == bodies[j] {
                "the same model (the same modes, parameters and equations)"
            } else {
                continue;
            };
            return Err(miette::miette!(
                help = "compare models that differ (e.g. with and without a term): a model compared with itself is supported exactly as much as itself",
                "model {} ({}) and model {} ({}) are {why}: there is nothing to compare",
                i + 1,
                paths[i].display(),
                j + 1,
                paths[j].display()
            ));
        }
    }
    Ok(())
}

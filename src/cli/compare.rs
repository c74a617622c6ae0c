//! `harmonid compare DATASET MODEL_A MODEL_B [...]`: the same data fitted by each model, ranked
//! by information criteria, with a likelihood-ratio test for every nested pair
//! (`harmonid_ident::compare`).

use crate::cli::common::{check_outputs, print_out, write_output, ForceArgs};
use harmonid_ident::{compare, Settings};
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
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let ds = super::common::load_dataset(&args.dataset)?;
    let mut models = Vec::with_capacity(args.models.len());
    for path in &args.models {
        let m = harmonid_model::load(path).map_err(miette::Report::new)?;
        models.push((path.display().to_string(), m));
    }
    let dataset_files = ds.input_files();
    let mut inputs: Vec<&std::path::Path> = args.models.iter().map(|p| p.as_path()).collect();
    inputs.extend(dataset_files.iter().map(|p| p.as_path()));
    if let Some(out) = &args.out {
        check_outputs(&[out.as_path()], &inputs)?;
    }
    let settings = Settings {
        force_model: args.forces.force_model(),
        ..Settings::default()
    };
    let pb = super::progress::spinner(&format!("fitting {} models", models.len()));
    let c = compare(&models, &ds, &settings);
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

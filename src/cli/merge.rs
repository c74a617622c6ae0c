//! `harmonid merge DS... --out DS`: pool datasets of one device (the rounds of the lab loop)
//! into one dataset folder. The rules (what must agree, how names that collide are renamed,
//! when truth.toml is kept) are [`harmonid_data::Dataset::merge`]'s; this file reads, writes
//! and prints.

use harmonid_data::Dataset;
use miette::WrapErr;
use std::path::{Path, PathBuf};

/// Arguments of `harmonid merge`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset folders to pool (at least two), in the order their measurements are listed.
    #[arg(required = true, num_args = 2..)]
    pub datasets: Vec<PathBuf>,
    /// Output dataset folder: created, or replaced when it is empty or a harmonid dataset.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace `--out` even when it is a non-empty folder that is not a harmonid dataset (never
    /// a folder holding an input, or any model, values, plan or result file).
    #[arg(long)]
    pub force: bool,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let inputs: Vec<&Path> = args.datasets.iter().map(|p| p.as_path()).collect();
    let opts = harmonid_files::DirWrite {
        force: args.force,
        inputs: &inputs,
    };
    // Before any work: a run that cannot write its output fails at once.
    harmonid_files::check_output_dir(&args.out, opts).map_err(miette::Report::new)?;
    let datasets = args
        .datasets
        .iter()
        .map(|d| {
            Dataset::load(d)
                .map_err(miette::Report::new)
                .wrap_err_with(|| format!("cannot read the dataset {}", d.display()))
        })
        .collect::<miette::Result<Vec<_>>>()?;
    let merged = Dataset::merge(&datasets)
        .map_err(miette::Report::new)
        .wrap_err("nothing written: the datasets cannot be merged")?;
    merged
        .write_with(&args.out, opts)
        .map_err(miette::Report::new)
        .wrap_err_with(|| format!("cannot write the dataset {}", args.out.display()))?;
    for note in &merged.notes {
        eprintln!("note: {note}");
    }
    eprintln!(
        "wrote {} ({} measurements from {} datasets{})",
        args.out.display(),
        merged.measurements.len(),
        datasets.len(),
        if merged.truth.is_some() {
            ", with truth.toml"
        } else {
            ""
        }
    );
    Ok(())
}

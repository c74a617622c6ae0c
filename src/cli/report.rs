//! `harmonid report MODEL DATASET [--result r.json] --out DIR`: one self-contained HTML page
//! with every figure of the identification (the work is in `harmonid_report`).

use harmonid_ident::Settings;
use harmonid_report::Source;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::PathBuf;

/// Arguments of `harmonid report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`), e.g. examples/nanostring_2mode/model.hb.
    pub model: PathBuf,
    /// The dataset folder (with dataset.toml).
    pub dataset: PathBuf,
    /// Take the values from this result (`harmonid identify --out`) instead of identifying.
    #[arg(long, value_name = "FILE.json")]
    pub result: Option<PathBuf>,
    /// The report folder: DIR/index.html and DIR/figures/*.{svg,png}. An existing folder is
    /// replaced only when it is a harmonid report.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let ds = super::common::load_dataset(&args.dataset)?;
    let source = match &args.result {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .into_diagnostic()
                .wrap_err_with(|| format!("cannot read {}", path.display()))?;
            let rep = harmonid_ident::Report::from_json(&text).map_err(|e| {
                miette!(
                    "{}: not a harmonid result ({e}); write one with `harmonid identify MODEL DATASET --out r.json`",
                    path.display()
                )
            })?;
            Source::Result(path.clone(), Box::new(rep))
        }
        None => Source::Identify(Settings::default()),
    };
    let pb = super::progress::spinner("identifying, reconstructing and drawing");
    let page = harmonid_report::build(&args.model, &model, &ds, source);
    pb.finish_and_clear();
    let page = page?;
    let dataset_files = ds.input_files();
    let mut inputs: Vec<&std::path::Path> = vec![args.model.as_path(), args.dataset.as_path()];
    inputs.extend(args.result.as_deref());
    inputs.extend(dataset_files.iter().map(|p| p.as_path()));
    page.write(&args.out, &inputs)?;
    for w in &page.warnings {
        eprintln!("warning: {w}");
    }
    crate::cli::common::print_out(format_args!(
        "wrote {} ({} figures)\n",
        args.out.join("index.html").display(),
        page.figures.len()
    ));
    Ok(())
}

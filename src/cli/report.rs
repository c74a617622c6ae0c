//! `harmonid report MODEL DATASET [--result r.json] --out DIR`: one self-contained HTML page
//! with every figure of the identification (the work is in `harmonid_report`).

use harmonid_ident::Settings;
use harmonid_report::Source;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::{Path, PathBuf};

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
    /// When identifying (no --result): fit a measurement background with the model, as
    /// `identify --background` does; the figures' model then includes it (a --result carries
    /// its own).
    #[arg(long, value_name = "drive[,slope][,constant]", value_parser = super::identify::background_parser)]
    pub background: Option<harmonid_ident::Background>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let ds = super::common::load_dataset(&args.dataset)?;
    if let (Some(path), Some(bg)) = (&args.result, &args.background) {
        return Err(miette!(
            "--background {bg} with --result {}: the result carries the background it was fitted with; leave out --background, or identify again (harmonid identify ... --background {bg} --out r.json)",
            path.display()
        ));
    }
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
            check_result_matches(path, &rep, &args.model, &model, &args.dataset, &ds)?;
            Source::Result(path.clone(), Box::new(rep))
        }
        None => Source::Identify(Settings {
            background: args.background.clone().unwrap_or_default(),
            ..Settings::default()
        }),
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

/// A result of another model or dataset is refused, naming what differs: its modes and
/// parameters must be the model's, and every measurement it fitted must be in the dataset
/// (a report headlines the result's fit, shots and values as those of this model and data).
fn check_result_matches(
    path: &Path,
    rep: &harmonid_ident::Report,
    model_path: &Path,
    model: &harmonid_model::Model,
    dataset_path: &Path,
    ds: &harmonid_data::Dataset,
) -> miette::Result<()> {
    let list = |names: Vec<&str>| {
        let names = names.into_iter().map(str::to_string).collect();
        harmonid_data::text::first_and_more(names, 8).join(", ")
    };
    let differs = |what: &str, theirs: Vec<&str>, ours: Vec<&str>, whose: &Path| {
        miette!(
            help = format!(
                "{} was identified from {} and {}: report it with those, or identify this pair (harmonid identify {} {} --out r.json)",
                path.display(),
                rep.model,
                rep.dataset,
                model_path.display(),
                dataset_path.display()
            ),
            "{} is a result of another {}: its {what} are {}; {} has {}",
            path.display(),
            if what == "measurements" { "dataset" } else { "model" },
            list(theirs),
            whose.display(),
            list(ours)
        )
    };
    let mut modes: Vec<&str> = rep.modes.keys().map(String::as_str).collect();
    let mut ours = model.mode_names();
    modes.sort_unstable();
    ours.sort_unstable();
    if modes != ours {
        return Err(differs("modes", modes, ours, model_path));
    }
    let params: Vec<&str> = rep.parameters.keys().map(String::as_str).collect();
    let mut ours = model.param_names();
    ours.sort_unstable();
    if params != ours {
        return Err(differs("parameters", params, ours, model_path));
    }
    let measured: Vec<&str> = ds
        .measurements
        .iter()
        .map(|m| m.spec.name.as_str())
        .collect();
    let fitted: Vec<&str> = rep.forces.keys().map(String::as_str).collect();
    if fitted.iter().any(|f| !measured.contains(f)) {
        return Err(differs("measurements", fitted, measured, dataset_path));
    }
    Ok(())
}

//! `harmonid discover DATASET MODEL --degrees 2,3 [--potential] [--velocities] [--nonsmooth]
//! --out selected.hb`: which
//! candidate terms the data support (`harmonid_ident::discover`); with `--holdout` (which
//! `--error-floor` needs) selected by the prediction of the held-out data.

use crate::cli::common::{check_outputs, print_out, write_output, ForceArgs};
use harmonid_ident::{discover, DiscoverSettings, Library, LibraryForm, Settings};
use miette::miette;
use std::path::PathBuf;

/// Arguments of `harmonid discover`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset folder (with dataset.toml).
    pub dataset: PathBuf,
    /// The starting model (`*.hb`): its modes, and the terms it already has.
    pub model: PathBuf,
    /// Degrees of the candidate equation terms: `--degrees 3` (cubic), `--degrees 2,3` (a
    /// repeated degree counts once). Optional with --nonsmooth (that family alone).
    #[arg(long, value_delimiter = ',', required_unless_present = "nonsmooth")]
    pub degrees: Vec<u32>,
    /// Candidates as potential terms (one parameter per monomial of degree + 1, its
    /// derivatives in every equation) instead of one parameter per equation and monomial.
    #[arg(long)]
    pub potential: bool,
    /// Also every monomial of those degrees that holds a velocity (`q1^2*d(q1)`, `d(q1)^3`,
    /// `q2^2*d(q1)`: nonlinear damping, own and cross), per equation even with --potential.
    #[arg(long)]
    pub velocities: bool,
    /// Also the non-analytic family of each mode in its own equation, one parameter each:
    /// `abs(q1)*q1` (b1_absq: a stiffness growing like the amplitude, a frequency shift
    /// proportional to it), `abs(d(q1))*d(q1)` (b1_absdq: quadratic drag) and `sign(d(q1))`
    /// (b1_signdq: Coulomb friction). No cross forms between modes.
    #[arg(long)]
    pub nonsmooth: bool,
    /// Family-wise error per step: a term is added when its likelihood-ratio p-value times
    /// the number of candidates tried is below this.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Most terms added.
    #[arg(long, default_value_t = 10)]
    pub max_terms: usize,
    /// Fit every model with an error floor added to the shot noise (as `identify
    /// --error-floor`): for measured sweeps whose steps scatter more than their own samples
    /// say. Every χ² then equals its expectation, so terms are selected by how well they
    /// predict the --holdout data, which this needs.
    #[arg(long)]
    pub error_floor: bool,
    /// Fit every model without these measurements or sweeps and select terms by how well the
    /// fit of the rest predicts them (relative RMS), instead of by the likelihood-ratio test.
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]")]
    pub holdout: Vec<String>,
    /// With --holdout: a term is added when it lowers the held-out relative RMS by more than
    /// this fraction of it (and kept only while removing it would raise it by as much).
    #[arg(long, default_value_t = 0.05, value_name = "FRACTION")]
    pub min_improvement: f64,
    /// Fit a measurement background with every model (as `identify --background`): per mode
    /// on every measured line at a drive tone, `drive` a complex feedthrough times the drive
    /// level, `slope` a complex slope times the drive times (f − f_mode), `constant` a
    /// drive-independent complex offset. Its unknowns count in every model's.
    #[arg(long, value_name = "drive[,slope][,constant]", value_parser = crate::cli::identify::background_parser)]
    pub background: Option<harmonid_ident::Background>,
    /// Write the selected model here (a model file, every term per equation).
    #[arg(long, value_name = "SELECTED.hb")]
    pub out: PathBuf,
    /// Also write the selected model's identification (the result file of `identify`).
    #[arg(long, value_name = "RESULT.json")]
    pub result: Option<PathBuf>,
    /// Print the steps as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub forces: ForceArgs,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let ds = super::common::load_dataset(&args.dataset)?;
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let dataset_files = ds.input_files();
    let mut inputs: Vec<&std::path::Path> = vec![args.model.as_path()];
    inputs.extend(dataset_files.iter().map(|p| p.as_path()));
    let outputs: Vec<&std::path::Path> = std::iter::once(args.out.as_path())
        .chain(args.result.as_deref())
        .collect();
    check_outputs(&outputs, &inputs)?;
    if args.max_terms == 0 {
        return Err(miette!("--max-terms 0: give at least 1"));
    }
    let settings = DiscoverSettings {
        identify: Settings {
            force_model: args.forces.force_model(),
            jackknife: false,
            error_floor: args.error_floor,
            background: args.background.clone().unwrap_or_default(),
            ..Settings::default()
        },
        alpha: args.alpha,
        max_added: args.max_terms,
        holdout: args.holdout.clone(),
        min_improvement: args.min_improvement,
    };
    let library = Library {
        degrees: args.degrees.clone(),
        form: if args.potential {
            LibraryForm::Potential
        } else {
            LibraryForm::Equation
        },
        velocities: args.velocities,
        nonsmooth: args.nonsmooth,
    };
    let pb = super::progress::bar(0, "discover: identifications", false);
    let found = discover(&model, &ds, &library, &settings, |done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    });
    pb.finish_and_clear();
    let found = found.map_err(miette::Report::new)?;
    if args.json {
        print_out(format_args!("{}\n", found.to_json()));
    } else {
        print_out(format_args!("{}", found.table()));
    }
    let source = found.model_source(
        &args.dataset.display().to_string(),
        &args.model.display().to_string(),
    );
    write_output(&args.out, source.as_bytes(), &inputs)?;
    eprintln!("wrote {}", args.out.display());
    if let Some(path) = &args.result {
        let mut r = found.result.clone();
        r.model = args.out.display().to_string();
        write_output(path, r.to_json().as_bytes(), &inputs)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

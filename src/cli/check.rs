//! `harmonid check MODEL`: parse and validate a model file and print its equations of motion.

use std::io::Write;
use std::path::PathBuf;

/// Arguments of `harmonid check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`), e.g. examples/nanostring_2mode/model.hb.
    pub model: PathBuf,
    /// Print the equations as a LaTeX `aligned` block.
    #[arg(long, conflicts_with = "json")]
    pub latex: bool,
    /// Print modes, parameters and every equation's terms as JSON
    /// (`{"eom": {"q1": {"q1^3": {"beta1": 1.0}}}}`).
    #[arg(long)]
    pub json: bool,
}

/// Runs the subcommand: the readable report by default, `--latex` or `--json` on request.
///
/// A model whose coefficients are not linear in the parameters is printed all the same (it is
/// fine for simulation); the readable form and a note on stderr say it cannot be identified.
pub fn run(args: Args) -> miette::Result<()> {
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let text = if args.json {
        model.to_json()
    } else if args.latex {
        model.to_latex()
    } else {
        model.to_text()
    };
    let mut out = std::io::stdout().lock();
    // A closed pipe (`harmonid check m.hb | head`) is not an error worth reporting.
    let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
    if args.json || args.latex {
        for t in model.non_affine_terms() {
            eprintln!("note: this model cannot be identified: {t}");
        }
    }
    Ok(())
}

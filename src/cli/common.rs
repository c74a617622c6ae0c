//! Helpers shared by the subcommands: safe output files (see the `harmonid-files` crate) and
//! printing to a standard output that may be a closed pipe.

use std::io::Write;
use std::path::Path;

/// Prints to standard output as `print!` does, except that a closed pipe (`harmonid identify
/// ... | head -1`) is no error: the text is dropped and the run goes on, so its files are still
/// written and it exits 0. Any other failure to write is reported on standard error, once per
/// call, and the run goes on as well (the results are in the files).
pub fn print_out(args: std::fmt::Arguments<'_>) {
    let mut out = std::io::stdout().lock();
    match out.write_fmt(args).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            eprintln!("warning: cannot write to standard output: {e}");
        }
        _ => {}
    }
}

/// Writes `bytes` to `path` atomically (a staging file renamed into place), only over a regular
/// file, with the umask's permissions, and never over one of the run's `inputs` (every command
/// passes all the files it read: an output named like an input is refused, not written).
pub fn write_output(path: &Path, bytes: &[u8], inputs: &[&Path]) -> miette::Result<()> {
    harmonid_files::write_file(path, bytes, inputs).map_err(miette::Report::new)
}

/// The force-model flags of the commands that identify (`identify`, `compare`).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ForceArgs {
    /// Leave every drive tone's force a free complex unknown (the paper's model), even when the
    /// manifest gives drive levels and phases.
    #[arg(long, conflicts_with = "gain_per_mode")]
    pub free_forces: bool,
    /// With drive levels: one actuator gain per mode for the whole dataset (default: one per
    /// mode and measurement).
    #[arg(long)]
    pub gain_per_mode: bool,
}

impl ForceArgs {
    /// The force model the flags ask for (`Auto` without one).
    pub fn force_model(self) -> harmonid_ident::ForceModel {
        use harmonid_ident::ForceModel;
        if self.free_forces {
            ForceModel::Free
        } else if self.gain_per_mode {
            ForceModel::GainPerMode
        } else {
            ForceModel::Auto
        }
    }
}

/// Checks, before any work, that every one of `outputs` can be written as a file: its folder
/// exists, nothing but a regular file is at the path, and it is none of `inputs`.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path]) -> miette::Result<()> {
    for out in outputs {
        harmonid_files::check_output_file(out, inputs).map_err(miette::Report::new)?;
    }
    Ok(())
}

/// Reads the dataset folder `dir` and prints what reading did that the user should know of
/// (one `note:` line per stepped sweep's settling samples dropped) on standard error.
pub fn load_dataset(dir: &Path) -> miette::Result<harmonid_data::Dataset> {
    let ds = harmonid_data::Dataset::load(dir).map_err(miette::Report::new)?;
    for note in &ds.notes {
        eprintln!("note: {note}");
    }
    Ok(ds)
}

/// One `--force MODE=AMPLITUDE` (N/kg, peak): the mode's index in `model` and the amplitude,
/// or an error naming the option's text and what to write. `sweep`, `states` and `response`
/// read their forces with it.
pub fn force_entry(
    model: &harmonid_sim::NumericModel,
    given: &str,
) -> miette::Result<(usize, f64)> {
    let (m, v) = given
        .split_once('=')
        .ok_or_else(|| miette::miette!("--force {given}: expected MODE=AMPLITUDE, e.g. q1=3.5"))?;
    let n = model
        .mode_names
        .iter()
        .position(|x| x == m.trim())
        .ok_or_else(|| {
            miette::miette!(
                "--force {given}: `{}` is not a mode ({})",
                m.trim(),
                model.mode_names.join(", ")
            )
        })?;
    let a: f64 = v
        .trim()
        .parse()
        .ok()
        .filter(|a: &f64| a.is_finite())
        .ok_or_else(|| miette::miette!("--force {given}: `{v}` is not a finite number of N/kg"))?;
    Ok((n, a))
}

/// Every `--force MODE=AMPLITUDE` as a force per mode (N/kg, phase 0; zero for modes not
/// named).
pub fn forces(
    model: &harmonid_sim::NumericModel,
    given: &[String],
) -> miette::Result<Vec<num_complex::Complex64>> {
    let mut force = vec![num_complex::Complex64::new(0.0, 0.0); model.n_modes()];
    for f in given {
        let (n, a) = force_entry(model, f)?;
        force[n] = num_complex::Complex64::new(a, 0.0);
    }
    Ok(force)
}

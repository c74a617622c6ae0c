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

/// Checks, before any work, that every one of `outputs` can be written as a file: its folder
/// exists, nothing but a regular file is at the path, and it is none of `inputs`.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path]) -> miette::Result<()> {
    for out in outputs {
        harmonid_files::check_output_file(out, inputs).map_err(miette::Report::new)?;
    }
    Ok(())
}

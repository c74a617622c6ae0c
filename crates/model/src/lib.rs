//! The harmonid model language.
//!
//! A model file (`*.hb`) declares the modes of a resonator, its parameters, and its nonlinear
//! terms, written directly in an equation or as an interaction potential `U(q)` whose derivative
//! `∂U/∂q_n` enters the equation of mode `n`:
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = F_n(t),    ω_n = 2π f_n.
//! ```
//!
//! This crate parses a file (pest grammar in `grammar/model.pest`), checks it, and lowers it to a
//! [`Model`] whose equations are exact polynomials ([`harmonid_poly::Poly`]). It works in stages,
//! each returning all of its errors as [`ModelErrors`]: parse → syntax tree → expand index
//! families → resolve names → lower to polynomials and differentiate the potential.
//!
//! ```
//! let src = "
//!     mode q1 at 207.58 kHz
//!     mode q2 at 415.84 kHz
//!     param beta1, beta2, g12 >= 0
//!     potential: beta1/4*q1^4 + beta2/4*q2^4 + g12/2*q1^2*q2^2
//! ";
//! let model = harmonid_model::parse_str(src, "nanostring.hb")?;
//! assert_eq!(model.mode_names(), ["q1", "q2"]);
//! assert_eq!(model.equation_text(0), "q1'' + (w1/Q1) q1' + w1^2 q1 + beta1 q1^3 + g12 q1 q2^2 = F1(t)");
//! # Ok::<(), harmonid_model::ModelErrors>(())
//! ```
//!
//! Errors render with miette; [`ModelErrors::render_plain`] gives the text without colours:
//!
//! ```
//! let err = harmonid_model::parse_str("mode q1\neom q2 += q1^3\n", "bad.hb").unwrap_err();
//! let text = err.render_plain(80);
//! assert!(text.contains("bad.hb:2:5"));
//! assert!(text.contains("not a declared mode"));
//! ```

mod ast;
mod error;
mod model;
mod nonsmooth;
mod output;
mod sema;
mod syntax;

pub use error::{Code, ModelDiagnostic, ModelErrors, Span};
pub use model::{
    velocity_name, Bounds, Linear, Mode, Model, NonAffineTerm, ParamKind, Parameter, PUMP_NAME,
};
pub use nonsmooth::{format_scale, sign, NonSmooth};
pub use output::latex_name;
pub use sema::equations_from_potential;

use std::path::Path;

/// Brackets (`(`, `[`, `{`) may nest at most this deep.
pub const MAX_NESTING: usize = 64;
/// Largest whole number accepted in a family range or an index.
pub const MAX_INDEX: i64 = 100_000;
/// Index families may expand to at most this many statements (over the whole file).
pub const MAX_FAMILY_INSTANCES: usize = 2_000_000;
/// Highest total degree of any term, in the modes and in the parameters separately.
pub const MAX_DEGREE: u32 = 64;
/// Most terms any expression, equation or the potential may hold.
pub const MAX_TERMS: usize = 2_000_000;
/// Most term pairs one product may multiply while expanding.
pub const MAX_PRODUCT_WORK: usize = 1_000_000;
/// Most diagnostics reported for one file.
pub const MAX_DIAGNOSTICS: usize = 100;
/// Largest model file `load` reads, in bytes.
pub const MAX_FILE_BYTES: u64 = 256 * 1024 * 1024;

/// Parses and checks a model written in the model language; `origin` names it in messages
/// (usually the file path).
///
/// Returns every diagnostic of the first stage that fails: syntax errors, or else all semantic
/// errors (unknown or duplicate names, undeclared modes, non-polynomial terms, families out of
/// range, resource limits, an empty model).
pub fn parse_str(source: &str, origin: &str) -> Result<Model, ModelErrors> {
    // A byte-order mark is not part of the text (editors on Windows add one).
    let source = source.strip_prefix('\u{FEFF}').unwrap_or(source);
    let file = syntax::parse(source).map_err(|d| ModelErrors::new(origin, source, d))?;
    sema::lower(&file, source, origin).map_err(|d| ModelErrors::new(origin, source, d))
}

/// Reads and checks the model file at `path`. An unreadable file and a file that is not UTF-8
/// are diagnostics too (the latter points at the first bad byte).
pub fn load(path: &Path) -> Result<Model, ModelErrors> {
    let origin = path.display().to_string();
    let io_error = |msg: String, help: &str| {
        ModelErrors::new(
            &origin,
            "",
            vec![ModelDiagnostic {
                code: Code::Io,
                message: msg,
                span: None,
                label: String::new(),
                help: help.to_string(),
            }],
        )
    };
    match std::fs::metadata(path) {
        Ok(m) if m.len() > MAX_FILE_BYTES => {
            return Err(io_error(
                format!(
                    "{origin} is {} bytes, larger than the limit of {MAX_FILE_BYTES}",
                    m.len()
                ),
                "a model file is a short text file; check the path",
            ))
        }
        Ok(m) if m.is_dir() => {
            return Err(io_error(
                format!("{origin} is a folder, not a model file"),
                "give the path of a model file, e.g. examples/nanostring_2mode/model.hb",
            ))
        }
        _ => {}
    }
    let bytes = std::fs::read(path).map_err(|e| {
        io_error(
            format!("cannot read {origin}: {e}"),
            "check that the path exists and is readable",
        )
    })?;
    parse_bytes(&bytes, &origin)
}

/// Parses and checks a model given as raw bytes (the content of a file); `origin` names it in
/// messages. Bytes that are not UTF-8 are a diagnostic pointing at the first bad byte; a leading
/// UTF-8 byte-order mark (written by some editors) is skipped.
pub fn parse_bytes(bytes: &[u8], origin: &str) -> Result<Model, ModelErrors> {
    match std::str::from_utf8(bytes) {
        Ok(text) => parse_str(text, origin),
        Err(err) => {
            let at = err.valid_up_to();
            let bad = err.error_len().unwrap_or(1);
            let lossy = String::from_utf8_lossy(bytes).into_owned();
            // The lossy text equals the original up to `at`; the replacement character that
            // stands for the bad bytes takes 3 bytes.
            Err(ModelErrors::new(
                origin,
                &lossy,
                vec![ModelDiagnostic {
                    code: Code::NotUtf8,
                    message: format!(
                        "{origin} is not UTF-8 text: byte {at} starts an invalid sequence of {bad} byte{}",
                        if bad == 1 { "" } else { "s" }
                    ),
                    span: Some(Span::new(at, at + '\u{FFFD}'.len_utf8())),
                    label: "not UTF-8".to_string(),
                    help: "save the file as UTF-8 (plain ASCII is fine); names and numbers are ASCII"
                        .to_string(),
                }],
            ))
        }
    }
}

#[cfg(test)]
mod test_nonsmooth;
#[cfg(test)]
mod tests;

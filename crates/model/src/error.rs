//! Diagnostics of the model language: every error is located, coded and explained.

use harmonid_files::{QuotedSource, QUOTE_LINE};
use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme, LabeledSpan, SourceSpan};
use std::fmt;

/// A byte range `start..end` in the model source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

impl Span {
    /// The range `start..end`.
    pub fn new(start: usize, end: usize) -> Self {
        Self { start, end }
    }

    pub(crate) fn from_pest(s: pest::Span<'_>) -> Self {
        Self::new(s.start(), s.end())
    }

    /// Length in bytes.
    pub fn len(&self) -> usize {
        self.end.saturating_sub(self.start)
    }

    /// Whether the range is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Stable codes of model diagnostics (shown as `model::<code>`; tests and docs rely on them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Code {
    /// The file cannot be read.
    Io,
    /// The file is not UTF-8 text.
    NotUtf8,
    /// The text does not follow the grammar.
    Syntax,
    /// Brackets nested deeper than [`crate::MAX_NESTING`].
    TooDeep,
    /// A number that cannot be represented (too many digits, out of range).
    BadNumber,
    /// A frequency or quality factor that is missing its unit, has a wrong one, or is not positive.
    BadLinear,
    /// Inconsistent bounds or value of a parameter.
    BadBound,
    /// A name declared twice (mode or parameter).
    Duplicate,
    /// A name used but not declared.
    UnknownName,
    /// A term in the equation of a name that is not a declared mode.
    UndeclaredMode,
    /// A family head or index that is malformed or out of range.
    FamilyRange,
    /// An expression that is not a polynomial (negative or fractional power, function, division
    /// by a variable).
    NotPolynomial,
    /// Exact arithmetic overflowed 128-bit rationals.
    Overflow,
    /// Past a documented resource bound (family size, degree, number of terms).
    TooLarge,
    /// The file declares no mode.
    EmptyModel,
    /// `d(...)` of something that is not one mode (`d(beta)`, `d(d(q1))`, `d(q1 + q2)`), or a
    /// dissipation function without a velocity.
    BadVelocity,
    /// A velocity `d(q1)` in a potential (a potential depends on the positions only).
    VelocityInPotential,
    /// A declaration of a built-in name (`pump`).
    ReservedName,
    /// A non-smooth factor (`abs`, `sign`, `tanh`) that is not of one mode or one velocity, a
    /// `tanh` scale that is not a positive number, or one in a potential or dissipation
    /// function.
    BadNonSmooth,
}

impl Code {
    /// The code as printed, e.g. `model::unknown-name`.
    pub fn as_str(self) -> &'static str {
        match self {
            Code::Io => "model::io",
            Code::NotUtf8 => "model::not-utf8",
            Code::Syntax => "model::syntax",
            Code::TooDeep => "model::too-deep",
            Code::BadNumber => "model::bad-number",
            Code::BadLinear => "model::bad-linear",
            Code::BadBound => "model::bad-bound",
            Code::Duplicate => "model::duplicate",
            Code::UnknownName => "model::unknown-name",
            Code::UndeclaredMode => "model::undeclared-mode",
            Code::FamilyRange => "model::family-range",
            Code::NotPolynomial => "model::not-polynomial",
            Code::Overflow => "model::overflow",
            Code::TooLarge => "model::too-large",
            Code::EmptyModel => "model::empty-model",
            Code::BadVelocity => "model::bad-velocity",
            Code::VelocityInPotential => "model::velocity-in-potential",
            Code::ReservedName => "model::reserved-name",
            Code::BadNonSmooth => "model::bad-nonsmooth",
        }
    }
}

impl fmt::Display for Code {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One located problem in a model file.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelDiagnostic {
    /// Stable code.
    pub code: Code,
    /// What is wrong, in plain words.
    pub message: String,
    /// Where (None for whole-file problems such as an unreadable file).
    pub span: Option<Span>,
    /// Short text under the caret.
    pub label: String,
    /// What to try.
    pub help: String,
}

impl ModelDiagnostic {
    pub(crate) fn new(
        code: Code,
        span: Span,
        message: impl Into<String>,
        label: impl Into<String>,
        help: impl Into<String>,
    ) -> Self {
        Self {
            code,
            message: message.into(),
            span: Some(span),
            label: label.into(),
            help: help.into(),
        }
    }
}

impl fmt::Display for ModelDiagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for ModelDiagnostic {}

impl Diagnostic for ModelDiagnostic {
    fn code<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        Some(Box::new(self.code))
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        if self.help.is_empty() {
            None
        } else {
            Some(Box::new(&self.help))
        }
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let span = self.span?;
        let label = (!self.label.is_empty()).then(|| self.label.clone());
        Some(Box::new(std::iter::once(LabeledSpan::new_with_span(
            label,
            SourceSpan::new(span.start.into(), span.len()),
        ))))
    }
}

/// All diagnostics of the stage that failed (parse, or the semantic checks), with the source
/// attached so that miette prints `file:line:col`, the offending line and a caret. A long line
/// (a 200 kB expression) is quoted as a window around the caret, never whole.
#[derive(Debug, Clone)]
pub struct ModelErrors {
    origin: String,
    source: QuotedSource,
    diagnostics: Vec<ModelDiagnostic>,
}

impl ModelErrors {
    pub(crate) fn new(origin: &str, source: &str, mut diagnostics: Vec<ModelDiagnostic>) -> Self {
        let quoted = QuotedSource::new(origin, source);
        // A label under a whole 200 kB expression would quote all of it: on a line longer than
        // QUOTE_LINE, the label covers at most the window QuotedSource shows.
        for d in &mut diagnostics {
            if let Some(span) = &mut d.span {
                let start = span.start.min(source.len());
                let end = span.end.clamp(start, source.len());
                let line_start = source[..start].rfind('\n').map_or(0, |i| i + 1);
                let line_end = source[end..].find('\n').map_or(source.len(), |i| end + i);
                if line_end - line_start > QUOTE_LINE {
                    let label = quoted.label(start..end);
                    *span = Span::new(label.offset(), label.offset() + label.len());
                }
            }
        }
        Self {
            origin: origin.to_string(),
            source: quoted,
            diagnostics,
        }
    }

    /// The diagnostics, in source order within each stage.
    pub fn diagnostics(&self) -> &[ModelDiagnostic] {
        &self.diagnostics
    }

    /// The file name or label the model came from.
    pub fn origin(&self) -> &str {
        &self.origin
    }

    /// Whether some diagnostic has the given code.
    pub fn has(&self, code: Code) -> bool {
        self.diagnostics.iter().any(|d| d.code == code)
    }

    /// Renders every diagnostic as plain text (no colours, no hyperlinks) wrapped at `width`
    /// columns: the form used by snapshot tests and by tests of other crates.
    pub fn render_plain(&self, width: usize) -> String {
        let handler = GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor())
            .with_width(width)
            .with_links(false);
        let mut out = String::new();
        if handler.render_report(&mut out, self).is_err() {
            // Rendering into a String cannot fail in practice; fall back to the bare messages.
            out = self.to_string();
            for d in &self.diagnostics {
                out.push_str(&format!("\n{}: {}", d.code, d.message));
            }
        }
        out
    }
}

impl fmt::Display for ModelErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.diagnostics.len() {
            1 => write!(f, "{}: 1 error in the model", self.origin),
            n => write!(f, "{}: {n} errors in the model", self.origin),
        }
    }
}

impl std::error::Error for ModelErrors {}

impl Diagnostic for ModelErrors {
    fn source_code(&self) -> Option<&dyn miette::SourceCode> {
        Some(&self.source)
    }

    fn related<'a>(&'a self) -> Option<Box<dyn Iterator<Item = &'a dyn Diagnostic> + 'a>> {
        Some(Box::new(
            self.diagnostics.iter().map(|d| d as &dyn Diagnostic),
        ))
    }
}

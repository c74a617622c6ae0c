//! Quoting an input file in a message without quoting all of it: a plan or manifest line can hold
//! thousands of tones (50 kB), and a message that prints the whole line buries the one key it is
//! about. [`QuotedSource`] is the source a located diagnostic shows (miette reads through it),
//! [`quote_line`] the same window as plain text for messages that are not rendered by miette.

use miette::{MietteError, MietteSpanContents, SourceCode, SourceSpan, SpanContents};
use std::ops::Range;

/// Lines up to this many bytes are quoted whole.
pub const QUOTE_LINE: usize = 400;
/// How many characters of a longer line are quoted on each side of the span a message points at.
pub const QUOTE_CONTEXT: usize = 60;
/// How many characters of the span itself are quoted (and underlined) at most.
pub const QUOTE_SPAN: usize = 80;

/// A file's text as a diagnostic's source code: lines up to [`QUOTE_LINE`] bytes are shown whole
/// with the lines around them, as miette shows any source; a longer line is shown as a window of
/// it around the span, alone, with its true line and column.
#[derive(Debug, Clone)]
pub struct QuotedSource {
    name: String,
    text: String,
}

impl QuotedSource {
    /// The source `text` of the file called `name` (the path, as messages print it).
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> QuotedSource {
        QuotedSource {
            name: name.into(),
            text: text.into(),
        }
    }

    /// The span to label for `span`: at most [`QUOTE_SPAN`] bytes of it (a label under a whole
    /// 50 kB array would quote it all), cut at a character boundary.
    pub fn label(&self, span: Range<usize>) -> SourceSpan {
        let start = floor_char(&self.text, span.start.min(self.text.len()));
        let end = floor_char(&self.text, span.end.clamp(start, start + QUOTE_SPAN));
        (start, end - start).into()
    }
}

impl SourceCode for QuotedSource {
    fn read_span<'a>(
        &'a self,
        span: &SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'a> + 'a>, MietteError> {
        let start = span.offset();
        let end = start + span.len();
        if end > self.text.len() {
            return Err(MietteError::OutOfBounds);
        }
        let window = window(&self.text, start..end);
        let (line_start, line_end) = line_bounds(&self.text, start..end);
        if window == (line_start..line_end) {
            // Short lines: as miette shows any text, context lines included.
            let inner = self
                .text
                .read_span(span, context_lines_before, context_lines_after)?;
            return Ok(Box::new(MietteSpanContents::new_named(
                self.name.clone(),
                inner.data(),
                *inner.span(),
                inner.line(),
                inner.column(),
                inner.line_count(),
            )));
        }
        // miette heads the snippet with the line and column of this span's start, as
        // `str`'s own `read_span` gives them; the data start only where the window does.
        let (line, column) = line_column(&self.text, start);
        Ok(Box::new(MietteSpanContents::new_named(
            self.name.clone(),
            &self.text.as_bytes()[window.clone()],
            (window.start, window.len()).into(),
            line,
            column,
            1,
        )))
    }
}

/// The line (or lines) holding `span` as plain text, cut to a window around the span with `…`
/// where it was cut, and its 1-based line and column: for messages that quote without miette
/// (`line 45, column 20015: … 207999.5] ; zzz = 3`).
pub fn quote_line(text: &str, span: Range<usize>) -> String {
    let start = floor_char(text, span.start.min(text.len()));
    let end = floor_char(text, span.end.clamp(start, text.len()));
    let w = window(text, start..end);
    let (line_start, line_end) = line_bounds(text, start..end);
    let (line, column) = line_column(text, start);
    let quoted = text[w.clone()].trim_end_matches(['\n', '\r']);
    format!(
        "line {}, column {}: {}{}{}",
        line + 1,
        column + 1,
        if w.start > line_start { "…" } else { "" },
        quoted,
        if w.end < line_end { "…" } else { "" }
    )
}

/// The bytes of `text` a message quotes for `span`: the lines it touches, whole up to
/// [`QUOTE_LINE`] bytes, else cut to [`QUOTE_CONTEXT`] characters before its start and after its
/// end (the span itself cut to [`QUOTE_SPAN`]), at character boundaries.
fn window(text: &str, span: Range<usize>) -> Range<usize> {
    let (line_start, line_end) = line_bounds(text, span.clone());
    if line_end - line_start <= QUOTE_LINE {
        return line_start..line_end;
    }
    let span_end = floor_char(text, span.end.min(span.start + QUOTE_SPAN));
    let start = back_chars(text, span.start, QUOTE_CONTEXT).max(line_start);
    let end = forward_chars(text, span_end, QUOTE_CONTEXT).min(line_end);
    start..end
}

/// The start of the first and the end (newline excluded) of the last line `span` touches.
fn line_bounds(text: &str, span: Range<usize>) -> (usize, usize) {
    let start = text[..span.start].rfind('\n').map_or(0, |i| i + 1);
    let end = text[span.end..]
        .find('\n')
        .map_or(text.len(), |i| span.end + i);
    (start, end)
}

/// The 0-based line and column (in characters) of byte `at`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let before = &text[..at];
    let line = before.matches('\n').count();
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count())
}

fn floor_char(text: &str, mut at: usize) -> usize {
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

fn back_chars(text: &str, at: usize, n: usize) -> usize {
    text[..at]
        .char_indices()
        .rev()
        .nth(n.saturating_sub(1))
        .map_or(0, |(i, _)| i)
}

fn forward_chars(text: &str, at: usize, n: usize) -> usize {
    text[at..]
        .char_indices()
        .nth(n)
        .map_or(text.len(), |(i, _)| at + i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme};

    #[derive(Debug, thiserror::Error, Diagnostic)]
    #[error("bad key")]
    struct Located {
        #[source_code]
        src: QuotedSource,
        #[label("here")]
        span: SourceSpan,
    }

    fn render(text: &str, span: Range<usize>) -> String {
        let src = QuotedSource::new("plan.toml", text);
        let err = Located {
            span: src.label(span),
            src,
        };
        let mut out = String::new();
        GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor())
            .with_width(400)
            .render_report(&mut out, &err)
            .expect("render");
        out
    }

    /// A plan line with 2000 tones, and a bad key after them.
    fn long_line() -> (String, Range<usize>) {
        let tones: Vec<String> = (0..2000).map(|i| format!("{}.5", 207000 + i)).collect();
        let text = format!(
            "name = \"long\"\nmeasure_hz = [{}] ; zzz = 3\nshots = 2\n",
            tones.join(", ")
        );
        let at = text.find("; zzz").expect("key");
        (text, at..at + 1)
    }

    #[test]
    fn a_long_line_is_quoted_as_a_window_with_its_true_position() {
        let (text, span) = long_line();
        assert!(text.len() > 16_000);
        let out = render(&text, span.clone());
        assert!(out.len() < 800, "{} bytes:\n{out}", out.len());
        assert!(out.contains("; zzz = 3"), "{out}");
        let (line, column) = line_column(&text, span.start);
        assert_eq!(line, 1);
        assert!(
            out.contains(&format!("[plan.toml:2:{}]", column + 1)),
            "{out}"
        );
        // The gutter numbers the quoted line with its line in the file.
        assert!(out.contains(" 2 │"), "{out}");
        assert!(!out.contains("207000.5"), "{out}");
    }

    #[test]
    fn short_lines_are_quoted_whole_with_context() {
        let text = "a = 1\nb = 2\nc = 3\n";
        let out = render(text, 6..7);
        for line in ["a = 1", "b = 2", "c = 3"] {
            assert!(out.contains(line), "{out}");
        }
        assert!(out.contains("[plan.toml:2:1]"), "{out}");
    }

    #[test]
    fn a_label_over_a_whole_long_value_is_cut() {
        let (text, _) = long_line();
        let start = text.find('[').expect("array");
        let end = text.find(']').expect("array end") + 1;
        let out = render(&text, start..end);
        assert!(out.len() < 1200, "{} bytes:\n{out}", out.len());
        assert!(out.contains("[207000.5"), "{out}");
    }

    #[test]
    fn plain_quote_marks_the_cuts() {
        let (text, span) = long_line();
        let q = quote_line(&text, span);
        assert!(q.starts_with("line 2, column "), "{q}");
        assert!(q.contains("…") && q.ends_with("; zzz = 3"), "{q}");
        assert!(q.chars().count() < 200, "{q}");
        assert_eq!(
            quote_line("a = 1\nb = ?\n", 10..11),
            "line 2, column 5: b = ?"
        );
    }

    #[test]
    fn multibyte_text_is_cut_at_character_boundaries() {
        let text = format!("x = \"{}\" ; bad", "µ".repeat(500));
        let at = text.find("; bad").expect("key");
        let q = quote_line(&text, at..at + 1);
        assert!(q.contains("; bad") && q.contains('µ'), "{q}");
        let out = render(&text, at + 1..at + 1);
        assert!(out.contains("; bad"), "{out}");
    }
}

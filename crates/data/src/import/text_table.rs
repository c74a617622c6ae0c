//! Text tables for `harmonid import table`: where a mapping's column is (a header name or a
//! 1-based column number), and the reading of a delimited text file into columns of numbers.
//!
//! A lab's text export comes as it comes: `#` (or a Moku's `%`) comment lines before and between
//! the data, a header line or none (a file whose first line that is not a comment is numbers
//! has none: its columns are mapped by number), separated by whitespace, tabs, commas or
//! semicolons. Every refusal names the file, the line and the column, and what to write instead.

use super::ImportError;
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// Where one quantity is in the input: a header name (or, in a MATLAB file, a variable path),
/// or a 1-based column number for a text file without a header line (`freq_hz = 2`).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum Column {
    /// A header name, or a MATLAB path (`forced_data.Data.X1__V_.data`).
    Name(String),
    /// A column number, 1 for the first (as a spreadsheet or `awk` counts them).
    Number(usize),
}

impl Column {
    /// The header name or MATLAB path, `None` for a column number.
    pub fn name(&self) -> Option<&str> {
        match self {
            Column::Name(n) => Some(n),
            Column::Number(_) => None,
        }
    }
}

impl fmt::Display for Column {
    /// `"X1__V_"` (quoted, escaped, cut) for a name, `column 3` for a number.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Column::Name(n) => f.write_str(&crate::text::header_names([n.as_str()])),
            Column::Number(k) => write!(f, "column {k}"),
        }
    }
}

impl<'de> serde::Deserialize<'de> for Column {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Column, D::Error> {
        d.deserialize_any(ColumnVisitor)
    }
}

/// Reads a mapping's column: a string is a header name, a whole number ≥ 1 a column number;
/// anything else is refused saying what to write.
struct ColumnVisitor;

impl serde::de::Visitor<'_> for ColumnVisitor {
    type Value = Column;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(
            "a header name in quotes (freq_hz = \"f\") or a 1-based column number (freq_hz = 2)",
        )
    }

    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Column, E> {
        if v.trim().is_empty() {
            return Err(E::custom(
                "an empty column name: write the header's name (freq_hz = \"f\"), or the column's number for a file without a header (freq_hz = 2)",
            ));
        }
        Ok(Column::Name(v.to_string()))
    }

    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Column, E> {
        match usize::try_from(v) {
            Ok(k) if k >= 1 => Ok(Column::Number(k)),
            _ => Err(E::custom(format!(
                "column {v}: columns are numbered from 1 (the first column is 1, as a spreadsheet counts them)"
            ))),
        }
    }

    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Column, E> {
        self.visit_i64(i64::try_from(v).unwrap_or(-1))
    }

    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Column, E> {
        Err(E::custom(format!(
            "column {v} is not a whole number: write a 1-based column number without a decimal point (freq_hz = 2), or a header name in quotes"
        )))
    }
}

/// The columns of one group of an input (a text table is one group; a MAT path with `(*)` one
/// group per element).
pub(super) struct Group {
    /// The group's name (empty: the input file's stem).
    pub name: String,
    /// The values of every wanted column but the sweep labels.
    pub cols: BTreeMap<Column, Vec<f64>>,
    /// The sweep label of each row, as written (text or a number), when a sweep column is
    /// mapped.
    pub labels: Option<Vec<String>>,
    /// The 1-based line of each value in a text file (comment and blank lines counted), for
    /// messages; `None` for a MATLAB file.
    pub rows: Option<Vec<usize>>,
}

/// A text table's field separator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sep {
    /// Any run of spaces and tabs.
    Whitespace,
    /// One character (`,` `;` or a tab): empty fields count.
    Char(char),
}

impl Sep {
    /// The mapping's `delimiter`, checked: "," ";" "\t" or " " (any run of whitespace).
    fn given(d: &str, path: &Path) -> Result<Sep, ImportError> {
        match d {
            " " => Ok(Sep::Whitespace),
            "," | ";" | "\t" => Ok(Sep::Char(d.chars().next().unwrap_or(','))),
            _ => Err(ImportError::Input {
                path: path.to_path_buf(),
                row: None,
                message: format!(
                    "delimiter = {}: expected \",\", \";\", \"\\t\" or \" \" (any run of spaces and tabs), or no delimiter to detect it from the first data line",
                    crate::text::header_names([d])
                ),
            }),
        }
    }

    /// The separator of a data line: `;` if it has one (then a comma is a decimal comma), else
    /// `,` if it has one, else whitespace (spaces and tabs).
    fn detect(line: &str) -> Sep {
        if line.contains(';') {
            Sep::Char(';')
        } else if line.contains(',') {
            Sep::Char(',')
        } else {
            Sep::Whitespace
        }
    }

    /// The fields of `line`, trimmed.
    fn split(self, line: &str) -> Vec<&str> {
        match self {
            Sep::Whitespace => line.split_whitespace().collect(),
            Sep::Char(c) => line.split(c).map(str::trim).collect(),
        }
    }

    /// The separator as a reader would name it.
    fn name(self) -> &'static str {
        match self {
            Sep::Whitespace => "spaces or tabs",
            Sep::Char(',') => "\",\"",
            Sep::Char(';') => "\";\"",
            Sep::Char(_) => "tabs",
        }
    }
}

/// Whether `line` is a comment: its first non-blank character is `#` or `%`.
fn is_comment(line: &str) -> bool {
    let t = line.trim_start();
    t.starts_with('#') || t.starts_with('%')
}

/// Whether `line` is data rather than a header line. With every column mapped by number
/// (`numbered`), a header holds no number at all (split by `sep` or by spaces: a data line
/// with a stray separator is still data, and refused as such, never dropped as a header; a
/// text sweep label is no header either). Else data when every field is a number.
fn is_data(line: &str, sep: Sep, numbered: bool) -> bool {
    let number = |c: &&str| c.parse::<f64>().is_ok();
    if numbered {
        sep.split(line).iter().any(number) || line.split_whitespace().any(|c| number(&c))
    } else {
        let f = sep.split(line);
        !f.is_empty() && f.iter().all(number)
    }
}

/// A cell for a message: quoted, escaped, cut.
fn shown(cell: &str) -> String {
    crate::text::header_names([cell])
}

/// What a table's lines are: the header's names and line (none for a file without a header),
/// the separator, and the 0-based index of the first data line.
struct Layout {
    header: Option<(usize, Vec<String>)>,
    sep: Sep,
    first_data: usize,
}

/// Finds the header and the data of `lines` (blank and comment lines skipped): the first
/// line that is not a comment is the header unless it is numbers; a file without one may have
/// its header as the last comment line before the data that holds every name `named` (a
/// Moku's `% Time (s), ...`, a `# f X Y`).
fn layout(
    path: &Path,
    lines: &[&str],
    delimiter: Option<&str>,
    named: &[&str],
) -> Result<Layout, ImportError> {
    let bad = |row: Option<usize>, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row,
        message,
    };
    let content = |from: usize| {
        (from..lines.len()).find(|&i| !lines[i].trim().is_empty() && !is_comment(lines[i]))
    };
    let Some(first) = content(0) else {
        return Err(bad(
            None,
            if lines.iter().all(|l| l.trim().is_empty()) {
                "the file is empty".into()
            } else {
                format!(
                    "no data: the file's {} lines are all comments (# or %) or blank; is it the file meant?",
                    lines.len()
                )
            },
        ));
    };
    let given = delimiter.map(|d| Sep::given(d, path)).transpose()?;
    let first_sep = given.unwrap_or_else(|| Sep::detect(lines[first]));
    if is_data(lines[first], first_sep, named.is_empty()) {
        // No header line: the columns are numbers, or named by a comment line.
        let header = if named.is_empty() {
            None
        } else {
            let found = lines[..first].iter().enumerate().rev().find_map(|(i, l)| {
                let t = l.trim_start().trim_start_matches(['%', '#']);
                let names: Vec<String> = first_sep.split(t).iter().map(|s| s.to_string()).collect();
                named
                    .iter()
                    .all(|n| names.iter().any(|h| h == n))
                    .then_some((i, names))
            });
            Some(found.ok_or_else(|| {
                bad(
                    Some(first + 1),
                    format!(
                        "line {} is numbers, so the file has no header line, but the mapping names columns by header ({}): map them by their 1-based number instead, e.g. freq_hz = 1, x = 2, y = 3 (no quotes)",
                        first + 1,
                        crate::text::header_names(named.iter().copied())
                    ),
                )
            })?)
        };
        return Ok(Layout {
            header,
            sep: first_sep,
            first_data: first,
        });
    }
    // Without a data line (refused once the header's names are checked), the header's own
    // separator.
    let data = content(first + 1).unwrap_or(lines.len());
    let sep = given.unwrap_or_else(|| Sep::detect(lines.get(data).unwrap_or(&lines[first])));
    let t = lines[first].trim_start().trim_start_matches(['%', '#']);
    let names = sep.split(t).iter().map(|s| s.to_string()).collect();
    Ok(Layout {
        header: Some((first, names)),
        sep,
        first_data: data,
    })
}

/// Each wanted column's 0-based field index: a name looked up in the header (an error lists
/// the header's names), a number as is.
fn field_indices(
    path: &Path,
    wanted: &[(&str, &Column)],
    header: Option<&(usize, Vec<String>)>,
) -> Result<Vec<usize>, ImportError> {
    wanted
        .iter()
        .map(|(key, col)| match (col, header) {
            (Column::Number(k), _) => Ok(k - 1),
            (Column::Name(n), Some((at, names))) => {
                names.iter().position(|h| h == n).ok_or_else(|| ImportError::Input {
                    path: path.to_path_buf(),
                    row: Some(at + 1),
                    message: format!(
                        "no column \"{n}\" ({key}) in the header (found: {}); or map it by its 1-based number, {key} = {}",
                        crate::text::header_names(names.iter().map(String::as_str)),
                        names.len().min(2)
                    ),
                })
            }
            // `layout` finds a header whenever a column is named.
            (Column::Name(n), None) => Err(ImportError::Input {
                path: path.to_path_buf(),
                row: None,
                message: format!("no header line to find \"{n}\" in: map {key} by its number"),
            }),
        })
        .collect()
}

/// Why a cell may not have parsed: another separator inside it (mixed separators, a decimal
/// comma), said as a hint.
fn separator_hint(cell: &str, sep: Sep) -> String {
    let other = [',', ';', '\t', ' ']
        .into_iter()
        .find(|&c| cell.contains(c) && Sep::Char(c) != sep);
    match other {
        Some(',') if sep == Sep::Char(';') => {
            "; a decimal comma (write numbers with a decimal point) or mixed separators (set delimiter = \",\" in the mapping)?".into()
        }
        Some(c) => format!(
            "; it holds {} but the fields are separated by {}: mixed separators? set delimiter = {} in the mapping",
            shown(&c.to_string()),
            sep.name(),
            shown(&c.to_string())
        ),
        None => String::new(),
    }
}

/// The one group of a text table: every wanted column (`(mapping key, column)`) read as
/// numbers but the sweep column (`sweep`), kept as written (`s00`, `1`); comment and blank
/// lines skipped anywhere. Each refusal names the line, the column and what to write.
pub(super) fn read_text(
    path: &Path,
    wanted: &[(&str, &Column)],
    delimiter: Option<&str>,
    sweep: Option<&Column>,
) -> Result<Vec<Group>, ImportError> {
    let text = super::read_input(path)?;
    let lines: Vec<&str> = text.lines().collect();
    // A column mapped twice (freq_hz and drive_level the same) is read once.
    let mut wanted: Vec<(&str, &Column)> = wanted.to_vec();
    let mut seen = std::collections::BTreeSet::new();
    wanted.retain(|(_, c)| seen.insert(*c));
    let named: Vec<&str> = wanted.iter().filter_map(|(_, c)| c.name()).collect();
    let Layout {
        header,
        sep,
        first_data,
    } = layout(path, &lines, delimiter, &named)?;
    let wanted = &wanted[..];
    let idx = field_indices(path, wanted, header.as_ref())?;
    if first_data >= lines.len() {
        return Err(ImportError::Input {
            path: path.to_path_buf(),
            row: header.as_ref().map(|h| h.0 + 1),
            message: "no data rows after the header line (only comments or blank lines)".into(),
        });
    }
    let bad = |row: usize, message: String| ImportError::Input {
        path: path.to_path_buf(),
        row: Some(row),
        message,
    };
    let mut cols: BTreeMap<Column, Vec<f64>> = wanted
        .iter()
        .filter(|(_, c)| Some(*c) != sweep)
        .map(|(_, c)| ((*c).clone(), Vec::new()))
        .collect();
    let mut labels = sweep.map(|_| Vec::new());
    let mut rows = Vec::new();
    let first_fields = sep.split(lines[first_data]).len();
    for (n, line) in lines.iter().enumerate().skip(first_data) {
        if line.trim().is_empty() || is_comment(line) {
            continue;
        }
        let fields = sep.split(line);
        for ((key, col), &i) in wanted.iter().zip(&idx) {
            let Some(&cell) = fields.get(i) else {
                let fix = match col {
                    Column::Number(_) => format!(
                        "; the first data line (line {}) has {first_fields}: map {key} to a column from 1 to {first_fields}",
                        first_data + 1
                    ),
                    Column::Name(_) => String::new(),
                };
                return Err(bad(
                    n + 1,
                    format!(
                        "{} fields (separated by {}), but {key} = {col} is field {}{fix}{}",
                        fields.len(),
                        sep.name(),
                        i + 1,
                        separator_hint(line, sep)
                    ),
                ));
            };
            if let (Some(l), true) = (labels.as_mut(), Some(*col) == sweep) {
                if cell.is_empty() {
                    return Err(bad(
                        n + 1,
                        format!("{key} = {col} (field {}): empty sweep label", i + 1),
                    ));
                }
                l.push(cell.to_string());
                continue;
            }
            let v: f64 = cell.parse().map_err(|_| {
                bad(
                    n + 1,
                    format!(
                        "field {} ({key} = {col}): {} is not a number{}",
                        i + 1,
                        shown(cell),
                        separator_hint(cell, sep)
                    ),
                )
            })?;
            if let Some(c) = cols.get_mut(*col) {
                c.push(v);
            }
        }
        rows.push(n + 1);
    }
    Ok(vec![Group {
        name: String::new(),
        cols,
        labels,
        rows: Some(rows),
    }])
}

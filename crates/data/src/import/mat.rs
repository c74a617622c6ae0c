//! MATLAB v5/v7 files (the `table` format's `.mat` inputs), read with the `matrw` crate, and
//! numeric vectors found in them by a path: `forced_data.Data.X1__V_.data` (struct fields),
//! `FRdata.ForceControl(2).frequency` (one element of a struct array, 1-based as in MATLAB) or
//! `FRdata.ForceControl(*).frequency` (every element: one group each).

use super::ImportError;
use matrw::{MatFile, MatVariable};
use std::path::Path;

/// Reads a MAT file (v5, or v7 with compression; not v7.3, which is HDF5).
pub fn load(path: &Path) -> Result<MatFile, ImportError> {
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |message: String| ImportError::Input {
        path: path.to_path_buf(),
        row: None,
        message,
    };
    // The parser is third-party code reading untrusted bytes: a panic in it is an error here.
    match std::panic::catch_unwind(|| matrw::load_matfile_from_u8(&bytes)) {
        Ok(Ok(f)) => Ok(f),
        Ok(Err(e)) => Err(bad(format!(
            "not a readable MATLAB v5/v7 file ({e}); a v7.3 file is HDF5: save with -v7, or export the variables to CSV"
        ))),
        Err(_) => Err(bad(
            "the MATLAB file is malformed (its parser gave up); save it again with -v7, or export the variables to CSV".into(),
        )),
    }
}

/// One segment of a path: a field or variable name, and an optional element selector.
#[derive(Clone, Copy)]
enum Select {
    Whole,
    One(usize),
    Every,
}

fn segment(text: &str) -> Result<(&str, Select), String> {
    match text.split_once('(') {
        None => Ok((text, Select::Whole)),
        Some((name, rest)) => {
            let inner = rest
                .strip_suffix(')')
                .ok_or_else(|| format!("\"{text}\": an element is written name(2) or name(*)"))?;
            if inner.trim() == "*" {
                return Ok((name, Select::Every));
            }
            match inner.trim().parse::<usize>() {
                Ok(k) if k >= 1 => Ok((name, Select::One(k - 1))),
                _ => Err(format!(
                    "\"{text}\": element numbers start at 1 (MATLAB's), or * for every element"
                )),
            }
        }
    }
}

/// The numeric vector at `path` in `file`, per group: one entry, or one per element where the
/// path says `(*)` (at most one `(*)`). The error message names the first segment not found
/// and what is there.
pub fn column(file: &MatFile, path: &str) -> Result<Vec<Vec<f64>>, String> {
    let mut parts = path.split('.');
    let first = parts.next().unwrap_or_default();
    let (name, sel) = segment(first)?;
    let top = file
        .iter()
        .find(|(k, _)| k.as_str() == name)
        .map(|(_, v)| v)
        .ok_or_else(|| {
            format!(
                "no variable \"{name}\" (the file has: {})",
                file.iter()
                    .map(|(k, _)| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
    let mut current: Vec<&MatVariable> = select(top, sel, name)?;
    let mut walked = name.to_string();
    for part in parts {
        let (field, sel) = segment(part)?;
        let mut next = Vec::with_capacity(current.len());
        for v in &current {
            let f = match v {
                MatVariable::Structure(s) => s.get(field),
                _ => None,
            }
            .ok_or_else(|| match v.fieldnames() {
                Some(names) => format!(
                    "\"{walked}\" has no field \"{field}\" (fields: {})",
                    names.join(", ")
                ),
                None => format!("\"{walked}\" is not a struct, so it has no field \"{field}\""),
            })?;
            next.extend(select(f, sel, field)?);
        }
        if matches!(sel, Select::Every) && current.len() > 1 {
            return Err(format!("\"{path}\": at most one (*) per path"));
        }
        current = next;
        walked = format!("{walked}.{part}");
    }
    current
        .into_iter()
        .map(|v| {
            v.to_vec::<f64>().ok_or_else(|| {
                format!(
                    "\"{path}\" is not an array of doubles (dimensions {:?})",
                    v.dim()
                )
            })
        })
        .collect()
}

/// The elements `sel` picks of `v` (a struct array's elements, or `v` itself).
fn select<'a>(v: &'a MatVariable, sel: Select, name: &str) -> Result<Vec<&'a MatVariable>, String> {
    let n: usize = v.dim().iter().product();
    match (v, sel) {
        (MatVariable::StructureArray(_), Select::Every) => {
            Ok((0..n).filter_map(|k| v.index_ref(k)).collect())
        }
        (MatVariable::StructureArray(_), Select::One(k)) => v
            .index_ref(k)
            .map(|e| vec![e])
            .ok_or_else(|| format!("\"{name}\" has {n} elements; ({}) is beyond them", k + 1)),
        (MatVariable::StructureArray(_), Select::Whole) if n == 1 => {
            Ok(v.index_ref(0).into_iter().collect())
        }
        (MatVariable::StructureArray(_), Select::Whole) => Err(format!(
            "\"{name}\" is an array of {n} structs: write {name}(1) for one, or {name}(*) for every one (one group each)"
        )),
        (_, Select::Whole) => Ok(vec![v]),
        (_, _) => Err(format!("\"{name}\" is not a struct array; remove its (…)")),
    }
}

/// `v[k]` for a struct array, through matrw's indexing.
trait IndexRef {
    fn index_ref(&self, k: usize) -> Option<&MatVariable>;
}

impl IndexRef for MatVariable {
    fn index_ref(&self, k: usize) -> Option<&MatVariable> {
        matrw::interface::index::Index::index_into_ref(&k, self)
    }
}

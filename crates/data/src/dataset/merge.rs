//! Pooling datasets of one device ([`Dataset::merge`]): the rounds of the lab loop (plan,
//! measure, identify, plan again, measure again) become one dataset to identify from.
//!
//! The inputs must agree on everything that says what a number means: `format`,
//! `displacement_unit`, the points and their mode shapes, the modes of `nominal_hz`, and the
//! import conventions (`[import].conventions`, or none in every input). The first disagreement
//! is a [`DatasetError::MergeMismatch`] naming the file, the key and both values.
//!
//! Nominal frequencies are guesses that each round of the lab loop refines (a plan writes its
//! guess into the dataset it makes), so their values may differ: the merged dataset keeps the
//! last input's (the latest round's), provided every measured line and drive tone of every input
//! belongs to the same mode under them as under its own (the spectrally closest nominal
//! resonance); otherwise [`DatasetError::MergeAttribution`] names the line.
//!
//! Names: a measurement or sweep name found in more than one input is renamed, in every input
//! holding it, to `<folder>_<name>` where `<folder>` is the name of the input's folder (`ds<i>`,
//! 1-based, for a dataset made in memory or a folder name of other than letters, digits, `-`,
//! `_` and `.`). When two such inputs have folders of the same name,
//! the merge is refused ([`DatasetError::MergeNameClash`]) naming both. Sweeps keep their steps;
//! every file is written as `<name>.csv` (a `file` key of the inputs is not carried over).
//! `truth.toml` is kept when every input has one describing the same device (modes and
//! equations of motion), with every input's forces keyed by the merged names; else dropped
//! with a note.

use super::*;
use crate::conventions::ImportRecord;
use std::collections::BTreeSet;

/// `a` and `b` equal within [`FREQ_REL_TOL`] (relative).
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= FREQ_REL_TOL * a.abs().max(b.abs()).max(1.0)
}

/// The manifest path of input `ds` (for messages).
fn manifest_path(ds: &Dataset) -> PathBuf {
    ds.dir.join("dataset.toml")
}

/// The input's name as a prefix: its folder's name, or `ds<i>` (1-based) for one in memory or
/// a folder whose name is not letters, digits, `-`, `_` and `.`.
fn prefix_of(ds: &Dataset, i: usize) -> String {
    ds.dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| {
            !n.is_empty()
                && n != "."
                && n != ".."
                && n.chars().all(|c| c.is_alphanumeric() || "-_.".contains(c))
        })
        .unwrap_or_else(|| format!("ds{}", i + 1))
}

/// Keys compared between inputs, with their values as text (`None`: the key is absent).
fn compared_keys(m: &Manifest) -> Vec<(String, Option<String>)> {
    let mut v = vec![
        ("format".to_string(), Some(m.format.clone())),
        (
            "displacement_unit".to_string(),
            Some(m.displacement_unit.clone()),
        ),
        (
            "point (names)".to_string(),
            Some(
                m.points
                    .iter()
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
        ),
    ];
    for p in &m.points {
        let modes: BTreeSet<&String> = p.shape.keys().collect();
        v.push((
            format!("point \"{}\" shape (modes)", p.name),
            Some(
                modes
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
        ));
    }
    let modes: Vec<&str> = m.nominal_hz.keys().map(|s| s.as_str()).collect();
    v.push(("nominal_hz (modes)".to_string(), Some(modes.join(", "))));
    let conv = m.import.as_ref().map(|r| {
        toml::to_string(&r.conventions)
            .unwrap_or_default()
            .trim()
            .replace('\n', ", ")
    });
    v.push(("import.conventions".to_string(), conv));
    v
}

/// The numbers compared within [`FREQ_REL_TOL`]: each point's shape value (the names were
/// compared first, so the lists line up).
fn compared_numbers(m: &Manifest) -> Vec<(String, f64)> {
    let mut v = Vec::new();
    for p in &m.points {
        for (mode, &x) in &p.shape {
            v.push((format!("point \"{}\" shape.{mode}", p.name), x));
        }
    }
    v
}

/// The mode whose nominal resonance is spectrally closest to `hz` (the first of equally close
/// ones: the identification's rule, `harmonid_spectral::nearest_of`).
fn nearest(nominal_hz: &BTreeMap<String, f64>, hz: f64) -> Option<&str> {
    nominal_hz
        .iter()
        .min_by(|a, b| (hz - a.1).abs().total_cmp(&(hz - b.1).abs()))
        .map(|(m, _)| m.as_str())
}

/// The merged dataset's nominal frequencies: the last input's, once every line and drive tone
/// of every input is checked to keep its mode under them; a note when the inputs differ.
fn merged_nominal(
    inputs: &[Dataset],
    notes: &mut Vec<String>,
) -> Result<BTreeMap<String, f64>, DatasetError> {
    let Some(last) = inputs.last() else {
        return Ok(BTreeMap::new());
    };
    let merged = last.manifest.nominal_hz.clone();
    let differ = inputs.iter().any(|d| {
        d.manifest
            .nominal_hz
            .iter()
            .zip(&merged)
            .any(|((_, a), (_, b))| !close(*a, *b))
    });
    if !differ {
        return Ok(merged);
    }
    for ds in inputs {
        let own = &ds.manifest.nominal_hz;
        for m in &ds.measurements {
            for &hz in m.freqs_hz.iter().chain(&m.spec.drives_hz) {
                let (a, b) = (nearest(own, hz), nearest(&merged, hz));
                if a != b {
                    return Err(DatasetError::MergeAttribution {
                        path: manifest_path(ds),
                        measurement: m.spec.name.clone(),
                        hz,
                        own: a.unwrap_or_default().to_string(),
                        merged: b.unwrap_or_default().to_string(),
                    });
                }
            }
        }
    }
    let shown = |ds: &Dataset| {
        ds.manifest
            .nominal_hz
            .iter()
            .map(|(m, f)| format!("{m} = {f}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    notes.push(format!(
        "the inputs' nominal frequencies differ ({}: {}); the merged dataset keeps the last input's, under which every line keeps its mode",
        manifest_path(&inputs[0]).display(),
        shown(&inputs[0])
    ));
    Ok(merged)
}

/// Refuses a folder given twice (by its canonical path; datasets made in memory are not
/// compared).
fn check_given_once(inputs: &[Dataset]) -> Result<(), DatasetError> {
    let mut seen = BTreeSet::new();
    for ds in inputs.iter().filter(|d| !d.dir.as_os_str().is_empty()) {
        let real = ds.dir.canonicalize().unwrap_or_else(|_| ds.dir.clone());
        if !seen.insert(real) {
            return Err(DatasetError::MergeTwice {
                path: ds.dir.clone(),
            });
        }
    }
    Ok(())
}

/// The first key on which `other` differs from `first`, as a [`DatasetError::MergeMismatch`].
fn check_agree(first: &Dataset, other: &Dataset) -> Result<(), DatasetError> {
    let mismatch = |key: String, expected: String, found: String| DatasetError::MergeMismatch {
        path: manifest_path(other),
        key,
        found,
        first: manifest_path(first),
        expected,
    };
    let shown =
        |v: Option<String>| v.map_or_else(|| "(absent)".to_string(), |v| format!("\"{v}\""));
    let (a, b) = (
        compared_keys(&first.manifest),
        compared_keys(&other.manifest),
    );
    for ((key, va), (_, vb)) in a.iter().zip(&b) {
        if va != vb {
            return Err(mismatch(key.clone(), shown(va.clone()), shown(vb.clone())));
        }
    }
    let (a, b) = (
        compared_numbers(&first.manifest),
        compared_numbers(&other.manifest),
    );
    for ((key, xa), (_, xb)) in a.iter().zip(&b) {
        if !close(*xa, *xb) {
            return Err(mismatch(key.clone(), format!("{xa:?}"), format!("{xb:?}")));
        }
    }
    Ok(())
}

/// The top-level names of `ds`: its measurements outside sweeps, and its sweeps.
fn top_names(ds: &Dataset) -> Vec<&str> {
    ds.manifest
        .sweeps
        .iter()
        .map(|s| s.name.as_str())
        .chain(
            ds.measurements
                .iter()
                .filter(|m| m.spec.sweep.is_none())
                .map(|m| m.spec.name.as_str()),
        )
        .collect()
}

/// Per input, the new name of each of its top-level names found in another input.
fn renames(inputs: &[Dataset]) -> Result<Vec<HashMap<String, String>>, DatasetError> {
    let mut holders: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, ds) in inputs.iter().enumerate() {
        for n in top_names(ds) {
            holders.entry(n).or_default().push(i);
        }
    }
    let mut out = vec![HashMap::new(); inputs.len()];
    let mut taken: BTreeSet<String> = holders.keys().map(|s| s.to_string()).collect();
    for (name, who) in holders.iter().filter(|(_, w)| w.len() > 1) {
        for (k, &i) in who.iter().enumerate() {
            let new = format!("{}_{name}", prefix_of(&inputs[i], i));
            if !taken.insert(new.clone()) {
                let j = who[..k]
                    .iter()
                    .copied()
                    .find(|&j| prefix_of(&inputs[j], j) == prefix_of(&inputs[i], i))
                    .unwrap_or(who[0]);
                return Err(DatasetError::MergeNameClash {
                    name: name.to_string(),
                    renamed: new,
                    first: manifest_path(&inputs[j]),
                    second: manifest_path(&inputs[i]),
                });
            }
            out[i].insert(name.to_string(), new);
        }
    }
    Ok(out)
}

/// The `[import]` record of the merged dataset: the first's conventions and settling rule,
/// every input file, the samples summed; the instrument settings all inputs share.
fn merged_import(inputs: &[Dataset], notes: &mut Vec<String>) -> Option<ImportRecord> {
    let records: Vec<&ImportRecord> = inputs
        .iter()
        .filter_map(|d| d.manifest.import.as_ref())
        .collect();
    let first = (*records.first()?).clone();
    let mut formats: Vec<String> = Vec::new();
    for r in &records {
        if !formats.contains(&r.format) {
            formats.push(r.format.clone());
        }
    }
    if records.iter().any(|r| r.settle != first.settle) {
        notes.push("the inputs were imported with different settling rules; [import].settle records the first input's".into());
    }
    Some(ImportRecord {
        format: formats.join("+"),
        inputs: records.iter().flat_map(|r| r.inputs.clone()).collect(),
        settling_dropped: records.iter().map(|r| r.settling_dropped).sum(),
        samples_read: records.iter().map(|r| r.samples_read).sum(),
        instrument: first
            .instrument
            .iter()
            .filter(|(k, v)| records.iter().all(|r| r.instrument.get(*k) == Some(*v)))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect(),
        ..first
    })
}

/// The truth of the merged dataset: kept when every input has one and all describe the same
/// device (`[modes]` and `[eom]` equal), with every input's forces keyed by the merged names
/// and the noise kept when all inputs had the same; else `None` and a note.
fn merged_truth(
    inputs: &[Dataset],
    renamed: &[Vec<(String, String)>],
    notes: &mut Vec<String>,
) -> Option<Truth> {
    let first = inputs[0].truth.as_ref();
    let same_device = |t: &Truth| first.is_some_and(|f| f.modes == t.modes && f.eom == t.eom);
    let truths = || inputs.iter().filter_map(|d| d.truth.as_ref());
    let with = truths().count();
    if with == 0 {
        return None;
    }
    if with < inputs.len() || !truths().all(same_device) {
        notes.push(format!(
            "truth.toml dropped: {with} of the {} inputs have one, and they do not all describe the same device",
            inputs.len()
        ));
        return None;
    }
    let mut truth = first?.clone();
    truth.forces.clear();
    if truths().any(|t| t.noise != truth.noise) {
        truth.noise = None;
        notes.push("truth.toml: the inputs' noise differs; the merged truth has none".into());
    }
    for (ds, pairs) in inputs.iter().zip(renamed) {
        let forces = ds.truth.as_ref().map(|t| &t.forces);
        for (old, new) in pairs {
            if let Some(f) = forces.and_then(|f| f.get(old)) {
                truth.forces.insert(new.clone(), f.clone());
            }
        }
    }
    Some(truth)
}

impl Dataset {
    /// Pools datasets of one device into one (in memory; [`Dataset::write`] writes it): every
    /// measurement and sweep of every input, in input order. The rules (what must agree, how
    /// colliding names are renamed, when `truth.toml` is kept) are the module's
    /// (docs/data-format.md, "Merging datasets"). What the merge did (renames, a dropped truth)
    /// is in [`Dataset::notes`]. The merged dataset's `dir` is empty until written.
    pub fn merge(inputs: &[Dataset]) -> Result<Dataset, DatasetError> {
        let Some(first) = inputs.first() else {
            return Err(DatasetError::Manifest {
                path: PathBuf::new(),
                message: "merge needs at least one dataset".into(),
            });
        };
        check_given_once(inputs)?;
        for other in &inputs[1..] {
            check_agree(first, other)?;
        }
        let new_names = renames(inputs)?;
        let mut notes = Vec::new();
        let mut manifest = Manifest {
            description: format!(
                "merged from {}",
                inputs
                    .iter()
                    .enumerate()
                    .map(|(i, d)| prefix_of(d, i))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            measurements: Vec::new(),
            sweeps: Vec::new(),
            import: None,
            ..first.manifest.clone()
        };
        manifest.import = merged_import(inputs, &mut notes);
        manifest.nominal_hz = merged_nominal(inputs, &mut notes)?;
        let mut measurements = Vec::new();
        let mut renamed: Vec<Vec<(String, String)>> = Vec::new();
        for (i, ds) in inputs.iter().enumerate() {
            let map = &new_names[i];
            let name_of = |n: &str| map.get(n).cloned().unwrap_or_else(|| n.to_string());
            let mut pairs = Vec::new();
            for (old, new) in map {
                notes.push(format!(
                    "\"{old}\" of {} is \"{new}\" (the name is in another input too)",
                    manifest_path(ds).display()
                ));
            }
            for sw in &ds.manifest.sweeps {
                let mut sw = sw.clone();
                sw.name = name_of(&sw.name);
                sw.file = None;
                manifest.sweeps.push(sw);
            }
            for m in &ds.measurements {
                let mut m = m.clone();
                let old = m.spec.name.clone();
                m.spec.file = None;
                if let Some(st) = &mut m.spec.sweep {
                    st.sweep = name_of(&st.sweep);
                    m.spec.name = format!("{}[{}]", st.sweep, st.step);
                } else {
                    m.spec.name = name_of(&m.spec.name);
                }
                pairs.push((old, m.spec.name.clone()));
                measurements.push(m);
            }
            renamed.push(pairs);
        }
        let truth = merged_truth(inputs, &renamed, &mut notes);
        let mut ds = Dataset::from_parts(PathBuf::new(), manifest, measurements, truth)?;
        ds.notes = notes;
        Ok(ds)
    }
}

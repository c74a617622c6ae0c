//! Reading one measurement's CSV, streamed: one reused record buffer, 56 bytes kept per row
//! while reading and 16 per value after.

use super::*;

/// Largest amplitude accepted, in metres (after unit conversion). Larger values are not
/// displacements of a resonator, and their powers overflow the fit's column scaling.
pub const MAX_AMPLITUDE_M: f64 = 1e3;
/// Largest frequency accepted, Hz (ω² and its products must stay finite).
pub const MAX_FREQ_HZ: f64 = 1e15;

/// One CSV value as kept while reading.
#[derive(Clone, Copy)]
pub(super) struct Cell {
    pub(super) freq_hz: f64,
    pub(super) x: Complex64,
    pub(super) shot: u32,
    pub(super) point: u32,
    pub(super) row: u32,
    /// The sweep step (0 for a measurement's CSV).
    pub(super) step: u32,
    /// The row's noise, when the CSV has `std` and `samples` columns: the standard deviation
    /// per quadrature of one averaged sample (m) and how many were averaged; else 0.
    pub(super) std: f64,
    pub(super) samples: u32,
}

/// Which CSV is read: a measurement's, or a sweep's (with its `step` column, `steps` steps,
/// and an optional `time_s` column whose rows before `settle_s` are dropped).
#[derive(Clone, Copy)]
pub(super) enum Columns {
    Measurement,
    Sweep { steps: usize, settle_s: Option<f64> },
}

/// At most this many characters of a field or header are quoted in a message.
const SHOWN_CHARS: usize = 40;

/// `text`, shortened to [`SHOWN_CHARS`] characters with "…" when longer.
pub(super) fn shown(text: &str) -> String {
    if text.chars().count() <= SHOWN_CHARS {
        text.to_string()
    } else {
        let mut s: String = text.chars().take(SHOWN_CHARS).collect();
        s.push('…');
        s
    }
}

/// A number for a message: plain when moderate, in exponent form when very large or small
/// (`{}` of 1e300 prints 301 digits); [`harmonid_files::number`], the one rule.
pub(super) fn num_text(x: f64) -> String {
    harmonid_files::number(x)
}

pub(super) fn read_csv<R: std::io::Read>(
    reader: R,
    path: &Path,
    spec: &MeasurementSpec,
    manifest: &Manifest,
    scale: f64,
) -> Result<Measurement, DatasetError> {
    let (mut cells, _) = read_cells(reader, path, manifest, scale, Columns::Measurement)?;
    assemble(&mut cells, path, spec, manifest)
}

/// One measurement from its CSV's cells: grouped by shot and point, every group checked to
/// list the same frequencies and every drive tone, shots numbered 0..S-1.
pub(super) fn assemble(
    cells: &mut [Cell],
    path: &Path,
    spec: &MeasurementSpec,
    manifest: &Manifest,
) -> Result<Measurement, DatasetError> {
    let row_err = |row: usize, message: String| DatasetError::Row {
        path: path.to_path_buf(),
        row,
        message,
    };
    if cells.is_empty() {
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!("measurement \"{}\" has no data rows", spec.name),
        });
    }
    cells.sort_unstable_by(|a, b| {
        (a.shot, a.point)
            .cmp(&(b.shot, b.point))
            .then(a.freq_hz.total_cmp(&b.freq_hz))
    });
    let group_of = |c: &Cell| (c.shot, c.point);
    let groups: Vec<&[Cell]> = cells.chunk_by(|a, b| group_of(a) == group_of(b)).collect();

    let mut shots: Vec<u32> = groups.iter().map(|g| g[0].shot).collect();
    shots.dedup();
    if shots
        .iter()
        .enumerate()
        .any(|(i, &s)| i as u64 != u64::from(s))
    {
        let listed: Vec<String> = shots.iter().take(10).map(|s| s.to_string()).collect();
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!(
                "shots must be numbered 0..S-1 without gaps; found {}{}",
                listed.join(", "),
                if shots.len() > 10 { ", ..." } else { "" }
            ),
        });
    }
    let n_shots = shots.len();
    let given = cells[0].samples > 0;
    if given && n_shots > 1 {
        return Err(DatasetError::Inconsistent {
            path: path.to_path_buf(),
            message: format!(
                "measurement \"{}\" has std and samples columns (each row an average with its noise) and {n_shots} shots: give one shot (0), or leave the noise to the shot scatter without those columns",
                spec.name
            ),
        });
    }
    let mut points: Vec<usize> = groups.iter().map(|g| g[0].point as usize).collect();
    points.sort_unstable();
    points.dedup();
    let pname = |p: usize| {
        manifest
            .points
            .get(p)
            .map(|q| q.name.clone())
            .unwrap_or_else(|| "(modal)".into())
    };
    for g in &groups {
        for w in g.windows(2) {
            if (w[1].freq_hz - w[0].freq_hz).abs() <= FREQ_REL_TOL * w[1].freq_hz {
                return Err(row_err(
                    w[1].row as usize,
                    format!(
                        "frequency {} Hz appears twice in the same shot and point (also row {})",
                        w[1].freq_hz, w[0].row
                    ),
                ));
            }
        }
    }
    if groups.len() != n_shots * points.len() {
        for &s in &shots {
            for &p in &points {
                if !groups
                    .iter()
                    .any(|g| g[0].shot == s && g[0].point as usize == p)
                {
                    return Err(DatasetError::Inconsistent {
                        path: path.to_path_buf(),
                        message: format!("shot {s} has no rows for point \"{}\"", pname(p)),
                    });
                }
            }
        }
    }
    let freqs: Vec<f64> = groups[0].iter().map(|c| c.freq_hz).collect();
    same_frequencies(&groups, &freqs, path, &pname)?;
    check_drives_measured(spec, &freqs, path)?;
    let nf = freqs.len();
    let np = points.len();
    let mut data = vec![Complex64::new(0.0, 0.0); n_shots * nf * np];
    let mut noise = given.then(|| GivenNoise {
        std: vec![0.0; nf * np],
        samples: vec![0; nf * np],
    });
    for g in &groups {
        let s = g[0].shot as usize;
        let pl = points.binary_search(&(g[0].point as usize)).unwrap_or(0);
        for (f, c) in g.iter().enumerate() {
            data[(s * nf + f) * np + pl] = c.x;
            if let Some(n) = noise.as_mut() {
                n.std[f * np + pl] = c.std;
                n.samples[f * np + pl] = c.samples;
            }
        }
    }
    drop(groups);
    Ok(Measurement {
        spec: spec.clone(),
        freqs_hz: freqs,
        points,
        n_shots,
        data,
        noise,
    })
}

/// Where a CSV's columns are, as its header gives them.
struct Layout {
    shot: usize,
    freq: usize,
    re: usize,
    im: usize,
    point: Option<usize>,
    /// The `std` and `samples` columns, when the CSV gives each row's noise.
    noise: Option<(usize, usize)>,
    /// A sweep's `step` column.
    step: Option<usize>,
    /// How many steps the sweep has (0 for a measurement).
    steps: usize,
    /// The `time_s` column and the settling time its rows are compared to.
    settle: Option<(usize, f64)>,
}

/// An error in row `row` of the CSV `path`.
fn row_error(path: &Path, row: usize, message: String) -> DatasetError {
    DatasetError::Row {
        path: path.to_path_buf(),
        row,
        message,
    }
}

/// The columns `headers` name, for a CSV read as `columns`: the required ones must be there,
/// none twice, `std` only with `samples`, `time_s` when a sweep drops settling by time.
fn layout(
    headers: &csv::StringRecord,
    path: &Path,
    columns: Columns,
) -> Result<Layout, DatasetError> {
    let row_err = |row: usize, message: String| row_error(path, row, message);
    let found = shown(&headers.iter().collect::<Vec<_>>().join(","));
    let col = |name: &str| -> Result<Option<usize>, DatasetError> {
        let mut idx = headers.iter().enumerate().filter(|(_, h)| *h == name);
        let first = idx.next().map(|(i, _)| i);
        if idx.next().is_some() {
            return Err(row_err(
                1,
                format!("column \"{name}\" appears more than once in the header"),
            ));
        }
        Ok(first)
    };
    let req = |name: &str| -> Result<usize, DatasetError> {
        col(name)?.ok_or_else(|| DatasetError::MissingColumn {
            path: path.to_path_buf(),
            column: name.to_string(),
            found: found.clone(),
        })
    };
    let (shot, freq, re, im) = (req("shot")?, req("freq_hz")?, req("re")?, req("im")?);
    let point = col("point")?;
    let noise = match (col("std")?, col("samples")?) {
        (Some(a), Some(b)) => Some((a, b)),
        (None, None) => None,
        _ => {
            return Err(row_err(
                1,
                "std and samples go together: the standard deviation per quadrature of the averaged samples and how many were averaged".into(),
            ))
        }
    };
    let (step, steps, settle) = match columns {
        Columns::Measurement => (None, 0, None),
        Columns::Sweep { steps, settle_s } => {
            let c_time = match settle_s {
                Some(t) => Some((
                    col("time_s")?.ok_or_else(|| {
                        row_err(
                            1,
                            format!("settle_s = {t} needs a time_s column (the time since the step began, s); add it, or drop settling samples by count with settle_samples"),
                        )
                    })?,
                    t,
                )),
                None => None,
            };
            (Some(req("step")?), steps, c_time)
        }
    };
    Ok(Layout {
        shot,
        freq,
        re,
        im,
        point,
        noise,
        step,
        steps,
        settle,
    })
}

/// One CSV row being read: its fields, parsed and checked with messages naming the row.
struct Row<'a> {
    rec: &'a csv::StringRecord,
    row: usize,
    path: &'a Path,
}

impl Row<'_> {
    /// An error in this row.
    fn err(&self, message: String) -> DatasetError {
        row_error(self.path, self.row, message)
    }

    /// The text of column `c`, called `name` in messages.
    fn field(&self, c: usize, name: &str) -> Result<&str, DatasetError> {
        self.rec
            .get(c)
            .ok_or_else(|| self.err(format!("no value in column \"{name}\"")))
    }

    /// The finite number in column `c`, called `name` in messages.
    fn num(&self, c: usize, name: &str) -> Result<f64, DatasetError> {
        let t = self.field(c, name)?;
        let v: f64 = t.parse().map_err(|_| {
            self.err(format!(
                "column \"{name}\": \"{}\" is not a number",
                shown(t)
            ))
        })?;
        if !v.is_finite() {
            return Err(self.err(format!("column \"{name}\": {} is not finite", shown(t))));
        }
        Ok(v)
    }

    /// The sweep step in column `c`, one of the sweep's `steps`.
    fn step(&self, c: usize, steps: usize) -> Result<u32, DatasetError> {
        let t = self.field(c, "step")?;
        match t.parse::<u32>() {
            Ok(k) if (k as usize) < steps => Ok(k),
            _ => Err(self.err(format!(
                "column \"step\": \"{}\" is not a step of this sweep (0 to {}, one per drives_hz list)",
                shown(t),
                steps.saturating_sub(1)
            ))),
        }
    }

    /// The shot number in column `c`.
    fn shot(&self, c: usize) -> Result<u32, DatasetError> {
        let st = self.field(c, "shot")?;
        st.parse().map_err(|_| {
            self.err(format!(
                "column \"shot\": \"{}\" is not a shot number (0, 1, 2, ...)",
                shown(st)
            ))
        })
    }

    /// The frequency in column `c`: positive and at most [`MAX_FREQ_HZ`].
    fn frequency(&self, c: usize) -> Result<f64, DatasetError> {
        let f = self.num(c, "freq_hz")?;
        if f <= 0.0 {
            return Err(self.err(format!(
                "freq_hz = {}: frequencies must be positive",
                num_text(f)
            )));
        }
        if f > MAX_FREQ_HZ {
            return Err(self.err(format!(
                "freq_hz = {}: above the largest frequency accepted, {MAX_FREQ_HZ:e} Hz",
                num_text(f)
            )));
        }
        Ok(f)
    }

    /// The amplitude in columns `re` and `im` times `scale`: at most [`MAX_AMPLITUDE_M`] per
    /// quadrature.
    fn amplitude(
        &self,
        re: usize,
        im: usize,
        scale: f64,
        manifest: &Manifest,
    ) -> Result<Complex64, DatasetError> {
        let x = Complex64::new(self.num(re, "re")?, self.num(im, "im")?) * scale;
        if x.re.abs() > MAX_AMPLITUDE_M || x.im.abs() > MAX_AMPLITUDE_M {
            return Err(self.err(format!(
                "amplitude {} {} is more than {MAX_AMPLITUDE_M:e} m: not a resonator's displacement; check the value and displacement_unit = \"{}\"",
                shown(self.field(re, "re")?),
                shown(self.field(im, "im")?),
                manifest.displacement_unit
            )));
        }
        Ok(x)
    }

    /// The noise in columns `(std, samples)`: a positive standard deviation times `scale`
    /// and a count of at least 2.
    fn noise(&self, (cs, cn): (usize, usize), scale: f64) -> Result<(f64, u32), DatasetError> {
        let sd = self.num(cs, "std")? * scale;
        if sd <= 0.0 {
            return Err(self.err(format!(
                "std = {}: a standard deviation must be positive",
                num_text(sd)
            )));
        }
        let t = self.field(cn, "samples")?;
        let n = t.parse::<u32>().ok().filter(|&n| n >= 2).ok_or_else(|| {
            self.err(format!(
                "column \"samples\": \"{}\" is not a count of at least 2 averaged samples",
                shown(t)
            ))
        })?;
        Ok((sd, n))
    }
}

/// The row `rec` (numbered `row`) as a cell, or `None` when it is earlier than the sweep's
/// settling time. Its fields are checked in this order (the first error is reported): step,
/// time, shot, frequency, amplitude, point, noise.
fn read_row(
    rec: &csv::StringRecord,
    row: usize,
    path: &Path,
    layout: &Layout,
    point_index: &HashMap<&str, usize>,
    manifest: &Manifest,
    scale: f64,
) -> Result<Option<Cell>, DatasetError> {
    let r = Row { rec, row, path };
    let row32 =
        u32::try_from(row).map_err(|_| r.err("more than 4,294,967,295 rows in one file".into()))?;
    let step = match layout.step {
        Some(c) => r.step(c, layout.steps)?,
        None => 0,
    };
    if let Some((c, settle_s)) = layout.settle {
        if r.num(c, "time_s")? < settle_s {
            return Ok(None);
        }
    }
    let shot = r.shot(layout.shot)?;
    let f = r.frequency(layout.freq)?;
    let x = r.amplitude(layout.re, layout.im, scale, manifest)?;
    let p = match layout.point {
        Some(c) if !r.field(c, "point")?.is_empty() => {
            point_of(r.field(c, "point")?, point_index, manifest).map_err(|m| r.err(m))?
        }
        _ => 0,
    };
    let (std, samples) = match layout.noise {
        Some(cols) => r.noise(cols, scale)?,
        None => (0.0, 0),
    };
    Ok(Some(Cell {
        freq_hz: f,
        x,
        shot,
        // Fewer than 2^32 points: the manifest holds them.
        point: u32::try_from(p).unwrap_or(u32::MAX),
        row: row32,
        step,
        std,
        samples,
    }))
}

/// Every row of a measurement's or sweep's CSV as a [`Cell`], in file order: the header's
/// columns found (`shot`, `freq_hz`, `re`, `im`, optional `point`; for a sweep `step` and
/// optional `time_s`), each value parsed and checked (a positive, finite frequency below
/// [`MAX_FREQ_HZ`], amplitudes times `scale` below [`MAX_AMPLITUDE_M`], a declared point, a
/// step of the sweep). Also returns how many rows were dropped as earlier than `settle_s`.
pub(super) fn read_cells<R: std::io::Read>(
    reader: R,
    path: &Path,
    manifest: &Manifest,
    scale: f64,
    columns: Columns,
) -> Result<(Vec<Cell>, usize), DatasetError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(reader);
    let headers = rdr
        .headers()
        .map_err(|e| row_error(path, 1, format!("cannot read the header: {e}")))?
        .clone();
    let layout = layout(&headers, path, columns)?;
    let mut early = 0usize;
    let point_index: HashMap<&str, usize> = manifest
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.name.as_str(), i))
        .collect();

    let mut cells: Vec<Cell> = Vec::new();
    let mut rec = csv::StringRecord::new();
    let mut row = 1usize;
    loop {
        row += 1;
        let more = rdr.read_record(&mut rec).map_err(|e| {
            row_error(
                path,
                row,
                match e.kind() {
                    csv::ErrorKind::UnequalLengths {
                        expected_len, len, ..
                    } => format!(
                        "{len} fields, but the header has {expected_len} columns (a missing or extra column)"
                    ),
                    _ => e.to_string(),
                },
            )
        })?;
        if !more {
            break;
        }
        match read_row(&rec, row, path, &layout, &point_index, manifest, scale)? {
            Some(cell) => cells.push(cell),
            None => early += 1,
        }
    }
    Ok((cells, early))
}

/// Every (shot, point) group lists the frequencies `freqs` of the first group (to
/// [`FREQ_REL_TOL`]); else an error naming the first that does not and the line that differs.
fn same_frequencies(
    groups: &[&[Cell]],
    freqs: &[f64],
    path: &Path,
    pname: &dyn Fn(usize) -> String,
) -> Result<(), DatasetError> {
    let (s0, p0) = (groups[0][0].shot, groups[0][0].point as usize);
    for g in groups {
        let same = g.len() == freqs.len()
            && g.iter()
                .zip(freqs)
                .all(|(c, f)| (c.freq_hz - f).abs() <= FREQ_REL_TOL * f);
        if !same {
            let (s, p) = (g[0].shot, g[0].point as usize);
            let extra = g.iter().find(|c| {
                !freqs
                    .iter()
                    .any(|f| (c.freq_hz - f).abs() <= FREQ_REL_TOL * f)
            });
            let detail = match extra {
                Some(c) => format!(
                    "{} Hz (row {}) is not measured in shot {s0}",
                    c.freq_hz, c.row
                ),
                None => format!(
                    "it lists {} frequencies, shot {s0} lists {}",
                    g.len(),
                    freqs.len()
                ),
            };
            return Err(DatasetError::Inconsistent {
                path: path.to_path_buf(),
                message: format!(
                    "shot {s}, point \"{}\" has a different frequency set from shot {s0}, point \"{}\": {detail}; every shot must list the same frequencies",
                    pname(p),
                    pname(p0)
                ),
            });
        }
    }
    Ok(())
}

/// The index of the point called `name` (from `point_index`), or the message that it is not
/// declared, listing those that are.
fn point_of(
    name: &str,
    point_index: &HashMap<&str, usize>,
    manifest: &Manifest,
) -> Result<usize, String> {
    point_index.get(name).copied().ok_or_else(|| {
        format!(
            "point \"{}\" is not declared in dataset.toml (declared: {})",
            shown(name),
            shown(
                &manifest
                    .points
                    .iter()
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        )
    })
}

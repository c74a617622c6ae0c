//! Checks of measurements built in memory ([`Dataset::from_parts`]), the same as a file's.

use super::csv_read::{num_text, MAX_AMPLITUDE_M, MAX_FREQ_HZ};
use super::*;

/// Every drive tone of `spec` must be among the measured frequencies `freqs`.
pub(super) fn check_drives_measured(
    spec: &MeasurementSpec,
    freqs: &[f64],
    path: &Path,
) -> Result<(), DatasetError> {
    for &d in &spec.drives_hz {
        if !freqs.iter().any(|f| (f - d).abs() <= FREQ_REL_TOL * d) {
            let nearest = freqs
                .iter()
                .copied()
                .min_by(|a, b| (a - d).abs().total_cmp(&(b - d).abs()))
                .unwrap_or(f64::NAN);
            return Err(DatasetError::DriveNotMeasured {
                path: path.to_path_buf(),
                measurement: spec.name.clone(),
                drive_hz: d,
                nearest_hz: nearest,
            });
        }
    }
    Ok(())
}

/// Checks one measurement built in memory (by [`Dataset::from_parts`]) as [`read_csv`] checks a
/// file, and sorts its frequencies (with their data) in increasing order as a file read gives
/// them.
pub(super) fn check_measurement(
    m: &mut Measurement,
    n_points: usize,
    path: &Path,
) -> Result<(), DatasetError> {
    let name = m.spec.name.clone();
    let bad = |message: String| DatasetError::Inconsistent {
        path: path.to_path_buf(),
        message: format!("measurement \"{name}\": {message}"),
    };
    let (nf, np) = (m.freqs_hz.len(), m.points.len());
    if m.n_shots == 0 || nf == 0 {
        return Err(bad(format!(
            "{} shots of {nf} frequencies: give at least one shot and one frequency",
            m.n_shots
        )));
    }
    if np == 0 || m.points.iter().any(|&p| p >= n_points.max(1)) {
        return Err(bad(format!(
            "point indices {} do not fit the {n_points} declared points",
            crate::text::index_list(&m.points)
        )));
    }
    if m.data.len() != m.n_shots * nf * np {
        return Err(bad(format!(
            "{} amplitudes for {} shots × {nf} frequencies × {np} points = {}",
            m.data.len(),
            m.n_shots,
            m.n_shots * nf * np
        )));
    }
    if let Some(f) = m
        .freqs_hz
        .iter()
        .find(|f| !(f.is_finite() && **f > 0.0 && **f <= MAX_FREQ_HZ))
    {
        return Err(bad(format!(
            "frequency {} Hz: frequencies must be positive, finite and at most {MAX_FREQ_HZ:e} Hz",
            num_text(*f)
        )));
    }
    if let Some(x) = m
        .data
        .iter()
        .find(|x| x.re.abs() > MAX_AMPLITUDE_M || x.im.abs() > MAX_AMPLITUDE_M)
    {
        return Err(bad(format!(
            "amplitude {}, {} m is more than {MAX_AMPLITUDE_M:e} m: not a resonator's displacement",
            num_text(x.re),
            num_text(x.im)
        )));
    }
    if let Some(i) = m
        .data
        .iter()
        .position(|x| !(x.re.is_finite() && x.im.is_finite()))
    {
        let (s, f, p) = (i / (nf * np), (i / np) % nf, i % np);
        return Err(bad(format!(
            "the amplitude of shot {s} at {} Hz (point #{p}) is {}, expected a finite number",
            m.freqs_hz[f], m.data[i]
        )));
    }
    if let Some(g) = &m.noise {
        if m.n_shots != 1 {
            return Err(bad(format!(
                "a noise given with the data (each row an average) needs one shot, not {}",
                m.n_shots
            )));
        }
        if g.std.len() != nf * np || g.samples.len() != nf * np {
            return Err(bad(format!(
                "{} standard deviations and {} sample counts for {nf} frequencies × {np} points",
                g.std.len(),
                g.samples.len()
            )));
        }
        if let Some(s) = g.std.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(bad(format!(
                "standard deviation {s}: it must be positive and finite"
            )));
        }
        if let Some(n) = g.samples.iter().find(|n| **n < 2) {
            return Err(bad(format!(
                "{n} samples averaged: a standard deviation needs at least 2"
            )));
        }
    }
    let mut order: Vec<usize> = (0..nf).collect();
    order.sort_by(|&a, &b| m.freqs_hz[a].total_cmp(&m.freqs_hz[b]));
    let freqs: Vec<f64> = order.iter().map(|&i| m.freqs_hz[i]).collect();
    if let Some(w) = freqs
        .windows(2)
        .find(|w| (w[1] - w[0]).abs() <= FREQ_REL_TOL * w[1])
    {
        return Err(bad(format!("frequency {} Hz appears twice", w[1])));
    }
    check_drives_measured(&m.spec, &freqs, path)?;
    if order.iter().enumerate().any(|(k, &i)| k != i) {
        let mut data = Vec::with_capacity(m.data.len());
        for s in 0..m.n_shots {
            for &f in &order {
                let at = (s * nf + f) * np;
                data.extend_from_slice(&m.data[at..at + np]);
            }
        }
        m.data = data;
        m.freqs_hz = freqs;
        if let Some(g) = m.noise.as_mut() {
            g.std = reorder(&g.std, &order, np);
            g.samples = reorder(&g.samples, &order, np);
        }
    }
    Ok(())
}

/// `v` (per frequency, `np` points each) with its frequencies in the order `order`.
fn reorder<T: Copy>(v: &[T], order: &[usize], np: usize) -> Vec<T> {
    order
        .iter()
        .flat_map(|&f| v[f * np..(f + 1) * np].iter().copied())
        .collect()
}

//! Per measurement and point: the measured spectrum, each line named by its combination of the
//! drive tones and classed as drive tone, sideband or mixing product, with the spectrum the
//! identified model gives by harmonic balance (harmonid_sim's solver) and the residual.

use harmonid_data::result::Report;
use harmonid_data::{Dataset, Measurement};
use harmonid_plot::{LineKind, Spectrum, SpectrumLine};
use harmonid_sim::{Excitation, HbSettings, NumericModel};
use harmonid_spectral::ToneSet;
use num_complex::Complex64;

/// Two frequencies closer than this are the same line, Hz.
const TOL_HZ: f64 = 1e-6;
/// Intermodulation orders searched when naming a line, highest first (a lattice too large for
/// many tones falls back to the next).
const ORDERS: [u32; 4] = [11, 9, 7, 5];

/// The median of the real and of the imaginary parts (robust to outlier shots).
pub(crate) fn complex_median(z: impl Iterator<Item = Complex64>) -> Complex64 {
    let (mut re, mut im): (Vec<f64>, Vec<f64>) = z.map(|z| (z.re, z.im)).unzip();
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            f64::NAN
        } else if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    Complex64::new(med(&mut re), med(&mut im))
}

/// The noise of a median over the shots, m: the median over lines of the per-quadrature spread
/// across shots, times `1.2533/√n`; `None` with fewer than 3 shots.
fn noise_of_median(m: &Measurement, p: usize) -> Option<f64> {
    let n = m.n_shots;
    if n < 3 {
        return None;
    }
    let mut sig: Vec<f64> = (0..m.freqs_hz.len())
        .map(|f| {
            let z: Vec<Complex64> = (0..n).map(|s| m.amplitude(s, f, p)).collect();
            let mean = z.iter().sum::<Complex64>() / n as f64;
            let var = z.iter().map(|x| (x - mean).norm_sqr()).sum::<f64>() / (n - 1) as f64;
            (0.5 * var).sqrt()
        })
        .collect();
    sig.sort_by(f64::total_cmp);
    let med = sig[sig.len() / 2];
    (med > 0.0).then(|| 1.2533 * med / (n as f64).sqrt())
}

/// Index of the mode whose resonance is nearest to `f`.
fn nearest(f: f64, modes_hz: &[f64]) -> Option<usize> {
    modes_hz
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - f).abs().total_cmp(&(b.1 - f).abs()))
        .map(|(i, _)| i)
}

/// The label and kind of every measured frequency: the lowest-order combination of the drive
/// tones (`f1`, `f2`, ... in the manifest's order) at that frequency; a drive tone itself, a
/// sideband when every tone it combines lies near the same resonance as the line, a mixing
/// product otherwise. `None` for a frequency no combination up to order 11 reaches.
pub fn classify(
    freqs: &[f64],
    drives: &[f64],
    modes_hz: &[f64],
) -> Vec<Option<(LineKind, String)>> {
    let Ok(tones) = ToneSet::new(drives) else {
        return vec![None; freqs.len()];
    };
    let Some(lattice) = ORDERS.iter().find_map(|&o| tones.lattice(o).ok()) else {
        return vec![None; freqs.len()];
    };
    let tone_mode: Vec<Option<usize>> = drives.iter().map(|&d| nearest(d, modes_hz)).collect();
    freqs
        .iter()
        .map(|&f| {
            let i = lattice.partition_point(|p| p.hz < f - TOL_HZ);
            let p = lattice.get(i).filter(|p| (p.hz - f).abs() <= TOL_HZ)?;
            let k = p.combination.coeffs();
            let label = p.combination.to_string().replace(['·', ' '], "");
            let kind = if p.combination.order() == 1 && p.combination.net() == 1 {
                LineKind::Drive
            } else {
                let own = nearest(f, modes_hz);
                if k.iter()
                    .zip(&tone_mode)
                    .all(|(&kd, &m)| kd == 0 || m == own)
                {
                    LineKind::Sideband
                } else {
                    LineKind::Mixing
                }
            };
            Some((kind, label))
        })
        .collect()
}

/// The steady state of the identified model under this measurement's drive, as complex
/// displacements at each (frequency, local point), or why not.
fn reconstruct(
    model: &NumericModel,
    result: &Report,
    ds: &Dataset,
    m: &Measurement,
) -> Result<Vec<Vec<Complex64>>, String> {
    let names = &model.mode_names;
    let drives = &m.spec.drives_hz;
    let forces = result
        .forces
        .get(&m.spec.name)
        .ok_or_else(|| format!("the result has no forces for measurement {}", m.spec.name))?;
    let mut force = vec![vec![Complex64::new(0.0, 0.0); drives.len()]; names.len()];
    for (n, name) in names.iter().enumerate() {
        for fr in forces.get(name).into_iter().flatten() {
            if let Some(d) = drives.iter().position(|&d| (d - fr.f_hz).abs() <= TOL_HZ) {
                force[n][d] = Complex64::from_polar(fr.amplitude, fr.phase_rad);
            }
        }
    }
    let drive = Excitation {
        pumps: m
            .spec
            .pump_tones()
            .into_iter()
            .map(harmonid_sim::PumpTone::from)
            .collect(),
        tones_hz: drives.clone(),
        force,
    };
    let mut hb = HbSettings::default();
    hb.lattice.extra_hz.clone_from(&m.freqs_hz);
    let st = harmonid_sim::steady_state(model, &drive, &hb).map_err(|e| e.to_string())?;
    if !st.converged() {
        return Err(format!(
            "harmonic balance did not converge for {} (residual {:.1e})",
            m.spec.name, st.residual
        ));
    }
    let shapes: Vec<Vec<f64>> = m
        .points
        .iter()
        .map(|&p| {
            names
                .iter()
                .map(|n| ds.manifest.points.get(p).map_or(1.0, |pt| pt.shape_of(n)))
                .collect()
        })
        .collect();
    Ok(m.freqs_hz
        .iter()
        .map(|&f| shapes.iter().map(|s| st.at_point(s, f)).collect())
        .collect())
}

/// The spectra of one measurement (one figure per point) and a warning when the model could not
/// reconstruct it.
pub fn spectra(
    model: Option<&NumericModel>,
    result: &Report,
    ds: &Dataset,
    m: &Measurement,
) -> (Vec<Spectrum>, Option<String>) {
    let modes_hz: Vec<f64> = match model {
        Some(nm) => nm.f_hz.clone(),
        None => ds.manifest.nominal_hz.values().copied().collect(),
    };
    let (rec, warning) = match model.map(|nm| reconstruct(nm, result, ds, m)) {
        Some(Ok(r)) => (Some(r), None),
        Some(Err(e)) => (None, Some(e)),
        None => (None, None),
    };
    let kinds = classify(&m.freqs_hz, &m.spec.drives_hz, &modes_hz);
    let nf = m.freqs_hz.len();
    // Shown in the dataset's unit (the data are held in metres, or volts).
    let scale = ds.manifest.unit_scale().unwrap_or(1.0);
    // The fit's own standardized residuals of this measurement's lines (the verdict's), by
    // frequency and point: the residual panel in noise units.
    let verdict: Vec<&harmonid_data::result::LineResidual> = result
        .goodness_of_fit
        .as_ref()
        .map(|g| {
            g.lines
                .iter()
                .filter(|l| l.measurement == m.spec.name)
                .collect()
        })
        .unwrap_or_default();
    let sigmas = |f_hz: f64, point: Option<&str>| -> Option<f64> {
        verdict
            .iter()
            .find(|l| {
                (l.freq_hz - f_hz).abs() <= 1e-9 * f_hz.abs().max(1.0)
                    && l.point.as_deref() == point
            })
            .map(|l| l.sigma)
    };
    let out = m
        .points
        .iter()
        .enumerate()
        .map(|(p, &pi)| {
            let point = ds.manifest.points.get(pi).map_or_else(
                || "modal coordinates".to_string(),
                |pt| format!("point {}", pt.name),
            );
            let point_name = ds.manifest.points.get(pi).map(|pt| pt.name.as_str());
            let in_sigmas =
                !verdict.is_empty() && (0..nf).all(|f| sigmas(m.freqs_hz[f], point_name).is_some());
            let lines = (0..nf)
                .map(|f| {
                    let x = complex_median((0..m.n_shots).map(|s| m.amplitude(s, f, p)));
                    let r = rec.as_ref().map(|r| r[f][p]);
                    let residual = if in_sigmas {
                        sigmas(m.freqs_hz[f], point_name)
                    } else {
                        r.map(|r| (x - r).norm() / scale)
                    };
                    let (kind, label) = kinds[f]
                        .clone()
                        .unwrap_or((LineKind::Mixing, "?".to_string()));
                    SpectrumLine {
                        f_hz: m.freqs_hz[f],
                        measured: x.norm() / scale,
                        reconstructed: r.map(|r| r.norm() / scale),
                        residual,
                        kind,
                        label,
                    }
                })
                .collect();
            Spectrum {
                title: format!("{} at {point}: median of {} shots", m.spec.name, m.n_shots),
                unit: ds.manifest.displacement_unit.clone(),
                lines,
                noise_floor: noise_of_median(m, p).map(|s| s / scale),
                residual_in_sigmas: in_sigmas,
            }
        })
        .collect();
    (out, warning)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_named_and_classed() {
        // Two tones near mode 1 (100 Hz), one near mode 2 (200 Hz).
        let drives = [99.0, 101.0, 200.5];
        let modes = [100.0, 200.0];
        let freqs = [97.0, 99.0, 103.0, 198.5, 200.5];
        let c = classify(&freqs, &drives, &modes);
        let kinds: Vec<LineKind> = c.iter().map(|x| x.as_ref().expect("named").0).collect();
        assert_eq!(
            kinds,
            [
                LineKind::Sideband,
                LineKind::Drive,
                LineKind::Sideband,
                LineKind::Mixing,
                LineKind::Drive
            ]
        );
        assert_eq!(c[0].as_ref().expect("named").1, "2f1−f2");
        // 198.5 = f1 + f3 − f2.
        assert_eq!(c[3].as_ref().expect("named").1, "f1+f3−f2");
    }

    #[test]
    fn complex_median_is_componentwise() {
        let z = [
            Complex64::new(1.0, 5.0),
            Complex64::new(2.0, -1.0),
            Complex64::new(100.0, 0.0),
        ];
        assert_eq!(complex_median(z.into_iter()), Complex64::new(2.0, 0.0));
    }
}

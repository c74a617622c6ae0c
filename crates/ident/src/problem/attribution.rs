//! Attribution of measured frequencies to modes, modal conversion, drive forces.

use super::{ForceModel, IdentError, Problem, Settings, Unknown};
use harmonid_data::{Dataset, DatasetError};
use harmonid_model::{Linear, Model};
use harmonid_spectral::{ProductPlan, FREQ_TOLERANCE_HZ};
use num_complex::Complex64;

/// Per measurement: attribution, plan and conversion weights.
#[derive(Debug, Clone)]
pub(super) struct MeasPrep {
    /// Mode each measured frequency is attributed to.
    pub(super) mode_of: Vec<usize>,
    /// Active modes (with attributed frequencies), ascending.
    pub(super) active: Vec<usize>,
    /// Modal conversion weights per frequency: `q̂ = Σ_p w[p] x_p` (local point index).
    pub(super) weights: Vec<Vec<f64>>,
    /// Frequency index of each drive tone.
    pub(super) drive_idx: Vec<usize>,
    /// Complex drive `V e^{iφ}` of each tone (if levels are given).
    pub(super) drive_c: Option<Vec<Complex64>>,
    /// The products' input lines: the measured frequencies, and the pump tones for a model
    /// with pump terms (Hz, sorted).
    pub(super) input_hz: Vec<f64>,
    /// Input line of each measured frequency.
    pub(super) input_of: Vec<usize>,
    /// The pump signal's spectrum on the input lines (empty for a model without pump terms).
    pub(super) pump: Vec<Complex64>,
    /// Products plan: input = `input_hz`, output = measured frequencies.
    pub(super) plan: ProductPlan,
}

impl Problem {
    /// Modal spectra of measurement `mi`, shot `shot`: `modal[n][r]`.
    pub fn modal_spectra(&self, ds: &Dataset, mi: usize, shot: usize) -> Vec<Vec<Complex64>> {
        let m = &ds.measurements[mi];
        let prep = &self.meas[mi];
        let nf = m.freqs_hz.len();
        let mut modal = vec![vec![Complex64::new(0.0, 0.0); nf]; self.mode_names.len()];
        let shot = shot.min(m.n_shots.saturating_sub(1));
        for r in 0..nf {
            let mut q = Complex64::new(0.0, 0.0);
            for (p, w) in prep.weights[r].iter().enumerate() {
                q += m.amplitude(shot, r, p) * *w;
            }
            modal[prep.mode_of[r]][r] = q;
        }
        modal
    }

    /// The spectra of the equation terms' variables for one shot on the products' input lines
    /// ([`MeasPrep::input_hz`]): [`Problem::modal_spectra`] (zero on a pump line nothing
    /// measures), then, for a model with velocity or pump terms, each mode's velocity
    /// `i 2π f X`, then the pump.
    pub(super) fn variable_spectra(
        &self,
        ds: &Dataset,
        mi: usize,
        shot: usize,
    ) -> Vec<Vec<Complex64>> {
        let prep = &self.meas[mi];
        let mut spectra = self.modal_spectra(ds, mi, shot);
        let n_in = prep.input_hz.len();
        let nm = spectra.len();
        let pump = !prep.pump.is_empty();
        // Without a pump the input lines are the measured ones: nothing to move.
        if pump {
            for row in &mut spectra {
                let mut x = vec![Complex64::new(0.0, 0.0); n_in];
                for (r, &z) in row.iter().enumerate() {
                    x[prep.input_of[r]] = z;
                }
                *row = x;
            }
        }
        if self.velocities || pump {
            for n in 0..nm {
                let mut v = vec![Complex64::new(0.0, 0.0); n_in];
                harmonid_spectral::velocity_spectrum(&prep.input_hz, &spectra[n], &mut v);
                spectra.push(v);
            }
        }
        if pump {
            spectra.push(prep.pump.clone());
        }
        spectra
    }

    /// The drive force on its mode of each tone of measurement `mi`, from unknown values
    /// `values` (N/kg): `(tone, mode, F)`.
    pub fn forces(&self, mi: usize, values: &[f64]) -> Vec<(usize, usize, Complex64)> {
        let prep = &self.meas[mi];
        prep.drive_idx
            .iter()
            .enumerate()
            .map(|(tone, &i)| {
                let n = prep.mode_of[i];
                let get = |u: Unknown| self.index_of(&u).map_or(f64::NAN, |j| values[j]);
                let f = match self.table.force_model() {
                    ForceModel::Free | ForceModel::Auto => Complex64::new(
                        get(Unknown::Force {
                            meas: mi,
                            tone,
                            quad: 0,
                        }),
                        get(Unknown::Force {
                            meas: mi,
                            tone,
                            quad: 1,
                        }),
                    ),
                    ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                        let meas = (self.table.force_model() == ForceModel::GainPerMeasurement)
                            .then_some(mi);
                        let gain = Complex64::new(
                            get(Unknown::Gain {
                                meas,
                                mode: n,
                                quad: 0,
                            }),
                            get(Unknown::Gain {
                                meas,
                                mode: n,
                                quad: 1,
                            }),
                        );
                        gain * prep
                            .drive_c
                            .as_ref()
                            .and_then(|v| v.get(tone).copied())
                            .unwrap_or_default()
                    }
                };
                (tone, n, f)
            })
            .collect()
    }

    /// Active modes of measurement `mi`.
    pub fn active_modes(&self, mi: usize) -> &[usize] {
        &self.meas[mi].active
    }
}

/// Nominal resonance frequency of every mode, Hz: the settings' override, else the dataset's
/// `[nominal_hz]`, else the model's `at`, else its fixed `f`.
pub(crate) fn nominal_frequencies(
    model: &Model,
    ds: &Dataset,
    settings: &Settings,
) -> Result<Vec<f64>, IdentError> {
    let nm = model.modes.len();
    let mut nominal_hz = Vec::with_capacity(nm);
    for m in &model.modes {
        let f = settings
            .nominal_hz
            .get(&m.name)
            .or_else(|| ds.manifest.nominal_hz.get(&m.name))
            .copied()
            .or(m.nominal_hz)
            .or(match m.f_hz {
                Linear::Fixed(f) => Some(f),
                Linear::Unknown => None,
            })
            .ok_or_else(|| IdentError::NoNominal {
                mode: m.name.clone(),
            })?;
        nominal_hz.push(f);
    }
    Ok(nominal_hz)
}

/// The mode whose nominal resonance is spectrally closest to `f` (Hz): the spectral crate's
/// rule ([`harmonid_spectral::nearest_of`]) on resolved nominal frequencies (0 when there is no
/// mode, which a checked model never has).
pub(crate) fn nearest_mode(nominal_hz: &[f64], f: f64) -> usize {
    harmonid_spectral::nearest_of(f, nominal_hz.iter().copied().map(Some)).map_or(0, |(n, _)| n)
}

/// The resonance measurement `mi`'s stepped sweep shows, Hz: the first drive tone of the step
/// whose response there (mean magnitude over its shots, first point) is the largest, when it
/// is a peak inside the sweep (not at its lowest or highest drive: a sweep in a resonance's
/// wing rises to its end). `None` for a measurement of no sweep, or a sweep without a peak.
fn sweep_resonance_hz(ds: &Dataset, mi: usize) -> Option<f64> {
    let sweep = &ds.measurements[mi].spec.sweep.as_ref()?.sweep;
    let steps = || {
        ds.measurements
            .iter()
            .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| &s.sweep == sweep))
    };
    let drives = steps().filter_map(|m| m.spec.drives_hz.first().copied());
    let (lo, hi) = drives.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), f| {
        (a.min(f), b.max(f))
    });
    let peak = steps()
        .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| &s.sweep == sweep))
        .filter_map(|m| {
            let d = *m.spec.drives_hz.first()?;
            let i = m.freq_index(d)?;
            let size = (0..m.n_shots)
                .map(|s| m.amplitude(s, i, 0).norm())
                .sum::<f64>();
            Some((d, size / m.n_shots.max(1) as f64))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(d, _)| d)?;
    (lo < peak && peak < hi).then_some(peak)
}

/// Attribution, drive tones, modal conversion weights and the products plan of measurement `mi`.
/// `pump_terms` names the model's pump terms, if it has any: the measurement must then have a
/// pump, whose tones become inputs of the products.
#[allow(clippy::too_many_arguments)]
pub(super) fn prepare_measurement(
    ds: &Dataset,
    mi: usize,
    mode_names: &[String],
    nominal_hz: &[f64],
    settings: &Settings,
    max_deg: usize,
    pump_terms: Option<&str>,
    manifest_path: &str,
) -> Result<MeasPrep, IdentError> {
    let m = &ds.measurements[mi];
    let mode_of: Vec<usize> = m
        .freqs_hz
        .iter()
        .map(|&f| nearest_mode(nominal_hz, f))
        .collect();
    let mut active: Vec<usize> = mode_of.clone();
    active.sort_unstable();
    active.dedup();
    let mut drive_idx = Vec::new();
    for &d in &m.spec.drives_hz {
        let n = nearest_mode(nominal_hz, d);
        let rel = (d - nominal_hz[n]).abs() / nominal_hz[n];
        // A low-Q resonance swept wide, or one its nonlinearity shifted: a tone near its
        // sweep's own resonance (a peak inside the sweep) is near the mode nearest that peak.
        let near_own = || {
            sweep_resonance_hz(ds, mi).is_some_and(|fp| {
                nearest_mode(nominal_hz, fp) == n && (d - fp).abs() <= settings.near_rel * fp
            })
        };
        if rel > settings.near_rel && !near_own() {
            return Err(IdentError::ToneNearNoResonance {
                file: manifest_path.to_string(),
                measurement: m.spec.name.clone(),
                drive_hz: d,
                mode: mode_names[n].clone(),
                nominal_hz: nominal_hz[n],
                rel,
                limit: settings.near_rel,
            });
        }
        // The dataset reader guarantees every drive is measured.
        let Some(i) = m.freq_index(d) else {
            return Err(IdentError::Dataset(DatasetError::DriveNotMeasured {
                path: ds.dir.join(m.spec.file_name()),
                measurement: m.spec.name.clone(),
                drive_hz: d,
                nearest_hz: f64::NAN,
            }));
        };
        drive_idx.push(i);
    }
    // Modal conversion weights.
    let mut weights = Vec::with_capacity(m.freqs_hz.len());
    for &n in &mode_of {
        let shapes: Vec<f64> = if ds.manifest.points.is_empty() {
            vec![1.0]
        } else {
            m.points
                .iter()
                .map(|&p| ds.manifest.points[p].shape_of(&mode_names[n]))
                .collect()
        };
        let s2: f64 = shapes.iter().map(|s| s * s).sum();
        if s2 == 0.0 {
            return Err(IdentError::ZeroShape {
                file: manifest_path.to_string(),
                measurement: m.spec.name.clone(),
                mode: mode_names[n].clone(),
            });
        }
        weights.push(shapes.iter().map(|s| s / s2).collect());
    }
    let drive_c = m.spec.drive_levels_and_phases().map(|(l, p)| {
        l.iter()
            .zip(p)
            .map(|(&v, &ph)| Complex64::from_polar(v, ph))
            .collect()
    });
    let pump_tones = m.spec.pump_tones();
    if pump_terms.is_some() && pump_tones.is_empty() {
        return Err(IdentError::NoPump {
            file: manifest_path.to_string(),
            measurement: m.spec.name.clone(),
            terms: pump_terms.unwrap_or_default().to_string(),
        });
    }
    let mut input_hz = m.freqs_hz.clone();
    if pump_terms.is_some() {
        input_hz.extend(pump_tones.iter().map(|&(f, _)| f));
        input_hz.sort_by(f64::total_cmp);
        input_hz.dedup_by(|a, b| (*a - *b).abs() <= FREQ_TOLERANCE_HZ);
    }
    let line = |f: f64| {
        input_hz
            .iter()
            .position(|&x| (x - f).abs() <= FREQ_TOLERANCE_HZ)
            .unwrap_or(0)
    };
    let input_of = m.freqs_hz.iter().map(|&f| line(f)).collect();
    let mut pump = Vec::new();
    if pump_terms.is_some() {
        pump = vec![Complex64::new(0.0, 0.0); input_hz.len()];
        for &(f, a) in &pump_tones {
            pump[line(f)] += a;
        }
    }
    let plan = ProductPlan::new(&input_hz, &m.freqs_hz, max_deg).map_err(|source| {
        IdentError::Spectral {
            measurement: m.spec.name.clone(),
            source,
        }
    })?;
    Ok(MeasPrep {
        mode_of,
        active,
        weights,
        drive_idx,
        drive_c,
        input_hz,
        input_of,
        pump,
        plan,
    })
}

#[cfg(test)]
mod tests {
    use super::super::testkit::{self, SHAPE};
    use super::super::{IdentError, Problem, Settings};
    use super::nearest_mode;

    #[test]
    fn frequencies_go_to_the_nearest_resonance() {
        assert_eq!(nearest_mode(&[1000.0, 3000.0], 1999.0), 0);
        assert_eq!(nearest_mode(&[1000.0, 3000.0], 2001.0), 1);
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        assert_eq!(p.meas[2].mode_of, vec![0, 0, 0, 0, 1, 1, 1]);
        assert_eq!(p.active_modes(2), &[0, 1]);
        assert_eq!(p.active_modes(1), &[1]);
        assert_eq!(p.meas[2].drive_idx, vec![1, 2, 5]);
        assert_eq!(p.table.nominal_hz(), &[1000.0, 3000.0]);
    }

    #[test]
    fn modal_amplitude_is_the_signal_over_the_shape() {
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let q = p.modal_spectra(&ds, 2, 0);
        for (r, &f) in ds.measurements[2].freqs_hz.iter().enumerate() {
            let n = p.meas[2].mode_of[r];
            let x = ds.measurements[2].amplitude(0, r, 0);
            assert!(
                (q[n][r] * SHAPE[n] - x).norm() <= 1e-15 * x.norm().max(1e-30),
                "{f}"
            );
            assert_eq!(q[1 - n][r].norm(), 0.0);
        }
    }

    #[test]
    fn a_tone_far_from_every_resonance_is_an_error() {
        let mut ds = testkit::dataset(false, 1, 0.0, 1);
        let m = &mut ds.measurements[0];
        m.spec.drives_hz[0] = 1985.0;
        m.freqs_hz[0] = 1985.0;
        let err = Problem::new(&testkit::model(), &ds, &Settings::default()).expect_err("refused");
        assert!(
            matches!(err, IdentError::ToneNearNoResonance { drive_hz, .. } if drive_hz == 1985.0),
            "{err}"
        );
    }

    #[test]
    fn a_mode_without_shape_at_the_points_is_an_error() {
        let mut ds = testkit::dataset(false, 1, 0.0, 1);
        ds.manifest.points[0].shape.insert("b".into(), 0.0);
        let err = Problem::new(&testkit::model(), &ds, &Settings::default()).expect_err("refused");
        assert!(
            matches!(&err, IdentError::ZeroShape { mode, .. } if mode == "b"),
            "{err}"
        );
    }

    #[test]
    fn gain_forces_are_gain_times_drive() {
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        let f = p.forces(2, &testkit::truth(&p));
        assert_eq!(f.len(), 3);
        assert_eq!((f[2].0, f[2].1), (2, 1));
        assert!((f[2].2 - testkit::GAIN[1] * 0.5).norm() < 1e-15);
    }
}

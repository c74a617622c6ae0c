//! Measurement backgrounds (`identify --background drive,slope,constant`): what a lock-in
//! records on a mode's measured line besides the resonator's response.
//!
//! On every measured line at a drive tone's frequency `f` attributed to mode `n` (the mode
//! whose nominal resonance `f_ref,n` is nearest; the lines a stepped sweep records), the
//! prediction is the harmonic balance's response plus
//!
//! ```text
//! B_n·D + S_n·D·(f − f_ref,n) + C_n,        D = V e^{iφ} (the tone's drive level and phase)
//! ```
//!
//! `drive` (`B`, electrical feedthrough, the data's unit per drive-level unit), `slope` (`S`,
//! per drive-level unit per Hz) and `constant` (`C`, the data's unit, independent of the
//! drive): each a complex unknown per mode ([`Unknown::Background`]), shared by every
//! measurement of the dataset. Intermodulation lines (no drive tone there) carry none.
//!
//! **Where it is fitted.** The background enters the output-error prediction linearly (its
//! Jacobian columns are `D`, `D·(f − f_ref)`, 1 and `i` times them), so the output-error fit,
//! its Fisher bounds and jackknife treat it as any other unknown. It is not linear in the
//! equation-error formulation (the nonlinear terms act on the background-free response), so
//! the equation-error start is fitted without it, the background at zero: the output-error
//! fit moves it from there. Hence `--estimator linear` with a background is refused, and an
//! output-error fit that fails (the linear estimate is then reported) says the background
//! was not fitted.

pub use crate::background_terms::{Background, BackgroundTerm, BadBackground};
use crate::layout::{Unknown, UnknownTable};
use crate::problem::{nearest_mode, IdentError};
use crate::settings::Settings;
use harmonid_data::Dataset;
use harmonid_sim::Observation;
use num_complex::Complex64;

/// Refuses a background the dataset or the settings cannot fit: the linear estimator (the
/// background is not linear in its equations), a term proportional to the drive without the
/// drive levels of every measurement, or data at several points (one background per mode
/// and point is not offered).
pub(crate) fn check(ds: &Dataset, settings: &Settings) -> Result<(), IdentError> {
    let bg = &settings.background;
    if bg.is_empty() {
        return Ok(());
    }
    let file = ds.dir.join("dataset.toml").display().to_string();
    if !settings.estimator.is_output_error() {
        return Err(IdentError::Background {
            file,
            why: format!(
                "--background {bg} needs the output-error estimator (the background is not linear in the equation-error fit): drop --estimator {}",
                settings.estimator
            ),
        });
    }
    if ds.manifest.points.len() > 1 {
        return Err(IdentError::Background {
            file,
            why: format!(
                "--background {bg}: the dataset has {} measurement points; a background per mode and point is not offered yet (identify one point's data, or leave --background out)",
                ds.manifest.points.len()
            ),
        });
    }
    let needs: Vec<&str> = bg
        .terms()
        .iter()
        .filter(|t| t.needs_drive_levels())
        .map(|t| t.name())
        .collect();
    if !needs.is_empty() {
        if let Some(m) = ds
            .measurements
            .iter()
            .find(|m| m.spec.drive_levels_and_phases().is_none())
        {
            return Err(IdentError::Background {
                file,
                why: format!(
                    "--background {bg}: measurement \"{}\" records no drive_levels_v and drive_phases_rad, which the {} term{} need{} (proportional to the drive level): give the dataset its drive levels (`harmonid import ... --map` with a drive_level column), or fit `--background constant` alone",
                    m.spec.name,
                    needs.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(" and "),
                    if needs.len() == 1 { "" } else { "s" },
                    if needs.len() == 1 { "s" } else { "" },
                ),
            });
        }
    }
    Ok(())
}

/// The values `settings.background_fixed` holds for a background unknown (mode, term, part),
/// converted from the dataset's unit to the fit's (metres, or volts), or `None` (free).
pub(crate) fn fixed_values<'a>(
    ds: &Dataset,
    settings: &'a Settings,
    mode_names: &'a [String],
) -> impl Fn(usize, BackgroundTerm, u8) -> Option<f64> + 'a {
    let scale = ds.manifest.unit_scale().unwrap_or(1.0);
    move |mode, term, quad| {
        let b = settings.background_fixed.get(mode_names.get(mode)?)?;
        let c = match term {
            BackgroundTerm::Drive => b.drive.as_ref(),
            BackgroundTerm::Slope => b.slope.as_ref(),
            BackgroundTerm::Constant => b.constant.as_ref(),
        }?;
        let v = if quad == 0 { c.re.value } else { c.im.value };
        v.is_finite().then_some(v * scale)
    }
}

/// The modes with a measured line at a drive tone's frequency (the lines a background sits
/// on), in index order: only they get background unknowns.
pub(crate) fn modes_with_lines(ds: &Dataset, nominal_hz: &[f64]) -> Vec<usize> {
    let mut modes: Vec<usize> = ds
        .measurements
        .iter()
        .flat_map(|m| {
            m.freqs_hz
                .iter()
                .filter(|&&f| tone_at(&m.spec.drives_hz, f).is_some())
                .map(|&f| nearest_mode(nominal_hz, f))
        })
        .collect();
    modes.sort_unstable();
    modes.dedup();
    modes
}

/// The drive tone at frequency `f_hz` (within 1e-9 relative), if any.
fn tone_at(drives_hz: &[f64], f_hz: f64) -> Option<usize> {
    drives_hz
        .iter()
        .position(|&d| (d - f_hz).abs() <= 1e-9 * d.abs().max(f_hz.abs()))
}

/// One background term on one observation of a measurement: the prediction there gains
/// `(θ[re] + i θ[im])·factor`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BackgroundLine {
    /// Observation index within its measurement.
    pub obs: usize,
    /// Column of the real part.
    pub re: usize,
    /// Column of the imaginary part.
    pub im: usize,
    /// `D`, `D·(f − f_ref)` or 1.
    pub factor: Complex64,
}

/// The background terms on the observations `obs` of a measurement with drive tones
/// `drives_hz` at complex levels `drive_c` (`V e^{iφ}`, `None` without levels), from the
/// background unknowns of `table` (none: empty).
pub(crate) fn lines(
    table: &UnknownTable,
    drives_hz: &[f64],
    drive_c: Option<&[Complex64]>,
    obs: &[Observation],
) -> Vec<BackgroundLine> {
    let mut out = Vec::new();
    let nominal = table.nominal_hz();
    for (o, ob) in obs.iter().enumerate() {
        let Some(tone) = tone_at(drives_hz, ob.f_hz) else {
            continue;
        };
        let n = nearest_mode(nominal, ob.f_hz);
        let d = drive_c.and_then(|d| d.get(tone).copied());
        for (k, u) in table.unknowns().iter().enumerate() {
            let Unknown::Background {
                mode,
                term,
                quad: 0,
            } = *u
            else {
                continue;
            };
            let im = table.index_of(&Unknown::Background {
                mode,
                term,
                quad: 1,
            });
            if mode != n {
                continue;
            }
            if let (Some(im), Some(factor)) = (im, term.factor(ob.f_hz, nominal[n], d)) {
                out.push(BackgroundLine {
                    obs: o,
                    re: k,
                    im,
                    factor,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_follow_the_drive_and_the_detuning() {
        let d = Some(Complex64::new(0.0, 2.0));
        let f = |t: BackgroundTerm, d| t.factor(105.0, 100.0, d);
        assert_eq!(f(BackgroundTerm::Drive, d), d);
        assert_eq!(f(BackgroundTerm::Slope, d), Some(Complex64::new(0.0, 10.0)));
        assert_eq!(
            f(BackgroundTerm::Constant, None),
            Some(Complex64::new(1.0, 0.0))
        );
        assert_eq!(f(BackgroundTerm::Drive, None), None);
        assert_eq!(tone_at(&[99.0, 100.0], 100.0 + 1e-8), Some(1));
        assert_eq!(tone_at(&[99.0, 100.0], 101.0), None);
    }
}

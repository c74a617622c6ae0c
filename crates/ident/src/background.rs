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

use crate::layout::{Unknown, UnknownTable};
use crate::problem::{nearest_mode, IdentError};
use crate::settings::Settings;
use harmonid_data::Dataset;
use harmonid_sim::Observation;
use num_complex::Complex64;

/// One term of a measurement background; [`BackgroundTerm::name`] is its one spelling
/// (`--background`, Python's `background=`, the result file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BackgroundTerm {
    /// `B_n·D`: feedthrough proportional to the drive.
    Drive,
    /// `S_n·D·(f − f_ref)`: a slope across the sweep, proportional to the drive.
    Slope,
    /// `C_n`: an offset independent of the drive.
    Constant,
}

impl BackgroundTerm {
    /// Every term, in the order the result lists them.
    pub const ALL: [BackgroundTerm; 3] = [
        BackgroundTerm::Drive,
        BackgroundTerm::Slope,
        BackgroundTerm::Constant,
    ];

    /// The term's name: `drive`, `slope`, `constant`.
    pub fn name(self) -> &'static str {
        match self {
            BackgroundTerm::Drive => "drive",
            BackgroundTerm::Slope => "slope",
            BackgroundTerm::Constant => "constant",
        }
    }

    /// Whether the term is proportional to the drive level (it needs the dataset's levels).
    pub fn needs_drive_levels(self) -> bool {
        self != BackgroundTerm::Constant
    }

    /// The term's coefficient on a line at `f_hz` of mode with nominal resonance `f_ref_hz`
    /// driven at `drive` (`V e^{iφ}`; `None`: no levels recorded, then only `Constant`).
    pub fn factor(self, f_hz: f64, f_ref_hz: f64, drive: Option<Complex64>) -> Option<Complex64> {
        match self {
            BackgroundTerm::Drive => drive,
            BackgroundTerm::Slope => drive.map(|d| d * (f_hz - f_ref_hz)),
            BackgroundTerm::Constant => Some(Complex64::new(1.0, 0.0)),
        }
    }
}

/// The background terms an identification fits (none by default). Read from
/// `drive[,slope][,constant]` (any order, each once; `none` or empty for none).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Background {
    terms: Vec<BackgroundTerm>,
}

impl Background {
    /// The background of these terms (sorted, each once).
    pub fn of(terms: &[BackgroundTerm]) -> Self {
        let mut terms = terms.to_vec();
        terms.sort();
        terms.dedup();
        Background { terms }
    }

    /// The terms, in [`BackgroundTerm::ALL`]'s order.
    pub fn terms(&self) -> &[BackgroundTerm] {
        &self.terms
    }

    /// Whether no background is fitted.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }
}

/// `drive,slope,constant`, or `none`.
impl std::fmt::Display for Background {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.terms.is_empty() {
            return f.write_str("none");
        }
        let names: Vec<&str> = self.terms.iter().map(|t| t.name()).collect();
        f.write_str(&names.join(","))
    }
}

impl std::str::FromStr for Background {
    type Err = UnknownBackground;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut terms = Vec::new();
        for word in s.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            if word == "none" {
                continue;
            }
            let t = BackgroundTerm::ALL
                .into_iter()
                .find(|t| t.name() == word)
                .ok_or_else(|| UnknownBackground {
                    found: word.to_string(),
                })?;
            terms.push(t);
        }
        Ok(Background::of(&terms))
    }
}

/// A word that is no [`BackgroundTerm`]'s name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("background term {found:?} is not one of \"drive\", \"slope\", \"constant\" (e.g. --background drive,slope; \"none\" for no background)")]
pub struct UnknownBackground {
    /// The word given.
    pub found: String,
}

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
    if let Some(first) = needs.first() {
        if let Some(m) = ds
            .measurements
            .iter()
            .find(|m| m.spec.drive_levels_and_phases().is_none())
        {
            return Err(IdentError::Background {
                file,
                why: format!(
                    "--background {bg}: measurement \"{}\" records no drive_levels_v and drive_phases_rad, and the {} term{} proportional to the drive level (e.g. `{first}`) need{} them: give the dataset its drive levels (`harmonid import ... --map` with a drive_level column), or fit `--background constant` alone",
                    m.spec.name,
                    needs.join(" and "),
                    if needs.len() == 1 { " is" } else { "s are" },
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
    fn background_words_read_back_and_unknown_ones_are_listed() {
        let b: Background = "constant, drive".parse().expect("parse");
        assert_eq!(
            b.terms(),
            &[BackgroundTerm::Drive, BackgroundTerm::Constant]
        );
        assert_eq!(b.to_string(), "drive,constant");
        assert_eq!(b.to_string().parse::<Background>(), Ok(b));
        assert!("none".parse::<Background>().expect("none").is_empty());
        assert!("".parse::<Background>().expect("empty").is_empty());
        let err = "drive,feedthrough".parse::<Background>().expect_err("bad");
        assert_eq!(err.found, "feedthrough");
        let text = err.to_string();
        assert!(
            text.contains("\"drive\", \"slope\", \"constant\""),
            "{text}"
        );
    }

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

//! Plans an instrument can run (`harmonid plan --instrument`): lock-in profiles (oscillators,
//! demodulators, output range, demodulation frequency, filter orders and time constants), the
//! design held to them (lines per measurement, the output's summed amplitude), and per level of
//! every measurement the drive volts, the demodulator filter, the settling time and the samples
//! ([`PlanInstrument`], the plan's `[instrument]`).
//!
//! Sources of the profiles' numbers:
//! - Zurich Instruments: MFLI with MF-MD 4 demodulators / 4 oscillators, UHFLI with UHF-MF 8 / 8,
//!   HF2LI with HF2-MF 6 / 6 (docs.zhinst.com `mfli_user_manual/functional_description/
//!   lock_in_mf.html` and the UHF / HF2 equivalents); every demodulator has a `harmonic` setting,
//!   so it can sit at n × an oscillator's frequency; filter orders 1–8 (6–48 dB/octave), the
//!   −3 dB bandwidth `sqrt(2^(1/n) − 1) / (2π τ)` (zhinst-utils `bwtc_scaling_factor`: 1.0,
//!   0.6436, 0.5098, 0.4350, 0.3856, 0.3499, 0.3226, 0.3008 for orders 1–8, checked in the tests).
//!   The MFLI without MF-MD: one oscillator (the Lock-in tab without the option), two
//!   demodulators both at harmonics of it. Output ranges (MFLI and HF2LI ±10 V, UHFLI ±1.5 V),
//!   demodulation frequencies (MFLI 500 kHz, 5 MHz with MF-5M; HF2LI 50 MHz; UHFLI 600 MHz) and
//!   time-constant ranges are the vendors' specification tables as recalled, not confirmed
//!   against stored pages: check them against your instrument's manual.
//! - Liquid Instruments Moku lock-in (apis.liquidinstruments.com `reference/lia`): one
//!   dual-phase demodulator with cascaded single-pole low-pass filters, slopes 6–24 dB/octave
//!   (`set_filter`: orders 1–4). Assumed here: one oscillator drives (a second tone would need
//!   another generator), one line demodulated at a time, ±1 V output (Moku:Lab into 50 Ω, the
//!   smallest of the family), demodulation up to 30 MHz (Moku:Go, the smallest of the family).

use crate::design::design_inner;
use crate::{DesignSettings, DesignStep, Evaluation, PlanError};
use harmonid_experiment::{LockinLevel, Plan, PlanInstrument, PlanMeasurement};
use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel};
use serde::{Deserialize, Serialize};

/// The lock-in a plan is designed for (`harmonid plan --instrument NAME`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LockIn {
    /// No instrument: any number of tones and lines, `--max-voltage` per tone (the behaviour
    /// before profiles).
    #[default]
    Generic,
    /// Zurich Instruments MFLI without the MF-MD option: one oscillator.
    Mfli,
    /// MFLI with the MF-MD multi-demodulator option: 4 oscillators, 4 demodulators.
    MfliMf,
    /// HF2LI with the HF2-MF option: 6 oscillators, 6 demodulators.
    Hf2li,
    /// UHFLI with the UHF-MF option: 8 oscillators, 8 demodulators.
    Uhfli,
    /// Liquid Instruments Moku lock-in: one oscillator, one demodulator.
    Moku,
}

/// Every [`LockIn`], in the order the help lists them.
pub const LOCKINS: [LockIn; 6] = [
    LockIn::Mfli,
    LockIn::MfliMf,
    LockIn::Hf2li,
    LockIn::Uhfli,
    LockIn::Moku,
    LockIn::Generic,
];

impl LockIn {
    /// Its name on the command line and in the plan file.
    pub fn name(self) -> &'static str {
        match self {
            LockIn::Generic => "generic",
            LockIn::Mfli => "mfli",
            LockIn::MfliMf => "mfli-mf",
            LockIn::Hf2li => "hf2li",
            LockIn::Uhfli => "uhfli",
            LockIn::Moku => "moku",
        }
    }

    /// The instrument's limits (`None` for [`LockIn::Generic`]).
    pub fn profile(self) -> Option<Profile> {
        let zi = |label, oscillators, demodulators, max_output_v, max_demod_hz, tc| Profile {
            label,
            oscillators,
            demodulators,
            max_output_v,
            max_demod_hz,
            filter_orders: (1, 8),
            time_constant_s: tc,
        };
        Some(match self {
            LockIn::Generic => return None,
            LockIn::Mfli => zi(
                "the MFLI (no MF-MD option)",
                1,
                2,
                10.0,
                5e5,
                (337e-9, 83.0),
            ),
            LockIn::MfliMf => zi("the MFLI with MF-MD", 4, 4, 10.0, 5e5, (337e-9, 83.0)),
            LockIn::Hf2li => zi("the HF2LI with HF2-MF", 6, 6, 10.0, 5e7, (780e-9, 500.0)),
            LockIn::Uhfli => zi("the UHFLI with UHF-MF", 8, 8, 1.5, 6e8, (30e-9, 76.0)),
            LockIn::Moku => Profile {
                label: "the Moku lock-in",
                oscillators: 1,
                demodulators: 1,
                max_output_v: 1.0,
                max_demod_hz: 3e7,
                filter_orders: (1, 4),
                time_constant_s: (1e-6, 1e3),
            },
        })
    }

    /// What to use for more simultaneous tones than `self` has oscillators.
    fn more_tones(self, tones: usize) -> String {
        let what = match tones {
            2 => "two simultaneous tones".to_string(),
            n => format!("{n} simultaneous tones"),
        };
        match self {
            LockIn::Mfli => format!("{what} need the MFLI's MF-MD option (4 oscillators): use --instrument mfli-mf"),
            LockIn::Moku => format!("{what} need more than the Moku lock-in's one oscillator: use an instrument with several (--instrument mfli-mf, hf2li, uhfli), or drive the other tones from another generator and plan with --instrument generic"),
            LockIn::MfliMf => format!("{what} are more than the MFLI's 4 oscillators: use --instrument hf2li (6) or uhfli (8)"),
            LockIn::Hf2li => format!("{what} are more than the HF2LI's 6 oscillators: use --instrument uhfli (8)"),
            _ => format!("{what} are more than {} has oscillators", self.profile().map_or("the instrument", |p| p.label)),
        }
    }
}

impl std::fmt::Display for LockIn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for LockIn {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        LOCKINS
            .into_iter()
            .find(|l| l.name() == s.trim())
            .ok_or_else(|| {
                let names: Vec<&str> = LOCKINS.iter().map(|l| l.name()).collect();
                format!(
                    "unknown instrument `{}`: expected one of {}",
                    s.chars().take(40).collect::<String>(),
                    names.join(", ")
                )
            })
    }
}

/// A lock-in's limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// The instrument in words (`the MFLI with MF-MD`).
    pub label: &'static str,
    /// Oscillators: each drive tone needs one, and so does each measured line that is not an
    /// integer harmonic of one.
    pub oscillators: usize,
    /// Demodulators: lines read at once.
    pub demodulators: usize,
    /// The signal output's largest amplitude, V (peak).
    pub max_output_v: f64,
    /// The highest demodulation frequency, Hz.
    pub max_demod_hz: f64,
    /// The low-pass filter's orders, lowest and highest.
    pub filter_orders: (u32, u32),
    /// The filter's time constants, shortest and longest, s.
    pub time_constant_s: (f64, f64),
}

/// Each demodulator's filter attenuates every other line by at least this factor (60 dB).
pub const REJECTION: f64 = 1e3;
/// The filter and the resonator count as settled within this fraction of their final value.
pub const SETTLE_ACCURACY: f64 = 1e-3;

/// What `--instrument` asks of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InstrumentSettings {
    /// The profile.
    pub lockin: LockIn,
    /// The output's largest summed amplitude, V (`--max-voltage`; `None`: the profile's range).
    pub max_voltage: Option<f64>,
    /// A fixed filter order (`None`: the one that settles fastest).
    pub filter_order: Option<u32>,
}

impl InstrumentSettings {
    /// The profile and the output's summed cap (V), checked: `None` for the generic profile.
    /// Errors: a cap that is not finite and positive or beyond the output's range, a filter
    /// order the instrument does not have.
    pub fn checked(&self) -> Result<Option<(Profile, f64)>, PlanError> {
        let err = |message: String| PlanError::Instrument { message };
        let Some(p) = self.lockin.profile() else {
            if let Some(n) = self.filter_order {
                return Err(err(format!("--filter-order {n} needs an instrument profile (--instrument mfli-mf, ...): the generic one has no demodulator filter")));
            }
            return Ok(None);
        };
        let cap = match self.max_voltage {
            None => p.max_output_v,
            Some(v) if !(v.is_finite() && v > 0.0) => {
                return Err(err(format!(
                    "--max-voltage {}: expected a positive amplitude in volts, at most {} (the output range of {})",
                    harmonid_files::number(v), p.max_output_v, p.label
                )))
            }
            Some(v) if v > p.max_output_v => {
                return Err(err(format!(
                    "--max-voltage {} V: {} outputs at most {} V (peak); give --max-voltage {} or less",
                    harmonid_files::number(v),
                    p.label,
                    p.max_output_v,
                    p.max_output_v
                )))
            }
            Some(v) => v,
        };
        if let Some(n) = self.filter_order {
            let (lo, hi) = p.filter_orders;
            if !(lo..=hi).contains(&n) {
                return Err(err(format!(
                    "--filter-order {n}: {} has filter orders {lo} to {hi} ({}–{} dB/octave)",
                    p.label,
                    6 * lo,
                    6 * hi
                )));
            }
        }
        Ok(Some((p, cap)))
    }
}

/// [`crate::design_with_progress`] held to an instrument: at most as many lines per
/// measurement as it has demodulators, every drive's tones summing to at most the output's cap
/// on the one output (each tone of a pair at most half of it), and the plan's `[instrument]`
/// written ([`lockin_plan`]). The generic profile designs as before.
/// Errors: those of [`InstrumentSettings::checked`], fewer oscillators than the design's two
/// tones (naming the option that has more), those of the design and of [`lockin_plan`].
pub fn design_for_instrument(
    model: &Model,
    values: &ModelValues,
    settings: &DesignSettings,
    inst: &InstrumentSettings,
    progress: &mut dyn FnMut(DesignStep<'_>),
) -> Result<(Plan, Evaluation), PlanError> {
    let Some((p, cap)) = inst.checked()? else {
        return crate::design_with_progress(model, values, settings, progress);
    };
    if p.oscillators < 2 {
        return Err(PlanError::Instrument {
            message: format!(
                "the design drives each mode with a tone pair: {}",
                inst.lockin.more_tones(2)
            ),
        });
    }
    let mut s = settings.clone();
    s.max_frequencies = s.max_frequencies.min(p.demodulators);
    s.max_voltage = Some(cap);
    let (mut plan, mut ev) = design_inner(model, values, &s, Some(cap), progress)?;
    if settings.max_frequencies > p.demodulators {
        ev.notes.push(format!(
            "{} reads {} lines at once: each measurement measures at most {} (--max-frequencies {} lowered)",
            p.label, p.demodulators, p.demodulators, settings.max_frequencies
        ));
    }
    let num = NumericModel::from_model(model, values)?;
    plan.instrument = Some(lockin_plan(&plan, &num, inst)?);
    Ok((plan, ev))
}

/// The lock-in settings of every level of `plan` on `inst` (the plan's `[instrument]`), with
/// the model at the guess `num` for the ring-down times. Per measurement: the lines (its
/// `measure_hz`, else its tones) each on a demodulator, read in as few passes of the same drive
/// as the demodulators and oscillators allow; the filter order and time constant that reject
/// the nearest other line by [`REJECTION`] and settle fastest; the settling time (the filter's
/// step response and the slowest driven mode's ring-down `Q/(π f)`, each to
/// [`SETTLE_ACCURACY`]); the record for the plan's shots. Per level: the tones' volts (the
/// level times `drive_levels_v`) and their sum.
/// Errors: more tones than oscillators, a line above the demodulation range, a level whose
/// summed volts exceed the cap, a measurement without drive levels in volts, a filter beyond
/// the time constants.
pub fn lockin_plan(
    plan: &Plan,
    num: &NumericModel,
    inst: &InstrumentSettings,
) -> Result<PlanInstrument, PlanError> {
    let err = |message: String| PlanError::Instrument { message };
    let Some((p, cap)) = inst.checked()? else {
        return Err(err(
            "the generic instrument has no lock-in settings: give --instrument".into(),
        ));
    };
    let mut levels = Vec::new();
    for m in &plan.measurements {
        let tones = m.drives_hz.len();
        if tones > p.oscillators {
            return Err(err(format!(
                "measurement `{}` drives {tones} tones at once: {}",
                m.name,
                inst.lockin.more_tones(tones)
            )));
        }
        let lines = m.measure_hz.clone().unwrap_or_else(|| m.drives_hz.clone());
        if let Some(&f) = lines.iter().find(|&&f| f > p.max_demod_hz) {
            let hint = if inst.lockin == LockIn::Mfli || inst.lockin == LockIn::MfliMf {
                " (the MF-5M option raises it to 5 MHz)"
            } else {
                ""
            };
            return Err(err(format!(
                "measurement `{}` measures a line at {f} Hz, above the {} Hz {} demodulates{hint}",
                m.name, p.max_demod_hz, p.label
            )));
        }
        let (oscillators, passes) = oscillators_and_passes(&m.drives_hz, &lines, &p)
            .ok_or_else(|| {
                err(format!(
                    "measurement `{}`: its lines off the tones' harmonics need oscillators of their own, and all {} of {} drive its {tones} tones; measure fewer lines (--max-frequencies {tones}) or use an instrument with more oscillators",
                    m.name, p.oscillators, p.label
                ))
            })?;
        let nearest = nearest_hz(&lines);
        let (order, tc) = choose_filter(nearest, &p, inst.filter_order)
            .map_err(|e| err(format!("measurement `{}`: {e}", m.name)))?;
        let ring = ring_down_s(m, num) * (1.0 / SETTLE_ACCURACY).ln();
        let nebw = nebw_hz(order, tc);
        let bw3 = bandwidth_3db_hz(order, tc);
        let settle = settle_time(order, SETTLE_ACCURACY) * tc + ring;
        let record = plan.noise.shots as f64 / (2.0 * nebw);
        let rate = round_up3(10.0 * bw3);
        let Some(volts) = &m.drive_levels_v else {
            return Err(err(format!(
                "measurement `{}` has no drive_levels_v: an instrument plan needs every tone's drive in volts (give the actuator gains, --gain MODE=N_PER_KG_PER_V or --gains-from)",
                m.name
            )));
        };
        let fractions = if m.levels.is_empty() {
            vec![1.0]
        } else {
            m.levels.clone()
        };
        for level in fractions {
            let drives_v: Vec<f64> = volts.iter().map(|v| v * level).collect();
            let output_v: f64 = drives_v.iter().map(|v| v.abs()).sum();
            if output_v > cap * (1.0 + 1e-9) {
                return Err(err(format!(
                    "measurement `{}` at level {level}: its tones sum to {output_v:.4} V on the output, above {cap} V (--max-voltage, or the output range of {}): tones on one output add",
                    m.name, p.label
                )));
            }
            levels.push(LockinLevel {
                measurement: m.name.clone(),
                level,
                drives_v,
                output_v,
                oscillators,
                demodulators: lines.len().div_ceil(passes),
                passes,
                nearest_hz: nearest,
                filter_order: order,
                time_constant_s: tc,
                bandwidth_3db_hz: bw3,
                nebw_hz: nebw,
                settle_s: settle,
                record_s: record,
                sample_rate_hz: rate,
                samples: (rate * record).ceil() as u64,
            });
        }
    }
    Ok(PlanInstrument {
        profile: inst.lockin.name().into(),
        max_output_v: cap,
        rejection: REJECTION,
        settle_accuracy: SETTLE_ACCURACY,
        levels,
    })
}

/// Oscillators one pass uses and the passes of the same drive needed to read every line:
/// each tone takes an oscillator; a line that is an integer harmonic of a tone rides on it,
/// any other needs one of its own; a pass reads at most as many lines as there are
/// demodulators. `None` when lines need oscillators and the tones take them all.
fn oscillators_and_passes(tones: &[f64], lines: &[f64], p: &Profile) -> Option<(usize, usize)> {
    let harmonic = |f: f64| {
        tones.iter().any(|&t| {
            let n = (f / t).round();
            n >= 1.0 && (f - n * t).abs() <= 1e-6 * f.max(1.0)
        })
    };
    let own = lines.iter().filter(|&&f| !harmonic(f)).count();
    let free = p.oscillators.checked_sub(tones.len())?;
    if own > 0 && free == 0 {
        return None;
    }
    let by_demods = lines.len().div_ceil(p.demodulators.max(1));
    let by_oscillators = if own == 0 { 1 } else { own.div_ceil(free) };
    let passes = by_demods.max(by_oscillators).max(1);
    Some((tones.len() + own.div_ceil(passes).min(free), passes))
}

/// The nearest other frequency in a demodulator's baseband, Hz: the smallest spacing between
/// two of `lines`, or the `2f` product of the lowest line (its sum with itself), whichever is
/// smaller.
pub fn nearest_hz(lines: &[f64]) -> f64 {
    let mut sorted = lines.to_vec();
    sorted.sort_by(f64::total_cmp);
    let spacing = sorted
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    spacing.min(2.0 * sorted.first().copied().unwrap_or(f64::INFINITY))
}

/// The −3 dB bandwidth of `order` cascaded first-order filters of time constant `tc`, Hz:
/// `sqrt(2^(1/n) − 1) / (2π τ)`.
pub fn bandwidth_3db_hz(order: u32, tc: f64) -> f64 {
    (2f64.powf(1.0 / order as f64) - 1.0).sqrt() / (std::f64::consts::TAU * tc)
}

/// The noise-equivalent bandwidth of `order` cascaded first-order filters of time constant
/// `tc`, Hz: `∫₀^∞ (1 + (2π f τ)²)^(−n) df = C(2n−2, n−1) / (4^(n−1) · 4τ)` (1/(4τ) at order 1).
pub fn nebw_hz(order: u32, tc: f64) -> f64 {
    let n = order.max(1) as usize;
    // C(2n−2, n−1) / 4^(n−1) as a running product (no overflow at order 8).
    let mut c = 1.0;
    for k in 1..n {
        c *= (2 * k - 1) as f64 / (2 * k) as f64;
    }
    c / (4.0 * tc)
}

/// The amplitude response of the filter at an offset of `hz` from the demodulation frequency.
pub fn attenuation(order: u32, tc: f64, hz: f64) -> f64 {
    (1.0 + (std::f64::consts::TAU * hz * tc).powi(2)).powf(-(order as f64) / 2.0)
}

/// The step response's settling time of `order` cascaded first-order filters, in time
/// constants: the `x` where `e^(−x) Σ_{k<n} x^k/k!` (what is left of the step) falls to `eps`.
pub fn settle_time(order: u32, eps: f64) -> f64 {
    let left = |x: f64| {
        let (mut term, mut sum) = (1.0, 1.0);
        for k in 1..order.max(1) {
            term *= x / k as f64;
            sum += term;
        }
        (-x).exp() * sum
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    while left(hi) > eps && hi < 1e4 {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if left(mid) > eps {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The filter order and time constant (s) that attenuate a line `nearest` Hz away by
/// [`REJECTION`] and settle fastest (`fixed`: that order), within the profile's time
/// constants. Errors: no order of the profile reaches the rejection within them, in words.
pub fn choose_filter(nearest: f64, p: &Profile, fixed: Option<u32>) -> Result<(u32, f64), String> {
    let (lo, hi) = fixed.map_or(p.filter_orders, |n| (n, n));
    let (tc_min, tc_max) = p.time_constant_s;
    let mut best: Option<(f64, u32, f64)> = None;
    let mut needed = Vec::new();
    for n in lo..=hi {
        let tc = ((REJECTION.powf(2.0 / n as f64) - 1.0).sqrt()
            / (std::f64::consts::TAU * nearest))
            .max(tc_min);
        if !(tc.is_finite() && tc <= tc_max) {
            needed.push(format!("order {n}: τ ≥ {tc:.3e} s"));
            continue;
        }
        let t = settle_time(n, SETTLE_ACCURACY) * tc;
        if best.is_none_or(|b| t < b.0) {
            best = Some((t, n, tc));
        }
    }
    best.map(|(_, n, tc)| (n, tc)).ok_or_else(|| {
        format!(
            "lines {nearest:.4e} Hz apart need a filter that {} cannot set ({}; its longest time constant is {tc_max} s): space the tones wider or use a higher filter order",
            p.label,
            needed.join(", ")
        )
    })
}

/// The longest amplitude ring-down `Q/(π f)` (s) of the modes `m` drives.
fn ring_down_s(m: &PlanMeasurement, num: &NumericModel) -> f64 {
    num.mode_names
        .iter()
        .enumerate()
        .filter(|(_, name)| {
            m.force
                .get(*name)
                .is_some_and(|f| f.iter().any(|&x| x != 0.0))
        })
        .map(|(n, _)| num.q_factor[n] / (std::f64::consts::PI * num.f_hz[n]))
        .fold(0.0, f64::max)
}

/// Rounds up to 3 significant digits.
fn round_up3(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let e = 10f64.powi(x.log10().floor() as i32 - 2);
    (x / e - 1e-9).ceil() * e
}

/// The settings of [`lockin_plan`] in words, one line per level, for the printed plan.
pub fn lockin_lines(i: &PlanInstrument) -> Vec<String> {
    let mut out = vec![format!(
        "instrument {}: tones on one output sum to at most {} V; each demodulator's filter rejects the nearest other line by {:.0} dB; settled to {} %",
        i.profile,
        i.max_output_v,
        20.0 * i.rejection.log10(),
        100.0 * (1.0 - i.settle_accuracy)
    )];
    for l in &i.levels {
        let volts: Vec<String> = l.drives_v.iter().map(|v| format!("{v:.4}")).collect();
        let passes = if l.passes > 1 {
            format!(" in {} passes of the same drive", l.passes)
        } else {
            String::new()
        };
        out.push(format!(
            "  {} ×{}: {} V = {:.4} V summed; {} demodulators ({} oscillators){passes}, order {}, τ {:.4e} s (−3 dB {:.4e} Hz, NEBW {:.4e} Hz; nearest line {:.4e} Hz away); settle {:.4e} s, record {:.4e} s: {} samples at {} Sa/s",
            l.measurement,
            l.level,
            volts.join(" + "),
            l.output_v,
            l.demodulators,
            l.oscillators,
            l.filter_order,
            l.time_constant_s,
            l.bandwidth_3db_hz,
            l.nebw_hz,
            l.nearest_hz,
            l.settle_s,
            l.record_s,
            l.samples,
            l.sample_rate_hz
        ));
    }
    out
}

/// The lock-in time the plan takes, s: per level, settling and recording in every pass.
pub fn lockin_time_s(i: &PlanInstrument) -> f64 {
    i.levels
        .iter()
        .map(|l| l.passes as f64 * (l.settle_s + l.record_s))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bandwidth_factors_are_zurich_instruments_table() {
        // zhinst-utils bwtc_scaling_factor, orders 1..8.
        let table = [1.0, 0.6436, 0.5098, 0.4350, 0.3856, 0.3499, 0.3226, 0.3008];
        for (k, want) in table.iter().enumerate() {
            let got = bandwidth_3db_hz(k as u32 + 1, 1.0) * std::f64::consts::TAU;
            assert!(
                (got - want).abs() < 5e-5,
                "order {}: {got} vs {want}",
                k + 1
            );
            // The −3 dB point is where the amplitude response is 1/√2.
            let a = attenuation(k as u32 + 1, 1.0, bandwidth_3db_hz(k as u32 + 1, 1.0));
            assert!((a - 0.5f64.sqrt()).abs() < 1e-12, "{a}");
        }
    }

    #[test]
    fn the_noise_bandwidth_is_the_integral_of_the_power_response() {
        for n in 1..=8u32 {
            // Trapezoid over x = 2π f τ in [0, 2000] (the tail beyond is < 1e-6 of it).
            let steps = 400_000;
            let dx = 2000.0 / steps as f64;
            let mut sum = 0.0;
            for k in 0..=steps {
                let x = k as f64 * dx;
                let w = if k == 0 || k == steps { 0.5 } else { 1.0 };
                sum += w * (1.0 + x * x).powi(-(n as i32));
            }
            let brute = sum * dx / std::f64::consts::TAU;
            let closed = nebw_hz(n, 1.0);
            assert!(
                (brute / closed - 1.0).abs() < 1e-3,
                "order {n}: {brute} vs {closed}"
            );
        }
        assert_eq!(nebw_hz(1, 0.5), 0.5);
    }

    #[test]
    fn settling_solves_the_erlang_tail() {
        assert!((settle_time(1, 1e-3) - 1000f64.ln()).abs() < 1e-9);
        // Order 2: e^{-x}(1 + x) = 1e-3.
        let x = settle_time(2, 1e-3);
        assert!(((-x).exp() * (1.0 + x) - 1e-3).abs() < 1e-12, "{x}");
        assert!((x - 9.233).abs() < 1e-3, "{x}");
    }

    #[test]
    fn the_filter_rejects_the_nearest_line_by_the_stated_factor() {
        let p = LockIn::MfliMf.profile().expect("profile");
        let (n, tc) = choose_filter(0.088, &p, None).expect("a filter");
        let a = attenuation(n, tc, 0.088);
        assert!((a * REJECTION - 1.0).abs() < 1e-9, "order {n}, τ {tc}: {a}");
        // The fastest to settle of every order that reaches it.
        let t = settle_time(n, SETTLE_ACCURACY) * tc;
        let mut possible = 0;
        for k in 1..=8 {
            // Order 1 would need τ = 1808 s, beyond the MFLI's 83 s.
            if let Ok((_, tk)) = choose_filter(0.088, &p, Some(k)) {
                possible += 1;
                assert!(
                    settle_time(k, SETTLE_ACCURACY) * tk >= t * (1.0 - 1e-12),
                    "{k}"
                );
            }
        }
        assert_eq!(possible, 7);
        // Lines 1 µHz apart need τ beyond the MFLI's 83 s at every order.
        let e = choose_filter(1e-6, &p, None).expect_err("impossible");
        assert!(e.contains("83 s") && e.contains("order 8"), "{e}");
    }

    #[test]
    fn names_round_trip_and_unknown_names_are_listed() {
        for l in LOCKINS {
            assert_eq!(l.name().parse::<LockIn>(), Ok(l));
            assert_eq!(l.to_string(), l.name());
        }
        let e = "sr830".parse::<LockIn>().expect_err("unknown");
        assert!(e.contains("mfli-mf") && e.contains("sr830"), "{e}");
        assert_eq!(LockIn::default(), LockIn::Generic);
    }

    #[test]
    fn harmonics_ride_on_their_tone_and_other_lines_take_oscillators() {
        let p = LockIn::MfliMf.profile().expect("profile");
        // A pair and its two third-order intermodulation lines: 4 oscillators, one pass.
        let tones = [42.747, 42.835];
        let lines = [42.659, 42.747, 42.835, 42.923];
        assert_eq!(oscillators_and_passes(&tones, &lines, &p), Some((4, 1)));
        // A tone and its 2nd and 3rd harmonics: one oscillator.
        assert_eq!(
            oscillators_and_passes(&[100.0], &[100.0, 200.0, 300.0], &p),
            Some((1, 1))
        );
        // Eight lines on four demodulators: two passes.
        let many: Vec<f64> = (0..8).map(|k| 100.0 * (k + 1) as f64).collect();
        assert_eq!(oscillators_and_passes(&[100.0], &many, &p), Some((1, 2)));
        // The MFLI's one oscillator drives the tone: an intermodulation line has none.
        let one = LockIn::Mfli.profile().expect("profile");
        assert_eq!(
            oscillators_and_passes(&[100.0], &[100.0, 150.0], &one),
            None
        );
    }
}

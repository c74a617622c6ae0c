//! `[instrument]` of a plan: what a lock-in needs to run it, written by `harmonid plan
//! --instrument` (the profile, the output's summed cap, and per level of every measurement the
//! drive volts, the demodulator filter, the settling time and the samples). Metadata: the
//! simulation does not read it; [`PlanInstrument::check`] keeps what is written finite.

use serde::{Deserialize, Serialize};

/// `[instrument]`: the lock-in a plan was designed for and its settings per level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanInstrument {
    /// The instrument profile (`mfli-mf`, `uhfli`, ...; `harmonid plan --instrument`).
    pub profile: String,
    /// The largest summed amplitude of the tones on the one drive output, V (peak): `Σ_k |V_k|`
    /// of every level is at most this.
    pub max_output_v: f64,
    /// Each demodulator's filter attenuates every other line (and the `2f` mixing product) by
    /// at least this factor in amplitude (1000 = 60 dB).
    pub rejection: f64,
    /// The filter and the resonator have settled when their step responses are within this
    /// fraction of the final value (1e-3 = 99.9 %).
    pub settle_accuracy: f64,
    /// One entry per level of every measurement, in the plan's order.
    #[serde(default, rename = "level", skip_serializing_if = "Vec::is_empty")]
    pub levels: Vec<LockinLevel>,
}

/// `[[instrument.level]]`: one level of one measurement as the lock-in runs it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LockinLevel {
    /// The measurement's name.
    pub measurement: String,
    /// The level's fraction of the measurement's drive (its `levels` entry; 1 without a
    /// ladder).
    pub level: f64,
    /// The drive amplitude of each tone at this level, V (peak), in `drives_hz` order.
    pub drives_v: Vec<f64>,
    /// `Σ_k |drives_v[k]|`, V: what the output must deliver at once.
    pub output_v: f64,
    /// Oscillators used: one per drive tone, one per measured line that is not an integer
    /// harmonic of a tone.
    pub oscillators: usize,
    /// Demodulators used in one pass: one per line it reads.
    pub demodulators: usize,
    /// Runs of the same drive (each settling and recording) needed to read every measured
    /// line, when the lines are more than the demodulators or oscillators (1: all at once).
    pub passes: usize,
    /// The nearest other frequency a demodulator sees in its baseband, Hz: the smallest
    /// spacing between measured lines, or twice the lowest line (the mixing product).
    pub nearest_hz: f64,
    /// The low-pass filter's order (poles; 6 dB/octave each).
    pub filter_order: u32,
    /// The filter's time constant, s.
    pub time_constant_s: f64,
    /// Its −3 dB bandwidth, Hz: `sqrt(2^(1/n) − 1) / (2π τ)`.
    pub bandwidth_3db_hz: f64,
    /// Its noise-equivalent bandwidth, Hz: `C(2n−2, n−1) / (4^(n−1) · 4τ)`.
    pub nebw_hz: f64,
    /// Wait this long after setting the level before recording, s: the filter's step response
    /// to `settle_accuracy` plus the slowest driven mode's ring-down `Q/(π f)` to it.
    pub settle_s: f64,
    /// Record this long after settling (in each pass), s: `shots / (2 NEBW)`, the time over which the
    /// filtered output holds `shots` independent samples.
    pub record_s: f64,
    /// A demodulator sample rate that resolves the filter (10 × its −3 dB bandwidth), Sa/s.
    pub sample_rate_hz: f64,
    /// Samples to record at that rate: `ceil(rate × record_s)`.
    pub samples: u64,
}

impl PlanInstrument {
    /// `Some(what)` when a number is not finite and positive (the plan would carry a NaN).
    pub fn check(&self) -> Option<String> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !pos(self.max_output_v) || !pos(self.rejection) || !pos(self.settle_accuracy) {
            return Some(format!(
                "max_output_v {}, rejection {}, settle_accuracy {}: expected finite positive numbers",
                self.max_output_v, self.rejection, self.settle_accuracy
            ));
        }
        for l in &self.levels {
            let numbers = [
                l.level,
                l.output_v,
                l.nearest_hz,
                l.time_constant_s,
                l.bandwidth_3db_hz,
                l.nebw_hz,
                l.settle_s,
                l.record_s,
                l.sample_rate_hz,
            ];
            if !numbers.iter().all(|&x| pos(x)) || !l.drives_v.iter().all(|v| v.is_finite()) {
                return Some(format!(
                    "level {} of `{}`: expected finite positive settings",
                    l.level, l.measurement
                ));
            }
        }
        None
    }
}

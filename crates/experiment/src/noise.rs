//! Noise of a lock-in measurement, three ways to state it, one number the simulation uses: the
//! standard deviation σ of the Gaussian error on the real and on the imaginary part of every
//! complex amplitude (peak convention, `x(t) = Re[X e^{i2πft}]`).
//!
//! - **Per quadrature**: σ itself.
//! - **Amplitude spectral density** `S` (m/√Hz, one-sided, white near the measured lines) seen
//!   through a lock-in of equivalent noise bandwidth `B` (Hz, of its low-pass filter): each
//!   quadrature of the RMS-scaled output carries `S·√B`, and the peak amplitude `X` is √2 times
//!   the RMS one, so `σ = S·√(2B)`. A lock-in that averages over a window of `T` seconds (a boxcar
//!   filter, as `harmonid` demodulates) has `B = 1/(2T)`, so `σ = S/√T`.
//! - **RMS of the time signal** `r` (white, sampled at `f_s`, `N = f_s·T` samples per window):
//!   `σ = r·√(2/N)` ([`harmonid_sim::lockin_noise_sigma`]). Its one-sided density is
//!   `S = r·√(2/f_s)`, which gives the same σ through the formula above: the three agree.

/// A noise level as a user states it; [`NoiseLevel::sigma_m`] converts it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseLevel {
    /// σ per quadrature of the lock-in amplitudes, m.
    SigmaPerQuadrature(f64),
    /// One-sided amplitude spectral density, m/√Hz.
    Asd(f64),
    /// RMS of white noise on the time signal, m.
    TimeRms(f64),
}

impl NoiseLevel {
    /// σ per quadrature (m) for a lock-in of equivalent noise bandwidth `enbw_hz` whose window
    /// holds `n_samples` samples.
    pub fn sigma_m(&self, enbw_hz: f64, n_samples: f64) -> f64 {
        match *self {
            NoiseLevel::SigmaPerQuadrature(s) => s,
            NoiseLevel::Asd(s) => sigma_from_asd(s, enbw_hz),
            NoiseLevel::TimeRms(r) => sigma_from_time_rms(r, n_samples),
        }
    }

    /// The number as given (m, m/√Hz or m).
    pub fn value(&self) -> f64 {
        match *self {
            NoiseLevel::SigmaPerQuadrature(x) | NoiseLevel::Asd(x) | NoiseLevel::TimeRms(x) => x,
        }
    }
}

/// σ per quadrature (m) of a lock-in amplitude from a one-sided amplitude spectral density
/// `asd` (m/√Hz) and the lock-in's equivalent noise bandwidth `enbw_hz`: `asd·√(2·enbw)`.
pub fn sigma_from_asd(asd: f64, enbw_hz: f64) -> f64 {
    asd * (2.0 * enbw_hz).sqrt()
}

/// σ per quadrature (m) from white noise of RMS `rms` (m) on `n_samples` samples of one lock-in
/// window: `rms·√(2/N)`.
pub fn sigma_from_time_rms(rms: f64, n_samples: f64) -> f64 {
    harmonid_sim::lockin_noise_sigma(rms, n_samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_ways_agree() {
        // 0.1 nm RMS sampled at 1.66 MHz, 0.2 s window (boxcar: ENBW = 1/(2T) = 2.5 Hz).
        let (r, fs, t): (f64, f64, f64) = (1e-10, 1.66e6, 0.2);
        let n = fs * t;
        let asd = r * (2.0 / fs).sqrt();
        let a = sigma_from_time_rms(r, n);
        let b = sigma_from_asd(asd, 1.0 / (2.0 * t));
        assert!((a - b).abs() <= 1e-15 * a, "{a} vs {b}");
        assert!((a - 1e-10 * (2.0 / n).sqrt()).abs() <= 1e-15 * a);
        assert_eq!(NoiseLevel::Asd(asd).sigma_m(2.5, n), b);
        assert_eq!(NoiseLevel::SigmaPerQuadrature(3e-13).sigma_m(2.5, n), 3e-13);
    }
}

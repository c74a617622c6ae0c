//! Drive tones and the forces they exert on each mode.

use crate::SimError;
use num_complex::Complex64;

/// A multi-tone drive: tone `d` at `tones_hz[d]` exerts on mode `n` the force
/// `Re[force[n][d] · e^{i 2π f_d t}] = |F| cos(2π f_d t + arg F)` (N/kg, mass-normalised), with
/// `t` the time base shared by the drive and every measured amplitude (`DATA_FORMAT.md`).
/// Pump tones, if any, make the model's `pump` signal (parametric pumping).
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// Drive frequencies, Hz (positive, distinct).
    pub tones_hz: Vec<f64>,
    /// `force[n][d]`: complex force amplitude of tone `d` on mode `n`, N/kg.
    pub force: Vec<Vec<Complex64>>,
    /// The pump tones: the model's `pump` signal is `Σ_k Re[P_k e^{i2πf_k t}]` (empty: no
    /// pump, and a model with pump terms is refused).
    pub pumps: Vec<PumpTone>,
}

/// One tone of the pump signal: `Re[amplitude · e^{i 2π hz t}]`, in the unit of the model's
/// pump coefficients (a `lambda` in `lambda*pump*q1` is N/kg/m per that unit), on the drive's
/// time base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PumpTone {
    /// Pump frequency, Hz (positive).
    pub hz: f64,
    /// Complex pump amplitude `level · e^{i phase}`.
    pub amplitude: Complex64,
}

impl From<(f64, Complex64)> for PumpTone {
    /// `(Hz, level · e^{i phase})`, as a dataset's measurement lists its pump tones.
    fn from((hz, amplitude): (f64, Complex64)) -> Self {
        Self { hz, amplitude }
    }
}

impl Excitation {
    /// A drive without a pump.
    pub fn new(tones_hz: Vec<f64>, force: Vec<Vec<Complex64>>) -> Self {
        Self {
            tones_hz,
            force,
            pumps: Vec::new(),
        }
    }

    /// The same tones and pump on the modes `modes` alone (indices into this drive's modes;
    /// out-of-range ones get no force): the drive of [`crate::NumericModel::restricted`].
    pub fn restricted(&self, modes: &[usize]) -> Excitation {
        let none = vec![Complex64::new(0.0, 0.0); self.tones_hz.len()];
        Excitation {
            tones_hz: self.tones_hz.clone(),
            force: modes
                .iter()
                .map(|&m| self.force.get(m).unwrap_or(&none).clone())
                .collect(),
            pumps: self.pumps.clone(),
        }
    }

    /// The pump frequencies, Hz.
    pub fn pump_hz(&self) -> Vec<f64> {
        self.pumps.iter().map(|p| p.hz).collect()
    }

    /// The generators of the response's combination frequencies: the drive tones, then half
    /// of each pump frequency. A pump at `f_p` mixes a line `f` to `f_p − f`, and its
    /// instability grows at `f_p / 2` (parametric resonance), so the lattice is built on
    /// `f_p / 2`; `f_p` itself is the even combination `2 · f_p/2`, which keeps the parity of
    /// an odd model's lines.
    pub fn generators_hz(&self) -> Vec<f64> {
        self.tones_hz
            .iter()
            .copied()
            .chain(self.pumps.iter().map(|p| 0.5 * p.hz))
            .collect()
    }
}

impl Excitation {
    /// Checks the shapes against `n_modes` and the values (finite, positive distinct tones).
    pub fn check(&self, n_modes: usize) -> Result<(), SimError> {
        if self.tones_hz.is_empty() {
            return Err(SimError::NoTone);
        }
        if self.force.len() != n_modes || self.force.iter().any(|f| f.len() != self.tones_hz.len())
        {
            return Err(SimError::Length {
                what: "the drive's forces",
                found: self.force.iter().map(Vec::len).sum(),
                expected: n_modes * self.tones_hz.len(),
                per: format!("{n_modes} modes × {} tones", self.tones_hz.len()),
            });
        }
        for (i, &f) in self.tones_hz.iter().enumerate() {
            if !(f.is_finite() && f > 0.0) {
                return Err(SimError::BadValue {
                    what: format!("drive tone {i}"),
                    value: f,
                    why: "tones must be finite positive frequencies in Hz".into(),
                });
            }
            if self.tones_hz[..i]
                .iter()
                .any(|&g| (g - f).abs() <= 1e-9 * f)
            {
                return Err(SimError::BadValue {
                    what: format!("drive tone {i}"),
                    value: f,
                    why: "two tones share this frequency; give one tone with the summed force"
                        .into(),
                });
            }
        }
        for (i, p) in self.pumps.iter().enumerate() {
            if !(p.hz.is_finite() && p.hz > 0.0) {
                return Err(SimError::BadValue {
                    what: format!("pump tone {i}"),
                    value: p.hz,
                    why: "pump tones must be finite positive frequencies in Hz".into(),
                });
            }
            if !(p.amplitude.re.is_finite() && p.amplitude.im.is_finite()) {
                return Err(SimError::BadValue {
                    what: format!("the level of pump tone {i}"),
                    value: p.amplitude.norm(),
                    why: "pump levels and phases must be finite".into(),
                });
            }
        }
        for row in &self.force {
            for z in row {
                if !(z.re.is_finite() && z.im.is_finite()) {
                    return Err(SimError::BadValue {
                        what: "a drive force".into(),
                        value: f64::NAN,
                        why: "forces must be finite".into(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The same drive with every force scaled by `s` (drive ramps).
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            tones_hz: self.tones_hz.clone(),
            force: self
                .force
                .iter()
                .map(|r| r.iter().map(|z| z * s).collect())
                .collect(),
            pumps: self.pumps.clone(),
        }
    }
}

/// The linear (small-amplitude) response of mode `n` to a force `F` at `f_hz`:
/// `F / (ω_n² − Ω² + i Ω ω_n/Q_n)` with `Ω = 2π f_hz` (DATA_FORMAT convention, peak amplitude).
pub fn linear_response(omega_n: f64, gamma_n: f64, f_hz: f64, force: Complex64) -> Complex64 {
    let w = std::f64::consts::TAU * f_hz;
    force / Complex64::new(omega_n * omega_n - w * w, w * gamma_n)
}

/// The grid spacing `Δ` (Hz) with every frequency an integer multiple of it, found by Euclid's
/// algorithm to `tol_hz`; `None` when the spacing would be below `min_hz`.
pub fn common_grid(freqs_hz: &[f64], tol_hz: f64, min_hz: f64) -> Option<f64> {
    let mut g = 0.0f64;
    for &f in freqs_hz {
        let (mut a, mut b) = (g.max(f), g.min(f));
        while b > tol_hz {
            let r = a % b;
            a = b;
            b = if r > b - tol_hz { 0.0 } else { r };
            if a < min_hz {
                return None;
            }
        }
        g = a;
    }
    if g < min_hz {
        return None;
    }
    // Check every frequency is a near-integer multiple.
    for &f in freqs_hz {
        let k = f / g;
        if (k - k.round()).abs() * g > 10.0 * tol_hz {
            return None;
        }
    }
    Some(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid() {
        let g = common_grid(&[207572.5, 207592.5, 415841.5], 1e-7, 1e-3);
        assert_eq!(g, Some(0.5));
        let g = common_grid(&[207572.5, 207592.5], 1e-7, 1e-3);
        assert_eq!(g, Some(2.5));
        let g = common_grid(&[1000.1, 1000.3], 1e-6, 1e-3).map(|g| (g * 1e6).round() / 1e6);
        assert_eq!(g, Some(0.1));
        assert_eq!(common_grid(&[1.0, std::f64::consts::PI], 1e-9, 1e-3), None);
    }

    #[test]
    fn shape_errors_carry_their_numbers() {
        let z = Complex64::new(1.0, 0.0);
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1000.0, 1001.0],
            force: vec![vec![z, z], vec![z]],
        };
        let e = drive.check(2).expect_err("one force short");
        assert_eq!(
            e,
            SimError::Length {
                what: "the drive's forces",
                found: 3,
                expected: 4,
                per: "2 modes × 2 tones".into(),
            }
        );
        assert_eq!(
            e.to_string(),
            "the drive's forces: 3 given, 4 expected (2 modes × 2 tones)"
        );
        let none = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![],
            force: vec![vec![]],
        };
        assert_eq!(none.check(1), Err(SimError::NoTone));
    }
}

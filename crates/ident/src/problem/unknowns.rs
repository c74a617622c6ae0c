//! The real unknowns of an identification and their readable names.

use super::{ForceModel, Problem};
use harmonid_model::{Linear, Model, ParamKind};
use std::f64::consts::PI;

/// One real unknown of the identification.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Unknown {
    /// `ω_n²` of mode `n`, rad²/s².
    OmegaSq(usize),
    /// `γ_n = ω_n/Q_n` of mode `n`, rad/s.
    Gamma(usize),
    /// Model parameter `p` (SI units of its terms).
    Param(usize),
    /// Real (`quad = 0`) or imaginary (`1`) part of the complex force of drive tone `tone` of
    /// measurement `meas`, on the mode it is attributed to, N/kg.
    Force {
        /// Measurement index.
        meas: usize,
        /// Drive tone index (`drives_hz` order).
        tone: usize,
        /// 0 real, 1 imaginary.
        quad: u8,
    },
    /// Real/imaginary part of the actuator gain of mode `mode` (per measurement `meas`, or for
    /// the whole dataset when `meas` is `None`), N/kg per drive-level unit.
    Gain {
        /// Measurement index, or `None` for a dataset-wide gain.
        meas: Option<usize>,
        /// Mode index.
        mode: usize,
        /// 0 real, 1 imaginary.
        quad: u8,
    },
}

pub(super) fn unknown_index(unknowns: &[Unknown], u: &Unknown) -> Option<usize> {
    unknowns.iter().position(|x| x == u)
}

impl Problem {
    pub(super) fn unknown_label(&self, u: &Unknown) -> String {
        match u {
            Unknown::OmegaSq(n) => format!("omega^2 of {}", self.mode_names[*n]),
            Unknown::Gamma(n) => format!("omega/Q of {}", self.mode_names[*n]),
            Unknown::Param(p) => self.param_names[*p].clone(),
            Unknown::Force { meas, tone, quad } => format!(
                "force of tone {tone} of measurement #{meas} ({})",
                if *quad == 0 { "re" } else { "im" }
            ),
            Unknown::Gain { meas, mode, quad } => format!(
                "gain of {}{} ({})",
                self.mode_names[*mode],
                meas.map(|m| format!(" in measurement #{m}"))
                    .unwrap_or_default(),
                if *quad == 0 { "re" } else { "im" }
            ),
        }
    }

    /// Readable name of unknown `i`.
    pub fn label(&self, i: usize) -> String {
        self.unknown_label(&self.unknowns[i])
    }
    /// Index of an unknown.
    pub fn index_of(&self, u: &Unknown) -> Option<usize> {
        unknown_index(&self.unknowns, u)
    }
}

/// The unknowns with their fixed values (NaN where unknown) and bounds, built in order.
#[derive(Debug, Clone, Default)]
pub(super) struct UnknownTable {
    pub(super) unknowns: Vec<Unknown>,
    pub(super) fixed: Vec<f64>,
    pub(super) bounds: Vec<(Option<f64>, Option<f64>)>,
}

impl UnknownTable {
    fn push(&mut self, u: Unknown, fixed: f64, bounds: (Option<f64>, Option<f64>)) {
        self.unknowns.push(u);
        self.fixed.push(fixed);
        self.bounds.push(bounds);
    }

    /// `ω²` and `γ` of every mode (bounded below by 0), then the model's parameters. Returns
    /// also the modes whose Q is fixed while f is identified (γ = ω/Q follows the fitted ω).
    pub(super) fn linear_and_params(model: &Model, nominal_hz: &[f64]) -> (Self, Vec<Option<f64>>) {
        let mut t = UnknownTable::default();
        let mut fixed_q = vec![None; model.modes.len()];
        for (n, m) in model.modes.iter().enumerate() {
            let w2 = match m.f_hz {
                Linear::Fixed(f) => (2.0 * PI * f).powi(2),
                Linear::Unknown => f64::NAN,
            };
            t.push(Unknown::OmegaSq(n), w2, (Some(0.0), None));
            let g = match (m.q_factor, m.f_hz) {
                (Linear::Fixed(q), Linear::Fixed(f)) => 2.0 * PI * f / q,
                (Linear::Fixed(q), Linear::Unknown) => {
                    fixed_q[n] = Some(q);
                    2.0 * PI * nominal_hz[n] / q
                }
                _ => f64::NAN,
            };
            t.push(Unknown::Gamma(n), g, (Some(0.0), None));
        }
        for (p, par) in model.params.iter().enumerate() {
            let v = match par.kind {
                ParamKind::Fixed(v) => v,
                ParamKind::Unknown => f64::NAN,
            };
            t.push(Unknown::Param(p), v, (par.bounds.lower, par.bounds.upper));
        }
        (t, fixed_q)
    }

    /// The force unknowns of measurement `mi`: two per drive tone (free forces), or two per
    /// driven mode's gain (`drive_modes`: the mode of each drive tone), shared across
    /// measurements for [`ForceModel::GainPerMode`].
    pub(super) fn add_forces(&mut self, force_model: ForceModel, mi: usize, drive_modes: &[usize]) {
        match force_model {
            ForceModel::Free | ForceModel::Auto => {
                for tone in 0..drive_modes.len() {
                    for quad in 0..2 {
                        self.push(
                            Unknown::Force {
                                meas: mi,
                                tone,
                                quad,
                            },
                            f64::NAN,
                            (None, None),
                        );
                    }
                }
            }
            ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                let per_meas = force_model == ForceModel::GainPerMeasurement;
                for &mode in drive_modes {
                    for quad in 0..2 {
                        let u = Unknown::Gain {
                            meas: per_meas.then_some(mi),
                            mode,
                            quad,
                        };
                        if unknown_index(&self.unknowns, &u).is_none() {
                            self.push(u, f64::NAN, (None, None));
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use super::super::{ForceModel, Problem, Settings};
    use super::Unknown;

    fn setup(force_model: ForceModel) -> Problem {
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let s = Settings {
            force_model,
            ..Settings::default()
        };
        Problem::new(&testkit::model(), &ds, &s).expect("problem")
    }

    #[test]
    fn unknowns_come_in_a_fixed_order() {
        let p = setup(ForceModel::GainPerMeasurement);
        assert_eq!(
            &p.unknowns[..6],
            &[
                Unknown::OmegaSq(0),
                Unknown::Gamma(0),
                Unknown::OmegaSq(1),
                Unknown::Gamma(1),
                Unknown::Param(0),
                Unknown::Param(1)
            ]
        );
        // Gains: a in single_a, b in single_b, a and b in pair_ab; two quadratures each.
        assert_eq!(p.unknowns.len(), 6 + 2 * 4);
        assert!(p.fixed.iter().all(|v| v.is_nan()));
        assert_eq!(p.bounds[0], (Some(0.0), None));
        assert_eq!(p.label(4), "beta");
        assert_eq!(p.label(1), "omega/Q of a");
        assert_eq!(p.index_of(&Unknown::Param(1)), Some(5));
    }

    #[test]
    fn gains_per_mode_are_shared_and_free_forces_are_per_tone() {
        let p = setup(ForceModel::GainPerMode);
        assert_eq!(p.unknowns.len(), 6 + 4);
        assert_eq!(p.label(6), "gain of a (re)");
        let p = setup(ForceModel::Free);
        assert_eq!(p.unknowns.len(), 6 + 2 * (2 + 2 + 3));
    }
}

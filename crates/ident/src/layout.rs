//! The layout of an identification's unknowns, read by both fits: the equation-error fit
//! ([`crate::Problem`]) and the output-error forward model ([`crate::ForwardModel`]) index one
//! vector `θ` the same way, so an estimate of one is a start of the other without mapping.
//!
//! Order: per mode `ω_n²` (rad²/s²) and `γ_n = ω_n/Q_n` (rad/s), every model parameter (SI
//! units of its terms), then per measurement its force unknowns (N/kg, or N/kg per drive-level
//! unit for actuator gains). A value the model fixes is `Some(v)`; `None` is to be identified.
//! A mode whose `Q` is fixed while its `f` is identified has `γ` fixed at `2π f_nominal/Q`
//! in the table, and both fits derive it from the fitted `ω²` (`γ = √ω²/Q`).

use crate::background_terms::BackgroundTerm;
use crate::settings::ForceModel;
use harmonid_model::{Linear, Model, ParamKind};
use std::f64::consts::TAU;

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
    /// Real/imaginary part of a measurement background term of mode `mode`
    /// ([`crate::background`]), shared by every measurement: the data's unit per drive-level
    /// unit (`Drive`), per drive-level unit per Hz (`Slope`), or the data's unit (`Constant`).
    Background {
        /// Mode index (of the measured lines attributed to it).
        mode: usize,
        /// Which term.
        term: BackgroundTerm,
        /// 0 real, 1 imaginary.
        quad: u8,
    },
}

/// A reported quantity: what a result, a bound, a jackknife or a warning is about. Its
/// spelling in files ([`Quantity::key`]: `f_hz:q1`, `Q:q1`, the parameter's name) is made
/// only where a column or a JSON key is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Quantity {
    /// Linear resonance frequency `f_n` of mode `n`, Hz.
    Frequency(usize),
    /// Quality factor `Q_n` of mode `n`.
    Q(usize),
    /// Model parameter `p`.
    Param(usize),
    /// Real/imaginary part of a background term of a mode ([`Unknown::Background`]).
    Background {
        /// Mode index.
        mode: usize,
        /// Which term.
        term: BackgroundTerm,
        /// 0 real, 1 imaginary.
        quad: u8,
    },
}

impl Quantity {
    /// The quantity an unknown reports as (`ω²` → f, `γ` → Q); forces and gains are not
    /// reported quantities.
    pub fn of(u: &Unknown) -> Option<Quantity> {
        match *u {
            Unknown::OmegaSq(n) => Some(Quantity::Frequency(n)),
            Unknown::Gamma(n) => Some(Quantity::Q(n)),
            Unknown::Param(p) => Some(Quantity::Param(p)),
            Unknown::Background { mode, term, quad } => {
                Some(Quantity::Background { mode, term, quad })
            }
            Unknown::Force { .. } | Unknown::Gain { .. } => None,
        }
    }

    /// The key of the per-shot CSV's column and of the bounds: `f_hz:<mode>`, `Q:<mode>`, or
    /// the parameter's name.
    pub fn key(self, mode_names: &[String], param_names: &[String]) -> String {
        match self {
            Quantity::Frequency(n) => format!("f_hz:{}", mode_names[n]),
            Quantity::Q(n) => format!("Q:{}", mode_names[n]),
            Quantity::Param(p) => param_names[p].clone(),
            Quantity::Background { mode, term, quad } => format!(
                "background_{}:{}:{}",
                term.name(),
                mode_names[mode],
                if quad == 0 { "re" } else { "im" }
            ),
        }
    }
}

/// The unknowns of an identification with their fixed values and bounds, the nominal
/// resonances that attribute tones to modes, and the force model in use (`Auto` resolved).
#[derive(Debug, Clone, PartialEq)]
pub struct UnknownTable {
    unknowns: Vec<Unknown>,
    fixed: Vec<Option<f64>>,
    bounds: Vec<(Option<f64>, Option<f64>)>,
    /// Per mode, its fixed `Q` when `f` is identified (`γ` follows the fitted `ω`).
    fixed_q: Vec<Option<f64>>,
    nominal_hz: Vec<f64>,
    force_model: ForceModel,
    /// Per measurement, the mode each drive tone pushes.
    tone_modes: Vec<Vec<usize>>,
}

impl UnknownTable {
    /// The table of `model`'s unknowns for measurements whose drive tones push `tone_modes`
    /// (per measurement, per tone), with nominal resonances `nominal_hz` (Hz, per mode) and
    /// a resolved force model (`Auto` is taken as free forces).
    pub fn new(
        model: &Model,
        nominal_hz: Vec<f64>,
        force_model: ForceModel,
        tone_modes: Vec<Vec<usize>>,
    ) -> Self {
        let mut t = UnknownTable {
            unknowns: Vec::new(),
            fixed: Vec::new(),
            bounds: Vec::new(),
            fixed_q: vec![None; model.modes.len()],
            nominal_hz,
            force_model,
            tone_modes: Vec::new(),
        };
        for (n, m) in model.modes.iter().enumerate() {
            let w2 = match m.f_hz {
                Linear::Fixed(f) => Some((TAU * f).powi(2)),
                Linear::Unknown => None,
            };
            t.push(Unknown::OmegaSq(n), w2, (Some(0.0), None));
            let g = match (m.q_factor, m.f_hz) {
                (Linear::Fixed(q), Linear::Fixed(f)) => Some(TAU * f / q),
                (Linear::Fixed(q), Linear::Unknown) => {
                    t.fixed_q[n] = Some(q);
                    Some(TAU * t.nominal_hz[n] / q)
                }
                _ => None,
            };
            t.push(Unknown::Gamma(n), g, (Some(0.0), None));
        }
        for (p, par) in model.params.iter().enumerate() {
            let v = match par.kind {
                ParamKind::Fixed(v) => Some(v),
                ParamKind::Unknown => None,
            };
            t.push(Unknown::Param(p), v, (par.bounds.lower, par.bounds.upper));
        }
        for (mi, modes) in tone_modes.iter().enumerate() {
            t.add_forces(mi, modes);
        }
        t.tone_modes = tone_modes;
        t
    }

    fn push(&mut self, u: Unknown, fixed: Option<f64>, bounds: (Option<f64>, Option<f64>)) {
        self.unknowns.push(u);
        self.fixed.push(fixed);
        self.bounds.push(bounds);
    }

    /// The force unknowns of measurement `mi`: two per drive tone (free forces), or two per
    /// driven mode's gain, shared across measurements for [`ForceModel::GainPerMode`].
    fn add_forces(&mut self, mi: usize, tone_modes: &[usize]) {
        match self.force_model {
            ForceModel::Free | ForceModel::Auto => {
                for tone in 0..tone_modes.len() {
                    for quad in 0..2 {
                        self.push(
                            Unknown::Force {
                                meas: mi,
                                tone,
                                quad,
                            },
                            None,
                            (None, None),
                        );
                    }
                }
            }
            ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                let per_meas = self.force_model == ForceModel::GainPerMeasurement;
                for &mode in tone_modes {
                    for quad in 0..2 {
                        let u = Unknown::Gain {
                            meas: per_meas.then_some(mi),
                            mode,
                            quad,
                        };
                        if self.index_of(&u).is_none() {
                            self.push(u, None, (None, None));
                        }
                    }
                }
            }
        }
    }

    /// This table with the background unknowns of `terms` appended (real then imaginary
    /// part of each term, for each of `modes` in turn): unbounded, after every other unknown,
    /// so the indices of the others do not move; free, or fixed at `fixed(mode, term, quad)`
    /// when it gives a value.
    pub(crate) fn with_background(
        &self,
        terms: &[BackgroundTerm],
        modes: &[usize],
        fixed: &dyn Fn(usize, BackgroundTerm, u8) -> Option<f64>,
    ) -> Self {
        let mut t = self.clone();
        for &mode in modes {
            for &term in terms {
                for quad in 0..2 {
                    let u = Unknown::Background { mode, term, quad };
                    t.push(u, fixed(mode, term, quad), (None, None));
                }
            }
        }
        t
    }

    /// The unknowns, in the order of `θ`.
    pub fn unknowns(&self) -> &[Unknown] {
        &self.unknowns
    }

    /// Number of unknowns (fixed ones included).
    pub fn len(&self) -> usize {
        self.unknowns.len()
    }

    /// Whether there is no unknown at all.
    pub fn is_empty(&self) -> bool {
        self.unknowns.is_empty()
    }

    /// Values the model fixes (`None`: to be identified).
    pub fn fixed(&self) -> &[Option<f64>] {
        &self.fixed
    }

    /// Whether unknown `k` is to be identified (not fixed by the model).
    pub fn is_free(&self, k: usize) -> bool {
        self.fixed[k].is_none()
    }

    /// Indices of the unknowns not fixed by the model.
    pub fn free(&self) -> Vec<usize> {
        (0..self.len()).filter(|&k| self.is_free(k)).collect()
    }

    /// Lower/upper bounds per unknown.
    pub fn bounds(&self) -> &[(Option<f64>, Option<f64>)] {
        &self.bounds
    }

    /// Index of an unknown.
    pub fn index_of(&self, u: &Unknown) -> Option<usize> {
        self.unknowns.iter().position(|x| x == u)
    }

    /// The fixed `Q` of mode `n` when its `f` is identified (its `γ` is `√ω²/Q`).
    pub fn fixed_q(&self, n: usize) -> Option<f64> {
        self.fixed_q[n]
    }

    /// Nominal resonance per mode, Hz.
    pub fn nominal_hz(&self) -> &[f64] {
        &self.nominal_hz
    }

    /// The force model (`Auto` resolved).
    pub fn force_model(&self) -> ForceModel {
        self.force_model
    }

    /// The mode each drive tone of measurement `mi` pushes.
    pub fn tone_modes(&self, mi: usize) -> &[usize] {
        &self.tone_modes[mi]
    }

    /// The output-error start from an equation-error estimate `linear` (same layout): fixed
    /// values as the model gives them, estimates where finite, and where the linear fit left
    /// an unknown undetermined (NaN) the nominal resonance (`ω²`), a Q of 1000 (`γ`), or 0
    /// (parameters, forces).
    pub fn start_from(&self, linear: &[f64]) -> Vec<f64> {
        self.unknowns
            .iter()
            .enumerate()
            .map(|(k, u)| {
                if let Some(v) = self.fixed[k] {
                    return v;
                }
                let v = linear[k];
                if v.is_finite() {
                    return v;
                }
                match *u {
                    Unknown::OmegaSq(n) => (TAU * self.nominal_hz[n]).powi(2),
                    Unknown::Gamma(n) => TAU * self.nominal_hz[n] / 1e3,
                    _ => 0.0,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(src: &str) -> Model {
        harmonid_model::parse_str(src, "test.hb").expect("model")
    }

    #[test]
    fn layout_order_fixed_values_and_shared_gains() {
        let m = model(
            "mode a at 100 kHz\nmode b, f = 150 kHz, Q = 1e4\nparam beta >= 0\neom a += beta * a^3\n",
        );
        let tones = vec![vec![0], vec![1, 1], vec![0, 1]];
        let t = UnknownTable::new(&m, vec![1e5, 1.5e5], ForceModel::GainPerMode, tones.clone());
        assert_eq!(
            &t.unknowns()[..5],
            &[
                Unknown::OmegaSq(0),
                Unknown::Gamma(0),
                Unknown::OmegaSq(1),
                Unknown::Gamma(1),
                Unknown::Param(0)
            ]
        );
        // Gains per mode, shared: a and b, two quadratures each.
        assert_eq!(t.len(), 5 + 4);
        assert_eq!(t.fixed()[0], None);
        assert_eq!(t.fixed()[2], Some((TAU * 1.5e5).powi(2)));
        assert_eq!(t.fixed()[3], Some(TAU * 1.5e5 / 1e4));
        assert_eq!(t.bounds()[4], (Some(0.0), None));
        assert_eq!(t.free(), vec![0, 1, 4, 5, 6, 7, 8]);
        // Free forces: two per tone.
        let t = UnknownTable::new(&m, vec![1e5, 1.5e5], ForceModel::Free, tones);
        assert_eq!(t.len(), 5 + 2 * 5);
        assert_eq!(t.tone_modes(2), &[0, 1]);
    }

    #[test]
    fn fixed_q_follows_the_nominal_and_starts_fill_gaps() {
        let m = model("mode a at 2 kHz, Q = 500\nparam g\neom a += g * a^2\n");
        let t = UnknownTable::new(&m, vec![2e3], ForceModel::Free, vec![vec![0]]);
        assert_eq!(t.fixed_q(0), Some(500.0));
        assert_eq!(t.fixed()[1], Some(TAU * 2e3 / 500.0));
        let start = t.start_from(&[f64::NAN, 7.0, f64::NAN, 1.5, f64::NAN]);
        assert_eq!(
            start,
            vec![(TAU * 2e3).powi(2), TAU * 2e3 / 500.0, 0.0, 1.5, 0.0]
        );
    }

    #[test]
    fn quantity_keys() {
        let modes = vec!["q1".to_string()];
        let params = vec!["beta1".to_string()];
        let key = |q: Quantity| q.key(&modes, &params);
        assert_eq!(key(Quantity::Frequency(0)), "f_hz:q1");
        assert_eq!(key(Quantity::Q(0)), "Q:q1");
        assert_eq!(key(Quantity::Param(0)), "beta1");
        assert_eq!(Quantity::of(&Unknown::Gamma(0)), Some(Quantity::Q(0)));
        let force = Unknown::Force {
            meas: 0,
            tone: 0,
            quad: 1,
        };
        assert_eq!(Quantity::of(&force), None);
    }
}

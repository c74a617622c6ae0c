//! The identification problem: modal conversion, regressor assembly, stages and per-shot fits.
//!
//! For each measurement, each measured frequency `Ω_r` is attributed to one mode `n` (the mode
//! whose nominal resonance is spectrally closest, as in the method's paper) and gives one complex
//! equation (conventions of `DATA_FORMAT.md`: `x(t) = Re[X e^{iΩt}]`, so `ẋ ↔ iΩX`,
//! `ẍ ↔ −Ω²X`):
//!
//! ```text
//! ω_n² q̂_n + γ_n (iΩ_r q̂_n) + Σ_p θ_p Σ_m a_{m,p}^(n) ĝ_m − F̂_n(Ω_r)
//!     = Ω_r² q̂_n − Σ_m a_{m,0}^(n) ĝ_m,           γ_n = ω_n/Q_n,
//! ```
//!
//! where `b_m^(n) = a_{m,0} + Σ_p a_{m,p} θ_p` is the (affine) coefficient of monomial `m` in
//! mode `n`'s equation and `ĝ_m` the exact complex amplitude of `m(q(t))` at `Ω_r`, computed
//! from the measured modal spectra. The unknowns are the model's parameters themselves, so a
//! parameter that a potential puts into several equations is one column shared by all of them:
//! this is the equality constraint of the paper's Eq. S15, satisfied exactly by construction.
//! Values fixed by the model or by an earlier stage are moved to the right-hand side (Eq. S14).
//! Each complex equation gives a real and an imaginary row.
//!
//! **Modal conversion.** With points of mode shapes `φ_p^n`, the modal amplitude of the mode `n`
//! a frequency is attributed to is the least-squares solution over points,
//! `q̂_n = Σ_p φ_p^n x_p / Σ_p (φ_p^n)²` (one point: `x_p / φ_p^n`); the other modes' share at
//! that frequency is neglected, as in the paper. Without points, data are modal amplitudes.
//!
//! **Forces.** Free (the paper's model): every drive tone has an unknown complex force on the
//! mode its frequency is attributed to. Drive levels (default when the manifest gives
//! `drive_levels_v` and `drive_phases_rad`): `F̂ = G_n · V · e^{iφ}` with one unknown complex
//! actuator gain `G_n` per mode and measurement (or per mode for the whole dataset).
//!
//! **Stages.** A measurement's active modes are those with measured frequencies attributed to
//! them. An unknown is visible in a measurement when its terms involve only active modes. Stage
//! `s` holds the measurements with `s` active modes; it fits the unknowns visible there that no
//! earlier stage determined, with everything else fixed. Measurements of one stage that share a
//! free unknown are fitted together. `joint` fits everything in one problem.

use crate::dataset::{Dataset, DatasetError};
use crate::solve::{solve_ls, FitStatus, LsSolution};
use harmonid_model::{Linear, Model, ParamKind};
use harmonid_poly::{rational_to_f64, PowerProduct};
use harmonid_spectral::{monomial_amplitudes, monomial_jacobian, ProductPlan, ProductScratch};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Which force model to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ForceModel {
    /// Drive levels when every measurement gives them, free forces otherwise.
    #[default]
    Auto,
    /// Every tone's force a free complex unknown (the paper's model).
    Free,
    /// `F = G_n V e^{iφ}` with one complex gain per mode and measurement.
    GainPerMeasurement,
    /// `F = G_n V e^{iφ}` with one complex gain per mode for the whole dataset.
    GainPerMode,
}

/// Settings of an identification. `Default` gives the documented defaults.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Force model (default [`ForceModel::Auto`]).
    pub force_model: ForceModel,
    /// Fit every unknown in one problem instead of the sequential stages (default false).
    pub joint: bool,
    /// Nominal resonance frequencies, Hz, that override the dataset's and the model's.
    pub nominal_hz: BTreeMap<String, f64>,
    /// A drive tone is "near" a resonance when `|f − f_nominal| ≤ near_rel · f_nominal`
    /// (default 0.05).
    pub near_rel: f64,
    /// Take the noise of each measured amplitude from the scatter across shots when there are
    /// at least this many shots (default 5; 0: assume equal noise on every amplitude).
    pub min_shots_for_weights: usize,
    /// Relative singular value below which a fit's matrix is considered rank deficient (default
    /// 1e-9): the unknown dominating the weakest direction is reported as not identifiable.
    pub rank_tol: f64,
    /// Generalised least squares (default true): after an unweighted first fit, weight the
    /// equations by the covariance of their errors that noise on the measured amplitudes
    /// causes (linearised, regressor noise included), twice. With at least
    /// `min_shots_for_weights` shots the amplitudes' noise comes from the scatter across shots.
    pub gls: bool,
    /// Number of reweighted fits after the unweighted one (default 1; a second changed the
    /// estimates by far less than their scatter in tests).
    pub gls_iterations: usize,
    /// With at least 20 shots (default true): weight by the sample covariance across shots of
    /// the equation residuals at the median estimate (shrunk 20 % towards its diagonal)
    /// instead of the linearised one. On simulated nanostring data (0.1 nm, 50 shots, four
    /// seeds) it gave 10-25 % smaller per-shot scatter of Q1 and f1 than the linearised one.
    pub sample_covariance: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            force_model: ForceModel::Auto,
            joint: false,
            nominal_hz: BTreeMap::new(),
            near_rel: 0.05,
            min_shots_for_weights: 5,
            rank_tol: 1e-9,
            gls: true,
            gls_iterations: 1,
            sample_covariance: true,
        }
    }
}

/// Errors of the identification (bad model/dataset combinations, detected before fitting).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentError {
    /// The dataset itself is malformed.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// The model has a coefficient that is not affine in the parameters.
    #[error("{0}")]
    NonAffine(#[from] harmonid_model::NonAffineTerm),
    /// No nominal frequency for a mode.
    #[error("mode {mode} has no nominal resonance frequency: give it in the model (`mode {mode} at ... kHz`), in the dataset's [nominal_hz], or on the command line")]
    NoNominal {
        /// Mode name.
        mode: String,
    },
    /// A drive tone sits near no resonance.
    #[error("{file}: measurement \"{measurement}\": drive tone {drive_hz} Hz is near no resonance (nearest: {mode} at {nominal_hz} Hz, {rel:.3} relative away; limit {limit}); check drives_hz and the nominal frequencies")]
    ToneNearNoResonance {
        /// Manifest path.
        file: String,
        /// Measurement name.
        measurement: String,
        /// Drive frequency, Hz.
        drive_hz: f64,
        /// Nearest mode.
        mode: String,
        /// Its nominal frequency, Hz.
        nominal_hz: f64,
        /// Relative distance.
        rel: f64,
        /// The limit ([`Settings::near_rel`]).
        limit: f64,
    },
    /// A measured mode has zero shape at every measured point.
    #[error("{file}: measurement \"{measurement}\": mode {mode} has zero shape at every measured point, so its amplitude cannot be measured; give a point where it moves")]
    ZeroShape {
        /// Manifest path.
        file: String,
        /// Measurement name.
        measurement: String,
        /// Mode.
        mode: String,
    },
    /// Fewer real equations than unknowns in a fit.
    #[error("{file}: {what} has {rows} real equations (2 per measured frequency) for {unknowns} unknowns ({names}); measure more frequencies (sidebands) or fix some parameters")]
    TooFewFrequencies {
        /// Manifest path.
        file: String,
        /// The measurement(s).
        what: String,
        /// Real equations.
        rows: usize,
        /// Unknowns.
        unknowns: usize,
        /// Names of the unknowns.
        names: String,
    },
    /// Unsupported model feature.
    #[error("{0}")]
    Unsupported(String),
    /// Planning products failed.
    #[error("measurement \"{measurement}\": {source}")]
    Spectral {
        /// Measurement name.
        measurement: String,
        /// The error.
        source: harmonid_spectral::SpectralError,
    },
}

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

/// Per measurement: attribution, plan and conversion weights.
#[derive(Debug, Clone)]
struct MeasPrep {
    /// Mode each measured frequency is attributed to.
    mode_of: Vec<usize>,
    /// Active modes (with attributed frequencies), ascending.
    active: Vec<usize>,
    /// Modal conversion weights per frequency: `q̂ = Σ_p w[p] x_p` (local point index).
    weights: Vec<Vec<f64>>,
    /// Frequency index of each drive tone.
    drive_idx: Vec<usize>,
    /// Complex drive `V e^{iφ}` of each tone (if levels are given).
    drive_c: Option<Vec<Complex64>>,
    /// Products plan: input = output = measured frequencies.
    plan: ProductPlan,
}

/// One term of an equation: monomial, constant part of its coefficient, parameter factors.
#[derive(Debug, Clone)]
struct Term {
    monomial: usize,
    konst: f64,
    params: Vec<(usize, f64)>,
}

/// A group of measurements fitted together, with its free unknowns.
#[derive(Debug, Clone)]
pub struct FitGroup {
    /// Stage number (number of active modes; 0 for a joint fit).
    pub stage: usize,
    /// Measurement indices.
    pub measurements: Vec<usize>,
    /// Free unknowns (indices into [`Problem::unknowns`]).
    pub unknowns: Vec<usize>,
}

/// An unknown that could not be determined, and why.
#[derive(Debug, Clone)]
pub struct NotIdentifiable {
    /// Index into [`Problem::unknowns`].
    pub unknown: usize,
    /// Explanation (which measurement would be needed, or which unknowns it is collinear with).
    pub reason: String,
}

/// The identification problem, set up once for a model and a dataset.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Mode names.
    pub mode_names: Vec<String>,
    /// Parameter names.
    pub param_names: Vec<String>,
    /// Nominal frequency of each mode, Hz.
    pub nominal_hz: Vec<f64>,
    /// All real unknowns.
    pub unknowns: Vec<Unknown>,
    /// Values fixed by the model (NaN where unknown).
    pub fixed: Vec<f64>,
    /// Lower/upper bounds per unknown.
    pub bounds: Vec<(Option<f64>, Option<f64>)>,
    /// Fit groups in order.
    pub groups: Vec<FitGroup>,
    /// Unknowns no measurement determines.
    pub not_identifiable: Vec<NotIdentifiable>,
    /// The force model in use.
    pub force_model: ForceModel,
    /// Warnings found while setting up.
    pub warnings: Vec<String>,
    /// Modes whose Q is fixed while f is identified: γ = ω/Q updated from the fitted ω.
    fixed_q: Vec<Option<f64>>,
    monomials: Vec<PowerProduct>,
    eqs: Vec<Vec<Term>>,
    meas: Vec<MeasPrep>,
    manifest_path: String,
}

fn unknown_index(unknowns: &[Unknown], u: &Unknown) -> Option<usize> {
    unknowns.iter().position(|x| x == u)
}

impl Problem {
    /// Sets up the problem: checks the model and the dataset against each other, attributes
    /// frequencies to modes, builds product plans, derives the stages.
    pub fn new(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Problem, IdentError> {
        model.check_identifiable()?;
        let mode_names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
        let names_ref: Vec<&str> = mode_names.iter().map(String::as_str).collect();
        ds.check_modes(&names_ref)?;
        let manifest_path = ds.dir.join("dataset.toml").display().to_string();
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
        // Equation terms.
        let mut monomials: Vec<PowerProduct> = Vec::new();
        let mut eqs = Vec::with_capacity(nm);
        for (n, eq) in model.eom.iter().enumerate() {
            let mut terms = Vec::new();
            for (m, c) in eq.terms() {
                let Some(aff) = c.affine() else {
                    return Err(IdentError::Unsupported(format!(
                        "the coefficient of {} in the equation of {} is not affine in the parameters",
                        model.monomial_name(m),
                        mode_names[n]
                    )));
                };
                if m.degree() < 2 {
                    return Err(IdentError::Unsupported(format!(
                        "the equation of {} has a term {} of degree {} < 2; linear and constant terms beyond ω² are not supported by the identification",
                        mode_names[n],
                        model.monomial_name(m),
                        m.degree()
                    )));
                }
                let idx = match monomials.iter().position(|x| x == m) {
                    Some(i) => i,
                    None => {
                        monomials.push(m.clone());
                        monomials.len() - 1
                    }
                };
                let mut konst = rational_to_f64(&aff.constant);
                let mut params = Vec::new();
                for (p, f) in aff.terms {
                    let f = rational_to_f64(&f);
                    match model.params[p.index()].kind {
                        ParamKind::Fixed(v) => konst += f * v,
                        ParamKind::Unknown => params.push((p.index(), f)),
                    }
                }
                terms.push(Term {
                    monomial: idx,
                    konst,
                    params,
                });
            }
            eqs.push(terms);
        }
        // Force model.
        let all_levels = ds
            .measurements
            .iter()
            .all(|m| m.spec.drive_levels_and_phases().is_some());
        let force_model = match settings.force_model {
            ForceModel::Auto if all_levels => ForceModel::GainPerMeasurement,
            ForceModel::Auto => ForceModel::Free,
            f @ (ForceModel::GainPerMeasurement | ForceModel::GainPerMode) if !all_levels => {
                let missing = ds
                    .measurements
                    .iter()
                    .find(|m| m.spec.drive_levels_and_phases().is_none())
                    .map(|m| m.spec.name.clone())
                    .unwrap_or_default();
                return Err(IdentError::Unsupported(format!(
                    "{manifest_path}: the force model {f:?} needs drive_levels_v and drive_phases_rad in every measurement; \"{missing}\" has none (use the free-force model)"
                )));
            }
            f => f,
        };
        // Unknowns: linear, params.
        let mut unknowns = Vec::new();
        let mut fixed = Vec::new();
        let mut bounds = Vec::new();
        let mut fixed_q = vec![None; nm];
        for (n, m) in model.modes.iter().enumerate() {
            unknowns.push(Unknown::OmegaSq(n));
            match m.f_hz {
                Linear::Fixed(f) => fixed.push((2.0 * PI * f).powi(2)),
                Linear::Unknown => fixed.push(f64::NAN),
            }
            bounds.push((Some(0.0), None));
            unknowns.push(Unknown::Gamma(n));
            match (m.q_factor, m.f_hz) {
                (Linear::Fixed(q), Linear::Fixed(f)) => fixed.push(2.0 * PI * f / q),
                (Linear::Fixed(q), Linear::Unknown) => {
                    fixed_q[n] = Some(q);
                    fixed.push(2.0 * PI * nominal_hz[n] / q);
                }
                _ => fixed.push(f64::NAN),
            }
            bounds.push((Some(0.0), None));
        }
        for (p, par) in model.params.iter().enumerate() {
            unknowns.push(Unknown::Param(p));
            fixed.push(match par.kind {
                ParamKind::Fixed(v) => v,
                ParamKind::Unknown => f64::NAN,
            });
            bounds.push((par.bounds.lower, par.bounds.upper));
        }
        let mut warnings = Vec::new();
        // Measurements.
        let max_deg = model.max_degree() as usize;
        let mut meas = Vec::with_capacity(ds.measurements.len());
        for (mi, m) in ds.measurements.iter().enumerate() {
            let nearest = |f: f64| -> usize {
                (0..nm)
                    .min_by(|&a, &b| {
                        (nominal_hz[a] - f)
                            .abs()
                            .total_cmp(&(nominal_hz[b] - f).abs())
                    })
                    .unwrap_or(0)
            };
            let mode_of: Vec<usize> = m.freqs_hz.iter().map(|&f| nearest(f)).collect();
            let mut active: Vec<usize> = mode_of.clone();
            active.sort_unstable();
            active.dedup();
            let mut drive_idx = Vec::new();
            for &d in &m.spec.drives_hz {
                let n = nearest(d);
                let rel = (d - nominal_hz[n]).abs() / nominal_hz[n];
                if rel > settings.near_rel {
                    return Err(IdentError::ToneNearNoResonance {
                        file: manifest_path.clone(),
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
                        file: manifest_path.clone(),
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
            let plan = ProductPlan::new(&m.freqs_hz, &m.freqs_hz, max_deg).map_err(|source| {
                IdentError::Spectral {
                    measurement: m.spec.name.clone(),
                    source,
                }
            })?;
            // Force unknowns.
            match force_model {
                ForceModel::Free | ForceModel::Auto => {
                    for tone in 0..m.spec.drives_hz.len() {
                        for quad in 0..2 {
                            unknowns.push(Unknown::Force {
                                meas: mi,
                                tone,
                                quad,
                            });
                            fixed.push(f64::NAN);
                            bounds.push((None, None));
                        }
                    }
                }
                ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                    let per_meas = force_model == ForceModel::GainPerMeasurement;
                    for &i in &drive_idx {
                        let mode = mode_of[i];
                        for quad in 0..2 {
                            let u = Unknown::Gain {
                                meas: per_meas.then_some(mi),
                                mode,
                                quad,
                            };
                            if unknown_index(&unknowns, &u).is_none() {
                                unknowns.push(u);
                                fixed.push(f64::NAN);
                                bounds.push((None, None));
                            }
                        }
                    }
                }
            }
            let _ = &mut warnings;
            meas.push(MeasPrep {
                mode_of,
                active,
                weights,
                drive_idx,
                drive_c,
                plan,
            });
        }
        let mut prob = Problem {
            mode_names,
            param_names: model.params.iter().map(|p| p.name.clone()).collect(),
            nominal_hz,
            unknowns,
            fixed,
            bounds,
            groups: Vec::new(),
            not_identifiable: Vec::new(),
            force_model,
            warnings,
            fixed_q,
            monomials,
            eqs,
            meas,
            manifest_path,
        };
        prob.derive_groups(ds, settings)?;
        Ok(prob)
    }

    /// The modes an unknown involves (for visibility), or `None` for force unknowns.
    fn unknown_modes(&self, u: &Unknown) -> Vec<Vec<usize>> {
        match u {
            Unknown::OmegaSq(n) | Unknown::Gamma(n) => vec![vec![*n]],
            Unknown::Param(p) => {
                let mut out = Vec::new();
                for (n, terms) in self.eqs.iter().enumerate() {
                    for t in terms {
                        if t.params.iter().any(|(q, _)| q == p) {
                            let mut s: Vec<usize> = self.monomials[t.monomial]
                                .factors()
                                .iter()
                                .map(|(v, _)| v.index())
                                .collect();
                            s.push(n);
                            s.sort_unstable();
                            s.dedup();
                            out.push(s);
                        }
                    }
                }
                out
            }
            Unknown::Force { .. } | Unknown::Gain { .. } => Vec::new(),
        }
    }

    /// Whether unknown `u` is visible in measurement `mi`.
    fn visible(&self, ui: usize, mi: usize) -> bool {
        let act = &self.meas[mi].active;
        match &self.unknowns[ui] {
            Unknown::Force { meas, .. } => *meas == mi,
            Unknown::Gain { meas, mode, .. } => {
                meas.is_none_or(|m| m == mi)
                    && self.meas[mi]
                        .drive_idx
                        .iter()
                        .any(|&i| self.meas[mi].mode_of[i] == *mode)
            }
            u => self
                .unknown_modes(u)
                .iter()
                .any(|s| s.iter().all(|n| act.contains(n))),
        }
    }

    fn unknown_label(&self, u: &Unknown) -> String {
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

    fn derive_groups(&mut self, ds: &Dataset, settings: &Settings) -> Result<(), IdentError> {
        let nu = self.unknowns.len();
        let nmeas = self.meas.len();
        let mut determined: Vec<bool> = self.fixed.iter().map(|v| v.is_finite()).collect();
        // Fixed-Q modes: γ is derived, not fitted.
        let mut stages: Vec<(usize, Vec<usize>)> = Vec::new();
        if settings.joint {
            stages.push((0, (0..nmeas).collect()));
        } else {
            let max_s = self.meas.iter().map(|m| m.active.len()).max().unwrap_or(0);
            for s in 1..=max_s {
                let ms: Vec<usize> = (0..nmeas)
                    .filter(|&m| self.meas[m].active.len() == s)
                    .collect();
                if !ms.is_empty() {
                    stages.push((s, ms));
                }
            }
        }
        let shot0 = self.shot_rows_all(ds, 0);
        for (stage, ms) in stages {
            // Free unknowns per measurement.
            let free: Vec<Vec<usize>> = ms
                .iter()
                .map(|&m| {
                    (0..nu)
                        .filter(|&u| !determined[u] && self.visible(u, m))
                        .collect()
                })
                .collect();
            // Union measurements sharing a free unknown.
            let mut comp: Vec<usize> = (0..ms.len()).collect();
            fn find(c: &mut [usize], i: usize) -> usize {
                let mut r = i;
                while c[r] != r {
                    r = c[r];
                }
                c[i] = r;
                r
            }
            for a in 0..ms.len() {
                for b in a + 1..ms.len() {
                    if free[a].iter().any(|u| free[b].contains(u)) {
                        let (ra, rb) = (find(&mut comp, a), find(&mut comp, b));
                        comp[ra] = rb;
                    }
                }
            }
            let mut roots: Vec<usize> = (0..ms.len()).map(|i| find(&mut comp, i)).collect();
            let order = roots.clone();
            roots.sort_unstable();
            roots.dedup();
            let mut new_groups = Vec::new();
            for r in roots {
                let members: Vec<usize> = (0..ms.len()).filter(|&i| order[i] == r).collect();
                let measurements: Vec<usize> = members.iter().map(|&i| ms[i]).collect();
                let mut unknowns: Vec<usize> =
                    members.iter().flat_map(|&i| free[i].clone()).collect();
                unknowns.sort_unstable();
                unknowns.dedup();
                if unknowns.is_empty() {
                    continue;
                }
                // Rank check on shot 0: drop unknowns along null directions.
                loop {
                    let values = vec![f64::NAN; nu];
                    let (a, _, _) = self.assemble(&shot0, &measurements, &unknowns, &values, None);
                    let rows = a.nrows();
                    if rows < unknowns.len() {
                        let names: Vec<String> = unknowns.iter().map(|&u| self.label(u)).collect();
                        return Err(IdentError::TooFewFrequencies {
                            file: self.manifest_path.clone(),
                            what: self.meas_names(ds, &measurements),
                            rows,
                            unknowns: unknowns.len(),
                            names: names.join(", "),
                        });
                    }
                    let b = DVector::zeros(rows);
                    let none = vec![None; unknowns.len()];
                    let sol = solve_ls(&a, &b, &none, &none);
                    let smax = sol.singular_values.first().copied().unwrap_or(0.0);
                    let smin = sol.singular_values.last().copied().unwrap_or(0.0);
                    let drop = if let Some(&z) = sol.zero_columns.first() {
                        Some((
                            z,
                            "its regressor column is zero at the measured frequencies".to_string(),
                        ))
                    } else if smin <= settings.rank_tol * smax {
                        let w = &sol.weakest_direction;
                        let j = (0..w.len())
                            .max_by(|&i, &k| w[i].abs().total_cmp(&w[k].abs()))
                            .unwrap_or(0);
                        let others: Vec<String> = (0..w.len())
                            .filter(|&i| i != j && w[i].abs() > 0.1)
                            .map(|i| self.label(unknowns[i]))
                            .collect();
                        Some((
                            j,
                            format!(
                                "its regressor column is collinear with {} at the measured frequencies",
                                if others.is_empty() { "the others".to_string() } else { others.join(", ") }
                            ),
                        ))
                    } else {
                        None
                    };
                    match drop {
                        Some((j, why)) => {
                            let u = unknowns.remove(j);
                            self.not_identifiable.push(NotIdentifiable {
                                unknown: u,
                                reason: format!(
                                    "not identifiable from {}: {why}; it needs a measurement whose sidebands it shapes independently (other drive levels or detunings)",
                                    self.meas_names(ds, &measurements)
                                ),
                            });
                        }
                        None => break,
                    }
                    if unknowns.is_empty() {
                        break;
                    }
                }
                if unknowns.is_empty() {
                    continue;
                }
                new_groups.push(FitGroup {
                    stage,
                    measurements,
                    unknowns,
                });
            }
            for g in &new_groups {
                for &u in &g.unknowns {
                    determined[u] = true;
                }
            }
            self.groups.extend(new_groups);
        }
        for (u, &done) in determined.iter().enumerate() {
            if !done && !self.not_identifiable.iter().any(|x| x.unknown == u) {
                let modes = self.unknown_modes(&self.unknowns[u]);
                let need = modes
                    .iter()
                    .map(|s| {
                        s.iter()
                            .map(|&n| self.mode_names[n].as_str())
                            .collect::<Vec<_>>()
                            .join("+")
                    })
                    .collect::<Vec<_>>()
                    .join(" or ");
                self.not_identifiable.push(NotIdentifiable {
                    unknown: u,
                    reason: format!(
                        "no measurement observes the modes it couples together: it needs a measurement with responses near the resonances of {need}"
                    ),
                });
            }
        }
        Ok(())
    }

    fn meas_names(&self, ds: &Dataset, ms: &[usize]) -> String {
        let names: Vec<String> = ms
            .iter()
            .map(|&m| format!("\"{}\"", ds.measurements[m].spec.name))
            .collect();
        format!("measurement {}", names.join(" + "))
    }

    /// Complex equations of every measurement for one shot.
    fn shot_rows_all(&self, ds: &Dataset, shot: usize) -> Vec<MeasRows> {
        let mut scratch: Vec<ProductScratch> = self.meas.iter().map(|m| m.plan.scratch()).collect();
        (0..self.meas.len())
            .map(|mi| self.shot_rows(ds, mi, shot, &mut scratch[mi]))
            .collect()
    }

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

    fn shot_rows(
        &self,
        ds: &Dataset,
        mi: usize,
        shot: usize,
        scratch: &mut ProductScratch,
    ) -> MeasRows {
        let m = &ds.measurements[mi];
        let prep = &self.meas[mi];
        let nf = m.freqs_hz.len();
        let modal = self.modal_spectra(ds, mi, shot);
        let modal_ref: Vec<&[Complex64]> = modal.iter().map(|v| v.as_slice()).collect();
        // Which monomials are needed: those of active equations.
        let mut g: Vec<Vec<Complex64>> = vec![Vec::new(); self.monomials.len()];
        for &n in &prep.active {
            for t in &self.eqs[n] {
                if g[t.monomial].is_empty() {
                    let mut out = vec![Complex64::new(0.0, 0.0); nf];
                    monomial_amplitudes(
                        &prep.plan,
                        &self.monomials[t.monomial],
                        &modal_ref,
                        &mut out,
                        scratch,
                    );
                    g[t.monomial] = out;
                }
            }
        }
        let mut rows = Vec::with_capacity(nf);
        for r in 0..nf {
            let n = prep.mode_of[r];
            let om = 2.0 * PI * m.freqs_hz[r];
            let q = modal[n][r];
            let mut coefs: Vec<(Unknown, Complex64)> = vec![
                (Unknown::OmegaSq(n), q),
                (Unknown::Gamma(n), Complex64::new(0.0, om) * q),
            ];
            let mut rhs = q * (om * om);
            for t in &self.eqs[n] {
                let gm = g[t.monomial][r];
                rhs -= gm * t.konst;
                for &(p, f) in &t.params {
                    match coefs.iter_mut().find(|(u, _)| *u == Unknown::Param(p)) {
                        Some(c) => c.1 += gm * f,
                        None => coefs.push((Unknown::Param(p), gm * f)),
                    }
                }
            }
            for (tone, &i) in prep.drive_idx.iter().enumerate() {
                if i != r {
                    continue;
                }
                match self.force_model {
                    ForceModel::Free | ForceModel::Auto => {
                        for quad in 0..2u8 {
                            let c = if quad == 0 {
                                Complex64::new(-1.0, 0.0)
                            } else {
                                Complex64::new(0.0, -1.0)
                            };
                            coefs.push((
                                Unknown::Force {
                                    meas: mi,
                                    tone,
                                    quad,
                                },
                                c,
                            ));
                        }
                    }
                    ForceModel::GainPerMeasurement | ForceModel::GainPerMode => {
                        let d = prep
                            .drive_c
                            .as_ref()
                            .and_then(|v| v.get(tone).copied())
                            .unwrap_or_default();
                        let meas =
                            (self.force_model == ForceModel::GainPerMeasurement).then_some(mi);
                        for quad in 0..2u8 {
                            let c = if quad == 0 { -d } else { -d * Complex64::i() };
                            let u = Unknown::Gain {
                                meas,
                                mode: n,
                                quad,
                            };
                            match coefs.iter_mut().find(|(x, _)| *x == u) {
                                Some(e) => e.1 += c,
                                None => coefs.push((u, c)),
                            }
                        }
                    }
                }
            }
            let coefs = coefs
                .into_iter()
                .filter_map(|(u, c)| unknown_index(&self.unknowns, &u).map(|i| (i, c)))
                .collect();
            rows.push(Row { coefs, rhs });
        }
        MeasRows { rows }
    }

    /// Real least-squares matrix and right-hand side of a group: rows (re, im) per complex
    /// equation, columns = `unknowns`; known values from `values` (NaN: take `fixed`; both NaN:
    /// 0) moved to the right-hand side. `weights[mi][r]` divides each row. Returns also the
    /// (measurement, frequency) of each complex row.
    fn assemble(
        &self,
        rows: &[MeasRows],
        measurements: &[usize],
        unknowns: &[usize],
        values: &[f64],
        weights: Option<&[Vec<f64>]>,
    ) -> (DMatrix<f64>, DVector<f64>, Vec<(usize, usize)>) {
        let nrow: usize = measurements.iter().map(|&m| rows[m].rows.len()).sum();
        let k = unknowns.len();
        let mut a = DMatrix::zeros(2 * nrow, k);
        let mut b = DVector::zeros(2 * nrow);
        let mut which = Vec::with_capacity(nrow);
        let mut col = vec![usize::MAX; self.unknowns.len()];
        for (j, &u) in unknowns.iter().enumerate() {
            col[u] = j;
        }
        let mut i = 0;
        for &m in measurements {
            for (r, row) in rows[m].rows.iter().enumerate() {
                let w = weights.map_or(1.0, |w| w[m][r]);
                let mut rhs = row.rhs;
                for &(u, c) in &row.coefs {
                    if col[u] != usize::MAX {
                        a[(2 * i, col[u])] += c.re * w;
                        a[(2 * i + 1, col[u])] += c.im * w;
                    } else {
                        let v = if values[u].is_finite() {
                            values[u]
                        } else if self.fixed[u].is_finite() {
                            self.fixed[u]
                        } else {
                            0.0
                        };
                        rhs -= c * v;
                    }
                }
                b[2 * i] = rhs.re * w;
                b[2 * i + 1] = rhs.im * w;
                which.push((m, r));
                i += 1;
            }
        }
        (a, b, which)
    }

    /// Fits every shot of the dataset: returns per-shot values of every unknown (NaN where not
    /// determined) and the per-group diagnostics.
    pub fn fit(&self, ds: &Dataset, settings: &Settings) -> Fit {
        let nshots = ds.measurements.iter().map(|m| m.n_shots).max().unwrap_or(1);
        let nu = self.unknowns.len();
        let mut scratch: Vec<ProductScratch> = self.meas.iter().map(|m| m.plan.scratch()).collect();
        let rows: Vec<Vec<MeasRows>> = (0..nshots)
            .map(|s| {
                (0..self.meas.len())
                    .map(|mi| self.shot_rows(ds, mi, s, &mut scratch[mi]))
                    .collect()
            })
            .collect();
        let mut values = vec![self.fixed.clone(); nshots];
        let mut cov_diag = vec![vec![f64::NAN; nu]; nshots];
        let mut cov_lin: Vec<BTreeMap<usize, [f64; 4]>> = vec![BTreeMap::new(); nshots];
        let mut groups = Vec::new();
        let weighted =
            settings.min_shots_for_weights > 0 && nshots >= settings.min_shots_for_weights;
        // Noise variance of every modal amplitude (per quadrature), from the scatter across
        // shots; relative (all 1) when there are too few shots or the data are noise-free.
        let mut data_var: Vec<Vec<f64>> = self
            .meas
            .iter()
            .map(|m| {
                m.weights
                    .iter()
                    .map(|w| w.iter().map(|x| x * x).sum())
                    .collect()
            })
            .collect();
        let relative_var = data_var.clone();
        let mut absolute = false;
        if weighted {
            let mut all_positive = true;
            for (mi, dv) in data_var.iter_mut().enumerate() {
                let spectra: Vec<Vec<Vec<Complex64>>> =
                    (0..nshots).map(|s| self.modal_spectra(ds, mi, s)).collect();
                for (r, v) in dv.iter_mut().enumerate() {
                    let n = self.meas[mi].mode_of[r];
                    let mean: Complex64 =
                        spectra.iter().map(|x| x[n][r]).sum::<Complex64>() / nshots as f64;
                    let var = spectra
                        .iter()
                        .map(|x| (x[n][r] - mean).norm_sqr())
                        .sum::<f64>()
                        / (2.0 * (nshots as f64 - 1.0));
                    *v = var;
                    all_positive &= var > 0.0;
                }
            }
            if all_positive {
                absolute = true;
            } else {
                data_var = relative_var;
            }
        }
        let gls_iters = if settings.gls {
            settings.gls_iterations
        } else {
            0
        };
        // The shot-averaged dataset (for linearising the noise propagation).
        let mut mean_ds = ds.clone();
        for m in &mut mean_ds.measurements {
            let per = m.freqs_hz.len() * m.points.len();
            let mut mean = vec![Complex64::new(0.0, 0.0); per];
            for s in 0..m.n_shots {
                for (i, x) in mean.iter_mut().enumerate() {
                    *x += m.data[s * per + i] / m.n_shots as f64;
                }
            }
            m.data = mean;
            m.n_shots = 1;
        }
        for g in &self.groups {
            let lower: Vec<Option<f64>> = g.unknowns.iter().map(|&u| self.bounds[u].0).collect();
            let upper: Vec<Option<f64>> = g.unknowns.iter().map(|&u| self.bounds[u].1).collect();
            let mut diag = GroupDiagnostics {
                stage: g.stage,
                measurements: g.measurements.clone(),
                unknowns: g.unknowns.clone(),
                cond: 0.0,
                rms_residual: 0.0,
                rms_rhs: 0.0,
                weighted: settings.gls,
                noise_from_shots: settings.gls && absolute,
                status_bounds: 0,
                rows: 0,
            };
            let mut conds = Vec::new();
            let (mut rss_sum, mut rhs_sum) = (0.0, 0.0);
            // Fixed-Q modes: iterate γ = ω/Q with the fitted ω.
            let iters = (1 + gls_iters).max(if self.fixed_q.iter().any(Option::is_some) {
                3
            } else {
                1
            });
            let mut sols: Vec<Option<(LsSolution, usize, f64, bool)>> = vec![None; nshots];
            for it in 0..iters {
                let gls_now = it > 0 && it <= gls_iters;
                // With many noisy shots: one weighting for all shots, linearised at the median
                // estimate and the shot-averaged spectra (much less noisy than one shot's).
                let shared_l = if gls_now && absolute && settings.sample_covariance && nshots >= 20
                {
                    self.whitening(&rows, g, &values, 0.2)
                } else if gls_now && absolute {
                    let mut xbar = values[0].clone();
                    for (u, xb) in xbar.iter_mut().enumerate() {
                        let mut v: Vec<f64> = values.iter().map(|x| x[u]).collect();
                        v.sort_by(f64::total_cmp);
                        *xb = v[v.len() / 2];
                    }
                    let sigma = self.equation_cov(&mean_ds, g, 0, &xbar, &data_var, &mut scratch);
                    sigma.cholesky().map(|c| c.l())
                } else {
                    None
                };
                for s in 0..nshots {
                    let (mut a, mut b, _) =
                        self.assemble(&rows[s], &g.measurements, &g.unknowns, &values[s], None);
                    let mut whitened = false;
                    let own_l = if gls_now && shared_l.is_none() {
                        self.equation_cov(ds, g, s, &values[s], &data_var, &mut scratch)
                            .cholesky()
                            .map(|c| c.l())
                    } else {
                        None
                    };
                    if let Some(l) = shared_l.as_ref().or(own_l.as_ref()) {
                        if let (Some(wa), Some(wb)) =
                            (l.solve_lower_triangular(&a), l.solve_lower_triangular(&b))
                        {
                            a = wa;
                            b = wb;
                            whitened = true;
                        }
                    }
                    let so = solve_ls(&a, &b, &lower, &upper);
                    if so.x.iter().all(|x| x.is_finite()) {
                        for (j, &u) in g.unknowns.iter().enumerate() {
                            values[s][u] = so.x[j];
                        }
                    }
                    self.update_fixed_q(&mut values[s]);
                    sols[s] = Some((so, a.nrows(), b.norm_squared(), whitened));
                }
            }
            for (s, sol) in sols.into_iter().enumerate() {
                let Some((so, nrows, bnorm2, whitened)) = sol else {
                    continue;
                };
                if so.status != FitStatus::Solved {
                    diag.status_bounds += 1;
                }
                // With known data noise the whitened problem has unit variance; otherwise the
                // scale comes from the residuals.
                let scale = if whitened && absolute { 1.0 } else { so.sigma2 };
                let k = g.unknowns.len();
                for (j, &u) in g.unknowns.iter().enumerate() {
                    cov_diag[s][u] = so.cov_unit[j * k + j] * scale;
                }
                // ω², γ covariance per mode, for f and Q errors.
                for (j, &u) in g.unknowns.iter().enumerate() {
                    if let Unknown::OmegaSq(n) = self.unknowns[u] {
                        if let Some(j2) = g
                            .unknowns
                            .iter()
                            .position(|&v| self.unknowns[v] == Unknown::Gamma(n))
                        {
                            let c = |x: usize, y: usize| so.cov_unit[x * k + y] * scale;
                            cov_lin[s].insert(n, [c(j, j), c(j, j2), c(j2, j), c(j2, j2)]);
                        }
                    }
                }
                conds.push(so.cond);
                rss_sum += so.rss;
                rhs_sum += bnorm2;
                diag.rows = nrows;
            }
            conds.sort_by(f64::total_cmp);
            diag.cond = conds.get(conds.len() / 2).copied().unwrap_or(f64::NAN);
            diag.rms_residual = (rss_sum / rhs_sum.max(f64::MIN_POSITIVE)).sqrt();
            diag.rms_rhs = rhs_sum;
            groups.push(diag);
        }
        Fit {
            values,
            cov_diag,
            cov_lin,
            groups,
        }
    }

    /// Covariance of the group's real equation errors caused by noise on the measured modal
    /// amplitudes, linearised at the current estimate: `Σ = J D Jᵀ`, where `J` is the derivative
    /// of every equation (real, imaginary rows) with respect to the real and imaginary parts of
    /// every modal amplitude (through the linear term and, via the products ĝ, the nonlinear
    /// terms), and `D` the amplitudes' noise variances. Row order as in `assemble`.
    ///
    /// Whitening with `Σ` makes the least squares a generalised (Gauss-Markov) fit that accounts
    /// for noise in the regressors to first order, and gives covariances that match the scatter.
    fn equation_cov(
        &self,
        ds: &Dataset,
        g: &FitGroup,
        shot: usize,
        values: &[f64],
        data_var: &[Vec<f64>],
        scratch: &mut [ProductScratch],
    ) -> DMatrix<f64> {
        let total: usize = g
            .measurements
            .iter()
            .map(|&m| self.meas[m].mode_of.len())
            .sum();
        let mut sigma = DMatrix::<f64>::zeros(2 * total, 2 * total);
        let val = |u: &Unknown| -> f64 {
            self.index_of(u).map_or(0.0, |i| {
                if values[i].is_finite() {
                    values[i]
                } else if self.fixed[i].is_finite() {
                    self.fixed[i]
                } else {
                    0.0
                }
            })
        };
        let mut offset = 0;
        for &mi in &g.measurements {
            let prep = &self.meas[mi];
            let m = &ds.measurements[mi];
            let nf = prep.mode_of.len();
            let modal = self.modal_spectra(ds, mi, shot);
            let modal_ref: Vec<&[Complex64]> = modal.iter().map(|v| v.as_slice()).collect();
            // J[o][2s + quad], complex.
            let mut jac = vec![Complex64::new(0.0, 0.0); nf * 2 * nf];
            for r in 0..nf {
                let n = prep.mode_of[r];
                let om = 2.0 * PI * m.freqs_hz[r];
                let lin = Complex64::new(
                    val(&Unknown::OmegaSq(n)) - om * om,
                    om * val(&Unknown::Gamma(n)),
                );
                jac[r * 2 * nf + 2 * r] += lin;
                jac[r * 2 * nf + 2 * r + 1] += lin * Complex64::i();
            }
            let mut jr = vec![Complex64::new(0.0, 0.0); nf * nf];
            let mut ji = vec![Complex64::new(0.0, 0.0); nf * nf];
            for &n in &prep.active {
                for t in &self.eqs[n] {
                    let b = t.konst
                        + t.params
                            .iter()
                            .map(|&(p, f)| f * val(&Unknown::Param(p)))
                            .sum::<f64>();
                    if b == 0.0 || !b.is_finite() {
                        continue;
                    }
                    let mono = &self.monomials[t.monomial];
                    for &(v, _) in mono.factors() {
                        monomial_jacobian(
                            &prep.plan,
                            mono,
                            &modal_ref,
                            v,
                            &mut jr,
                            &mut ji,
                            &mut scratch[mi],
                        );
                        for o in (0..nf).filter(|&o| prep.mode_of[o] == n) {
                            for s in (0..nf).filter(|&s| prep.mode_of[s] == v.index()) {
                                jac[o * 2 * nf + 2 * s] += jr[o * nf + s] * b;
                                jac[o * 2 * nf + 2 * s + 1] += ji[o * nf + s] * b;
                            }
                        }
                    }
                }
            }
            // Σ_block = Jr D Jrᵀ with real rows (2o: re, 2o+1: im).
            let real = |row: usize, c: usize| -> f64 {
                let z = jac[(row / 2) * 2 * nf + c];
                if row % 2 == 0 {
                    z.re
                } else {
                    z.im
                }
            };
            for r1 in 0..2 * nf {
                for r2 in r1..2 * nf {
                    let mut acc = 0.0;
                    for c in 0..2 * nf {
                        let a = real(r1, c);
                        if a != 0.0 {
                            acc += a * real(r2, c) * data_var[mi][c / 2];
                        }
                    }
                    sigma[(offset + r1, offset + r2)] = acc;
                    sigma[(offset + r2, offset + r1)] = acc;
                }
            }
            offset += 2 * nf;
        }
        sigma
    }

    /// Cholesky factor `L` (`L Lᵀ = Σ`) of the sample covariance of the group's real rows, where `Σ` is the covariance
    /// across shots of the equation residuals evaluated at the median estimate (held fixed):
    /// the equation error the data noise makes, correlations between rows included (the same
    /// noisy amplitude enters several rows through the products). `Σ` is shrunk towards its
    /// diagonal by `shrinkage` (the sample covariance of few shots is noisy). Residuals of
    /// per-shot fits would understate the noise where a row's own unknowns absorb it.
    fn whitening(
        &self,
        rows: &[Vec<MeasRows>],
        g: &FitGroup,
        values: &[Vec<f64>],
        shrinkage: f64,
    ) -> Option<DMatrix<f64>> {
        // Returns the Cholesky factor L of the shrunk sample covariance (whiten with L⁻¹).
        let nshots = rows.len();
        let mut xbar = values.first()?.clone();
        for &u in &g.unknowns {
            let mut v: Vec<f64> = values.iter().map(|x| x[u]).collect();
            v.sort_by(f64::total_cmp);
            xbar[u] = v[v.len() / 2];
        }
        let xv = DVector::from_iterator(g.unknowns.len(), g.unknowns.iter().map(|&u| xbar[u]));
        let mut res: Vec<DVector<f64>> = Vec::with_capacity(nshots);
        for shot_rows in rows {
            let (a, b, _) = self.assemble(shot_rows, &g.measurements, &g.unknowns, &xbar, None);
            res.push(&a * &xv - &b);
        }
        let m = res.first()?.len();
        let mean = res.iter().fold(DVector::zeros(m), |acc, r| acc + r) / nshots as f64;
        let mut cov = DMatrix::<f64>::zeros(m, m);
        for r in &res {
            let d = r - &mean;
            cov += &d * d.transpose();
        }
        cov /= (nshots as f64 - 1.0).max(1.0);
        let dmax = cov.diagonal().max();
        if !(dmax > 0.0 && dmax.is_finite()) {
            return None;
        }
        for i in 0..m {
            // Floor: rows whose residual never moves get the smallest nonzero variance.
            if cov[(i, i)] <= 1e-300 {
                cov[(i, i)] = dmax * 1e-12;
            }
            for j in 0..m {
                if i != j {
                    cov[(i, j)] *= 1.0 - shrinkage;
                }
            }
        }
        cov.cholesky().map(|c| c.l())
    }

    fn update_fixed_q(&self, values: &mut [f64]) {
        for (n, q) in self.fixed_q.iter().enumerate() {
            if let Some(q) = q {
                let Some(iw) = unknown_index(&self.unknowns, &Unknown::OmegaSq(n)) else {
                    continue;
                };
                let Some(ig) = unknown_index(&self.unknowns, &Unknown::Gamma(n)) else {
                    continue;
                };
                if values[iw].is_finite() && values[iw] > 0.0 {
                    values[ig] = values[iw].sqrt() / q;
                }
            }
        }
    }

    /// Index of an unknown.
    pub fn index_of(&self, u: &Unknown) -> Option<usize> {
        unknown_index(&self.unknowns, u)
    }

    /// The monomials of mode `n`'s equation with their coefficient as a function of parameter
    /// values `theta[p]`: `(monomial, b)`.
    pub fn eom_coefficients(&self, n: usize, theta: &[f64]) -> Vec<(PowerProduct, f64)> {
        self.eqs[n]
            .iter()
            .map(|t| {
                let b = t.konst + t.params.iter().map(|&(p, f)| f * theta[p]).sum::<f64>();
                (self.monomials[t.monomial].clone(), b)
            })
            .collect()
    }

    /// Complex force of each drive tone of measurement `mi` on the mode it is attributed to,
    /// from unknown values `values` (N/kg): `(tone, mode, F)`.
    pub fn forces(&self, mi: usize, values: &[f64]) -> Vec<(usize, usize, Complex64)> {
        let prep = &self.meas[mi];
        prep.drive_idx
            .iter()
            .enumerate()
            .map(|(tone, &i)| {
                let n = prep.mode_of[i];
                let get = |u: Unknown| self.index_of(&u).map_or(f64::NAN, |j| values[j]);
                let f = match self.force_model {
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
                        let meas =
                            (self.force_model == ForceModel::GainPerMeasurement).then_some(mi);
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

/// One complex equation: sparse coefficients on unknowns, and the right-hand side.
#[derive(Debug, Clone)]
struct Row {
    coefs: Vec<(usize, Complex64)>,
    rhs: Complex64,
}

#[derive(Debug, Clone)]
struct MeasRows {
    rows: Vec<Row>,
}

/// Diagnostics of one fit group.
#[derive(Debug, Clone)]
pub struct GroupDiagnostics {
    /// Stage (0 for joint).
    pub stage: usize,
    /// Measurement indices.
    pub measurements: Vec<usize>,
    /// Unknown indices fitted.
    pub unknowns: Vec<usize>,
    /// Median over shots of the condition number of the equilibrated matrix.
    pub cond: f64,
    /// `sqrt(Σ RSS / Σ ‖b‖²)` over shots: relative residual of the fit.
    pub rms_residual: f64,
    /// `Σ ‖b‖²` over shots (for reference).
    pub rms_rhs: f64,
    /// Whether the fit is a generalised least squares (equations weighted by the covariance
    /// of their errors).
    pub weighted: bool,
    /// Whether the amplitudes' noise came from the scatter across shots (else: equal noise on
    /// every measured amplitude, scale from the residuals).
    pub noise_from_shots: bool,
    /// Number of shots in which a bound was active (or the bounded solve failed).
    pub status_bounds: usize,
    /// Real rows of the fit.
    pub rows: usize,
}

/// Per-shot results of [`Problem::fit`].
#[derive(Debug, Clone)]
pub struct Fit {
    /// `values[shot][unknown]`.
    pub values: Vec<Vec<f64>>,
    /// Variance of each unknown from the single-shot residuals, `cov_diag[shot][unknown]`.
    pub cov_diag: Vec<Vec<f64>>,
    /// Per shot and mode: covariance of (ω², γ) as `[var ω², cov, cov, var γ]`.
    pub cov_lin: Vec<BTreeMap<usize, [f64; 4]>>,
    /// Per group diagnostics.
    pub groups: Vec<GroupDiagnostics>,
}

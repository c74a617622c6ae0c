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

mod attribution;
mod equations;
mod error;
mod fit;
mod force_model;
mod nonsmooth;
mod regressors;
mod stages;
#[cfg(test)]
mod testkit;
mod unknowns;
mod weighting;

pub(crate) use crate::layout::Unknown;
pub(crate) use attribution::{nearest_mode, nominal_frequencies};
pub use error::IdentError;
pub use fit::{Fit, GroupDiagnostics};
pub use stages::{FitGroup, NotIdentifiable};

use crate::layout::UnknownTable;
use crate::settings::{ForceModel, Settings};
use attribution::MeasPrep;
use equations::Term;
use harmonid_data::Dataset;
use harmonid_model::Model;
use harmonid_poly::PowerProduct;
use regressors::MeasRows;

/// The identification problem, set up once for a model and a dataset.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Mode names.
    pub mode_names: Vec<String>,
    /// Parameter names.
    pub param_names: Vec<String>,
    /// Names of the variables of the equation terms: the modes, then their velocities
    /// (`d(q1)`), as monomial names spell them.
    pub variable_names: Vec<String>,
    /// A term holds a velocity: the regressors need each mode's velocity spectrum.
    velocities: bool,
    /// The unknowns (the layout the output-error fit shares), nominal resonances and the
    /// force model in use.
    pub table: UnknownTable,
    /// Fit groups in order.
    pub groups: Vec<FitGroup>,
    /// Unknowns no measurement determines.
    pub not_identifiable: Vec<NotIdentifiable>,
    /// Warnings found while setting up.
    pub warnings: Vec<String>,
    /// The settings it was set up with.
    settings: Settings,
    /// The shape of the dataset it was set up for.
    shape: DatasetShape,
    monomials: Vec<PowerProduct>,
    eqs: Vec<Vec<Term>>,
    meas: Vec<MeasPrep>,
    /// Per monomial, its split for evaluation in time when it holds a non-smooth factor.
    ns: Vec<Option<nonsmooth::NsMonomial>>,
    /// Per measurement, for a model with non-smooth terms, the harmonics of the common period
    /// its input and measured lines are (empty otherwise).
    ns_lattice: Vec<nonsmooth::Lattice>,
    /// The non-smooth terms (`abs(q1)*q1 in the equation of q1`), for messages.
    nonsmooth_names: Vec<String>,
    /// Canonical name of each monomial (`q1^3`, `abs(q1)*q1`).
    monomial_names: Vec<String>,
    manifest_path: String,
}

impl Problem {
    /// Sets up the problem: checks the model and the dataset against each other, attributes
    /// frequencies to modes, builds product plans, derives the stages. The settings and the
    /// dataset's shape are kept: [`Problem::fit`] takes a dataset of this shape only.
    pub fn new(model: &Model, ds: &Dataset, settings: &Settings) -> Result<Problem, IdentError> {
        model.check_identifiable()?;
        let mode_names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
        let names_ref: Vec<&str> = mode_names.iter().map(String::as_str).collect();
        ds.check_modes(&names_ref)?;
        let manifest_path = ds.dir.join("dataset.toml").display().to_string();
        let nominal_hz = attribution::nominal_frequencies(model, ds, settings)?;
        let (monomials, eqs) = equations::build_equations(model, &mode_names)?;
        let monomials_for_ns = monomials.clone();
        let force_model =
            force_model::resolve_force_model(settings.force_model, ds, &manifest_path)?;
        let max_deg = model.max_degree() as usize;
        let pump_terms = model
            .has_pump_terms()
            .then(|| model.pump_term_names().join(", "));
        let mut meas = Vec::with_capacity(ds.measurements.len());
        let mut tone_modes = Vec::with_capacity(ds.measurements.len());
        for mi in 0..ds.measurements.len() {
            let prep = attribution::prepare_measurement(
                ds,
                mi,
                &mode_names,
                &nominal_hz,
                settings,
                max_deg,
                pump_terms.as_deref(),
                &manifest_path,
            )?;
            tone_modes.push(prep.drive_idx.iter().map(|&i| prep.mode_of[i]).collect());
            meas.push(prep);
        }
        crate::background::check(ds, settings)?;
        let table = UnknownTable::new(model, nominal_hz, force_model, tone_modes);
        // The background's unknowns (after all others): the output-error fit's only; the
        // equation-error stages leave them at zero (`crate::background`).
        let table = match settings.background.terms() {
            [] => table,
            terms => {
                let modes = crate::background::modes_with_lines(ds, table.nominal_hz());
                let fixed = crate::background::fixed_values(ds, settings, &mode_names);
                table.with_background(terms, &modes, &fixed)
            }
        };
        let mut prob = Problem {
            mode_names,
            param_names: model.params.iter().map(|p| p.name.clone()).collect(),
            variable_names: model.variable_names(),
            velocities: model.has_velocity_terms(),
            table,
            groups: Vec::new(),
            not_identifiable: Vec::new(),
            warnings: Vec::new(),
            settings: settings.clone(),
            shape: DatasetShape::of(ds),
            monomials,
            eqs,
            meas,
            ns: nonsmooth::split_monomials(model, &monomials_for_ns),
            ns_lattice: Vec::new(),
            nonsmooth_names: model.nonsmooth_term_names(),
            monomial_names: monomials_for_ns
                .iter()
                .map(|m| model.monomial_name(m))
                .collect(),
            manifest_path,
        };
        if model.has_nonsmooth() {
            prob.ns_lattice = nonsmooth::lattices(&prob, ds)?;
        }
        prob.derive_groups(ds)?;
        Ok(prob)
    }

    /// The settings the problem was set up with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The shape of the dataset the problem was set up for.
    pub fn shape(&self) -> &DatasetShape {
        &self.shape
    }

    /// Checks that `ds` has the shape of the dataset the problem was set up for (same
    /// measurements, frequencies and points; any number of shots).
    pub fn check_shape(&self, ds: &Dataset) -> Result<(), IdentError> {
        let other = DatasetShape::of(ds);
        if other.measurements == self.shape.measurements {
            Ok(())
        } else {
            Err(IdentError::ShapeMismatch {
                file: ds.dir.join("dataset.toml").display().to_string(),
            })
        }
    }

    /// The value of unknown `i` moved to the right-hand side: its estimate in `values` when
    /// finite, else the model's fixed value, else 0 (not yet estimated).
    fn known_value(&self, values: &[f64], i: usize) -> f64 {
        if values[i].is_finite() {
            values[i]
        } else {
            self.table.fixed()[i].unwrap_or(0.0)
        }
    }

    /// γ = ω/Q of the modes whose Q is fixed while f is identified, from the fitted ω².
    fn update_fixed_q(&self, values: &mut [f64]) {
        for n in 0..self.mode_names.len() {
            if let Some(q) = self.table.fixed_q(n) {
                let Some(iw) = self.index_of(&Unknown::OmegaSq(n)) else {
                    continue;
                };
                let Some(ig) = self.index_of(&Unknown::Gamma(n)) else {
                    continue;
                };
                if values[iw].is_finite() && values[iw] > 0.0 {
                    values[ig] = values[iw].sqrt() / q;
                }
            }
        }
    }
}

/// The shape of a dataset as a problem sees it: per measurement its name, the number of
/// measured frequencies, points and shots.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatasetShape {
    /// `(name, frequencies, points)` per measurement.
    pub measurements: Vec<(String, usize, usize)>,
    /// Shots per measurement.
    pub shots: Vec<usize>,
}

impl DatasetShape {
    /// The shape of `ds`.
    pub fn of(ds: &Dataset) -> Self {
        DatasetShape {
            measurements: ds
                .measurements
                .iter()
                .map(|m| (m.spec.name.clone(), m.freqs_hz.len(), m.points.len()))
                .collect(),
            shots: ds.measurements.iter().map(|m| m.n_shots).collect(),
        }
    }

    /// The largest number of shots of any measurement.
    pub fn max_shots(&self) -> usize {
        self.shots.iter().copied().max().unwrap_or(1).max(1)
    }
}

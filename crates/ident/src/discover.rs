//! Which terms do the data support? Starting from a model, candidate terms from a library are
//! added one at a time while the data demand them, then every parameter the data do not need
//! is removed: stepwise selection by the likelihood-ratio test of the output-error fits
//! ([`identify`]), Bonferroni-corrected for the number of candidates tried at each step.
//!
//! **Library.** All monomials of the modes (no velocities) of the given equation degrees,
//! either per equation (each `(equation, monomial)` its own parameter, `b{n}_{exponents}`:
//! `b1_011` is `q2·q3` in the equation of q1) or as potential terms (one parameter `u_{exponents}`
//! per monomial `M` of degree `d + 1`, whose derivatives `∂M/∂q_n` enter every equation:
//! conservative couplings, tied as the method's paper ties them). Terms the model already has
//! are left out. With [`Library::velocities`], also every monomial of the positions and
//! velocities that holds a velocity, per equation (`b1_2_1` is `q1²·d(q1)` in the equation of
//! q1, one mode): nonlinear damping and velocity couplings. With [`Library::nonsmooth`], also
//! the non-analytic family of each mode in its own equation (one parameter each):
//! `abs(qn)*qn` (`b{n}_absq`, a stiffness growing like the amplitude), `abs(d(qn))*d(qn)`
//! (`b{n}_absdq`, quadratic drag) and `sign(d(qn))` (`b{n}_signdq`, Coulomb friction). No cross
//! forms (`abs(q2)*q1`, `abs(d(q1))*d(q2)`): a non-smooth force comes from one place on the
//! structure (a contact, a clamp, the fluid at the tip) and acts on the displacement there,
//! `u = Σ φₙ qₙ`; its `|u|·u` projected on the modes is not a sum of products of per-mode
//! factors, so a per-mode cross product would be a guess, not a physical term. On one driven
//! mode (the sweeps these terms are found on) the own forms are what the data can tell.
//!
//! **Test.** Adding a candidate to the current model lowers the fit's `χ²` by `Δ`. With the
//! noise from the shots, `Δ/E₀` (`E₀` a correct model's `χ²/dof`) is `χ²₁` when the candidate
//! is not in the device; with the noise from the residual (one shot), the residual sum of
//! squares falls by `Δ`, taken over the richer fit's residual per degree of freedom (the
//! F-test's statistic, read as `χ²₁`). The best candidate is added when its p-value times the number of
//! candidates tried is below `alpha` (family-wise error `alpha` per step); candidates the data
//! do not determine (reported not identifiable, or relative standard error above 1) are
//! skipped. Then, while some parameter's removal (fixing it at zero) raises `χ²` by less than
//! that corrected threshold over the number of parameters, the least needed one is removed.
//!
//! **Held-out selection.** With measurements or sweeps held out ([`DiscoverSettings::holdout`]),
//! which an error floor ([`Settings::error_floor`]) requires (the floor brings every fit's `χ²`
//! to its expectation, so the test above has nothing left to test), every fit is made without
//! them and judged by how well it predicts them ([`crate::identify_with_holdout`]): the pooled
//! relative RMS `r` of the held-out amplitudes. A richer model's gain over a simpler one is
//! `1 − r_richer/r_simpler`; the best candidate is added when it gains more than
//! [`DiscoverSettings::min_improvement`], and a parameter is removed while its removal loses
//! less than that and the fit does not find it nonzero (`|value| ≥ 2 stderr`: the held-out
//! data may not need a term the others determine). Candidates the remaining measurements do
//! not determine are skipped; the starting model need not be determined by them.
//!
//! Every step is a full identification, so the work is bounded: at most `max_added` terms,
//! and a library larger than the data's real residuals minus the model's unknowns, or above
//! [`MAX_CANDIDATES`], is refused with the count.

use crate::compare::pooled_holdout;
use crate::finalize::Report;
use crate::holdout::fit_and_predict;
use crate::identify::identify;
use crate::problem::IdentError;
use crate::settings::{Estimator, Settings};
use crate::uncertainty::chi2_tail;
use harmonid_data::Dataset;
use harmonid_model::{Bounds, Model, NonSmooth, ParamKind, Parameter};
use harmonid_poly::{Coeff, Poly, PowerProduct, Rational, VarId};
use serde::Serialize;

/// Most candidate terms a library may hold (each step fits every one).
pub const MAX_CANDIDATES: usize = 400;

/// How library terms enter the equations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LibraryForm {
    /// Each (equation, monomial) its own parameter.
    Equation,
    /// Each potential monomial one parameter, its derivatives in every equation.
    Potential,
}

/// The candidate terms.
#[derive(Debug, Clone, PartialEq)]
pub struct Library {
    /// Degrees of the equation terms (a potential monomial has one more); a repeated degree
    /// counts once.
    pub degrees: Vec<u32>,
    /// Per equation or as potentials.
    pub form: LibraryForm,
    /// Also every monomial of those degrees that holds a velocity (`q1^2*d(q1)`,
    /// `d(q1)^3`, `q2^2*d(q1)`: nonlinear damping, own and cross), always per equation (a
    /// potential has no velocities): `b{n}_{position exponents}_{velocity exponents}`.
    pub velocities: bool,
    /// Also the non-analytic family of each mode in its own equation: `abs(qn)*qn`
    /// (`b{n}_absq`), `abs(d(qn))*d(qn)` (`b{n}_absdq`), `sign(d(qn))` (`b{n}_signdq`); no cross
    /// forms (see the module documentation). With it `degrees` may be empty (this family alone).
    pub nonsmooth: bool,
}

/// Settings of a discovery.
#[derive(Debug, Clone)]
pub struct DiscoverSettings {
    /// The identification's settings (the estimator is always output-error ML, and its staged
    /// start does not scan: [`Settings::staged_scan`] is off).
    pub identify: Settings,
    /// Family-wise error per step (default 0.01).
    pub alpha: f64,
    /// Most terms added (default 10).
    pub max_added: usize,
    /// Measurements or sweeps held out (names as for [`crate::identify_with_holdout`]): when
    /// not empty, terms are selected by how well the fit of the rest predicts them.
    pub holdout: Vec<String>,
    /// With a holdout: the least relative drop of the held-out RMS that adds a term (and the
    /// least relative rise that keeps one), e.g. 0.05 for 5 % (default).
    pub min_improvement: f64,
}

impl Default for DiscoverSettings {
    fn default() -> Self {
        DiscoverSettings {
            identify: Settings {
                jackknife: false,
                ..Settings::default()
            },
            alpha: 0.01,
            max_added: 10,
            holdout: Vec::new(),
            min_improvement: 0.05,
        }
    }
}

/// One accepted step.
#[derive(Debug, Clone, Serialize)]
pub struct DiscoveryStep {
    /// `"added"` or `"removed"`.
    pub action: &'static str,
    /// The parameter.
    pub parameter: String,
    /// The term in words: `q2*q3 in the equation of q1`, `potential q1*q2*q3`.
    pub term: String,
    /// `χ²` the term takes away (added) or that its removal adds (removed), in noise units
    /// (selection by `χ²`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delta_chi2: Option<f64>,
    /// The likelihood-ratio p-value, uncorrected (selection by `χ²`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p_value: Option<f64>,
    /// The held-out relative RMS (a fraction) before the step (held-out selection).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_rms_before: Option<f64>,
    /// The held-out relative RMS after the step (held-out selection).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_rms_after: Option<f64>,
    /// Candidates (or parameters) it was chosen among: the Bonferroni factor.
    pub among: usize,
    /// The value the fit gives it (added), or had (removed).
    pub value: f64,
}

/// What a discovery found.
#[derive(Debug, Clone, Serialize)]
pub struct Discovery {
    /// Candidate terms in the library (those the model did not have).
    pub candidates: usize,
    /// The accepted steps, in order.
    pub steps: Vec<DiscoveryStep>,
    /// Identifications run (with a holdout each is a fit and a prediction).
    pub fits: usize,
    /// What selects the terms: `"chi2"` (the likelihood-ratio test) or `"holdout"`.
    pub selected_by: &'static str,
    /// The measurements or sweeps held out (held-out selection).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_out: Vec<String>,
    /// The selected model's held-out relative RMS (held-out selection).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_relative_rms: Option<f64>,
    /// The selected model.
    #[serde(skip)]
    pub model: Model,
    /// Its identification (with a holdout: without the held-out data, their prediction in
    /// [`Report::holdout`]).
    #[serde(skip)]
    pub result: Report,
}

/// Why a discovery cannot run.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum DiscoverError {
    /// The library holds nothing the model does not have.
    #[error("the library (degrees {degrees:?}, {form:?} form) has no candidate term the model does not already have")]
    #[diagnostic(
        code(harmonid::discover::no_candidates),
        help("widen it: other degrees (--degrees 2,3), the per-equation form, velocity terms (--velocities) or the non-analytic family (--nonsmooth)")
    )]
    NoCandidates {
        /// The degrees.
        degrees: Vec<u32>,
        /// The form.
        form: LibraryForm,
    },
    /// More candidates than the data or the budget allow.
    #[error("the library has {candidates} candidate terms, more than {limit} ({why})")]
    #[diagnostic(
        code(harmonid::discover::too_large),
        help("narrow it: fewer degrees, or the potential form (one parameter per monomial)")
    )]
    TooLarge {
        /// Candidates.
        candidates: usize,
        /// The limit.
        limit: usize,
        /// Which limit.
        why: String,
    },
    /// A bad setting.
    #[error("{0}")]
    #[diagnostic(code(harmonid::discover::setting))]
    Setting(String),
    /// The model itself cannot be identified by the output-error fit.
    #[error("the starting model: {0}")]
    #[diagnostic(code(harmonid::discover::start))]
    Start(String),
    /// An identification failed.
    #[error(transparent)]
    #[diagnostic(code(harmonid::discover::identify))]
    Identify(#[from] IdentError),
}

/// One candidate: its parameter name, its terms per equation and, for a potential, the
/// monomial; with `factor`, every term's monomial is multiplied by that non-smooth factor
/// (the term goes into `Model::nonsmooth`).
#[derive(Debug, Clone)]
struct Candidate {
    name: String,
    terms: Vec<(usize, PowerProduct, Rational)>,
    potential: Option<PowerProduct>,
    factor: Option<NonSmooth>,
    words: String,
}

/// A fit's misfit and the scale of one degree of freedom's share: with shot noise `χ²` and
/// `E₀`; without (the noise is the residual's, so every fit's `χ²` is its dof), the residual
/// sum of squares relative to the data's, `relative_rms²`, and its value per dof.
struct Fitted {
    chi2: f64,
    scale: f64,
    /// With a holdout: the prediction's pooled relative RMS of the held-out amplitudes.
    holdout: Option<f64>,
    report: Report,
}

/// `model`'s output-error fit to `ds` (without the `held` measurements when any, and then
/// judged by its prediction of them); `None` when it fails, does not converge or (with a
/// holdout, and `determined`) the rest does not determine it.
fn fit(
    model: &Model,
    ds: &Dataset,
    settings: &Settings,
    held: &[String],
    determined: bool,
) -> Option<Fitted> {
    let report = if held.is_empty() {
        identify(model, ds, settings).ok()?
    } else {
        fit_and_predict(model, ds, held, settings, determined)
            .ok()?
            .ok()?
    };
    let holdout = if held.is_empty() {
        None
    } else {
        Some(pooled_holdout(&report, |h| Some(h.relative_rms))?)
    };
    if report.estimator != Estimator::Ml.name() {
        return None;
    }
    let g = report.goodness_of_fit.as_ref()?;
    if !g.converged {
        return None;
    }
    let (chi2, scale) = if g.p_value.is_some() {
        (g.chi2, g.expected_chi2_per_dof)
    } else {
        let rss = g.relative_rms.powi(2);
        (rss, (rss / g.dof.max(1) as f64).max(f64::MIN_POSITIVE))
    };
    Some(Fitted {
        chi2,
        scale,
        holdout,
        report,
    })
}

/// How the steps are judged: the likelihood-ratio test, or the held-out prediction.
#[derive(Debug, Clone, Copy)]
enum Criterion {
    /// Family-wise error per step.
    Chi2 { alpha: f64 },
    /// The least relative drop of the held-out RMS.
    Holdout { min_improvement: f64 },
}

impl Criterion {
    /// What the richer of two fits gains over the simpler: `Δχ²` in noise units (over the
    /// richer fit's scale), or the relative drop of the held-out RMS.
    fn gain(self, simpler: &Fitted, richer: &Fitted) -> f64 {
        match self {
            Criterion::Chi2 { .. } => (simpler.chi2 - richer.chi2) / richer.scale,
            Criterion::Holdout { .. } => match (simpler.holdout, richer.holdout) {
                (Some(s), Some(r)) if s > 0.0 => 1.0 - r / s,
                _ => f64::NEG_INFINITY,
            },
        }
    }

    /// Whether a gain among `among` tries is significant (adds a term, or keeps one).
    fn significant(self, gain: f64, among: usize) -> bool {
        match self {
            Criterion::Chi2 { alpha } => chi2_tail(gain, 1.0) * (among as f64) < alpha,
            Criterion::Holdout { min_improvement } => gain > min_improvement,
        }
    }
}

/// Runs the discovery; `progress(done, total)` is called after every identification of a
/// step. See the module documentation.
pub fn discover(
    model: &Model,
    ds: &Dataset,
    library: &Library,
    settings: &DiscoverSettings,
    mut progress: impl FnMut(usize, usize),
) -> Result<Discovery, DiscoverError> {
    check_settings(settings, library)?;
    // Without the staged start's scan of poorly started groups: most models tried lack a term
    // the device has, their groups fit poorly from every start, and the scan cannot make
    // them fit (three cubic modes: a third of the discovery's time, the same terms found).
    let ident = Settings {
        estimator: Estimator::Ml,
        staged_scan: false,
        ..settings.identify.clone()
    };
    let mut pool = candidates(model, library);
    if pool.is_empty() {
        return Err(DiscoverError::NoCandidates {
            degrees: library.degrees.clone(),
            form: library.form,
        });
    }
    let held = settings.holdout.as_slice();
    let current = model.clone();
    // The start need not be determined without the held-out data (a wrong model's error bars
    // are inflated by the floor): it is where the search starts, not a selected model.
    let here = fit(&current, ds, &ident, held, false)
        .ok_or_else(|| start_error(model, ds, &ident, held))?;
    check_room(&pool, &here)?;
    let total = pool.len();
    let criterion = if held.is_empty() {
        Criterion::Chi2 {
            alpha: settings.alpha,
        }
    } else {
        Criterion::Holdout {
            min_improvement: settings.min_improvement,
        }
    };
    let mut search = Search {
        ds,
        ident,
        held,
        criterion,
        current,
        here,
        steps: Vec::new(),
        fits: 1,
    };
    // Forward: the candidate that gains most, while its gain is significant.
    for _ in 0..settings.max_added {
        if !search.add_best(&mut pool, total, &mut progress) {
            break;
        }
    }
    // Backward: the least needed parameter while its removal is not significant.
    let mut removed = false;
    while search.remove_weakest() {
        removed = true;
    }
    let Search {
        ident,
        current,
        here,
        steps,
        mut fits,
        ..
    } = search;
    // The selected model's own fit: after a removal, the parameter is gone rather than fixed
    // at zero, so the result lists it no more; otherwise the last fit is that model's.
    let here = if removed {
        fits += 1;
        fit(&current, ds, &ident, held, true).unwrap_or(here)
    } else {
        here
    };
    Ok(Discovery {
        candidates: total,
        steps,
        fits,
        selected_by: if held.is_empty() { "chi2" } else { "holdout" },
        held_out: held.to_vec(),
        holdout_relative_rms: here.holdout,
        model: current,
        result: here.report,
    })
}

/// Why the starting model has no fit to start from: the identification's error or first
/// warning, or (with a holdout) what the rest does not determine.
fn start_error(model: &Model, ds: &Dataset, ident: &Settings, held: &[String]) -> DiscoverError {
    let why = |r: Result<Report, IdentError>| {
        r.map(|r| r.warnings.first().cloned().unwrap_or_default())
            .unwrap_or_else(|e| e.to_string())
    };
    DiscoverError::Start(if held.is_empty() {
        why(identify(model, ds, ident))
    } else {
        match fit_and_predict(model, ds, held, ident, false) {
            Ok(Err(u)) => u.message,
            Ok(Ok(r)) => why(Ok(r)),
            Err(e) => e.to_string(),
        }
    })
}

/// The settings a discovery cannot start without: a family-wise error in (0, 1), equation-term
/// degrees from 1 to 7, a holdout with an error floor and a least improvement in [0, 1).
fn check_settings(settings: &DiscoverSettings, library: &Library) -> Result<(), DiscoverError> {
    if settings.identify.error_floor && settings.holdout.is_empty() {
        return Err(DiscoverError::Setting(
            "--error-floor without --holdout: with an error floor every fit's χ² is brought to its expectation, so the likelihood-ratio test cannot select terms; hold out measurements or sweeps to select by their prediction (--holdout NAME, e.g. the strongest drive level's sweeps; Python holdout=[...])".into(),
        ));
    }
    if !(0.0..1.0).contains(&settings.min_improvement) {
        return Err(DiscoverError::Setting(format!(
            "--min-improvement {} (Python min_improvement=): give the least relative drop of the held-out RMS that adds a term, from 0 to below 1, e.g. 0.05",
            settings.min_improvement
        )));
    }
    if !(settings.alpha > 0.0 && settings.alpha < 1.0) {
        return Err(DiscoverError::Setting(format!(
            "alpha = {}: give a family-wise error between 0 and 1, e.g. 0.01",
            settings.alpha
        )));
    }
    if (library.degrees.is_empty() && !library.nonsmooth)
        || library.degrees.iter().any(|&d| d == 0 || d > 7)
    {
        return Err(DiscoverError::Setting(format!(
            "degrees {:?}: give equation-term degrees from 1 to 7, e.g. 2,3 (or none with --nonsmooth, Python nonsmooth=True: that family alone)",
            library.degrees
        )));
    }
    Ok(())
}

/// The pool fits the data and the budget: no more candidates than the data's real residuals
/// minus the starting model's unknowns (`here` is its fit), nor than [`MAX_CANDIDATES`].
fn check_room(pool: &[Candidate], here: &Fitted) -> Result<(), DiscoverError> {
    let n_real = here
        .report
        .goodness_of_fit
        .as_ref()
        .map_or(0, |g| 2 * g.lines.len());
    let k = n_real - here.report.goodness_of_fit.as_ref().map_or(0, |g| g.dof);
    let room = n_real.saturating_sub(k);
    for (limit, why) in [
        (
            room,
            "the data's real residuals minus the model's unknowns".to_string(),
        ),
        (
            MAX_CANDIDATES,
            "the budget of one identification per candidate and step".into(),
        ),
    ] {
        if pool.len() > limit {
            return Err(DiscoverError::TooLarge {
                candidates: pool.len(),
                limit,
                why,
            });
        }
    }
    Ok(())
}

/// Where the stepwise search is: the model selected so far and its fit, the steps taken and
/// the identifications run.
struct Search<'a> {
    ds: &'a Dataset,
    ident: Settings,
    held: &'a [String],
    criterion: Criterion,
    current: Model,
    here: Fitted,
    steps: Vec<DiscoveryStep>,
    fits: usize,
}

impl Search<'_> {
    /// One forward step: adds the determined candidate of `pool` that gains most, if its gain
    /// is significant among the candidates tried. Returns whether one was added.
    fn add_best(
        &mut self,
        pool: &mut Vec<Candidate>,
        total: usize,
        progress: &mut impl FnMut(usize, usize),
    ) -> bool {
        let among = pool.len();
        let mut best: Option<(usize, f64, Fitted, Model)> = None;
        for (i, c) in pool.iter().enumerate() {
            // A candidate whose terms overflow exact arithmetic cannot be written: skipped.
            let Some(trial) = with_candidate(&self.current, c) else {
                continue;
            };
            let f = fit(&trial, self.ds, &self.ident, self.held, true);
            self.fits += 1;
            progress(self.fits, total * (self.steps.len() + 1));
            let Some(f) = f else { continue };
            let determined = f.report.parameters.get(&c.name).is_some_and(|e| {
                e.identifiable && e.stderr.is_finite() && e.stderr < e.value.abs()
            });
            if !determined {
                continue;
            }
            let delta = self.criterion.gain(&self.here, &f);
            if best.as_ref().is_none_or(|b| delta > b.1) {
                best = Some((i, delta, f, trial));
            }
        }
        let Some((i, delta, f, trial)) = best else {
            return false;
        };
        if !self.criterion.significant(delta, among) {
            return false;
        }
        let c = pool.remove(i);
        let value = f.report.parameters[&c.name].value;
        self.steps
            .push(self.step("added", c.name, c.words, delta, among, value, &f));
        self.current = trial;
        self.here = f;
        true
    }

    /// One backward step: removes the free parameter whose removal loses least, if that loss
    /// is not significant among the parameters tried. Returns whether one was removed.
    fn remove_weakest(&mut self) -> bool {
        let current = &self.current;
        let free: Vec<usize> = (0..current.params.len())
            .filter(|&p| current.params[p].kind == ParamKind::Unknown)
            .collect();
        let among = free.len();
        let mut weakest: Option<(usize, f64, Fitted, Model)> = None;
        for &p in &free {
            // Held-out selection: a parameter the fit finds nonzero (|value| ≥ 2 stderr) stays,
            // whatever the held-out data need (they may not see it at all).
            let nonzero = self
                .here
                .report
                .parameters
                .get(&current.params[p].name)
                .is_some_and(|e| {
                    e.identifiable && e.stderr.is_finite() && e.value.abs() >= 2.0 * e.stderr
                });
            if matches!(self.criterion, Criterion::Holdout { .. }) && nonzero {
                continue;
            }
            let mut trial = current.clone();
            trial.params[p].kind = ParamKind::Fixed(0.0);
            trial.params[p].bounds = Bounds::default();
            let f = fit(&trial, self.ds, &self.ident, self.held, true);
            self.fits += 1;
            let Some(f) = f else { continue };
            let delta = self.criterion.gain(&f, &self.here);
            if weakest.as_ref().is_none_or(|w| delta < w.1) {
                weakest = Some((p, delta, f, trial));
            }
        }
        let Some((p, delta, f, trial)) = weakest else {
            return false;
        };
        if self.criterion.significant(delta, among) {
            return false;
        }
        let name = current.params[p].name.clone();
        let value = self
            .here
            .report
            .parameters
            .get(&name)
            .map_or(f64::NAN, |e| e.value);
        let term = terms_of(current, p);
        let step = self.step("removed", name, term, delta, among, value, &f);
        self.steps.push(step);
        // Dropped from the model; fixed at zero (the same equations) should that overflow.
        self.current = without(&trial, p).unwrap_or(trial);
        self.here = f;
        true
    }
}

impl Search<'_> {
    /// The record of a step from the current fit to `after`, whose gain (of the richer over
    /// the simpler of the two) is `gain` among `among` tries.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &self,
        action: &'static str,
        parameter: String,
        term: String,
        gain: f64,
        among: usize,
        value: f64,
        after: &Fitted,
    ) -> DiscoveryStep {
        let by_chi2 = matches!(self.criterion, Criterion::Chi2 { .. });
        DiscoveryStep {
            action,
            parameter,
            term,
            delta_chi2: by_chi2.then_some(gain),
            p_value: by_chi2.then(|| chi2_tail(gain, 1.0)),
            holdout_rms_before: self.here.holdout,
            holdout_rms_after: after.holdout,
            among,
            value,
        }
    }
}

/// Every library term the model does not have.
fn candidates(model: &Model, library: &Library) -> Vec<Candidate> {
    let nm = model.modes.len();
    let taken = |name: &str| model.params.iter().any(|p| p.name == name);
    let unique = |base: String| {
        let mut name = base;
        while taken(&name) {
            name.push('_');
        }
        name
    };
    let vars: Vec<String> = model.variable_names();
    let exps = |m: &PowerProduct| -> String {
        (0..nm)
            .map(|v| m.exponent(VarId(v as u32)).to_string())
            .collect()
    };
    let mut out = Vec::new();
    // A degree given twice (`--degrees 3,3,3`) is one degree: each candidate once, or the
    // library and the multiple-testing count would be inflated by repeats.
    let mut degrees: Vec<u32> = Vec::with_capacity(library.degrees.len());
    for &d in &library.degrees {
        if !degrees.contains(&d) {
            degrees.push(d);
        }
    }
    for d in degrees {
        if library.velocities {
            velocity_candidates(model, d, &vars, &unique, &mut out);
        }
        match library.form {
            LibraryForm::Equation => {
                for m in monomials(nm, d) {
                    for n in 0..nm {
                        if model.eom[n].coeff(&m).is_some() {
                            continue;
                        }
                        out.push(Candidate {
                            name: unique(format!("b{}_{}", n + 1, exps(&m))),
                            words: format!(
                                "{} in the equation of {}",
                                m.name(&vars),
                                model.modes[n].name
                            ),
                            terms: vec![(n, m.clone(), Rational::from_integer(1))],
                            potential: None,
                            factor: None,
                        });
                    }
                }
            }
            LibraryForm::Potential => {
                for m in monomials(nm, d + 1) {
                    if model.potential.coeff(&m).is_some() {
                        continue;
                    }
                    let terms: Vec<(usize, PowerProduct, Rational)> = (0..nm)
                        .filter_map(|n| {
                            let (k, rest) = m.derivative(VarId(n as u32))?;
                            Some((n, rest, Rational::from_integer(i128::from(k))))
                        })
                        .collect();
                    // Already in every equation it would enter (written per equation).
                    if terms
                        .iter()
                        .all(|(n, r, _)| model.eom[*n].coeff(r).is_some())
                    {
                        continue;
                    }
                    out.push(Candidate {
                        name: unique(format!("u_{}", exps(&m))),
                        words: format!("potential {}", m.name(&vars)),
                        terms,
                        potential: Some(m),
                        factor: None,
                    });
                }
            }
        }
    }
    if library.nonsmooth {
        nonsmooth_candidates(model, &vars, &unique, &mut out);
    }
    out
}

/// The non-analytic family of each mode in its own equation: `abs(qn)*qn`,
/// `abs(d(qn))*d(qn)`, `sign(d(qn))` (those the model does not have).
fn nonsmooth_candidates(
    model: &Model,
    vars: &[String],
    unique: &dyn Fn(String) -> String,
    out: &mut Vec<Candidate>,
) {
    let nm = model.modes.len();
    for n in 0..nm {
        let (q, dq) = (VarId(n as u32), VarId((nm + n) as u32));
        for (tag, factor, poly) in [
            ("absq", NonSmooth::Abs(q), PowerProduct::var(q)),
            ("absdq", NonSmooth::Abs(dq), PowerProduct::var(dq)),
            ("signdq", NonSmooth::Sign(dq), PowerProduct::one()),
        ] {
            if has_nonsmooth_term(model, n, factor, &poly) {
                continue;
            }
            let mut words = factor.name(vars);
            if !poly.is_one() {
                words = format!("{words}*{}", poly.name(vars));
            }
            out.push(Candidate {
                name: unique(format!("b{}_{tag}", n + 1)),
                words: format!("{words} in the equation of {}", model.modes[n].name),
                terms: vec![(n, poly, Rational::from_integer(1))],
                potential: None,
                factor: Some(factor),
            });
        }
    }
}

/// Whether the equation of mode `n` has the term `factor · poly` (one factor, to the first
/// power, times the polynomial part `poly`).
fn has_nonsmooth_term(model: &Model, n: usize, factor: NonSmooth, poly: &PowerProduct) -> bool {
    model.nonsmooth.get(n).is_some_and(|eq| {
        eq.terms().any(|(m, _)| {
            let (p, fs) = model.split_nonsmooth(m);
            p == *poly
                && matches!(fs.as_slice(), [(k, 1)] if model.nonsmooth_factors.get(*k) == Some(&factor))
        })
    })
}

/// The per-equation candidates of degree `d` that hold a velocity (variables `nm..2nm`).
fn velocity_candidates(
    model: &Model,
    d: u32,
    vars: &[String],
    unique: &dyn Fn(String) -> String,
    out: &mut Vec<Candidate>,
) {
    let nm = model.modes.len();
    let digits = |m: &PowerProduct, from: usize| -> String {
        (from..from + nm)
            .map(|v| m.exponent(VarId(v as u32)).to_string())
            .collect()
    };
    for m in monomials(2 * nm, d) {
        if (nm..2 * nm).all(|v| m.exponent(VarId(v as u32)) == 0) {
            continue;
        }
        for n in 0..nm {
            if model.eom[n].coeff(&m).is_some() {
                continue;
            }
            out.push(Candidate {
                name: unique(format!("b{}_{}_{}", n + 1, digits(&m, 0), digits(&m, nm))),
                words: format!(
                    "{} in the equation of {}",
                    m.name(vars),
                    model.modes[n].name
                ),
                terms: vec![(n, m.clone(), Rational::from_integer(1))],
                potential: None,
                factor: None,
            });
        }
    }
}

/// Every monomial of degree `d` in `nm` variables, lexicographic.
fn monomials(nm: usize, d: u32) -> Vec<PowerProduct> {
    fn rec(nm: usize, v: usize, left: u32, e: &mut Vec<u32>, out: &mut Vec<PowerProduct>) {
        if v + 1 == nm {
            e[v] = left;
            out.push(PowerProduct::from_exponents(e));
            return;
        }
        for k in (0..=left).rev() {
            e[v] = k;
            rec(nm, v + 1, left - k, e, out);
        }
    }
    let mut out = Vec::new();
    if nm > 0 {
        rec(nm, 0, d, &mut vec![0; nm], &mut out);
    }
    out
}

/// `model` with candidate `c`'s parameter and terms (`None` when exact arithmetic overflows).
fn with_candidate(model: &Model, c: &Candidate) -> Option<Model> {
    let mut m = model.clone();
    let p = VarId(m.params.len() as u32);
    m.params.push(Parameter {
        name: c.name.clone(),
        kind: ParamKind::Unknown,
        bounds: Bounds::default(),
    });
    // A non-smooth factor: its variable (an existing one, or a new one after the others).
    let factor_var = c.factor.map(|f| {
        let k = match m.nonsmooth_factors.iter().position(|g| *g == f) {
            Some(k) => k,
            None => {
                m.nonsmooth_factors.push(f);
                m.nonsmooth_factors.len() - 1
            }
        };
        m.nonsmooth_var(k)
    });
    if m.nonsmooth.len() < m.modes.len() {
        m.nonsmooth.resize(m.modes.len(), Poly::zero());
    }
    for (n, mono, k) in &c.terms {
        let coeff = Coeff::param(p).checked_scale_rational(k).ok()?;
        match factor_var {
            None => {
                m.eom[*n] = m.eom[*n]
                    .checked_add(&Poly::term(mono.clone(), coeff))
                    .ok()?;
            }
            Some(v) => {
                // The factor's variable comes after every polynomial one: the product's
                // factors stay sorted.
                let mono = mono.checked_mul(&PowerProduct::var(v)).ok()?;
                m.nonsmooth[*n] = m.nonsmooth[*n].checked_add(&Poly::term(mono, coeff)).ok()?;
            }
        }
    }
    if let Some(pm) = &c.potential {
        m.potential = m
            .potential
            .checked_add(&Poly::term(pm.clone(), Coeff::param(p)))
            .ok()?;
    }
    Some(m)
}

/// The terms parameter `p` enters, in words.
fn terms_of(model: &Model, p: usize) -> String {
    let mut out = Vec::new();
    for (n, m, c) in model.all_terms() {
        if c.variables().iter().any(|v| v.index() == p) {
            out.push(format!(
                "{} in the equation of {}",
                model.monomial_name(m),
                model.modes[n].name
            ));
        }
    }
    out.join(", ")
}

/// `model` (where parameter `p` is fixed at zero) without `p`: its terms dropped, the later
/// parameters renumbered (`None` when exact arithmetic overflows).
fn without(model: &Model, p: usize) -> Option<Model> {
    let zero_and_shift = |poly: &Poly| -> Option<Poly> {
        let mut out = Poly::zero();
        for (mono, c) in poly.terms() {
            let c = without_param(c, p)?;
            if !c.is_zero() {
                out = out.checked_add(&Poly::term(mono.clone(), c)).ok()?;
            }
        }
        Some(out)
    };
    let mut m = model.clone();
    m.eom = m.eom.iter().map(zero_and_shift).collect::<Option<_>>()?;
    m.nonsmooth = m
        .nonsmooth
        .iter()
        .map(zero_and_shift)
        .collect::<Option<_>>()?;
    m.potential = zero_and_shift(&m.potential)?;
    m.dissipation = zero_and_shift(&m.dissipation)?;
    m.params.remove(p);
    Some(m)
}

/// Coefficient `c` with parameter `p` at zero and the later parameters renumbered down by one
/// (`None` when exact arithmetic overflows).
fn without_param(c: &Coeff, p: usize) -> Option<Coeff> {
    let mut out = Coeff::zero();
    for (m, r) in c.terms() {
        if m.exponent(VarId(p as u32)) > 0 {
            continue;
        }
        let shifted = m.factors().iter().map(|&(v, k)| {
            let i = v.index();
            (VarId(if i > p { i - 1 } else { i } as u32), k)
        });
        let m = PowerProduct::from_factors(shifted).ok()?;
        out = out.checked_add(&Coeff::term(m, *r)).ok()?;
    }
    Some(out)
}

impl DiscoveryStep {
    /// Why the step was taken: `Δχ² = 563.1  p = 1.8e-124`, or `held-out 21.78 % → 10.20 %`.
    fn evidence(&self) -> String {
        match (self.delta_chi2, self.p_value) {
            (Some(d), Some(p)) => format!("Δχ² = {d:>10.1}  p = {p:.2e}"),
            _ => {
                let pct =
                    |x: Option<f64>| x.map_or("–".into(), |x| format!("{:.2} %", 100.0 * x));
                format!(
                    "held-out {} → {}",
                    pct(self.holdout_rms_before),
                    pct(self.holdout_rms_after)
                )
            }
        }
    }
}

impl Discovery {
    /// The steps and the selected terms as a table for the terminal.
    pub fn table(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "harmonid discover: {} candidate terms, {} identifications",
            self.candidates, self.fits
        );
        if self.steps.is_empty() {
            let _ = writeln!(
                s,
                "no step: the data demand no candidate term, and need every parameter of the model"
            );
        }
        if !self.held_out.is_empty() {
            let _ = writeln!(
                s,
                "selected by the prediction of {} (held out, not fitted): {}",
                self.held_out.join(", "),
                self.holdout_relative_rms.map_or("–".into(), |r| format!(
                    "{:.2} % RMS at the end",
                    100.0 * r
                ))
            );
        }
        for st in &self.steps {
            let _ = writeln!(
                s,
                "  {:<8} {:<12} {:<40} {} (× {} tried) value {:.4e}",
                st.action,
                st.parameter,
                st.term,
                st.evidence(),
                st.among,
                st.value
            );
        }
        let names: Vec<&str> = self.model.params.iter().map(|p| p.name.as_str()).collect();
        let _ = writeln!(s, "selected parameters: {}", names.join(", "));
        if let Some(g) = &self.result.goodness_of_fit {
            let _ = writeln!(s, "its fit: {}", g.one_line());
        }
        s
    }

    /// The steps as JSON (the selected model is written as a model file, its fit as a result
    /// file).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The selected model as a model file, its header naming the steps.
    pub fn model_source(&self, dataset: &str, start: &str) -> String {
        let rule = if self.held_out.is_empty() {
            "family-wise error per step as given".to_string()
        } else {
            format!(
                "selected by the prediction of {} (held out), least improvement as given",
                self.held_out.join(", ")
            )
        };
        let mut header = format!(
            "Selected by harmonid discover from {start} on {dataset}: {} candidate terms, {rule}.",
            self.candidates
        );
        for st in &self.steps {
            header.push_str(&format!(
                "\n{} {} ({}): {} among {}",
                st.action,
                st.parameter,
                st.term,
                st.evidence(),
                st.among
            ));
        }
        self.model.to_source(&header)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(src: &str) -> Model {
        harmonid_model::parse_str(src, "m.hb").expect("model")
    }

    #[test]
    fn libraries_hold_every_monomial_the_model_lacks() {
        // Three modes: 6 quadratic and 10 cubic monomials.
        assert_eq!(monomials(3, 2).len(), 6);
        assert_eq!(monomials(3, 3).len(), 10);
        let m = model("mode q1 at 1 MHz\nmode q2 at 2 MHz\nparam b\neom q1 += b*q1^3\n");
        let per_eq = candidates(
            &m,
            &Library {
                degrees: vec![3],
                form: LibraryForm::Equation,
                velocities: false,
                nonsmooth: false,
            },
        );
        // 4 cubic monomials × 2 equations, less q1^3 in the equation of q1.
        assert_eq!(per_eq.len(), 7);
        // hostile 12: a repeated degree is one degree (it tripled the library).
        let repeated = Library {
            degrees: vec![3, 3, 3],
            form: LibraryForm::Equation,
            velocities: false,
            nonsmooth: false,
        };
        let names = |c: &[Candidate]| c.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
        assert_eq!(names(&candidates(&m, &repeated)), names(&per_eq));
        assert!(per_eq
            .iter()
            .any(|c| c.name == "b1_21" && c.words == "q1^2*q2 in the equation of q1"));
        let pot = candidates(
            &m,
            &Library {
                degrees: vec![3],
                form: LibraryForm::Potential,
                velocities: false,
                nonsmooth: false,
            },
        );
        // 5 quartic monomials; q1^4 would only give q1^3 in q1's equation, which it has.
        assert_eq!(
            pot.len(),
            4,
            "{:?}",
            pot.iter().map(|c| &c.name).collect::<Vec<_>>()
        );
        let c = pot.iter().find(|c| c.name == "u_22").expect("q1^2 q2^2");
        // d/dq1 (q1^2 q2^2) = 2 q1 q2^2, d/dq2 = 2 q1^2 q2.
        let k: Vec<(usize, String, Rational)> = c
            .terms
            .iter()
            .map(|(n, m, k)| (*n, m.name(&["q1", "q2"]), *k))
            .collect();
        assert_eq!(
            k,
            [
                (0, "q1*q2^2".to_string(), Rational::from_integer(2)),
                (1, "q1^2*q2".to_string(), Rational::from_integer(2))
            ]
        );
    }

    #[test]
    fn velocity_libraries_hold_damping_terms_per_equation() {
        let lib = |form| Library {
            degrees: vec![3],
            form,
            velocities: true,
            nonsmooth: false,
        };
        let one = model("mode q1 at 1 MHz\nparam b\npotential: b/4*q1^4\n");
        let c = candidates(&one, &lib(LibraryForm::Potential));
        let got: Vec<(&str, &str)> = c
            .iter()
            .map(|c| (c.name.as_str(), c.words.as_str()))
            .collect();
        assert_eq!(
            got,
            [
                ("b1_2_1", "q1^2*d(q1) in the equation of q1"),
                ("b1_1_2", "q1*d(q1)^2 in the equation of q1"),
                ("b1_0_3", "d(q1)^3 in the equation of q1"),
            ]
        );
        // Two modes: 20 cubic monomials of (q1, q2, d(q1), d(q2)), 16 with a velocity, in
        // each of 2 equations; plus the 8 position monomials per equation.
        let two = model("mode q1 at 1 MHz\nmode q2 at 2 MHz\nparam b\neom q1 += b*q1^2*d(q1)\n");
        let c = candidates(&two, &lib(LibraryForm::Equation));
        assert_eq!(
            c.iter()
                .filter(|c| c.name.matches('_').count() == 2)
                .count(),
            31
        );
        assert_eq!(c.len(), 31 + 8);
        assert!(c
            .iter()
            .any(|c| c.name == "b2_20_10" && c.words == "q1^2*d(q1) in the equation of q2"));
    }

    #[test]
    fn nonsmooth_libraries_hold_each_modes_own_family() {
        let lib = Library {
            degrees: Vec::new(),
            form: LibraryForm::Equation,
            velocities: false,
            nonsmooth: true,
        };
        // The model has abs(q1)*q1 already, and abs(q2) as a factor of another term.
        let m = model(
            "mode q1 at 1 MHz\nmode q2 at 2 MHz\nparam k, c\neom q1 += k*abs(q1)*q1\neom q2 += c*abs(q2)*q2^2\n",
        );
        let c = candidates(&m, &lib);
        let got: Vec<(&str, &str)> = c
            .iter()
            .map(|c| (c.name.as_str(), c.words.as_str()))
            .collect();
        assert_eq!(
            got,
            [
                ("b1_absdq", "abs(d(q1))*d(q1) in the equation of q1"),
                ("b1_signdq", "sign(d(q1)) in the equation of q1"),
                ("b2_absq", "abs(q2)*q2 in the equation of q2"),
                ("b2_absdq", "abs(d(q2))*d(q2) in the equation of q2"),
                ("b2_signdq", "sign(d(q2)) in the equation of q2"),
            ]
        );
        // Added: the model reads back through its source with the term, the factor abs(q2)
        // shared; removed: the term goes, the rest stays.
        let with = |name: &str, m: &Model| {
            let cand = c.iter().find(|c| c.name == name).expect("candidate");
            with_candidate(m, cand).expect("no overflow")
        };
        let w = with("b2_absq", &with("b1_signdq", &m));
        assert_eq!(w.nonsmooth_factors.len(), 3);
        let src = w.to_source("test");
        let back = model(&src);
        let mut names: Vec<String> = back
            .all_terms()
            .map(|(n, mono, _)| format!("{n}:{}", back.monomial_name(mono)))
            .collect();
        names.sort();
        assert_eq!(
            names,
            [
                "0:abs(q1)*q1",
                "0:sign(d(q1))",
                "1:abs(q2)*q2",
                "1:abs(q2)*q2^2"
            ],
            "{src}"
        );
        assert_eq!(
            terms_of(&w, w.param_index("b1_signdq").expect("p")),
            "sign(d(q1)) in the equation of q1"
        );
        let p = w.param_index("k").expect("k");
        let wo = without(&w, p).expect("no overflow");
        let left: Vec<String> = wo
            .all_terms()
            .map(|(_, mono, _)| wo.monomial_name(mono))
            .collect();
        assert_eq!(left.len(), 3, "{left:?}");
        assert!(!left.contains(&"abs(q1)*q1".to_string()));
        // Without degrees and without the family, the library is refused.
        let bad = Library {
            nonsmooth: false,
            ..lib
        };
        let err = check_settings(&DiscoverSettings::default(), &bad).expect_err("empty");
        assert!(err.to_string().contains("--nonsmooth"), "{err}");
    }

    #[test]
    fn a_removed_parameter_takes_its_terms_and_the_rest_renumber() {
        let m = model(
            "mode q1 at 1 MHz\nmode q2 at 2 MHz\nparam a, b, c\neom q1 += a*q1^3 + b*q1*q2^2\neom q2 += c*q2^3 + b*q1^2*q2\n",
        );
        let w = without(&m, 1).expect("no overflow");
        assert_eq!(
            w.params.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(),
            ["a", "c"]
        );
        let vars = w.variable_names();
        let names = w.param_names();
        let eq = |n: usize| -> Vec<String> {
            w.eom[n]
                .terms()
                .map(|(m, c)| format!("{}*{}", c.to_string_with(&names), m.name(&vars)))
                .collect()
        };
        assert_eq!(eq(0), ["a*q1^3"]);
        assert_eq!(eq(1), ["c*q2^3"]);
    }
}

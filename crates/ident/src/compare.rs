//! Which model do the data support? The same dataset fitted by several models, each by
//! [`identify`] (output-error maximum likelihood), ranked by information criteria, with a
//! likelihood-ratio test for every nested pair.
//!
//! Every model is fitted to the same pooled shots with the same noise (each line's scatter
//! over the shots), so the log-likelihoods differ only by their `χ²`:
//! `ln L = −χ²/2 + C`, `C` shared by all models and left out. With one shot the noise is each
//! fit's own residual, and `N ln(RSS)` (the Gaussian likelihood profiled over one noise
//! level, up to a shared constant) stands for `χ²`. `AIC = χ² + 2k` and
//! `BIC = χ² + k ln N` with `k` the fitted unknowns (model quantities, forces or gains) and `N`
//! the real residuals. The model with the smallest BIC is the one the data support; the BIC
//! difference to the next says how strongly (Kass and Raftery: below 2 barely, 2–6 positive,
//! 6–10 strong, above 10 very strong).
//!
//! **Nested pairs.** Model A is taken as nested in B when every monomial of every equation of
//! A is one of B's (B can reproduce A by its extra coefficients) and A has fewer unknowns.
//! This is necessary, not sufficient, for nesting (B could tie its coefficients in a way A
//! does not): read the test as valid for models written as special cases of each other. Then
//! `Δχ² = χ²_A − χ²_B` over the noise expectation `E₀` of `χ²/dof` (the shot-estimated
//! noise's, [`crate::GoodnessOfFit::expected_chi2_per_dof`]) is `χ²` with `Δk` degrees of
//! freedom if A is right, which gives the p-value: a small one says the data need B's extra
//! terms.
//!
//! **Held-out prediction.** With measurements held out ([`compare_with_holdout`]), every model
//! is fitted without them and predicts them ([`identify_with_holdout`]); each model's
//! prediction error is reported beside its criteria. With an error floor
//! ([`Settings::error_floor`]) every fit's `χ²` is brought to its expectation by the floor, so
//! `χ²`, AIC and BIC no longer tell the models apart: the models are then ranked by their
//! held-out prediction error (relative RMS), and a comparison with a floor and nothing held out
//! is refused.

use crate::finalize::Report;
use crate::holdout::{fit_and_predict, HeldOut};
use crate::identify::identify;
use crate::problem::IdentError;
use crate::settings::Settings;
use crate::uncertainty::{chi2_tail, p_text};
use harmonid_data::Dataset;
use harmonid_model::Model;
use serde::Serialize;
use std::collections::BTreeSet;

/// One model's fit in a comparison.
#[derive(Debug, Clone, Serialize)]
pub struct ModelFit {
    /// The model's name (its file, as given).
    pub model: String,
    /// Fitted unknowns `k` (model quantities, forces or gains).
    pub unknowns: usize,
    /// `χ²` of its output-error fit; without shot noise (one shot), `N ln(RSS/Σ|X̄|²)`, the
    /// profile likelihood's equivalent (every fit's own `χ²` is then its dof).
    pub chi2: f64,
    /// Real residuals minus `k`.
    pub dof: usize,
    /// `χ²/dof`.
    pub chi2_per_dof: f64,
    /// Whether the model fits the data ([`crate::GoodnessOfFit::fits`]).
    pub fits: Option<bool>,
    /// Its goodness-of-fit p-value.
    pub p_value: Option<f64>,
    /// `−χ²/2`: the log-likelihood up to a constant all models share.
    pub log_likelihood: f64,
    /// `χ² + 2k`.
    pub aic: f64,
    /// `χ² + k ln N`.
    pub bic: f64,
    /// AIC minus the smallest AIC.
    pub delta_aic: f64,
    /// BIC minus the smallest BIC.
    pub delta_bic: f64,
    /// With measurements held out: the prediction's relative RMS over them, `√(Σ nᵢ rᵢ² / Σ nᵢ)`
    /// over each held-out measurement's (or sweep's) relative RMS `rᵢ` and lines `nᵢ`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_relative_rms: Option<f64>,
    /// With measurements held out and shot noise: the prediction's RMS standardized residual
    /// per quadrature over their lines, in noise sigmas (with the error floor added when the
    /// fit has one; about 1 for a model that predicts as well as it fits).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_rms_sigma: Option<f64>,
    /// The full result of the model's identification.
    #[serde(skip)]
    pub result: Report,
}

/// A likelihood-ratio test of a model against a richer one it is nested in.
#[derive(Debug, Clone, Serialize)]
pub struct NestedTest {
    /// The simpler model.
    pub simpler: String,
    /// The richer model.
    pub richer: String,
    /// `χ²` of the simpler minus that of the richer.
    pub delta_chi2: f64,
    /// Extra unknowns of the richer model.
    pub delta_unknowns: usize,
    /// Probability of a `Δχ²` at least this large if the simpler model is right.
    pub p_value: f64,
}

/// A model the measurements left after the holdout do not determine: not ranked.
#[derive(Debug, Clone, Serialize)]
pub struct NotDetermined {
    /// The model's name.
    pub model: String,
    /// The quantities those measurements do not determine.
    pub quantities: Vec<String>,
    /// Why, in words (the first quantity's reason, and what to hold out instead).
    pub reason: String,
}

/// The comparison of several models on one dataset.
#[derive(Debug, Clone, Serialize)]
pub struct ModelComparison {
    /// Real residuals `N` (the same for every model).
    pub observations: usize,
    /// Every model the comparison could judge, in the order given.
    pub models: Vec<ModelFit>,
    /// With a holdout: the models the other measurements do not determine, left out of the
    /// ranking (in the order given).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_determined: Vec<NotDetermined>,
    /// Every nested pair's likelihood-ratio test (none with an error floor: every `χ²` is then
    /// its expectation, and the held-out prediction compares them instead).
    pub nested: Vec<NestedTest>,
    /// Index of the model the data support (smallest BIC; with an error floor, the smallest
    /// held-out prediction error).
    pub best: usize,
    /// What ranks the models: `"bic"`, or `"holdout"` (with an error floor).
    pub ranked_by: String,
    /// The measurements held out (none: every model fitted to everything).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_out: Vec<String>,
    /// The verdict in words.
    pub verdict: String,
}

/// Why models cannot be compared.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum CompareError {
    /// Fewer than two models.
    #[error("compare needs at least two models, {found} given")]
    #[diagnostic(
        code(harmonid::compare::too_few),
        help("e.g. harmonid compare DATASET duffing.hb duffing_quintic.hb")
    )]
    TooFew {
        /// Models given.
        found: usize,
    },
    /// A model cannot be identified from the dataset.
    #[error("{model}: {source}")]
    #[diagnostic(code(harmonid::compare::model))]
    Model {
        /// The model's name.
        model: String,
        /// Why.
        #[source]
        source: Box<IdentError>,
    },
    /// An error floor makes every fit's `χ²` its expectation: nothing left to rank by.
    #[error("with an error floor every model's χ² is brought to its expectation, so χ², AIC and BIC cannot rank the models: hold out measurements or sweeps for them to predict (--holdout NAME; Python holdout=[...])")]
    #[diagnostic(
        code(harmonid::compare::floor_without_holdout),
        help("name measurements or sweeps the models must predict: --holdout NAME (repeatable; e.g. the strongest drive level's sweep)")
    )]
    FloorWithoutHoldout,
    /// No model is determined by the measurements left after the holdout.
    #[error("--holdout {held}: without it the other measurements determine none of the models: {models}")]
    #[diagnostic(
        code(harmonid::compare::none_determined),
        help("hold out a measurement or sweep the others do not need (e.g. one drive level of several, not the only measurement of a mode or coupling)")
    )]
    NoneDetermined {
        /// The held-out names, comma-separated.
        held: String,
        /// Each model and the quantities it leaves undetermined.
        models: String,
    },
    /// A model's output-error fit failed, so it has no likelihood to compare.
    #[error("{model}: no output-error fit to compare ({why})")]
    #[diagnostic(
        code(harmonid::compare::no_ml_fit),
        help("compare ranks output-error (maximum-likelihood) fits; fix what the warning says, or leave the model out")
    )]
    NoMlFit {
        /// The model's name.
        model: String,
        /// The first warning of its identification.
        why: String,
    },
    /// The models were fitted to different observations (a model whose modes attribute the
    /// lines differently).
    #[error("{a} is fitted to {na} real residuals but {b} to {nb}: the models must share the dataset's modes")]
    #[diagnostic(code(harmonid::compare::different_data))]
    DifferentData {
        /// One model.
        a: String,
        /// Its residuals.
        na: usize,
        /// Another.
        b: String,
        /// Its residuals.
        nb: usize,
    },
}

/// Fits `ds` by each of `models` (name, model) with `settings` (the estimator is always the
/// output-error one) and compares them; see the module documentation.
pub fn compare(
    models: &[(String, Model)],
    ds: &Dataset,
    settings: &Settings,
) -> Result<ModelComparison, CompareError> {
    compare_with_holdout(models, ds, &[], settings)
}

/// [`compare`], every model fitted without the measurements or sweeps named in `held` and
/// judged by how well it predicts them too; with [`Settings::error_floor`], ranked by that
/// prediction (see the module documentation).
pub fn compare_with_holdout(
    models: &[(String, Model)],
    ds: &Dataset,
    held: &[String],
    settings: &Settings,
) -> Result<ModelComparison, CompareError> {
    if models.len() < 2 {
        return Err(CompareError::TooFew {
            found: models.len(),
        });
    }
    if settings.error_floor && held.is_empty() {
        return Err(CompareError::FloorWithoutHoldout);
    }
    let settings = Settings {
        estimator: crate::Estimator::Ml,
        ..settings.clone()
    };
    let mut fits = Vec::with_capacity(models.len());
    let mut not_determined = Vec::new();
    let mut observations = None;
    for (name, model) in models {
        let to_err = |source| CompareError::Model {
            model: name.clone(),
            source: Box::new(source),
        };
        let result = if held.is_empty() {
            identify(model, ds, &settings).map_err(to_err)?
        } else {
            match fit_and_predict(model, ds, held, &settings, true).map_err(to_err)? {
                Ok(r) => r,
                // Not determined without the held-out data: reported, the others ranked.
                Err(u) => {
                    not_determined.push(NotDetermined {
                        model: name.clone(),
                        quantities: u.names,
                        reason: u.message,
                    });
                    continue;
                }
            }
        };
        let (fit, n) = model_fit(name, result)?;
        match observations {
            None => observations = Some((name.clone(), n)),
            Some((ref a, na)) if na != n => {
                return Err(CompareError::DifferentData {
                    a: a.clone(),
                    na,
                    b: name.clone(),
                    nb: n,
                })
            }
            _ => {}
        }
        fits.push(fit);
    }
    if fits.is_empty() {
        return Err(CompareError::NoneDetermined {
            held: held.join(","),
            models: not_determined
                .iter()
                .map(|u| format!("{} ({})", u.model, u.quantities.join(", ")))
                .collect::<Vec<_>>()
                .join("; "),
        });
    }
    let n = observations.map_or(0, |o| o.1);
    let min_aic = fits.iter().map(|f| f.aic).fold(f64::INFINITY, f64::min);
    let min_bic = fits.iter().map(|f| f.bic).fold(f64::INFINITY, f64::min);
    for f in &mut fits {
        f.delta_aic = f.aic - min_aic;
        f.delta_bic = f.bic - min_bic;
    }
    let terms: Vec<BTreeSet<(String, String)>> = fits.iter().map(|f| terms(&f.result)).collect();
    let mut nested = Vec::new();
    // With an error floor every χ² is its expectation: no likelihood-ratio test is valid.
    for (i, a) in fits.iter().enumerate().filter(|_| !settings.error_floor) {
        for (j, b) in fits.iter().enumerate() {
            if i != j && a.unknowns < b.unknowns && terms[i].is_subset(&terms[j]) {
                let dk = b.unknowns - a.unknowns;
                let d = a.chi2 - b.chi2;
                nested.push(NestedTest {
                    simpler: a.model.clone(),
                    richer: b.model.clone(),
                    delta_chi2: d,
                    delta_unknowns: dk,
                    p_value: chi2_tail(d / b.expected_chi2_per_dof(), dk as f64),
                });
            }
        }
    }
    let models = fits;
    let by_holdout = settings.error_floor;
    let key = |m: &ModelFit| {
        if by_holdout {
            m.holdout_relative_rms.unwrap_or(f64::INFINITY)
        } else {
            m.bic
        }
    };
    let best = (0..models.len())
        .min_by(|&a, &b| key(&models[a]).total_cmp(&key(&models[b])))
        .unwrap_or(0);
    let mut verdict = if by_holdout {
        holdout_verdict(&models, best)
    } else {
        verdict(&models, best)
    };
    if !not_determined.is_empty() {
        let names: Vec<String> = not_determined
            .iter()
            .map(|u| format!("{} ({})", u.model, u.quantities.join(", ")))
            .collect();
        verdict.push_str(&format!(
            "; not ranked, because the measurements left after the holdout do not determine them: {}",
            names.join(", ")
        ));
    }
    Ok(ModelComparison {
        observations: n,
        models,
        not_determined,
        nested,
        best,
        ranked_by: if by_holdout { "holdout" } else { "bic" }.into(),
        held_out: held.to_vec(),
        verdict,
    })
}

/// A model's row from its identification `result`, and the real residuals it was fitted to.
fn model_fit(name: &str, result: Report) -> Result<(ModelFit, usize), CompareError> {
    let Some(g) = result.goodness_of_fit.clone() else {
        return Err(CompareError::NoMlFit {
            model: name.to_string(),
            why: result.warnings.first().cloned().unwrap_or_default(),
        });
    };
    let n = 2 * g.lines.len();
    let k = n - g.dof;
    // Without shot noise every fit's χ² is its dof (the noise is its own residual): the
    // Gaussian likelihood profiled over one noise level, N ln(RSS) up to a shared
    // constant, takes its place.
    let chi2 = if g.p_value.is_some() {
        g.chi2
    } else {
        n as f64 * (g.relative_rms.powi(2)).ln()
    };
    let fit = ModelFit {
        model: name.to_string(),
        unknowns: k,
        chi2,
        dof: g.dof,
        chi2_per_dof: g.chi2_per_dof,
        fits: g.fits,
        p_value: g.p_value,
        log_likelihood: -0.5 * chi2,
        aic: chi2 + 2.0 * k as f64,
        bic: chi2 + k as f64 * (n as f64).ln(),
        delta_aic: 0.0,
        delta_bic: 0.0,
        holdout_relative_rms: pooled_holdout(&result, |h| Some(h.relative_rms)),
        holdout_rms_sigma: pooled_holdout(&result, |h| h.rms_sigma_floor.or(h.rms_sigma)),
        result,
    };
    Ok((fit, n))
}

/// A held-out RMS pooled over the held-out measurements and sweeps (each step of a held-out
/// sweep is in its sweep's entry): `√(Σ nᵢ xᵢ² / Σ nᵢ)` with `nᵢ` the entry's lines; `None`
/// when nothing is held out or an entry lacks the value.
pub(crate) fn pooled_holdout(r: &Report, value: impl Fn(&HeldOut) -> Option<f64>) -> Option<f64> {
    let entries: Vec<&HeldOut> = r.holdout.iter().filter(|h| h.sweep.is_none()).collect();
    if entries.is_empty() {
        return None;
    }
    let (mut sum, mut lines) = (0.0, 0usize);
    for h in entries {
        sum += h.lines as f64 * value(h)?.powi(2);
        lines += h.lines;
    }
    (lines > 0).then(|| (sum / lines as f64).sqrt())
}

/// Which model predicts the held-out data best, by how much, and how that compares with its fit.
fn holdout_verdict(models: &[ModelFit], best: usize) -> String {
    let b = &models[best];
    let pct = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{:.2} %", 100.0 * x));
    let runner_up = models
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != best)
        .map(|(_, m)| m)
        .min_by(|x, y| {
            let k = |m: &ModelFit| m.holdout_relative_rms.unwrap_or(f64::INFINITY);
            k(x).total_cmp(&k(y))
        });
    let mut s = format!(
        "{} predicts the held-out data best ({} RMS of their amplitudes",
        b.model,
        pct(b.holdout_relative_rms)
    );
    if let Some(r) = runner_up {
        s.push_str(&format!(
            ", against {} for {}",
            pct(r.holdout_relative_rms),
            r.model
        ));
    }
    s.push_str("; ranked by prediction because the error floor makes every χ² its expectation)");
    s
}

/// Every (equation, monomial) of a result's model.
fn terms(r: &Report) -> BTreeSet<(String, String)> {
    r.eom
        .iter()
        .flat_map(|(mode, row)| row.keys().map(move |m| (mode.clone(), m.clone())))
        .collect()
}

/// A criterion difference: one decimal below 10⁵, exponent form above.
fn delta(x: f64) -> String {
    if x.abs() < 1e5 {
        format!("{x:.1}")
    } else {
        format!("{x:.3e}")
    }
}

/// The strength of evidence for a BIC difference (Kass and Raftery 1995).
fn strength(delta_bic: f64) -> &'static str {
    match delta_bic {
        d if d > 10.0 => "very strongly",
        d if d > 6.0 => "strongly",
        d if d > 2.0 => "positively",
        _ => "barely",
    }
}

/// Which model the data support, how strongly, and whether it fits.
fn verdict(models: &[ModelFit], best: usize) -> String {
    let b = &models[best];
    let runner_up = models
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != best)
        .map(|(_, m)| m)
        .min_by(|x, y| x.bic.total_cmp(&y.bic));
    let mut s = match runner_up {
        Some(r) => format!(
            "the data {} support {} (BIC {} below {}'s)",
            strength(r.delta_bic),
            b.model,
            delta(r.delta_bic),
            r.model
        ),
        None => format!("the data support {}", b.model),
    };
    if b.fits == Some(false) {
        s.push_str(&format!(
            "; but even {} does not fit the data (χ²/dof {:.3e}, p {}): the data need something none of these models has",
            b.model,
            b.chi2_per_dof,
            p_text(b.p_value.unwrap_or(f64::NAN))
        ));
    }
    s
}

impl ModelFit {
    /// A correct model's `χ²/dof` with the noise the fit used (its goodness of fit's).
    fn expected_chi2_per_dof(&self) -> f64 {
        self.result
            .goodness_of_fit
            .as_ref()
            .map_or(1.0, |g| g.expected_chi2_per_dof)
    }
}

impl ModelComparison {
    /// The comparison as a table and the verdict.
    pub fn table(&self) -> String {
        use std::fmt::Write as _;
        let w = self
            .models
            .iter()
            .map(|m| m.model.len())
            .chain(self.not_determined.iter().map(|u| u.model.len()))
            .max()
            .unwrap_or(5)
            .max(5);
        let mut s = format!(
            "harmonid compare: {} models on {} real residuals\n\n{:<w$} {:>8} {:>12} {:>10} {:>9} {:>14} {:>10} {:>10}\n",
            self.models.len(),
            self.observations,
            "model",
            "unknowns",
            "chi2/dof",
            "fit p",
            "fits",
            "log L + C",
            "ΔAIC",
            "ΔBIC",
        );
        for m in &self.models {
            let _ = writeln!(
                s,
                "{:<w$} {:>8} {:>12.4e} {:>10} {:>9} {:>14.6e} {:>10} {:>10}",
                m.model,
                m.unknowns,
                m.chi2_per_dof,
                m.p_value.map_or("–".into(), |p| if p < 1e-300 {
                    "<1e-300".into()
                } else {
                    format!("{p:.1e}")
                }),
                match m.fits {
                    Some(true) => "yes",
                    Some(false) => "NO",
                    None => "–",
                },
                m.log_likelihood,
                delta(m.delta_aic),
                delta(m.delta_bic),
            );
        }
        if !self.nested.is_empty() {
            let _ = writeln!(s, "\nnested pairs (likelihood ratio):");
            for t in &self.nested {
                let _ = writeln!(
                    s,
                    "  {} within {}: Δχ² = {:.4e} for {} more unknown(s), p {}{}",
                    t.simpler,
                    t.richer,
                    t.delta_chi2,
                    t.delta_unknowns,
                    p_text(t.p_value),
                    if t.p_value < 1e-3 {
                        ": the data need the richer model's terms"
                    } else {
                        ": the extra terms are not needed"
                    }
                );
            }
        }
        if self.ranked_by == "holdout" && self.models.len() > 1 {
            let _ = writeln!(
                s,
                "\nno likelihood-ratio test of nested pairs: the error floor makes every χ² its expectation (the held-out prediction compares the models)"
            );
        }
        if !self.held_out.is_empty() {
            let _ = writeln!(
                s,
                "\nheld out ({}), predicted by the fit of the rest:",
                self.held_out.join(", ")
            );
            for m in &self.models {
                let _ = writeln!(
                    s,
                    "  {:<w$} {} RMS of the amplitudes{}",
                    m.model,
                    m.holdout_relative_rms
                        .map_or("–".into(), |x| format!("{:.2} %", 100.0 * x)),
                    m.holdout_rms_sigma
                        .map_or(String::new(), |x| format!(", {x:.3} noise sigmas")),
                );
            }
        }
        for u in &self.not_determined {
            let _ = writeln!(s, "  {:<w$} not determined: {}", u.model, u.reason);
        }
        let _ = writeln!(s, "\n{}", self.verdict);
        s
    }

    /// The comparison as JSON (the table's numbers, the nested tests and the verdict).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_tail_and_strength() {
        // χ²₂: P(≥ x) = e^{−x/2}.
        assert!((chi2_tail(6.0, 2.0) - (-3.0f64).exp()).abs() < 1e-12);
        assert_eq!(chi2_tail(-1.0, 3.0), 1.0);
        assert_eq!(strength(12.0), "very strongly");
        assert_eq!(strength(1.0), "barely");
    }
}

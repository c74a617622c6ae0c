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

use crate::finalize::Report;
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

/// The comparison of several models on one dataset.
#[derive(Debug, Clone, Serialize)]
pub struct ModelComparison {
    /// Real residuals `N` (the same for every model).
    pub observations: usize,
    /// Every model, in the order given.
    pub models: Vec<ModelFit>,
    /// Every nested pair's likelihood-ratio test.
    pub nested: Vec<NestedTest>,
    /// Index of the model the data support (smallest BIC).
    pub best: usize,
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
    if models.len() < 2 {
        return Err(CompareError::TooFew {
            found: models.len(),
        });
    }
    let settings = Settings {
        estimator: crate::Estimator::Ml,
        ..settings.clone()
    };
    let mut fits = Vec::with_capacity(models.len());
    let mut observations = None;
    for (name, model) in models {
        let result = identify(model, ds, &settings).map_err(|source| CompareError::Model {
            model: name.clone(),
            source: Box::new(source),
        })?;
        let Some(g) = result.goodness_of_fit.clone() else {
            return Err(CompareError::NoMlFit {
                model: name.clone(),
                why: result.warnings.first().cloned().unwrap_or_default(),
            });
        };
        let n = 2 * g.lines.len();
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
        let k = n - g.dof;
        // Without shot noise every fit's χ² is its dof (the noise is its own residual): the
        // Gaussian likelihood profiled over one noise level, N ln(RSS) up to a shared
        // constant, takes its place.
        let chi2 = if g.p_value.is_some() {
            g.chi2
        } else {
            n as f64 * (g.relative_rms.powi(2)).ln()
        };
        fits.push(ModelFit {
            model: name.clone(),
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
            result,
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
    for (i, a) in fits.iter().enumerate() {
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
    let best = (0..models.len())
        .min_by(|&a, &b| models[a].bic.total_cmp(&models[b].bic))
        .unwrap_or(0);
    let verdict = verdict(&models, best);
    Ok(ModelComparison {
        observations: n,
        models,
        nested,
        best,
        verdict,
    })
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

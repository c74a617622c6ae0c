//! The result's `unfit` groups: the unknowns the identification could not fit, why, and what
//! measurement would help, from what the fit already knows (its failure, the staged start's
//! groups that missed their own measurements, each quantity's verdict).

use super::tables::FIXED_BY_THE_MODEL;
use super::NOT_CONVERGED;
use crate::layout::{Quantity, Unknown};
use crate::output_error::{OutputError, OutputErrorFailure, PoorGroup};
use crate::problem::Problem;
use harmonid_data::result::{Estimate, ModeResult, UnfitGroup, UnfitWhy};
use harmonid_data::text::first_and_more;
use std::collections::{BTreeMap, BTreeSet};

/// What [`unfit_groups`] reads.
pub(super) struct Verdicts<'a> {
    pub prob: &'a Problem,
    /// The output-error fit, when it ran and is reported.
    pub fo: Option<&'a OutputError>,
    /// Why the output-error fit asked for could not be made (the linear estimate reported).
    pub fallback: Option<&'a OutputErrorFailure>,
    pub modes: &'a BTreeMap<String, ModeResult>,
    pub parameters: &'a BTreeMap<String, Estimate>,
}

impl Verdicts<'_> {
    /// Every reported quantity (modes' f and Q, then parameters) with its estimate.
    fn quantities(&self) -> Vec<(Quantity, &Estimate)> {
        let mut out = Vec::new();
        for (n, name) in self.prob.mode_names.iter().enumerate() {
            if let Some(m) = self.modes.get(name) {
                out.push((Quantity::Frequency(n), &m.f_hz));
                out.push((Quantity::Q(n), &m.q));
            }
        }
        for (p, name) in self.prob.param_names.iter().enumerate() {
            if let Some(e) = self.parameters.get(name) {
                out.push((Quantity::Param(p), e));
            }
        }
        out
    }

    fn key(&self, q: Quantity) -> String {
        q.key(&self.prob.mode_names, &self.prob.param_names)
    }

    /// The modes a measurement must respond near to shape `q` (`q1+q2 or q2+q3`).
    fn modes_of(&self, q: Quantity) -> String {
        let u = match q {
            Quantity::Frequency(n) | Quantity::Q(n) => Unknown::OmegaSq(n),
            Quantity::Param(p) => Unknown::Param(p),
            Quantity::Background { mode, .. } => Unknown::OmegaSq(mode),
        };
        self.prob.modes_needed(&u)
    }
}

/// The groups of unknowns not fitted, in the order a user acts on them: the fit that could
/// not be made or did not converge, the staged start's groups that missed their own
/// measurements, then the quantities the data do not determine or hold at a bound (grouped
/// by the modes a measurement must reach to determine them). Empty when every reported
/// quantity was fitted and determined.
pub(super) fn unfit_groups(v: &Verdicts<'_>) -> Vec<UnfitGroup> {
    let quantities = v.quantities();
    let free: Vec<String> = quantities
        .iter()
        .filter(|(_, e)| e.reason.as_deref() != Some(FIXED_BY_THE_MODEL))
        .map(|(q, _)| v.key(*q))
        .collect();
    let mut out = Vec::new();
    if let Some(why) = v.fallback {
        let advice = match why {
            OutputErrorFailure::Setup(_) => "a model the harmonic balance can simulate for this dataset (the detail names what it refused), or --estimator linear",
            _ => "measurements at a lower drive, nearer the linear response, where the pooled linear estimate is a good start and the harmonic balance finds a steady state from it",
        };
        out.push(UnfitGroup {
            why: UnfitWhy::NoOutputError,
            unknowns: free.clone(),
            measurements: Vec::new(),
            chi2_per_dof: None,
            detail: format!("{why}; the pooled equation-error (linear) estimate is reported"),
            advice: advice.into(),
        });
    }
    if let Some(fo) = v.fo {
        out.extend(not_converged(v, fo, &free));
        let e0 = fo.goodness.expected_chi2_per_dof;
        out.extend(fo.poor_groups.iter().map(|g| group_not_fitted(v, e0, g)));
    }
    out.extend(undetermined(v, &quantities));
    out
}

/// The entry of a fit that stopped before converging: every quantity it fitted.
fn not_converged(v: &Verdicts<'_>, fo: &OutputError, free: &[String]) -> Option<UnfitGroup> {
    if fo.fit.converged {
        return None;
    }
    let advice = if fo.poor_groups.is_empty() {
        "a start nearer the estimate: measurements at a lower drive, nearer the linear response (the pooled linear estimate is then a good start), or fewer unknowns (fix the parameters the plan does not determine)".to_string()
    } else {
        "see the groups not fitted (why \"group_not_fitted\"): the joint fit failed where they did, and their measurements would help".to_string()
    };
    let unknowns = v
        .quantities()
        .iter()
        .filter(|(_, e)| e.reason.as_deref() == Some(NOT_CONVERGED))
        .map(|(q, _)| v.key(*q))
        .collect::<Vec<_>>();
    Some(UnfitGroup {
        why: UnfitWhy::NotConverged,
        unknowns: if unknowns.is_empty() {
            free.to_vec()
        } else {
            unknowns
        },
        measurements: Vec::new(),
        chi2_per_dof: None,
        detail: format!(
            "the output-error fit stopped after {} steps before converging (χ² {:.4e} from {:.4e}): the values are where it stopped, not estimates",
            fo.fit.steps, fo.fit.chi2, fo.fit.chi2_start
        ),
        advice,
    })
}

/// The entry of a staged group whose own fit missed its measurements: its quantities, its
/// measurements, and the modes to drive alone (`e0`: a correct model's `χ²/dof`).
fn group_not_fitted(v: &Verdicts<'_>, e0: f64, g: &PoorGroup) -> UnfitGroup {
    let unknowns = v.prob.table.unknowns();
    let mut keys: Vec<String> = Vec::new();
    let mut modes = BTreeSet::new();
    let mut nuisances = 0;
    for &k in &g.unknowns {
        match unknowns.get(k).and_then(Quantity::of) {
            Some(q) => {
                let key = v.key(q);
                if !keys.contains(&key) {
                    keys.push(key);
                }
                match q {
                    Quantity::Frequency(n) | Quantity::Q(n) => {
                        modes.insert(n);
                    }
                    Quantity::Param(p) => {
                        modes.extend(v.prob.mode_sets(&Unknown::Param(p)).into_iter().flatten());
                    }
                    Quantity::Background { mode, .. } => {
                        modes.insert(mode);
                    }
                }
            }
            None => nuisances += 1,
        }
    }
    let mode_list: Vec<&str> = modes
        .iter()
        .map(|&n| v.prob.mode_names[n].as_str())
        .collect();
    let meas: Vec<String> = g.measurements.iter().map(|m| format!("\"{m}\"")).collect();
    UnfitGroup {
        why: UnfitWhy::GroupNotFitted,
        unknowns: keys,
        measurements: g.measurements.clone(),
        chi2_per_dof: Some(g.reduced_chi2),
        detail: format!(
            "the output-error fit of these measurements alone, the unknowns earlier groups fitted held there, missed them (a correct model gives χ²/dof about {e0:.3}){}",
            if nuisances > 0 {
                format!("; with {nuisances} forces or gains of theirs")
            } else {
                String::new()
            }
        ),
        advice: match &mode_list[..] {
            // A single mode's own measurements: driving it alone is what they already do.
            [] | [_] => format!(
                "{} at a lower drive (nearer the linear response, where the linear estimate is a good start); if that fits, the model lacks a term the stronger drive excites",
                first_and_more(meas, 3).join(", ")
            ),
            many => format!(
                "measurements of {} each driven alone (their f and Q fitted before what couples them), or {} at a lower drive (nearer the linear response, where the linear estimate is a good start)",
                many.join(", "),
                first_and_more(meas, 3).join(", ")
            ),
        },
    }
}

/// The quantities the data do not determine or hold at a bound, one entry per reason and
/// set of modes a measurement must reach (fits stopped early and fixed values are not
/// listed: [`not_converged`] has them).
fn undetermined(v: &Verdicts<'_>, quantities: &[(Quantity, &Estimate)]) -> Vec<UnfitGroup> {
    // (why, modes) -> (keys, (key, reason)).
    type Details = Vec<(String, String)>;
    let mut groups: Vec<((UnfitWhy, String), Vec<String>, Details)> = Vec::new();
    for (q, e) in quantities {
        let reason = e.reason.as_deref().unwrap_or("");
        if e.identifiable || reason == FIXED_BY_THE_MODEL || reason == NOT_CONVERGED {
            continue;
        }
        let why = if e.at_bound {
            UnfitWhy::AtBound
        } else {
            UnfitWhy::NotDetermined
        };
        let id = (why, v.modes_of(*q));
        let key = v.key(*q);
        let detail = (key.clone(), reason.to_string());
        match groups.iter_mut().find(|g| g.0 == id) {
            Some(g) => {
                g.1.push(key);
                g.2.push(detail);
            }
            None => groups.push((id, vec![key], vec![detail])),
        }
    }
    groups
        .into_iter()
        .map(|((why, modes), keys, details)| UnfitGroup {
            why,
            unknowns: keys,
            measurements: Vec::new(),
            chi2_per_dof: None,
            // A single quantity's reason alone; several, each named.
            detail: match &details[..] {
                [(_, one)] => one.clone(),
                _ => first_and_more(
                    details.iter().map(|(k, r)| format!("{k}: {r}")).collect(),
                    3,
                )
                .join("; "),
            },
            advice: match why {
                UnfitWhy::AtBound => format!(
                    "check the bound in the model; a measurement with responses near the resonances of {modes} at other drive levels would show whether the data's value beyond it is real"
                ),
                _ => format!(
                    "a measurement with responses near the resonances of {modes} that shapes it independently of the others (other drive levels or detunings; harmonid plan designs one)"
                ),
            },
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::Settings;
    use harmonid_data::Dataset;
    use std::path::Path;

    fn nanostring_2mode() -> Problem {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/nanostring_2mode");
        let model = harmonid_model::load(&dir.join("model.hb")).expect("model");
        let ds = Dataset::load(dir.join("data")).expect("dataset");
        Problem::new(&model, &ds, &Settings::default()).expect("problem")
    }

    /// A staged group whose own fit failed names its quantities (not its gains), its
    /// measurement, and the modes to drive alone.
    #[test]
    fn a_group_not_fitted_names_its_quantities_and_the_modes_to_drive_alone() {
        let prob = nanostring_2mode();
        let (modes, parameters) = (BTreeMap::new(), BTreeMap::new());
        let v = Verdicts {
            prob: &prob,
            fo: None,
            fallback: None,
            modes: &modes,
            parameters: &parameters,
        };
        let table = prob.table.unknowns();
        let g12 = table
            .iter()
            .position(|u| *u == Unknown::Param(2))
            .expect("g12");
        let gains: Vec<usize> = (0..table.len())
            .filter(|&k| Quantity::of(&table[k]).is_none())
            .take(2)
            .collect();
        assert_eq!(gains.len(), 2, "{table:?}");
        let g = group_not_fitted(
            &v,
            1.036,
            &PoorGroup {
                measurements: vec!["couple_q1_q2".into()],
                unknowns: [vec![g12], gains].concat(),
                reduced_chi2: 320.0,
            },
        );
        assert_eq!(g.why, UnfitWhy::GroupNotFitted);
        assert_eq!(g.unknowns, vec!["g12".to_string()]);
        assert_eq!(g.measurements, vec!["couple_q1_q2".to_string()]);
        assert_eq!(g.chi2_per_dof, Some(320.0));
        assert!(
            g.advice
                .starts_with("measurements of q1, q2 each driven alone")
                && g.advice.contains("or \"couple_q1_q2\" at a lower drive"),
            "{}",
            g.advice
        );
        assert!(
            g.detail.ends_with("with 2 forces or gains of theirs"),
            "{}",
            g.detail
        );
    }
}

//! Stages: which measurements determine which unknowns, fitted in which order.

use super::{IdentError, Problem, Unknown};
use crate::solve::solve_ls;
use harmonid_data::{text::first_and_more, Dataset};
use nalgebra::{DMatrix, DVector};

/// A group of measurements fitted together, with its free unknowns.
#[derive(Debug, Clone)]
pub struct FitGroup {
    /// Stage number (number of active modes; 0 for a joint fit).
    pub stage: usize,
    /// Measurement indices.
    pub measurements: Vec<usize>,
    /// Free unknowns (indices into [`Problem::table`]'s unknowns).
    pub unknowns: Vec<usize>,
}

/// An unknown that could not be determined, and why.
#[derive(Debug, Clone)]
pub struct NotIdentifiable {
    /// Index into [`Problem::table`]'s unknowns.
    pub unknown: usize,
    /// Explanation (which measurement would be needed, or which unknowns it is collinear with).
    pub reason: String,
}

impl Problem {
    /// The modes a measurement must respond near to shape unknown `u` (`q1+q2 or q2+q3`):
    /// the advice of a report on an unknown the data do not determine.
    pub(crate) fn modes_needed(&self, u: &Unknown) -> String {
        mode_sets_text(&self.unknown_modes(u), &self.mode_names)
    }

    /// The sets of modes unknown `u` involves (one per monomial it multiplies: its modes and
    /// the equation's), mode indices.
    pub(crate) fn mode_sets(&self, u: &Unknown) -> Vec<Vec<usize>> {
        self.unknown_modes(u)
    }

    /// Whether unknown `u` is visible in measurement `mi`.
    pub(super) fn visible(&self, ui: usize, mi: usize) -> bool {
        let act = &self.meas[mi].active;
        match &self.table.unknowns()[ui] {
            Unknown::Force { meas, .. } => *meas == mi,
            // Not in the equation-error equations (`crate::background`).
            Unknown::Background { .. } => false,
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
    pub(super) fn derive_groups(&mut self, ds: &Dataset) -> Result<(), IdentError> {
        let settings = self.settings.clone();
        let nu = self.table.len();
        let nmeas = self.meas.len();
        let mut determined: Vec<bool> = self.table.fixed().iter().map(Option::is_some).collect();
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
                        let names =
                            first_and_more(unknowns.iter().map(|&u| self.label(u)).collect(), 8);
                        return Err(IdentError::TooFewFrequencies {
                            file: self.manifest_path.clone(),
                            what: measurement_list(ds, &measurements),
                            rows,
                            unknowns: unknowns.len(),
                            names: names.join(", "),
                        });
                    }
                    let drop = self.weakest_unknown(&a, &unknowns, settings.rank_tol);
                    match drop {
                        Some((j, why)) => {
                            let u = unknowns.remove(j);
                            self.not_identifiable.push(NotIdentifiable {
                                unknown: u,
                                reason: format!(
                                    "not identifiable from {}: {why}; it needs a measurement whose sidebands it shapes independently (other drive levels or detunings)",
                                    measurement_list(ds, &measurements)
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
            let background = matches!(self.table.unknowns()[u], Unknown::Background { .. });
            if !done && !background && !self.not_identifiable.iter().any(|x| x.unknown == u) {
                let modes = self.unknown_modes(&self.table.unknowns()[u]);
                let need = mode_sets_text(&modes, &self.mode_names);
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

    /// The unknown to drop from a fit with matrix `a` over `unknowns` (none when its rank is
    /// full): a zero column, or the unknown dominating the weakest direction when the smallest
    /// singular value is below `rank_tol` of the largest; with why.
    fn weakest_unknown(
        &self,
        a: &DMatrix<f64>,
        unknowns: &[usize],
        rank_tol: f64,
    ) -> Option<(usize, String)> {
        let rows = a.nrows();
        let b = DVector::zeros(rows);
        let none = vec![None; unknowns.len()];
        let sol = solve_ls(a, &b, &none, &none);
        let smax = sol.singular_values.first().copied().unwrap_or(0.0);
        let smin = sol.singular_values.last().copied().unwrap_or(0.0);
        if let Some(&z) = sol.zero_columns.first() {
            Some((
                z,
                "its regressor column is zero at the measured frequencies".to_string(),
            ))
        } else if smin <= rank_tol * smax {
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
                    if others.is_empty() {
                        "the others".to_string()
                    } else {
                        others.join(", ")
                    }
                ),
            ))
        } else {
            None
        }
    }
}

/// The measurements `ms` for a message: `measurement "a" + "b"`, at most
/// [`NAMES_SHOWN`] names and then how many more (a stepped sweep fits hundreds together).
pub(super) fn measurement_list(ds: &Dataset, ms: &[usize]) -> String {
    let names = ms
        .iter()
        .map(|&m| format!("\"{}\"", ds.measurements[m].spec.name))
        .collect();
    format!(
        "measurement {}",
        first_and_more(names, NAMES_SHOWN).join(" + ")
    )
}

/// At most this many measurement names are quoted in one message.
const NAMES_SHOWN: usize = 5;

/// The mode sets an unknown couples, as `a+b or a+c`: each set once, in first-seen order.
fn mode_sets_text(sets: &[Vec<usize>], mode_names: &[String]) -> String {
    let mut seen: Vec<&Vec<usize>> = Vec::new();
    for s in sets {
        if !seen.contains(&s) {
            seen.push(s);
        }
    }
    seen.iter()
        .map(|s| {
            s.iter()
                .map(|&n| mode_names[n].as_str())
                .collect::<Vec<_>>()
                .join("+")
        })
        .collect::<Vec<_>>()
        .join(" or ")
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use harmonid_data::{Dataset, Manifest, Measurement, MeasurementSpec};

    #[test]
    fn long_measurement_lists_are_cut_with_a_count() {
        let ms = (0..7)
            .map(|i| {
                let spec = MeasurementSpec::new(format!("s{i}"), vec![1000.0]);
                Measurement::zeros(spec, vec![1000.0], vec![], 1)
            })
            .collect();
        let ds = Dataset::from_parts("d", Manifest::new("t"), ms, None).expect("dataset");
        assert_eq!(
            measurement_list(&ds, &[0, 1, 2, 3, 4, 5, 6]),
            "measurement \"s0\" + \"s1\" + \"s2\" + \"s3\" + \"s4\" + 2 more"
        );
        assert_eq!(
            measurement_list(&ds, &[2, 5]),
            "measurement \"s2\" + \"s5\""
        );
    }
    use super::super::{Problem, Settings, Unknown};
    use super::{measurement_list, mode_sets_text};

    #[test]
    fn single_mode_measurements_come_first_and_the_pair_fits_the_coupling() {
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        assert_eq!(p.groups.len(), 3);
        assert_eq!(
            (p.groups[0].stage, &p.groups[0].measurements),
            (1, &vec![0])
        );
        assert_eq!(
            (p.groups[1].stage, &p.groups[1].measurements),
            (1, &vec![1])
        );
        let g2 = &p.groups[2];
        assert_eq!((g2.stage, &g2.measurements), (2, &vec![2]));
        let names: Vec<&Unknown> = g2
            .unknowns
            .iter()
            .map(|&u| &p.table.unknowns()[u])
            .collect();
        assert!(names.contains(&&Unknown::Param(1)));
        assert!(!names.contains(&&Unknown::Param(0)));
        assert!(!names.contains(&&Unknown::OmegaSq(0)));
        assert!(p.not_identifiable.is_empty());
        let joint = Settings {
            joint: true,
            ..Settings::default()
        };
        let p = Problem::new(&testkit::model(), &ds, &joint).expect("problem");
        assert_eq!(p.groups.len(), 1);
        assert_eq!(p.groups[0].unknowns.len(), p.table.len());
    }

    #[test]
    fn a_coupling_without_a_pair_measurement_is_not_identifiable_once() {
        let ds = testkit::dataset(false, 1, 0.0, 1);
        let p = Problem::new(&testkit::model(), &ds, &Settings::default()).expect("problem");
        assert_eq!(p.not_identifiable.len(), 1);
        let ni = &p.not_identifiable[0];
        assert_eq!(p.table.unknowns()[ni.unknown], Unknown::Param(1));
        assert!(ni.reason.ends_with("resonances of a+b"), "{}", ni.reason);
        let names = vec!["a".to_string(), "b".into(), "c".into()];
        assert_eq!(
            mode_sets_text(&[vec![0, 1], vec![0, 2], vec![0, 1]], &names),
            "a+b or a+c"
        );
    }
}

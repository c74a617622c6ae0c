//! The readable names of the problem's unknowns ([`crate::layout`] lays them out).

use super::Problem;
use crate::layout::Unknown;

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
            Unknown::Background { mode, term, quad } => format!(
                "background {} of {} ({})",
                term.name(),
                self.mode_names[*mode],
                if *quad == 0 { "re" } else { "im" }
            ),
        }
    }

    /// Readable name of unknown `i`.
    pub fn label(&self, i: usize) -> String {
        self.unknown_label(&self.table.unknowns()[i])
    }
    /// Index of an unknown.
    pub fn index_of(&self, u: &Unknown) -> Option<usize> {
        self.table.index_of(u)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use super::super::{ForceModel, Problem, Settings};
    use crate::layout::Unknown;

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
            &p.table.unknowns()[..6],
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
        assert_eq!(p.table.len(), 6 + 2 * 4);
        assert!(p.table.fixed().iter().all(Option::is_none));
        assert_eq!(p.table.bounds()[0], (Some(0.0), None));
        assert_eq!(p.label(4), "beta");
        assert_eq!(p.label(1), "omega/Q of a");
        assert_eq!(p.index_of(&Unknown::Param(1)), Some(5));
    }

    #[test]
    fn gains_per_mode_are_shared_and_free_forces_are_per_tone() {
        let p = setup(ForceModel::GainPerMode);
        assert_eq!(p.table.len(), 6 + 4);
        assert_eq!(p.label(6), "gain of a (re)");
        let p = setup(ForceModel::Free);
        assert_eq!(p.table.len(), 6 + 2 * (2 + 2 + 3));
    }
}

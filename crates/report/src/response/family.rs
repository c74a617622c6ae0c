//! Which sweeps form one frequency-response figure: the single-tone frequency sweeps (not
//! drive ladders) of one constant drive level.

use harmonid_data::{Dataset, Direction, PerStep, SweepSpec};

/// Sweeps of one drive level (or one sweep whose level changes from step to step).
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    /// Legend text: `level 0.1` (the manifest's drive level, in its unit), or the sweep's name.
    pub label: String,
    /// The drive level shared by every step, when there is one.
    pub level: Option<f64>,
    /// Indices of its sweeps in `manifest.sweeps`, in manifest order.
    pub sweeps: Vec<usize>,
}

/// Whether `s` is a frequency sweep this module draws: one drive tone at every step, and not a
/// drive ladder (whose steps share their frequency).
pub fn is_frequency_sweep(s: &SweepSpec) -> bool {
    s.direction != Direction::Level
        && !s.drives_hz.is_empty()
        && s.drives_hz.iter().all(|d| d.len() == 1)
}

/// The drive level of every step of `s`, when the sweep has one and it never changes.
fn constant_level(s: &SweepSpec) -> Option<f64> {
    let levels = s.drive_levels_v.as_ref()?;
    let first = *levels.at(0).first()?;
    let same = match levels {
        PerStep::Same(_) => true,
        PerStep::Each(v) => v
            .iter()
            .all(|l| l.len() == 1 && (l[0] - first).abs() <= 1e-9 * first.abs()),
    };
    same.then_some(first)
}

/// The families of `ds`: sweeps of equal constant drive level together, by rising level;
/// then every frequency sweep without one, alone, in manifest order.
pub fn families(ds: &Dataset) -> Vec<Family> {
    let mut out: Vec<Family> = Vec::new();
    let mut alone: Vec<Family> = Vec::new();
    for (i, s) in ds.manifest.sweeps.iter().enumerate() {
        if !is_frequency_sweep(s) {
            continue;
        }
        match constant_level(s) {
            Some(l) => match out
                .iter_mut()
                .find(|f| f.level.is_some_and(|x| (x - l).abs() <= 1e-9 * l.abs()))
            {
                Some(f) => f.sweeps.push(i),
                None => out.push(Family {
                    label: format!("level {}", harmonid_plot::style::tick(l)),
                    level: Some(l),
                    sweeps: vec![i],
                }),
            },
            None => alone.push(Family {
                label: s.name.clone(),
                level: None,
                sweeps: vec![i],
            }),
        }
    }
    out.sort_by(|a, b| a.level.unwrap_or(0.0).total_cmp(&b.level.unwrap_or(0.0)));
    out.extend(alone);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_data::Manifest;

    fn sweep(name: &str, dir: Direction, levels: Option<PerStep>) -> SweepSpec {
        let mut s = SweepSpec::new(name, dir, vec![vec![1.0], vec![2.0]]);
        s.drive_levels_v = levels;
        s
    }

    #[test]
    fn sweeps_group_by_constant_level_and_ladders_are_left_out() {
        let mut m = Manifest::new("t");
        m.sweeps = vec![
            sweep("up_b", Direction::Up, Some(PerStep::Same(vec![0.2]))),
            sweep("up_a", Direction::Up, Some(PerStep::Same(vec![0.1]))),
            sweep(
                "dn_b",
                Direction::Down,
                Some(PerStep::Each(vec![vec![0.2], vec![0.2]])),
            ),
            sweep(
                "fc",
                Direction::Up,
                Some(PerStep::Each(vec![vec![0.2], vec![0.3]])),
            ),
            sweep("ladder", Direction::Level, Some(PerStep::Same(vec![0.2]))),
        ];
        let ds = Dataset {
            dir: Default::default(),
            manifest: m,
            measurements: Vec::new(),
            truth: None,
            notes: Vec::new(),
        };
        let f = families(&ds);
        let got: Vec<(&str, Vec<usize>)> = f
            .iter()
            .map(|f| (f.label.as_str(), f.sweeps.clone()))
            .collect();
        assert_eq!(
            got,
            [
                ("level 0.1", vec![1]),
                ("level 0.2", vec![0, 2]),
                ("fc", vec![3])
            ]
        );
    }
}

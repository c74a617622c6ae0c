//! A sweep cut into its monotonic passes: a lab's sweep up then down at one level (hysteresis),
//! or a LabOne sweeper in bidirectional mode with several loops (up, down, up, down, … in one
//! file). The output-error forward model follows a branch only along an ordered sweep, so each
//! pass becomes its own sweep, in the order it was measured.
//!
//! A sweep is cut only when it is wholly a chain of passes: each pass of two steps or more,
//! strictly one way, the next pass the other way; its first step may repeat the turning point
//! (a sweeper measures the end of its grid twice). Any other order (points out of order, two
//! steps at one frequency inside a pass) keeps the sweep whole and `unordered`, as before.
//! Names: one turn gives `<name>_up` and `<name>_down` (as since issue 37); more passes give
//! `<name>_up`, `<name>_down`, `<name>_up_2`, `<name>_down_2`, … (the n-th pass that way, as
//! `zi-sweeper` has always named its loops).

use super::{input_path, Grouping, ImportError, Step};
use std::path::PathBuf;

/// A cut sweep: its `[start, end)` range of steps and the suffix of its name (`_up`, `_down`,
/// `_up_2`, … for the passes of a sweep that turns back; empty otherwise).
pub(super) type Cut = (usize, usize, String);

/// The passes of the drives `fs`: each pass's first index and whether it goes up, when `fs`
/// turns back at least once and is wholly a chain of passes, else `None` (a sweep one way, or
/// in any other order). Issue 37's rule for one turn, generalised: the sign of each step (a
/// step to an equal frequency counts as up, as that rule counted it), a new pass where the sign
/// changes, starting at the step after the turn (so a sweeper's repeated bottom point starts
/// the pass that leaves it), and every pass after the first of two steps or more. For one turn
/// it is that rule exactly (tested against it below, on every small sequence).
pub(super) fn passes(fs: &[f64]) -> Option<Vec<(usize, bool)>> {
    if fs.len() < 4 {
        return None;
    }
    let up = |i: usize| fs[i] >= fs[i - 1];
    let mut passes = vec![(0, up(1))];
    for i in 2..fs.len() {
        if up(i) != up(i - 1) {
            if i - passes.last().map_or(0, |p| p.0) < 2 {
                return None;
            }
            passes.push((i, up(i)));
        }
    }
    let last = passes.last().map_or(0, |p| p.0);
    (passes.len() >= 2 && fs.len() - last >= 2).then_some(passes)
}

/// The suffix of each pass of `passes` (`_up`, `_down`, then `_up_2`, `_down_2`, …: the
/// n-th pass that way).
fn suffixes(passes: &[(usize, bool)]) -> Vec<String> {
    let (mut ups, mut downs) = (0, 0);
    passes
        .iter()
        .map(|&(_, up)| {
            let (word, n) = if up {
                ups += 1;
                ("up", ups)
            } else {
                downs += 1;
                ("down", downs)
            };
            if n == 1 {
                format!("_{word}")
            } else {
                format!("_{word}_{n}")
            }
        })
        .collect()
}

/// The sweeps `sweeps`, each that turns back cut into its passes ([`passes`]); when one
/// is, every other sweep one way is named by its direction too (the top level swept up only is
/// `level_0.6_up`, beside the others' `_up` and `_down`). Returns the cuts and, per sweep cut,
/// its first step's index and its number of passes (for the note).
pub(super) fn split_passes(
    steps: &[Step],
    sweeps: &[(usize, usize)],
) -> (Vec<Cut>, Vec<(usize, usize)>) {
    let mut cuts: Vec<Cut> = Vec::new();
    let mut split = Vec::new();
    for &(a, b) in sweeps {
        let fs: Vec<f64> = steps[a..b].iter().map(|s| s.drive).collect();
        match passes(&fs) {
            Some(p) => {
                for (k, suffix) in suffixes(&p).into_iter().enumerate() {
                    let to = p.get(k + 1).map_or(b, |q| a + q.0);
                    cuts.push((a + p[k].0, to, suffix));
                }
                split.push((a, p.len()));
            }
            None => cuts.push((a, b, String::new())),
        }
    }
    if !split.is_empty() {
        for c in cuts.iter_mut().filter(|c| c.2.is_empty() && c.1 - c.0 >= 2) {
            let fs: Vec<f64> = steps[c.0..c.1].iter().map(|s| s.drive).collect();
            if fs.windows(2).all(|w| w[1] > w[0]) {
                c.2 = "_up".into();
            } else if fs.windows(2).all(|w| w[1] < w[0]) {
                c.2 = "_down".into();
            }
        }
    }
    (cuts, split)
}

/// When `grouping` asks ([`Grouping::passes_need_level`]): a sweep without drive levels cut
/// into three passes or more is refused, naming it and its file: it may be several levels, each
/// swept up and down, merged into one (a table without its level column).
pub(super) fn refuse_levelless_passes(
    steps: &[Step],
    split: &[(usize, usize)],
    grouping: &Grouping,
    inputs: &[PathBuf],
) -> Result<(), ImportError> {
    if !grouping.passes_need_level {
        return Ok(());
    }
    let Some(&(a, n)) = split
        .iter()
        .find(|&&(a, n)| n >= 3 && steps[a].level.is_none())
    else {
        return Ok(());
    };
    Err(ImportError::Input {
        path: input_path(inputs, steps[a].origin),
        row: None,
        message: format!(
            "sweep \"{}\" turns back {} times ({n} passes up and down) and the mapping gives no drive level: several drive levels merged into one sweep, each swept up and down? Map the level column ([columns] drive_level = \"<its header>\") or label the sweeps ([columns] sweep = \"<column>\"); if it is one level swept back and forth, give that level ([drive] level = <V>, or [files.\"<file>\"] drive_level = <V>)",
            super::base_name(steps[a].group, steps[a].level, grouping),
            n - 1
        ),
    })
}

/// The note's words on the sweeps cut into passes (`split`: first step and passes of each),
/// empty when none was: `level_0.1 turned back: 3 passes (level_0.1_up, level_0.1_down,
/// level_0.1_up_2)`, or for several `12 sweeps turned back: 23 passes`.
pub(super) fn passes_note(
    steps: &[Step],
    cuts: &[Cut],
    split: &[(usize, usize)],
    grouping: &Grouping,
) -> String {
    match split {
        [] => String::new(),
        [(a, n)] => {
            let base = super::base_name(steps[*a].group, steps[*a].level, grouping);
            let names: Vec<String> = cuts
                .iter()
                .filter(|c| c.0 >= *a && !c.2.is_empty())
                .take(*n)
                .map(|c| format!("{base}{}", c.2))
                .collect();
            format!("; {base} turned back: {n} passes ({})", names.join(", "))
        }
        _ => format!(
            "; {} sweeps turned back: {} passes up and down, each its own sweep",
            split.len(),
            split.iter().map(|s| s.1).sum::<usize>()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 37's one-turn rule, kept as the reference for one turn.
    fn turning_point(fs: &[f64]) -> Option<usize> {
        if fs.len() < 4 {
            return None;
        }
        let dir = (fs[1] - fs[0]).signum();
        if dir == 0.0 {
            return None;
        }
        let k = 1 + fs
            .windows(2)
            .take_while(|w| (w[1] - w[0]).signum() == dir)
            .count();
        if k == fs.len() {
            return None;
        }
        let back = &fs[k..];
        let turns = (fs[k] - fs[k - 1]) * dir <= 0.0
            && back.windows(2).all(|w| (w[1] - w[0]).signum() == -dir);
        (k >= 2 && back.len() >= 2 && turns).then_some(k)
    }

    /// Every sequence of 4 to 8 drives over 0..4 (with repeats): where the old rule finds one
    /// turn, the new finds the same one; where the new finds one, so does the old; more passes
    /// only where the old found none. 4^4 + ... + 4^8 = 87 296 sequences, all brute force.
    #[test]
    fn one_turn_is_cut_as_before_on_every_small_sequence() {
        let (mut one, mut more) = (0, 0);
        for len in 4..=8u32 {
            for code in 0..4usize.pow(len) {
                let fs: Vec<f64> = (0..len)
                    .map(|i| ((code / 4usize.pow(i)) % 4) as f64)
                    .collect();
                let new = passes(&fs).map(|p| p.iter().skip(1).map(|q| q.0).collect::<Vec<_>>());
                match (turning_point(&fs), &new) {
                    (Some(k), Some(c)) => {
                        assert_eq!(c, &vec![k], "{fs:?}");
                        one += 1;
                    }
                    (None, Some(c)) => {
                        assert!(c.len() >= 2, "{fs:?}: {c:?}");
                        more += 1;
                    }
                    (Some(k), None) => panic!("{fs:?}: old cut at {k}, new none"),
                    (None, None) => {}
                }
            }
        }
        assert!(one > 100 && more > 10, "{one} one-turn, {more} multi-pass");
    }

    fn names(fs: &[f64]) -> Option<(Vec<usize>, Vec<String>)> {
        passes(fs).map(|p| (p.iter().map(|q| q.0).collect(), suffixes(&p)))
    }

    #[test]
    fn passes_and_their_names() {
        let (starts, s) = names(&[1.0, 2.0, 3.0, 2.0, 1.0, 2.0, 3.0]).expect("three passes");
        assert_eq!(starts, [0, 3, 5]);
        assert_eq!(s, ["_up", "_down", "_up_2"]);
        // A sweeper's loops measure the bottom twice: the repeat starts the pass up.
        let loops = [1.0, 2.0, 3.0, 2.0, 1.0, 1.0, 2.0, 3.0, 2.0, 1.0];
        let (starts, s) = names(&loops).expect("four passes");
        assert_eq!(starts, [0, 3, 5, 8]);
        assert_eq!(s, ["_up", "_down", "_up_2", "_down_2"]);
        // Down first.
        let (_, s) = names(&[3.0, 2.0, 1.0, 2.0, 3.0, 2.0, 1.0]).expect("three passes");
        assert_eq!(s, ["_down", "_up", "_down_2"]);
        // One point out of order (the sloshing files): a pass of one step, kept whole.
        assert_eq!(passes(&[1.0, 2.0, 3.0, 4.0, 3.5, 5.0, 6.0, 7.0]), None);
        // A last pass of one step: kept whole.
        assert_eq!(passes(&[1.0, 2.0, 3.0, 2.0, 1.0, 2.0]), None);
        // One way only: nothing to cut.
        assert_eq!(passes(&[1.0, 2.0, 3.0, 4.0]), None);
    }
}

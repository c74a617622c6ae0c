//! The drive variants of a coupled measurement, and the choice among them.

use harmonid_sim::NumericModel;
use std::collections::BTreeSet;

/// Variants whose worst bound is within this factor of the best count as comparable; among
/// them the cheapest lattice wins.
pub(crate) const COMPARABLE: f64 = 1.2;

/// How a mode of a coupled measurement is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Tones {
    /// Its stage-1 tone pair.
    Pair,
    /// One tone at the centre of its stage-1 pair (on resonance), at the pair's force per tone.
    Centre,
}

/// A drive of a coupled measurement: `(mode, how)` per driven mode (a mode not listed is left
/// undriven).
pub(crate) type Variant = Vec<(usize, Tones)>;

/// The drives of a coupled measurement with one set of driven modes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DrivenSet {
    /// One mode with its tone pair, the others with one tone each, in every orientation (three
    /// tones for two modes: the paper's coupled measurement); empty for a single driven mode.
    pub three_tone: Vec<Variant>,
    /// Every driven mode with its tone pair (four tones for two modes).
    pub pairs: Variant,
}

/// The drive variants of a measurement coupling `modes`, per set of driven modes: all of
/// them, and all but one whose frequency is a sum or difference of the others' (three-wave
/// `f3 ≈ f1 + f2`, `2f1 ≈ f2`: its line appears through the coupling), fewest driven modes
/// first. Fewer tones make smaller lattices (a three-wave group's three-tone drives 80–130
/// lines, its four-tone ones 440–530): tried first, they set the bound a costlier drive must
/// beat by [`COMPARABLE`] before the design checks it over the range, and a time budget cuts
/// the costly ones, not the cheap ones.
///
/// Why three tones: the pair's intermodulation lines and the other mode's response, both
/// shifted by the coupling, carry the coupling on a lattice several times smaller than two
/// pairs give (for the five-mode nanostring 19–116 lines against 106–576), so the plan is
/// cheap to simulate and identify.
pub(crate) fn coupled_variants(num: &NumericModel, modes: &[usize]) -> Vec<DrivenSet> {
    let mut driven: Vec<BTreeSet<usize>> = vec![modes.iter().copied().collect()];
    for &m in modes {
        let others: Vec<f64> = modes
            .iter()
            .filter(|&&k| k != m)
            .map(|&k| num.f_hz[k])
            .collect();
        let fm = num.f_hz[m];
        let hit = (1..1u32 << (2 * others.len())).any(|mask| {
            let mut sum = 0.0;
            for (i, &fo) in others.iter().enumerate() {
                sum += match (mask >> (2 * i)) & 3 {
                    1 => fo,
                    2 => -fo,
                    3 => 2.0 * fo,
                    _ => 0.0,
                };
            }
            (sum.abs() - fm).abs() <= 0.005 * fm
        });
        if hit {
            driven.push(modes.iter().copied().filter(|&k| k != m).collect());
        }
    }
    driven.sort_by_key(BTreeSet::len);
    driven
        .into_iter()
        .map(|d| DrivenSet {
            three_tone: if d.len() >= 2 {
                d.iter()
                    .map(|&p| {
                        d.iter()
                            .map(|&n| (n, if n == p { Tones::Pair } else { Tones::Centre }))
                            .collect()
                    })
                    .collect()
            } else {
                Vec::new()
            },
            pairs: d.iter().map(|&n| (n, Tones::Pair)).collect(),
        })
        .collect()
}

/// Scored variants `(worst bound, lattice lines, payload)` in the order a design prefers them:
/// first those whose worst bound is within [`COMPARABLE`] of the best, smallest lattice first
/// (cheaper to simulate and identify, for bounds about as good; ties: the smaller bound), then
/// the others by bound (a weaker measurement the lab can use beats one it cannot); none with
/// an infinite bound.
pub(crate) fn preference_order<T>(scored: Vec<(f64, usize, T)>) -> Vec<T> {
    let best = scored.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return Vec::new();
    }
    let (mut near, mut far): (Vec<_>, Vec<_>) = scored
        .into_iter()
        .filter(|v| v.0.is_finite())
        .partition(|v| v.0 <= COMPARABLE * best);
    near.sort_by(|a, b| a.1.cmp(&b.1).then(a.0.total_cmp(&b.0)));
    far.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.into_iter().chain(far).map(|v| v.2).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn num(f_hz: &[f64]) -> NumericModel {
        let names: Vec<String> = (1..=f_hz.len()).map(|i| format!("q{i}")).collect();
        NumericModel::new(names, f_hz.to_vec(), vec![1e4; f_hz.len()], Vec::new())
            .expect("linear model")
    }

    #[test]
    fn two_unrelated_modes_get_the_four_and_both_three_tone_variants() {
        let v = coupled_variants(&num(&[100e3, 173e3]), &[0, 1]);
        assert_eq!(
            v,
            vec![DrivenSet {
                three_tone: vec![
                    vec![(0, Tones::Pair), (1, Tones::Centre)],
                    vec![(0, Tones::Centre), (1, Tones::Pair)],
                ],
                pairs: vec![(0, Tones::Pair), (1, Tones::Pair)],
            }]
        );
    }

    #[test]
    fn a_mode_at_twice_the_other_may_stay_undriven() {
        // 2 f1 ≈ f2 within 0.5 %: q2 responds through the coupling.
        // Fewest driven modes first.
        let v = coupled_variants(&num(&[100e3, 200.3e3]), &[0, 1]);
        assert_eq!(v.len(), 2);
        assert!(v[0].three_tone.is_empty());
        assert_eq!(v[0].pairs, vec![(0, Tones::Pair)]);
        assert_eq!(v[1].three_tone.len(), 2);
        // Three-wave f3 = f1 + f2: each mode may stay undriven; with all three driven (last),
        // one pair and two single tones.
        let v = coupled_variants(&num(&[1.0e6, 1.6e6, 2.6e6]), &[0, 1, 2]);
        assert_eq!(v.len(), 4);
        assert!(v[..3].iter().all(|d| d.three_tone.len() == 2));
        assert_eq!(v[3].three_tone.len(), 3);
        assert_eq!(
            v[3].three_tone[1],
            vec![(0, Tones::Centre), (1, Tones::Pair), (2, Tones::Centre)]
        );
    }

    #[test]
    fn the_cheapest_of_comparable_bounds_wins() {
        // 4-tone 0.020 on 576 lines, 3-tone 0.023 on 116: the 3-tone one.
        assert_eq!(
            preference_order(vec![(0.020, 576, "4"), (0.023, 116, "3")])
                .first()
                .copied(),
            Some("3")
        );
        // The 3-tone one twice as bad: the 4-tone one.
        assert_eq!(
            preference_order(vec![(0.020, 576, "4"), (0.040, 116, "3")])
                .first()
                .copied(),
            Some("4")
        );
        // Equal lattices: the smaller bound.
        assert_eq!(
            preference_order(vec![(0.022, 116, "a"), (0.020, 116, "b")])
                .first()
                .copied(),
            Some("b")
        );
        assert_eq!(
            preference_order(vec![(f64::INFINITY, 10, "x")])
                .first()
                .copied(),
            None
        );
        assert_eq!(preference_order::<&str>(Vec::new()).first().copied(), None);
        // The comparable ones by lattice, then the rest by bound.
        assert_eq!(
            preference_order(vec![
                (0.09, 10, "far"),
                (0.020, 576, "4"),
                (0.023, 116, "3"),
                (0.05, 20, "nearer"),
                (f64::INFINITY, 5, "x")
            ]),
            ["3", "4", "nearer", "far"]
        );
    }
}
